"""Optional dependencies: import them on demand, or fail with the extra that installs them.

The distribution is called :data:`DISTRIBUTION` (the import name stays ``bluesky_gym``); the
package index does not serve it, so an install hint never names the distribution itself: it lists
the extra's own requirements, read from the installed metadata (or, in a source checkout, from
its ``pyproject.toml``), and in a checkout also the editable install of the extra.
:func:`missing_extra` builds every missing-extra error of the package.

This module imports nothing else from the package, so every layer may use it.
"""

from __future__ import annotations

import importlib.metadata
import re
from pathlib import Path
from types import ModuleType

#: Name of the distribution (``pip install -e ".[train]"`` from a checkout installs it).
DISTRIBUTION = "bluesky-gym-batched"

_EXTRA_MARKER = re.compile(r"""\s*extra\s*==\s*["']([^"']+)["']\s*""")


class MissingDependencyError(ImportError):
    """An optional dependency is not installed; the message says which extra provides it."""


def _normalise(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _self_reference(requirement: str) -> list[str] | None:
    """The extras of a requirement on this distribution itself (``NAME[a,b]``), else None."""
    m = re.match(r"^\s*([A-Za-z0-9][A-Za-z0-9._-]*)\s*\[([^\]]*)\]\s*$", requirement)
    if m is None or _normalise(m.group(1)) != _normalise(DISTRIBUTION):
        return None
    return [e.strip() for e in m.group(2).split(",") if e.strip()]


def requirements_of_extra(requires_dist: list[str], extra: str) -> list[str]:
    """The requirements an extra adds, from ``Requires-Dist`` lines, self-references expanded.

    Args:
        requires_dist: Metadata lines such as ``'torch==2.13.0; extra == "train"'``.
        extra: Extra name.

    Returns:
        Requirement strings without the ``extra == ...`` marker (other markers kept), in order,
        without duplicates.

    """
    out: list[str] = []

    def visit(name: str, seen: set[str]) -> None:
        if name in seen:
            return
        seen.add(name)
        for line in requires_dist:
            requirement, _, marker = line.partition(";")
            clauses = [c for c in re.split(r"\band\b", marker) if c.strip()]
            extras = [m.group(1) for c in clauses if (m := _EXTRA_MARKER.fullmatch(c))]
            if extras != [name]:
                continue
            rest = " and ".join(c.strip() for c in clauses if not _EXTRA_MARKER.fullmatch(c))
            nested = _self_reference(requirement)
            if nested is not None:
                for e in nested:
                    visit(e, seen)
                continue
            text = requirement.strip() + (f"; {rest}" if rest else "")
            if text not in out:
                out.append(text)

    visit(extra, set())
    return out


def source_checkout() -> Path | None:
    """The root of the source checkout this package is imported from, if it is one."""
    root = Path(__file__).resolve().parents[2]
    pyproject = root / "pyproject.toml"
    if not pyproject.is_file():
        return None
    try:
        text = pyproject.read_text(encoding="utf-8")
    except OSError:
        return None
    return root if re.search(rf'^name\s*=\s*"{re.escape(DISTRIBUTION)}"\s*$', text, flags=re.MULTILINE) else None


def _checkout_requires_dist(root: Path) -> list[str]:
    """``Requires-Dist``-style lines of the optional dependencies in a checkout's ``pyproject.toml``."""
    import tomllib

    with open(root / "pyproject.toml", "rb") as f:
        extras = tomllib.load(f).get("project", {}).get("optional-dependencies", {})
    return [f'{r}; extra == "{name}"' for name, reqs in extras.items() for r in reqs]


def extra_requirements(extra: str) -> list[str]:
    """The requirements of an extra: from the installed metadata, else from the checkout's ``pyproject.toml``."""
    try:
        lines = importlib.metadata.distribution(DISTRIBUTION).requires or []
    except importlib.metadata.PackageNotFoundError:
        root = source_checkout()
        lines = _checkout_requires_dist(root) if root is not None else []
    return requirements_of_extra(lines, extra)


def install_hint(extra: str) -> str:
    """A command line that installs an extra, e.g. ``pip install "stable-baselines3>=2.3" "torch==2.13.0" ...``.

    From a source checkout, the editable install of the extra is offered as well.
    """
    hints = []
    requirements = extra_requirements(extra)
    if requirements:
        hints.append("pip install " + " ".join(f'"{r}"' for r in requirements))
    root = source_checkout()
    if root is not None:
        hints.append(f'pip install -e "{root}[{extra}]"')
    if not hints:
        return f"install the '{extra}' extra of {DISTRIBUTION}"
    return hints[0] if len(hints) == 1 else f"{hints[0]} (or, in this checkout: {hints[1]})"


def missing_extra(need: str, extra: str) -> MissingDependencyError:
    """The error for a missing optional dependency: what needs it, the extra and how to install it.

    Args:
        need: What is missing, e.g. ``"training needs Stable-Baselines3 and PyTorch"``.
        extra: The extra that provides it (``train``, ``render``, ...).

    """
    return MissingDependencyError(f"{need}, which is not installed (the '{extra}' extra): {install_hint(extra)}")


def require_sb3() -> ModuleType:
    """Import Stable-Baselines3, or raise :class:`MissingDependencyError` naming the extra."""
    try:
        import stable_baselines3
    except ImportError as exc:
        raise missing_extra("training needs Stable-Baselines3 and PyTorch", "train") from exc
    return stable_baselines3


def require_ray() -> ModuleType:
    """Import Ray, or raise :class:`MissingDependencyError` naming the extra (and the sequential alternative)."""
    try:
        import ray
    except ImportError as exc:
        error = missing_extra("distributed sweeps need Ray", "distributed")
        raise MissingDependencyError(f"{error} (or run the sweep with --local)") from exc
    return ray


def require_rliable() -> tuple[ModuleType, ModuleType]:
    """Import ``rliable.library`` and ``rliable.metrics``, or raise :class:`MissingDependencyError` naming the extra."""
    try:
        from rliable import library, metrics
    except ImportError as exc:
        raise missing_extra("aggregate scores need rliable", "train") from exc
    return library, metrics
