#!/usr/bin/env python3
"""Fail on files over the repository's size limit (500 KiB), naming each one.

With file arguments (as the pre-commit hook passes the files being committed) it checks those;
without, every file git tracks. Run data goes to a release asset instead (``bluesky-gym results
pack``); a recording over the limit is stored compressed (``tests/data/reference/README.md``).
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

#: The largest file the repository takes, in KiB (as pre-commit's ``check-added-large-files --maxkb``).
MAX_KB = 500


def tracked_files(root: Path) -> list[str]:
    """The files git tracks below ``root`` (paths relative to it)."""
    out = subprocess.run(["git", "ls-files", "-z"], cwd=root, check=True, capture_output=True).stdout
    return [p for p in out.decode("utf-8").split("\0") if p]


def oversized(paths: Sequence[str], root: Path, max_kb: int = MAX_KB) -> list[tuple[str, int]]:
    """``(path, size in bytes)`` of the files over ``max_kb`` KiB (missing files, e.g. deleted ones, left out)."""
    big = []
    for p in paths:
        f = root / p
        if f.is_file() and f.stat().st_size > max_kb * 1024:
            big.append((p, f.stat().st_size))
    return big


def main(argv: Sequence[str]) -> int:
    """Check the files named in ``argv`` (default: every tracked file); exit 1 naming those over the limit."""
    root = Path.cwd()
    paths = list(argv) or tracked_files(root)
    big = oversized(paths, root)
    for p, size in big:
        print(f"{p}: {size} bytes, over the repository's limit of {MAX_KB} KiB ({MAX_KB * 1024} bytes)", file=sys.stderr)
    return 1 if big else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
