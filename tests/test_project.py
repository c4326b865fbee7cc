"""Project hygiene: the license file, the one place of the version, the documents the code cites, the size of tracked files."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

import bluesky_gym

ROOT = Path(__file__).resolve().parents[1]

#: A citation of a project document: ``docs/dynamics.md §2.3``, ``docs/environments-v0.md §3-4``.
CITATION = re.compile(r"docs/([\w-]+\.md)(?: §(\d+(?:\.\d+)*)(?:-(\d+(?:\.\d+)*))?)?")
#: Citation forms that name no file of the repository.
STALE_CITATION = re.compile(r"(?<![\w/])dynamics\.md|\bspec (?:sections?\b|§|\d|conventions)|\benvs-v0 sections?\b")
#: A numbered heading: ``## 2. What one step does``, ``### 2.3 Autopilot``.
NUMBERED_HEADING = re.compile(r"^#+\s+(\d+(?:\.\d+)*)\.?\s", re.MULTILINE)
#: A relative Markdown link target: ``[text](docs/backends.md)``.
MARKDOWN_LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


def _pyproject() -> dict[str, Any]:
    import tomllib

    with open(ROOT / "pyproject.toml", "rb") as f:
        return tomllib.load(f)


def _citing_files() -> list[Path]:
    """The package and test sources, and the Markdown files next to the code."""
    sources = [p for d in ("bluesky_gym", "tests") for p in sorted((ROOT / d).rglob("*.py")) if p != Path(__file__).resolve()]
    return sources + [ROOT / "README.md", *sorted((ROOT / "tests").rglob("*.md"))]


def _sections(document: Path) -> set[str]:
    return set(NUMBERED_HEADING.findall(document.read_text(encoding="utf-8")))


def test_license_file_is_the_declared_license() -> None:
    assert _pyproject()["project"]["license"] == "GPL-3.0-or-later"
    text = (ROOT / "LICENSE").read_text(encoding="utf-8")
    assert text.split()[:6] == ["GNU", "GENERAL", "PUBLIC", "LICENSE", "Version", "3,"]
    assert "END OF TERMS AND CONDITIONS" in text  # the full text, not a notice


def test_version_is_written_once_and_has_a_changelog_entry() -> None:
    project = _pyproject()
    assert "version" not in project["project"] and "version" in project["project"]["dynamic"]
    assert project["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "bluesky_gym.__version__"}
    assert re.fullmatch(r"\d+\.\d+\.\d+\S*", bluesky_gym.__version__)
    assert f"## [{bluesky_gym.__version__}]" in (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")


def test_citations_name_existing_documents_and_sections() -> None:
    problems = []
    for path in _citing_files():
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            where = f"{path.relative_to(ROOT)}:{n}"
            if STALE_CITATION.search(line):
                problems.append(f"{where}: cite as docs/<page>.md §N: {line.strip()}")
            for name, first, last in CITATION.findall(line):
                document = ROOT / "docs" / name
                if not document.is_file():
                    problems.append(f"{where}: no docs/{name}")
                    continue
                missing = [s for s in (first, last) if s and s not in _sections(document)]
                if missing:
                    problems.append(f"{where}: docs/{name} has no section {', '.join(missing)}")
    assert not problems, "\n".join(problems)


def _generated_doc_pages() -> set[Path]:
    """The pages the documentation site makes from the code (docs/hooks.py), as paths below docs/."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("docs_hooks_pages", ROOT / "docs" / "hooks.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return {(ROOT / "docs" / p).resolve() for p in module.generated_pages()}


def test_markdown_links_point_to_existing_files() -> None:
    broken = []
    generated = _generated_doc_pages()
    for page in [ROOT / "README.md", ROOT / "CHANGELOG.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for target in MARKDOWN_LINK.findall(page.read_text(encoding="utf-8")):
            path = (page.parent / target.split("#", 1)[0]).resolve()
            if "://" not in target and not path.exists() and path not in generated:
                broken.append(f"{page.relative_to(ROOT)}: {target}")
    assert not broken, "\n".join(broken)


def test_citation_patterns() -> None:
    assert CITATION.findall("[docs/dynamics.md §2.2 steps 6-8]") == [("dynamics.md", "2.2", "")]
    assert CITATION.findall("(docs/environments-v0.md §3-4, one-step lag)") == [("environments-v0.md", "3", "4")]
    assert CITATION.findall("see docs/backends.md") == [("backends.md", "", "")]
    for stale in ("[dynamics.md 2.3]", "(spec section 5)", "(kept, spec 6)", "spec sections 2 and 3", "(spec conventions)", "envs-v0 sections 1"):
        assert STALE_CITATION.search(stale), stale
    for fine in ("[docs/dynamics.md §2.3]", "self.observation_spec", "build_action_spec()", "a spec of the run"):
        assert not STALE_CITATION.search(fine), fine
    assert _sections(ROOT / "docs" / "dynamics.md") >= {"1", "1.6", "2.2", "9"}


def test_install_documents_state_the_python_version_and_every_extra() -> None:
    """docs/installation.md and README.md give the Python version pyproject.toml requires and name every extra it declares."""
    project = _pyproject()["project"]
    minimum = re.fullmatch(r">=(\d+\.\d+)", project["requires-python"])
    assert minimum, project["requires-python"]
    installation = (ROOT / "docs" / "installation.md").read_text(encoding="utf-8")
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    stated = set(re.findall(r"Python (\d+\.\d+) or newer", installation + readme))
    assert stated == {minimum.group(1)}, f"the documents say Python {sorted(stated)} or newer; pyproject.toml requires {minimum.group(0)}"
    extras = set(project["optional-dependencies"])
    table = set(re.findall(r"^\| `(\w+)` \|", installation, flags=re.MULTILINE))
    assert table == extras, f"docs/installation.md's extras table: missing {sorted(extras - table)}, unknown {sorted(table - extras)}"
    install_line = re.search(r"Install from the clone: .*?\(extras: (.*?)\)", readme, flags=re.DOTALL)
    assert install_line, "README.md lists the extras where it says how to install from the clone"
    listed = set(re.findall(r"`(\w+)`", install_line.group(1)))
    assert listed == extras - {"fast"}, f"README.md's extras: missing {sorted(extras - {'fast'} - listed)}"


def test_the_readme_gives_the_setup_and_test_durations() -> None:
    """The first commands of the README say how long they take and how much the environment weighs (measured, with their conditions)."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    first_block = readme.split("```bash\n", 1)[1].split("```", 1)[0]
    setup, tests = first_block.split("bash scripts/test.sh")[0].split("\n\n")
    assert re.search(r"\d+ (?:to \d+ )?minutes", setup) and re.search(r"\d(?:\.\d)? GB", setup), setup
    assert re.search(r"\d+ minutes", tests), tests


def _size_check() -> Any:
    import importlib.util

    spec = importlib.util.spec_from_file_location("check_file_sizes", ROOT / "scripts" / "check_file_sizes.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(), reason="needs a git checkout")
def test_no_tracked_file_is_over_the_size_limit() -> None:
    check = _size_check()
    tracked = check.tracked_files(ROOT)
    assert "pyproject.toml" in tracked
    assert check.oversized(tracked, ROOT) == [], "tracked files over the limit: run data goes to a release asset (bluesky-gym results pack)"


@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(), reason="needs a git checkout")
def test_the_committed_results_stay_under_5_mb() -> None:
    """results/ keeps what the pages read; models and raw logs are a release asset (bluesky-gym results pack)."""
    check = _size_check()
    results = [p for p in check.tracked_files(ROOT) if p.startswith("results/")]
    assert any(p.endswith("/curve.csv") for p in results)
    total = sum((ROOT / p).stat().st_size for p in results if (ROOT / p).is_file())
    assert total < 5_000_000, f"results/ holds {total / 1e6:.2f} MB of tracked files, over 5 MB"


def test_the_size_check_names_a_file_over_the_limit(tmp_path: Path) -> None:
    check = _size_check()
    (tmp_path / "big.bin").write_bytes(b"x" * (check.MAX_KB * 1024 + 1))
    (tmp_path / "small.bin").write_bytes(b"x" * (check.MAX_KB * 1024))
    assert check.oversized(["big.bin", "small.bin", "deleted.bin"], tmp_path) == [("big.bin", check.MAX_KB * 1024 + 1)]
    done = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "check_file_sizes.py"), "big.bin", "small.bin"], cwd=tmp_path, capture_output=True, text=True
    )
    assert done.returncode == 1
    assert done.stderr.startswith("big.bin: 512001 bytes, over the repository's limit of 500 KiB")
    assert "small.bin" not in done.stderr
