"""`realtraffic fidelity|stats --json` and `realtraffic report`: saved measurements and the tables made from them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from bluesky_gym.cli import main
from bluesky_gym.realtraffic.report import STATS_KIND, ReportError, clean_path, fill, render_blocks, render_stats, stats_document

from .synthetic import save, traffic_collection


def test_clean_path_keeps_no_machine_path(tmp_path: Path) -> None:
    assert clean_path("results/x.json") == "results/x.json"
    assert clean_path(tmp_path / "sub" / "x.json", cwd=tmp_path) == "sub/x.json"
    assert clean_path(tmp_path / "x.json", cwd=tmp_path / "elsewhere") == "x.json"


def _stats(collection: str, policies: dict[str, float], conflicts: float = 0.5, command: str = "bluesky-gym realtraffic stats") -> dict:
    kpis = {p: {"return": r, "los_per_episode": 0.25, "min_separation_nm": 4.0, "route_deviation_nm": 0.5} for p, r in policies.items()}
    row = {"collection": collection, "flights": 10, "aircraft_hours": 2.0, "conflicts_per_flight_hour": conflicts, "policies": kpis}
    return stats_document(command, "1.0.0", {"collections": [collection], "windows": 4, "episodes": 5, "model": None}, [row])


def test_stats_files_merge_per_collection_reference_policies_first() -> None:
    ref = _stats("paris", {"classical": -3.0, "random": -5.0})
    ppo = _stats("paris", {"runs/ppo": -2.5, "random": -5.0}, command="bluesky-gym realtraffic stats --model runs/ppo")
    text = render_stats([("stats.json", ref), ("stats-paris.json", ppo)])
    rows = [line.split(" | ")[4] for line in text.splitlines() if line.startswith("| paris")]
    assert rows == ["random", "classical", "runs/ppo"]
    assert "`bluesky-gym realtraffic stats --model runs/ppo`" in text
    with pytest.raises(ReportError, match="stats-paris.json: policy 'random' on 'paris' differs from stats.json"):
        render_stats([("stats.json", ref), ("stats-paris.json", _stats("paris", {"random": -4.0}))])
    with pytest.raises(ReportError, match="other flights or conflict figures"):
        render_stats([("stats.json", ref), ("stats-paris.json", _stats("paris", {"x": 1.0}, conflicts=0.7))])


def test_fill_names_page_and_line_of_a_bad_block() -> None:
    blocks = {"a": "A"}
    assert fill("x\n<!-- realtraffic:a -->\nold\n<!-- /realtraffic:a -->\ny", blocks) == "x\n<!-- realtraffic:a -->\nA\n<!-- /realtraffic:a -->\ny"
    with pytest.raises(ReportError, match=r"p.md:2: block 'realtraffic:b' has no measurements"):
        fill("x\n<!-- realtraffic:b -->\n<!-- /realtraffic:b -->", blocks, "p.md")
    with pytest.raises(ReportError, match=r"p.md:1: block 'realtraffic:a' has no end marker"):
        fill("<!-- realtraffic:a -->\nold", blocks, "p.md")
    with pytest.raises(ReportError, match=r"p.md:2: marker .* inside block 'realtraffic:a' opened on line 1"):
        fill("<!-- realtraffic:a -->\n<!-- /realtraffic:b -->\n<!-- /realtraffic:a -->", blocks, "p.md")


def test_a_file_of_another_kind_is_refused(tmp_path: Path) -> None:
    (tmp_path / "fidelity.json").write_text(json.dumps({"kind": STATS_KIND}))
    with pytest.raises(ReportError, match="fidelity.json: not a 'realtraffic-fidelity' document"):
        render_blocks(tmp_path)


def test_commands_save_json_and_report_fills_and_checks_a_page(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    data = save(traffic_collection(n_flights=16, spacing_s=300.0), tmp_path / "data")
    monkeypatch.chdir(tmp_path)
    out = Path("results")
    assert main(["realtraffic", "fidelity", "--collections", data, "--windows", "2", "--json", str(out / "fidelity.json")]) == 0
    assert (
        main(["realtraffic", "fidelity", "--collections", data, "--windows", "2", "--type", "b738", "--json", str(out / "fidelity-b738.json")]) == 0
    )
    assert (
        main(["realtraffic", "stats", "--collections", data, "--windows", "2", "--episodes", "1", "--json", str(tmp_path / out / "stats.json")]) == 0
    )
    fid = json.loads((out / "fidelity.json").read_text())
    assert fid["command"] == "bluesky-gym realtraffic fidelity --collections data/synthetic.npz --windows 2 --json results/fidelity.json"
    assert fid["version"] and fid["inputs"] == {"collections": ["data/synthetic.npz"], "windows": 2, "window_minutes": 20.0, "type": None}
    (col,) = fid["collections"]
    assert col["windows"] == 2 and col["flights_with_type"] == 16 and set(col["flown_types"]) == {"A320"}
    assert [r["minutes"] for r in col["rows"]] == [5.0, 10.0, 20.0]
    assert set(json.loads((out / "fidelity-b738.json").read_text())["collections"][0]["flown_types"]) == {"B738"}
    stats = json.loads((out / "stats.json").read_text())
    assert stats["command"] == "bluesky-gym realtraffic stats --collections data/synthetic.npz --windows 2 --episodes 1 --json results/stats.json"
    assert list(stats["rows"][0]["policies"]) == ["random", "classical"]

    page = Path("page.md")
    markers = "<!-- realtraffic:fidelity -->\nhand-written\n<!-- /realtraffic:fidelity -->\n<!-- realtraffic:stats -->\n<!-- /realtraffic:stats -->"
    page.write_text(f"# Page\n{markers}\n")
    capsys.readouterr()
    assert main(["realtraffic", "report", str(out), str(page), "--check"]) == 1
    assert "hand-written" in page.read_text()
    assert main(["realtraffic", "report", str(out), str(page)]) == 0
    text = page.read_text()
    assert "hand-written" not in text and "| synthetic | 5 min |" in text and "| synthetic | 16 |" in text
    assert "Measured by `bluesky-gym realtraffic fidelity --collections data/synthetic.npz" in text
    assert main(["realtraffic", "report", str(out), str(page), "--check"]) == 0
    page.write_text(text.replace("| synthetic | 5 min |", "| synthetic | 6 min |"))
    assert main(["realtraffic", "report", str(out), str(page), "--check"]) == 1
    assert main(["realtraffic", "report", str(tmp_path / "missing"), str(page)]) == 2
    assert "missing: no such directory of measurements" in capsys.readouterr().err


def test_stats_of_several_seeds_is_one_row_their_mean(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``stats --model A B``: models of one algorithm (seeds) make one row, the mean of each model's own figures."""
    pytest.importorskip("stable_baselines3")
    import gymnasium as gym
    from stable_baselines3 import PPO

    import bluesky_gym

    bluesky_gym.register_envs()
    data = save(traffic_collection(n_flights=16, spacing_s=300.0), tmp_path / "data")
    monkeypatch.chdir(tmp_path)
    env = gym.make("RealTrafficCREnv-v0", collections=(data,), min_traffic=1)
    models = []
    for seed in (0, 1):  # two untrained policies: different weights, different actions
        PPO("MultiInputPolicy", env, seed=seed, n_steps=8, batch_size=8, device="cpu").save(tmp_path / f"m{seed}.zip")
        models.append(f"m{seed}.zip")
    figures = {}
    for name, given in (("m0", models[:1]), ("m1", models[1:]), ("both", models)):
        argv = ["realtraffic", "stats", "--collections", data, "--windows", "2", "--episodes", "2", "--model", *given, "--json", f"{name}.json"]
        assert main(argv) == 0
        figures[name] = json.loads(Path(f"{name}.json").read_text())
    both = figures["both"]
    assert both["command"].endswith("--model m0.zip m1.zip --json both.json") and both["inputs"]["model"] == models
    (row,) = both["rows"]
    assert list(row["policies"]) == ["random", "classical", "PPO (2 seeds)"]
    one = [figures[k]["rows"][0]["policies"]["PPO"] for k in ("m0", "m1")]
    assert one[0]["return"] != one[1]["return"]
    for key, value in row["policies"]["PPO (2 seeds)"].items():
        assert value == pytest.approx((one[0][key] + one[1][key]) / 2)
