"""The package has no hidden passages: no module reads stack frames, and no two classes share a name.

A stack frame read (``sys._getframe``, ``inspect.stack``, ``inspect.currentframe``) makes a
function depend on who called it, which no signature shows. Two classes of the same name in
different modules make an import, a traceback or a page of the documentation ambiguous.
"""

from __future__ import annotations

import ast
import re
from collections import defaultdict
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parents[1] / "bluesky_gym"

#: What reads the caller's frame.
FRAME_READS = re.compile(r"\b(_getframe|currentframe|inspect\.stack|inspect\.trace|f_back|f_locals)\b")


def _modules() -> list[Path]:
    return sorted(PACKAGE_DIR.rglob("*.py"))


def frame_reads(paths: list[Path], root: Path = PACKAGE_DIR.parent) -> dict[tuple[str, str], list[str]]:
    """The lines reading stack frames, by (module path under ``root``, enclosing function; "" at module level)."""
    found: dict[tuple[str, str], list[str]] = defaultdict(list)
    for path in paths:
        text = path.read_text(encoding="utf-8")
        lines = text.splitlines()
        owner = [""] * (len(lines) + 1)
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                for n in range(node.lineno, (node.end_lineno or node.lineno) + 1):
                    owner[n] = owner[n] or node.name  # the outermost function
        for number, line in enumerate(lines, start=1):
            if FRAME_READS.search(line):
                found[(str(path.relative_to(root)), owner[number])].append(f"{number}: {line.strip()}")
    return found


def test_no_module_reads_stack_frames() -> None:
    found = frame_reads(_modules())
    assert not found, "modules reading stack frames:\n" + "\n".join(f"{m} ({f}): {line}" for (m, f), v in found.items() for line in v)


def test_a_frame_read_is_found(tmp_path: Path) -> None:
    module = tmp_path / "caller.py"
    module.write_text("import sys\n\n\ndef who_called():\n    return sys._getframe(1).f_code.co_name\n")
    assert dict(frame_reads([module], tmp_path)) == {("caller.py", "who_called"): ["5: return sys._getframe(1).f_code.co_name"]}


def test_the_frame_pattern_finds_a_frame_read() -> None:
    assert FRAME_READS.search("frame = sys._getframe(1)") and FRAME_READS.search("inspect.stack()[1]")
    assert not FRAME_READS.search("np.stack(arrays)")


#: Names that may still be defined twice (none: the random and MVP policies are one class each).
PENDING_MERGE: frozenset[str] = frozenset()


def class_names(root: Path) -> dict[str, list[str]]:
    """Where each class under ``root`` is defined (module path and line), by class name; nested classes count."""
    where: dict[str, list[str]] = defaultdict(list)
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ClassDef):
                where[node.name].append(f"{path.relative_to(root.parent)}:{node.lineno}")
    return where


def test_no_two_classes_share_a_name() -> None:
    shared = {name: places for name, places in class_names(PACKAGE_DIR).items() if len(places) > 1}
    unexpected = {name: places for name, places in shared.items() if name not in PENDING_MERGE}
    assert not unexpected, "classes defined more than once:\n" + "\n".join(f"{n}: {', '.join(p)}" for n, p in sorted(unexpected.items()))
    assert PENDING_MERGE <= shared.keys(), f"{sorted(PENDING_MERGE - shared.keys())} are merged: remove them from PENDING_MERGE"


def test_a_shared_class_name_is_found(tmp_path: Path) -> None:
    for name in ("a.py", "b.py"):
        (tmp_path / name).write_text("class Player:\n    class Inner:\n        pass\n")
    found = class_names(tmp_path)
    assert len(found["Player"]) == 2 and len(found["Inner"]) == 2
