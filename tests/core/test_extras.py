"""Install hints of missing extras: a distribution name of its own, requirements read from the metadata."""

from __future__ import annotations

import re
import shutil
import sys
import tomllib
from pathlib import Path

import pytest
from packaging.requirements import Requirement

from bluesky_gym.core import extras
from bluesky_gym.core.extras import DISTRIBUTION, MissingDependencyError, install_hint, missing_extra, requirements_of_extra

ROOT = Path(__file__).resolve().parents[2]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))


def _name(text: str) -> str:
    return re.sub(r"[-_.]+", "-", text).lower()


def test_the_distribution_has_a_name_of_its_own() -> None:
    # The package index serves "bluesky-gym" as the reference implementation 0.2.0.
    assert PYPROJECT["project"]["name"] == DISTRIBUTION
    assert _name(DISTRIBUTION) != "bluesky-gym"
    assert PYPROJECT["project"]["scripts"] == {"bluesky-gym": "bluesky_gym.cli:main"}
    for reqs in PYPROJECT["project"]["optional-dependencies"].values():
        for r in reqs:
            assert _name(Requirement(r).name) != "bluesky-gym", r


def test_requirements_of_an_extra_are_read_from_requires_dist_lines() -> None:
    lines = [
        "numpy>=1.26",
        'torch==2.13.0; extra == "train"',
        "tomli>=2; python_version < \"3.11\" and extra == 'train'",
        'pettingzoo>=1.24; extra == "multiagent"',
        'pytest>=8; extra == "test"',
        f'{DISTRIBUTION}[test]; extra == "dev"',
        f'{DISTRIBUTION}[train,dev]; extra == "all"',
        'torch==2.13.0; extra == "all"',
    ]
    assert requirements_of_extra(lines, "train") == ["torch==2.13.0", 'tomli>=2; python_version < "3.11"']
    assert requirements_of_extra(lines, "all") == ["torch==2.13.0", 'tomli>=2; python_version < "3.11"', "pytest>=8"]
    assert requirements_of_extra(lines, "nothing") == []


@pytest.mark.parametrize("extra", sorted(PYPROJECT["project"]["optional-dependencies"]))
def test_every_hint_installs_the_extras_own_requirements(extra: str) -> None:
    hint = install_hint(extra)
    first = hint.split(" (or, in this checkout: ")[0]
    listed = [] if first.startswith("pip install -e ") else re.findall(r'"([^"]+)"', first)
    for r in listed:
        Requirement(r)  # every listed requirement parses
    declared = PYPROJECT["project"]["optional-dependencies"][extra]
    own = [r for r in declared if _name(Requirement(r).name) != _name(DISTRIBUTION)]
    assert {str(Requirement(r)) for r in own} <= {str(Requirement(r)) for r in listed}  # specifier order aside
    assert not any(_name(Requirement(r).name) in (_name(DISTRIBUTION), "bluesky-gym") for r in listed)
    assert f'pip install -e "{ROOT}[{extra}]"' in hint  # tests run from a checkout


def test_the_hint_comes_from_the_installed_metadata_when_there_is_one(monkeypatch: pytest.MonkeyPatch) -> None:
    class Dist:
        requires = ('made-up-package==1.2; extra == "train"', "numpy")

    def distribution(name: str) -> Dist:
        assert name == DISTRIBUTION
        return Dist()

    monkeypatch.setattr(extras.importlib.metadata, "distribution", distribution)
    monkeypatch.setattr(extras, "source_checkout", lambda: None)
    assert install_hint("train") == 'pip install "made-up-package==1.2"'


def test_a_missing_extra_error_names_the_extra_and_the_hint() -> None:
    error = missing_extra("training needs Stable-Baselines3", "train")
    assert isinstance(error, MissingDependencyError) and isinstance(error, ImportError)
    assert str(error).startswith("training needs Stable-Baselines3, which is not installed (the 'train' extra): pip install ")
    assert "\n" not in str(error)
    assert '"torch==2.13.0"' in str(error)


def test_no_install_hint_names_the_index_package() -> None:
    texts = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md")), *sorted((ROOT / "bluesky_gym").rglob("*.py"))]
    for path in texts:
        text = path.read_text(encoding="utf-8")
        assert not re.search(r"pip install [\"']?bluesky-gym\b", text), path


def test_the_sb3_error_carries_the_hint(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "stable_baselines3", None)
    with pytest.raises(MissingDependencyError, match=re.escape(install_hint("train"))):
        extras.require_sb3()


def test_the_hint_from_the_checkouts_own_built_metadata(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The metadata setuptools builds from pyproject.toml gives every extra's requirements, self-references expanded."""
    import importlib.metadata

    build_meta = pytest.importorskip("setuptools.build_meta")
    monkeypatch.chdir(ROOT)
    dist_info = build_meta.prepare_metadata_for_build_wheel(str(tmp_path))
    for leftover in ROOT.glob("*.egg-info"):
        shutil.rmtree(leftover)
    dist = importlib.metadata.PathDistribution(tmp_path / dist_info)
    assert dist.metadata["Name"] == DISTRIBUTION
    monkeypatch.setattr(extras.importlib.metadata, "distribution", lambda name: dist)
    monkeypatch.setattr(extras, "source_checkout", lambda: None)
    declared = PYPROJECT["project"]["optional-dependencies"]
    assert install_hint("train") == "pip install " + " ".join(f'"{r}"' for r in declared["train"])
    everything = {Requirement(r).name for r in re.findall(r'"([^"]+)"', install_hint("all"))}
    (itself,) = declared["all"]
    nested = {"test", *Requirement(itself).extras}  # "all" names its extras; "dev" adds "test"
    expected = {Requirement(r).name for extra in nested for r in declared[extra]}
    assert everything == expected - {DISTRIBUTION}
