"""results.jsonl -> results.json + results.md: env-steps/s per (candidate, setting) and the ratio to SB3.

The SB3 reference of a setting is the geometric mean of its two runs (first and last in run_all.sh).
"""

import json
import math
import sys
from collections import defaultdict

jl, out = sys.argv[1], sys.argv[2]
recs = [json.loads(line) for line in open(jl) if line.strip()]
runs = defaultdict(list)
for r in recs:
    runs[(r["candidate"], r["setting"])].append(r)

settings = ["A", "B", "C"]
desc = {
    "A": "PPO, 1024 envs x 16 steps, minibatch 4096, 10 epochs (1 warm-up + 5 timed rollouts)",
    "B": "PPO, 16 envs x 128 steps, minibatch 64, 10 epochs (1 warm-up + 10 timed rollouts)",
    "C": "SAC, 1 env, batch 256, 1 gradient step per env step (300 warm-up + 1500 timed steps)",
}


def sps(r):
    return r.get("sps") if r.get("status") == "ok" else None


def cps(r):
    """env-steps per CPU-second of the process (less sensitive to other load on the machine than wall time)."""
    return r["env_steps"] / r["cpu_seconds"] if r.get("status") == "ok" and r.get("cpu_seconds") else None


def gmean(v):
    v = [x for x in v if x]
    return math.exp(sum(map(math.log, v)) / len(v)) if v else None


sb3_ref = {s: gmean([sps(r) for r in runs.get(("sb3", s), [])]) for s in settings}
sb3_ref_cpu = {s: gmean([cps(r) for r in runs.get(("sb3", s), [])]) for s in settings}

order = ["env-only", "sb3", "torchrl", "skrl", "rl_games", "pufferlib", "sbx", "bluesky-gym fast"]
table = []
for c in order:
    for s in settings:
        rs = runs.get((c, s), [])
        if not rs:
            continue
        vals = [sps(r) for r in rs]
        ok = [v for v in vals if v]
        row = dict(
            candidate=c,
            setting=s,
            runs=len(rs),
            sps_each=vals,
            sps=(math.exp(sum(map(math.log, ok)) / len(ok)) if ok else None),
            cpu_share_each=[r.get("cpu_share") for r in rs],
            status=rs[-1].get("status"),
            error=next((r.get("error") for r in rs if r.get("error")), None),
        )
        row["ratio_to_sb3"] = row["sps"] / sb3_ref[s] if row["sps"] and sb3_ref[s] else None
        row["steps_per_cpu_s_each"] = [cps(r) for r in rs]
        row["steps_per_cpu_s"] = gmean(row["steps_per_cpu_s_each"])
        row["cpu_ratio_to_sb3"] = row["steps_per_cpu_s"] / sb3_ref_cpu[s] if row["steps_per_cpu_s"] and sb3_ref_cpu[s] else None
        if c == "sb3":
            row["ratio_first_over_last"] = vals[0] / vals[-1] if len(ok) == 2 else None
        table.append(row)

json.dump(
    dict(settings=desc, sb3_reference_sps=sb3_ref, sb3_reference_steps_per_cpu_s=sb3_ref_cpu, rows=table, raw=recs),
    open(f"{out}/results.json", "w"),
    indent=1,
)


def f(x, nd=0):
    return "-" if x is None else f"{x:,.{nd}f}"


lines = [
    "| candidate | setting | env-steps/s (wall) | ratio to SB3 (wall) | env-steps per CPU-s | ratio to SB3 (CPU)"
    " | runs: env-steps/s each | CPU share of timed part | status |",
    "|---|---|---:|---:|---:|---:|---|---|---|",
]
for r in table:
    each = ", ".join(f(v) for v in r["sps_each"])
    share = ", ".join("-" if x is None else f"{x:.2f}" for x in r["cpu_share_each"])
    st = r["status"] if r["status"] == "ok" else f"{r['status']}: {(r['error'] or '')[:120]}"
    env = r["candidate"] == "env-only"
    rw = f(r["ratio_to_sb3"], 2) if not env else "(" + f(r["ratio_to_sb3"], 1) + ")"
    rc = f(r["cpu_ratio_to_sb3"], 2) if not env else "(" + f(r["cpu_ratio_to_sb3"], 1) + ")"
    lines.append(f"| {r['candidate']} | {r['setting']} | {f(r['sps'])} | {rw} | {f(r['steps_per_cpu_s'])} | {rc} | {each} | {share} | {st} |")
md = ["# Training throughput on SectorCREnv-v0 (native vector env)", ""]
md += [f"- {k}: {v}" for k, v in desc.items()]
md += [
    "",
    "env-steps/s: timed env-steps / wall seconds, geometric mean of the runs; ratio: to the geometric mean of SB3's first and last run",
    "of the same setting. env-steps per CPU-s: timed env-steps / CPU seconds of the process (all threads) over the timed part, which",
    "discounts the time the process waited for a core on the shared machine. CPU share = CPU-s / wall-s of the timed part.",
    "env-only rows: the environment alone with random actions, same N and step count (ratio in brackets = env alone / SB3).",
    "",
]
md += lines
open(f"{out}/results.md", "w").write("\n".join(md) + "\n")
print("\n".join(md))
