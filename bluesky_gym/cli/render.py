"""``bluesky-gym render``: fly episodes with a policy and write them to a GIF or MP4 (or a window).

Examples::

    bluesky-gym render --env HorizontalCREnv-v0 --out horizontal.gif    # random actions
    bluesky-gym render --env MergeEnv-v0 --policy classical --episodes 2 --out merge.mp4 --seed 7
    bluesky-gym render --env SectorCREnv-v1 --policy mvp --out sector_mvp.gif    # MVP resolving
    bluesky-gym render --env DescentEnv-v0 --policy runs/descent/model.zip --out descent.gif
    bluesky-gym render --env SectorCREnv-v0 --grid 4 --out sector_grid.gif  # 4 side by side
    bluesky-gym render --env VerticalCREnv-v0 --human                 # watch in a window
    bluesky-gym render --env MergeEnv-v0 --out merge.gif --scn merge.scn  # and a BlueSky scenario

The policy is ``random`` (uniform actions, seeded by ``--seed``), ``classical`` (the benchmark's
hand-written controller), ``mvp`` (BlueSky's MVP conflict resolution, for the environments with
traffic) or the path of a Stable-Baselines3 model ``.zip`` (its algorithm is read from the file,
or given with ``--algo``). ``--seed`` seeds the first episode; the following ones
continue the environment's generator, so the same command always writes the same video.
"""

from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path
from typing import Any

from bluesky_gym.cli.arguments import add_env_option, non_negative_int, positive_float, positive_int, whole_number
from bluesky_gym.training.recording import SB3_ALGORITHMS, record


def _option(text: str) -> tuple[str, Any]:
    key, sep, raw = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    try:
        value = ast.literal_eval(raw)
    except (ValueError, SyntaxError):
        value = raw
    return key.strip(), value


def add_parser(subparsers: Any) -> None:
    """Register the ``render`` subcommand."""
    p = subparsers.add_parser(
        "render",
        help="draw episodes of an environment to a GIF/MP4 file or a window",
        description=__doc__,
    )
    add_env_option(p, help="environment id, e.g. HorizontalCREnv-v0")
    p.add_argument(
        "--policy",
        default="random",
        help="random, classical, mvp (environments with traffic), or the path of a Stable-Baselines3 model .zip (default: random)",
    )
    p.add_argument("--algo", choices=sorted(SB3_ALGORITHMS), help="algorithm of the model .zip (default: read from the file)")
    p.add_argument("--stochastic", action="store_true", help="sample the model's actions instead of taking the deterministic ones")
    p.add_argument("--episodes", type=positive_int, default=1, metavar="K", help="episodes to record (default: 1)")
    p.add_argument("--out", type=Path, metavar="FILE", help="output .gif or .mp4 (default: ID.gif; not written with --human)")
    p.add_argument("--seed", type=non_negative_int, default=0, help="seed of the first episode and of random actions (default: 0)")
    p.add_argument("--max-steps", type=positive_int, metavar="N", help="truncate each episode after N steps (default: the id's limit)")
    p.add_argument("--every", type=positive_int, default=1, metavar="N", help="keep one frame every N steps (default: 1)")
    p.add_argument("--max-frames", type=positive_int, metavar="N", help="stop after N frames")
    p.add_argument("--fps", type=positive_float, default=10.0, help="frames per second of the video (default: 10)")
    p.add_argument("--scale", type=positive_float, default=1.0, help="resize factor of the video frames (default: 1)")
    p.add_argument("--colors", type=whole_number, default=192, metavar="N", help="palette size of GIF frames, 2..256 (default: 192)")
    p.add_argument("--grid", type=positive_int, default=1, metavar="N", help="draw N episodes of a batched environment side by side")
    p.add_argument("--human", action="store_true", help="show the episodes in a window instead of writing a file")
    p.add_argument("--scn", type=Path, metavar="OUT.scn", help="also write each episode as a BlueSky scenario file (OUT-k.scn for several)")
    p.add_argument("--option", type=_option, action="append", default=[], metavar="KEY=VALUE", help="scenario option (repeatable)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the ``render`` subcommand."""
    try:
        path, n = record(
            args.env,
            policy=args.policy,
            episodes=args.episodes,
            out=args.out,
            seed=args.seed,
            max_steps=args.max_steps,
            every=args.every,
            max_frames=args.max_frames,
            fps=args.fps,
            scale=args.scale,
            colors=args.colors,
            grid=args.grid,
            human=args.human,
            algo=args.algo,
            deterministic=not args.stochastic,
            options=dict(args.option),
            log=lambda s: print(s, file=sys.stderr),
            scn=args.scn,
        )
    except (ValueError, TypeError, ImportError) as exc:  # bad id, option, policy, format or missing package
        print(f"bluesky-gym render: error: {exc}", file=sys.stderr)
        return 2
    if path is not None:
        print(f"wrote {n} frames to {path} ({path.stat().st_size / 1024:.0f} KiB)")
    return 0
