"""The real-traffic tables of the documentation, generated from saved measurements.

``bluesky-gym realtraffic fidelity --json FILE`` and ``bluesky-gym realtraffic stats --json FILE``
save their measurements as JSON documents (:func:`fidelity_document`, :func:`stats_document`) that
carry the command line that made them (program name and arguments, no machine paths), the
package version and the inputs. ``bluesky-gym realtraffic report DIR`` renders the documents of a
directory into Markdown blocks (:func:`render_blocks`) and writes each block between its markers in
the pages (:func:`fill`)::

    <!-- realtraffic:fidelity -->
    (generated: never edit by hand)
    <!-- /realtraffic:fidelity -->

A block named ``NAME`` is rendered from ``DIR/NAME.json`` (a fidelity table; ``NAME.vertical``
is its vertical deviations over 1000 ft by cause); the block ``stats`` from every
``stats*.json`` of the directory together (e.g. one file with the reference policies of every
collection and one per collection with its trained model), one table row per collection and
policy. Rendering the same documents gives the same text, so a page whose blocks differ from a
fresh rendering was edited by hand or is out of date.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from bluesky_gym.realtraffic.fidelity import summary_table
from bluesky_gym.tasks import REFERENCE_POLICIES  # reference policies first, in this order; trained models after them

#: ``kind`` of the two documents, and the version of their layout.
FIDELITY_KIND = "realtraffic-fidelity"
STATS_KIND = "realtraffic-stats"
FORMAT_VERSION = 1
PROGRAM = "bluesky-gym"
#: The statistics table (one row per collection and policy).
STATS_HEADER = (
    "| collection | flights | aircraft-hours | LoS per flight-hour (nobody acts) | policy | return | LoS / episode | min sep [NM] | route dev [NM] |"
)
STATS_RULE = "|---|---:|---:|---:|---|---:|---:|---:|---:|"
MARKER = re.compile(r"^<!-- (/?)realtraffic:([A-Za-z0-9_.-]+) -->$")


class ReportError(ValueError):
    """A measurement file or a page that cannot be rendered or filled (the message names it)."""


def clean_path(path: str | os.PathLike[str], cwd: Path | None = None) -> str:
    """A path as a command line of the documentation shows it: relative to ``cwd`` when inside it, else its name.

    A relative path stays as given; an absolute one (a machine's path) is made relative to the
    working directory when it lies inside it, and is reduced to its file name otherwise.
    """
    p = Path(path)
    if not p.is_absolute():
        return p.as_posix()
    base = (cwd or Path.cwd()).resolve()
    try:
        return p.resolve().relative_to(base).as_posix()
    except ValueError:
        return p.name


def command_line(words: Sequence[str]) -> str:
    """``bluesky-gym`` followed by ``words`` (already cleaned), quoted for a shell where needed."""
    import shlex

    return " ".join([PROGRAM, *(shlex.quote(str(w)) for w in words)])


def _base(kind: str, command: str, version: str, inputs: dict[str, Any]) -> dict[str, Any]:
    return {"kind": kind, "format": FORMAT_VERSION, "command": command, "version": version, "inputs": inputs}


def fidelity_document(command: str, version: str, inputs: dict[str, Any], collections: list[dict[str, Any]]) -> dict[str, Any]:
    """The JSON document of ``realtraffic fidelity``.

    Args:
        command: The command line that made it (:func:`command_line`).
        version: The package version.
        inputs: Collections, windows per collection, window length [min], type override (or None).
        collections: Per collection: ``name``, ``windows``, ``flights``, ``flights_with_type``
            (flights whose recording names a type), ``flown_types`` (type -> aircraft of the
            replayed windows flying with its data) and ``rows`` (:meth:`Fidelity.summary`).
    """
    return {**_base(FIDELITY_KIND, command, version, inputs), "collections": collections}


def stats_document(command: str, version: str, inputs: dict[str, Any], rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The JSON document of ``realtraffic stats``.

    Args:
        command: The command line that made it (:func:`command_line`).
        version: The package version.
        inputs: Collections, windows, episodes per policy, model path as given (or None).
        rows: Per collection: ``collection``, ``flights``, ``aircraft_hours``,
            ``conflicts_per_flight_hour`` and ``policies`` (policy -> ``return``,
            ``los_per_episode``, ``min_separation_nm``, ``route_deviation_nm``).
    """
    return {**_base(STATS_KIND, command, version, inputs), "rows": rows}


def stats_lines(rows: Iterable[dict[str, Any]]) -> list[str]:
    """The Markdown table of statistics rows (as in :func:`stats_document`)."""
    lines = [STATS_HEADER, STATS_RULE]
    for r in rows:
        for policy, k in r["policies"].items():
            lines.append(
                f"| {r['collection']} | {r['flights']} | {r['aircraft_hours']:.1f} | {r['conflicts_per_flight_hour']:.3f} | {policy} | "
                f"{k['return']:.2f} | {k['los_per_episode']:.2f} | {k['min_separation_nm']:.2f} | {k['route_deviation_nm']:.2f} |"
            )
    return lines


def _read(path: Path, kind: str) -> dict[str, Any]:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        raise ReportError(f"{path}: not a readable JSON file ({exc})") from exc
    found = doc.get("kind") if isinstance(doc, dict) else None
    if found != kind:
        raise ReportError(f"{path}: not a '{kind}' document (written by 'bluesky-gym realtraffic ... --json'); its kind is {found!r}")
    if doc.get("format") != FORMAT_VERSION:
        raise ReportError(f"{path}: format {doc.get('format')!r}, this version reads format {FORMAT_VERSION}")
    for key in ("command", "version", "inputs"):
        if key not in doc:
            raise ReportError(f"{path}: no '{key}'")
    return doc


def _made_by(docs: list[tuple[str, dict[str, Any]]]) -> str:
    made = "; ".join(f"`{doc['command']}` (bluesky-gym {doc['version']})" for _, doc in docs)
    return f"Measured by {made}; written here by `bluesky-gym realtraffic report`."


def render_fidelity(name: str, doc: dict[str, Any]) -> str:
    """The block of a fidelity document: the table, what was replayed, and the command that measured it."""
    cols = doc["collections"]
    table = summary_table([(c["name"], c["rows"]) for c in cols])
    minutes = doc["inputs"].get("window_minutes", 20)
    windows = ", ".join(f"{c['name']}: {c['windows']} windows" for c in cols)
    override = doc["inputs"].get("type")
    flown = (
        f"every aircraft flown as the {override}" if override else "every aircraft with its recorded type (BlueSky's B744 where missing or unknown)"
    )
    recorded = ", ".join(f"{c['name']} {c['flights_with_type']} of {c['flights']}" for c in cols)
    types = "; ".join(
        f"{c['name']}: " + ", ".join(f"{t} {n}" for t, n in sorted(c["flown_types"].items(), key=lambda kv: (-kv[1], kv[0]))) for c in cols
    )
    return "\n".join(
        [
            table,
            "",
            f"{windows} of {minutes:.0f} minutes, nobody acting, {flown}. Flights whose recording names a type: {recorded}. "
            f"Aircraft of the replayed windows by the type they fly: {types}.",
            "",
            _made_by([(name, doc)]),
        ]
    )


def render_vertical(name: str, doc: dict[str, Any]) -> str:
    """The block ``NAME.vertical`` of a fidelity document: its vertical deviations over 1000 ft, by what the recording asked of the type."""
    flown = f"the {doc['inputs']['type']}" if doc["inputs"].get("type") else "its type"
    head = (
        f"| collection | after | aircraft | vertical deviation > 1000 ft | recorded above {flown}'s ceiling | recorded steeper than {flown}'s vsmax |"
    )
    lines = [
        f"{head} other |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for c in doc["collections"]:
        for r in c["large_vertical"]:
            counts = " | ".join(str(r[k]) for k in ("aircraft", "large", "above_ceiling", "steeper_than_vsmax", "other"))
            lines.append(f"| {c['name']} | {r['minutes']:.0f} min | {counts} |")
    return "\n".join([*lines, "", _made_by([(name, doc)])])


def render_stats(docs: list[tuple[str, dict[str, Any]]]) -> str:
    """The block of one or more statistics documents, merged per collection (reference policies first)."""
    merged: dict[str, dict[str, Any]] = {}
    origin: dict[tuple[str, str], str] = {}
    for name, doc in docs:
        for row in doc["rows"]:
            col = row["collection"]
            head = {k: row[k] for k in ("collection", "flights", "aircraft_hours", "conflicts_per_flight_hour")}
            if col not in merged:
                merged[col] = {**head, "policies": {}}
            elif {k: merged[col][k] for k in head} != head:
                raise ReportError(f"{name}: collection '{col}' has other flights or conflict figures than in {origin[(col, '')]}")
            origin.setdefault((col, ""), name)
            for policy, kpis in row["policies"].items():
                seen = merged[col]["policies"].get(policy)
                if seen is not None and seen != kpis:
                    raise ReportError(f"{name}: policy '{policy}' on '{col}' differs from {origin[(col, policy)]} (measured twice, differently)")
                merged[col]["policies"][policy] = kpis
                origin.setdefault((col, policy), name)
    rows = []
    for r in merged.values():
        pol = r["policies"]
        order = [p for p in REFERENCE_POLICIES if p in pol] + [p for p in pol if p not in REFERENCE_POLICIES]
        rows.append({**r, "policies": {p: pol[p] for p in order}})
    episodes = sorted({int(doc["inputs"]["episodes"]) for _, doc in docs})
    note = f"Means over {' or '.join(map(str, episodes))} test episodes of each collection per policy."
    return "\n".join(["\n".join(stats_lines(rows)), "", note, "", _made_by(docs)])


def render_blocks(directory: str | os.PathLike[str]) -> dict[str, str]:
    """Every block the JSON documents of ``directory`` give, by name (see the module docstring)."""
    d = Path(directory)
    if not d.is_dir():
        raise ReportError(f"{d}: no such directory of measurements")
    blocks: dict[str, str] = {}
    stats: list[tuple[str, dict[str, Any]]] = []
    for path in sorted(d.glob("*.json")):
        shown = path.as_posix()
        if path.stem.startswith("stats"):
            stats.append((shown, _read(path, STATS_KIND)))
        else:
            doc = _read(path, FIDELITY_KIND)
            blocks[path.stem] = render_fidelity(shown, doc)
            if all("large_vertical" in c for c in doc["collections"]):
                blocks[f"{path.stem}.vertical"] = render_vertical(shown, doc)
    if stats:
        blocks["stats"] = render_stats(stats)
    return blocks


def fill(text: str, blocks: dict[str, str], page: str = "page") -> str:
    """``text`` with every marked block replaced by its rendering.

    Raises:
        ReportError: A block without a rendering, or a marker without its end (``page:line``).
    """
    lines = text.split("\n")
    out: list[str] = []
    open_name: str | None = None
    open_line = 0
    for k, line in enumerate(lines, start=1):
        m = MARKER.match(line.strip())
        if open_name is None:
            out.append(line)
            if m and not m.group(1):
                open_name, open_line = m.group(2), k
                if open_name not in blocks:
                    raise ReportError(f"{page}:{k}: block 'realtraffic:{open_name}' has no measurements (no {open_name}.json in the directory)")
        elif m and m.group(1) and m.group(2) == open_name:
            out.extend([blocks[open_name], line])
            open_name = None
        elif m:
            raise ReportError(f"{page}:{k}: marker '{line.strip()}' inside block 'realtraffic:{open_name}' opened on line {open_line}")
    if open_name is not None:
        raise ReportError(f"{page}:{open_line}: block 'realtraffic:{open_name}' has no end marker '<!-- /realtraffic:{open_name} -->'")
    return "\n".join(out)


def blocks_in(text: str) -> list[str]:
    """Names of the blocks a page marks, in order."""
    return [m.group(2) for line in text.split("\n") if (m := MARKER.match(line.strip())) and not m.group(1)]
