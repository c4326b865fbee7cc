"""``bluesky-gym results``: the results page (Markdown and figures) from sweep directories.

Examples::

    bluesky-gym results results/v0-ppo results/v1-ppo --out docs/results.md

For every environment in the sweeps: a KPI table of the reference policies (``random``,
``classical``, and where the environment has traffic the conflict resolution methods ``mvp``,
``eby``, ``swarm`` and ``ssd``) and of every trained algorithm, with 95% confidence
intervals over seeds and held-out episodes; its learning curves and KPI curves; and per
environment version an aggregate of the normalised held-out scores (IQM, mean, median,
optimality gap, probability of improvement; ``rliable``). Figures go to a directory named after
the page (``docs/results/`` for ``docs/results.md``). The page names the command that made it;
rerunning the command on the same directories reproduces it.

The reference policies are evaluated on the same held-out scenarios as the runs (as many
episodes as the runs' evaluations, or ``--reference-episodes N``) where a sweep does not hold
their per-episode records yet, and kept in its ``references/episodes/`` for the next time, each
record as soon as it is made (an interrupted run resumes; ``ssd``, the slow one, comes last).

The repository keeps run summaries (``bluesky-gym runs DIR --summarise``); what a summary drops
(models, checkpoints, TensorBoard and raw episode logs) is a release asset made by ``results
pack``, a ``.tar.gz`` with a SHA-256 manifest that is committed::

    bluesky-gym results pack results/v0-ppo results/v1-ppo --out results/run-files.tar.gz
    bluesky-gym results unpack results/run-files.manifest.json    # the files back in their runs
    bluesky-gym results results/v0-ppo --artifact results/run-files.manifest.json --out x.md

``pack`` writes the manifest beside the archive (``--manifest FILE`` elsewhere). ``unpack`` and
``--artifact`` take the manifest (the archive beside it, under the name it records) or the
archive (its manifest beside it) and check every file against its SHA-256; ``--artifact`` draws
the learning curves of summarised runs from their raw episode logs instead of the binned
``curve.csv``. A sweep directory called ``pack`` or ``unpack`` is written ``./pack``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from bluesky_gym.cli.arguments import non_negative_int
from bluesky_gym.core.extras import MissingDependencyError


def add_parser(subparsers: Any) -> None:
    """Register the ``results`` subcommand."""
    p = subparsers.add_parser(
        "results",
        help="write the results page (KPI tables, curves, aggregate) from sweeps",
        description=__doc__,
    )
    p.add_argument("sweeps", nargs="+", type=Path, metavar="SWEEP_DIR", help="sweep (or run) directories")
    p.add_argument("--out", type=Path, default=Path("docs/results.md"), metavar="FILE", help="the page to write (default: docs/results.md)")
    p.add_argument(
        "--reference-episodes",
        type=non_negative_int,
        metavar="N",
        help="held-out episodes of the reference policies a sweep lacks (default: as many as the runs' evaluations)",
    )
    p.add_argument(
        "--artifact",
        type=Path,
        metavar="FILE",
        help="packed run files (manifest or archive, see results pack): raw learning curves of summarised runs",
    )
    p.set_defaults(func=run)

    pack = p.add_nested(
        "pack",
        description=(
            "Pack what the summaries of the runs below DIR drop (models, checkpoints, raw logs)\n"
            "into a .tar.gz release asset and write its SHA-256 manifest (committed)."
        ),
        help="pack run files into a release artifact with a SHA-256 manifest",
    )
    pack.add_argument("dirs", nargs="+", type=Path, metavar="DIR", help="sweep (or run) directories")
    pack.add_argument("--out", type=Path, required=True, metavar="ARCHIVE", help="the .tar.gz to write")
    pack.add_argument("--manifest", type=Path, metavar="FILE", help="the manifest to write (default: NAME.manifest.json beside NAME.tar.gz)")
    pack.set_defaults(func=run_pack)

    unpack = p.add_nested(
        "unpack",
        description=(
            "Check packed run files against their SHA-256 manifest and write them back into their\n"
            "run directories (paths relative to the current directory)."
        ),
        help="restore packed run files into their run directories",
    )
    unpack.add_argument("artifact", type=Path, metavar="FILE", help="the manifest (archive beside it) or the archive (manifest beside it)")
    unpack.set_defaults(func=run_unpack)


def run(args: argparse.Namespace) -> int:
    """Run the ``results`` subcommand."""
    from bluesky_gym.training.results import build_results, complete_references

    command = ["bluesky-gym", "results", *map(str, args.sweeps)]
    if args.artifact is not None:
        command += ["--artifact", str(args.artifact)]
    command += ["--out", str(args.out)]
    try:
        artifact = None
        if args.artifact is not None:
            from bluesky_gym.training.pack import RunArtifact

            artifact = RunArtifact.open(args.artifact)
        for line in complete_references(args.sweeps, args.reference_episodes):
            print(line, file=sys.stderr)
        page = build_results(args.sweeps, args.out, command, artifact=artifact)
    except (MissingDependencyError, FileNotFoundError, ValueError) as exc:
        print(f"bluesky-gym results: error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {page} and its figures in {page.parent / page.stem}")
    return 0


def run_pack(args: argparse.Namespace) -> int:
    """Run ``results pack``."""
    from bluesky_gym.training.pack import default_manifest_path, pack_runs

    command = ["bluesky-gym", "results", "pack", *map(str, args.dirs), "--out", str(args.out)]
    if args.manifest is not None:
        command += ["--manifest", str(args.manifest)]
    try:
        manifest_path = args.manifest if args.manifest is not None else default_manifest_path(args.out)
        record = pack_runs(args.dirs, args.out, manifest_path, command=command)
    except (FileNotFoundError, ValueError) as exc:
        print(f"bluesky-gym results pack: error: {exc}", file=sys.stderr)
        return 2
    size = sum(e["bytes"] for e in record["files"])
    packed = f"packed {len(record['files'])} files of {len(record['runs'])} runs ({size / 1e6:.1f} MB)"
    print(f"{packed} into {args.out} ({record['archive_bytes'] / 1e6:.1f} MB); manifest {manifest_path}")
    return 0


def run_unpack(args: argparse.Namespace) -> int:
    """Run ``results unpack``."""
    from bluesky_gym.training.pack import RunArtifact

    try:
        written = RunArtifact.open(args.artifact).unpack()
    except (FileNotFoundError, ValueError) as exc:
        print(f"bluesky-gym results unpack: error: {exc}", file=sys.stderr)
        return 2
    print(f"checked and wrote {len(written)} files")
    return 0
