"""The package's layers: no import cycles between its modules and no import from a lower layer into a higher one.

Every import statement counts, also one inside a function (it runs when the function is called);
imports under ``if TYPE_CHECKING:`` do not (they never run). A module may import its own packages
(``bluesky_gym.core.geo`` may import ``bluesky_gym.core``) and the top-level ``bluesky_gym``.

Layers, lowest first; a module may import from its own layer and the layers below it:

    core < backends < tasks, scenarios < wrappers, render < envs, multiagent
         < registration, training < benchmarks < cli < __main__

An environment's folder (``bluesky_gym/environments/<name>/``) cuts across the layers: each file
is ranked by its role, the layer it extends (:data:`ROLES`: ``task.py`` with the tasks,
``scene.py`` with render, ``env.py`` with envs, ...), so inside a folder too imports only look
down (a task may not import its scene). The folders' ``__init__.py`` files rank lowest: they
import nothing.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parents[1] / "bluesky_gym"

#: Rank of every top-level module or subpackage of ``bluesky_gym``.
LAYERS = {
    "core": 0,
    "backends": 1,
    "tasks": 2,
    "scenarios": 2,
    "realtraffic": 2,
    "wrappers": 3,
    "render": 3,
    "envs": 4,
    "multiagent": 4,
    "registration": 5,
    "training": 5,
    "benchmarks": 6,
    "cli": 7,
    "__main__": 8,
    "environments": 0,  # the package and folder ``__init__.py`` files of ``bluesky_gym.environments``
}

#: The layer of each file of an environment folder, by file name (``bluesky_gym/environments/<name>/<role>.py``).
ROLES = {
    "task": "tasks",
    "scene": "render",
    "env": "envs",
    "multiagent": "multiagent",
    "parallel": "multiagent",
    "controller": "training",
    "device_step": "envs",
}


def module_name(path: Path, package_dir: Path) -> str:
    """Dotted name of the module in ``path`` (a package is named by its ``__init__.py``)."""
    parts = list(path.relative_to(package_dir.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def package_modules(package_dir: Path) -> dict[str, Path]:
    """Every module of the package, by dotted name."""
    return {module_name(p, package_dir): p for p in sorted(package_dir.rglob("*.py"))}


def _is_type_checking(test: ast.expr) -> bool:
    """``TYPE_CHECKING`` or ``typing.TYPE_CHECKING``."""
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _runtime_imports(tree: ast.Module) -> list[ast.Import | ast.ImportFrom]:
    """The import statements of a module that can run: all of them but those under ``if TYPE_CHECKING:``."""
    never_run: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            never_run.update(id(n) for statement in node.body for n in ast.walk(statement))
    return [n for n in ast.walk(tree) if isinstance(n, (ast.Import, ast.ImportFrom)) and id(n) not in never_run]


def _absolute(node: ast.ImportFrom, importer: str, importer_path: Path) -> str:
    """The absolute module name of a ``from ... import`` (resolving relative imports)."""
    if not node.level:
        return node.module or ""
    package = importer.split(".") if importer_path.name == "__init__.py" else importer.split(".")[:-1]
    package = package[: len(package) - (node.level - 1)]
    return ".".join(package + ([node.module] if node.module else []))


def imports_of(importer: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The package modules that ``importer`` imports at run time."""
    candidates: list[str] = []
    for node in _runtime_imports(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            candidates += [alias.name for alias in node.names]
        else:
            base = _absolute(node, importer, path)
            candidates += [base] + [f"{base}.{alias.name}" for alias in node.names]  # a name may be a submodule
    root = importer.split(".")[0]
    found = set()
    for name in candidates:
        while name and name not in modules:  # ``pkg.mod.function`` -> ``pkg.mod``
            name = name.rpartition(".")[0]
        if name and name != importer and name != root and not importer.startswith(name + "."):
            found.add(name)
    return found


def import_graph(package_dir: Path) -> dict[str, set[str]]:
    """Module -> the package modules it imports."""
    modules = package_modules(package_dir)
    return {name: imports_of(name, path, modules) for name, path in modules.items()}


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Groups of modules that import each other, directly or through others (Tarjan's strongly connected components)."""
    index: dict[str, int] = {}
    lowlink: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = lowlink[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                lowlink[v] = min(lowlink[v], lowlink[w])
            elif w in on_stack:
                lowlink[v] = min(lowlink[v], index[w])
        if lowlink[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return cycles


def layer(module: str) -> str | None:
    """The layer of a module: its top-level module or subpackage under the root (None for the root itself).

    A file of an environment folder (``root.environments.<name>.<role>``) is in its role's layer
    (:data:`ROLES`); a file without a known role is named ``environments.<name>.<role>``, which
    has no rank.
    """
    parts = module.split(".")
    if len(parts) > 3 and parts[1] == "environments":
        return ROLES.get(parts[3], ".".join(parts[1:4]))
    return parts[1] if len(parts) > 1 else None


def rank(module: str) -> int | None:
    """The rank of a module's layer (None for the root and for parts without a rank)."""
    part = layer(module)
    return LAYERS.get(part) if part is not None else None


def upward_imports(graph: dict[str, set[str]]) -> list[tuple[str, str]]:
    """(importer, imported) pairs where the imported module sits in a higher layer."""
    up = []
    for importer, targets in graph.items():
        for imported in targets:
            low, high = rank(importer), rank(imported)
            if low is not None and high is not None and high > low:
                up.append((importer, imported))
    return sorted(up)


# --- the package ---------------------------------------------------------------------------------


def test_every_part_of_the_package_has_a_layer() -> None:
    parts = {layer(m) for m in package_modules(PACKAGE_DIR)} - {None}
    assert parts <= set(LAYERS), f"give {sorted(parts - set(LAYERS))} a rank in LAYERS (a file of an environment folder: a role in ROLES)"


def test_every_environment_folder_file_has_a_role() -> None:
    folders = [p for p in (PACKAGE_DIR / "environments").iterdir() if p.is_dir() and p.name != "__pycache__"]
    assert len(folders) >= 8
    for folder in folders:
        files = {p.stem for p in folder.glob("*.py")} - {"__init__"}
        assert "task" in files and "env" in files, f"{folder.name}: an environment folder holds at least task.py and env.py"
        assert files <= set(ROLES), f"{folder.name}: {sorted(files - set(ROLES))} have no role in ROLES"


def test_no_import_cycles() -> None:
    cycles = import_cycles(import_graph(PACKAGE_DIR))
    assert not cycles, "import cycles:\n" + "\n".join(" <-> ".join(c) for c in cycles)


def test_no_import_from_a_higher_layer() -> None:
    up = upward_imports(import_graph(PACKAGE_DIR))
    assert not up, "imports from a higher layer:\n" + "\n".join(f"{a} imports {b}" for a, b in up)


# --- the checker itself ----------------------------------------------------------------------------


def _write_package(root: Path, files: dict[str, str]) -> Path:
    package_dir = root / "pkg"
    for name, text in files.items():
        path = package_dir / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return package_dir


def test_checker_counts_function_level_imports_and_skips_type_checking_blocks(tmp_path: Path) -> None:
    package_dir = _write_package(
        tmp_path,
        {
            "__init__.py": "",
            "core/__init__.py": "",
            "core/a.py": "def f():\n    from pkg.core import b\n",  # runs when f is called: counts
            "core/b.py": "from . import a\n",
            "core/c.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg.tasks import t\nelse:\n    import pkg.core.a\n",
            "tasks/__init__.py": "",
            "tasks/t.py": "from pkg.core.c import x\n",
            "envs/__init__.py": "from ..core import a\n",
        },
    )
    graph = import_graph(package_dir)
    assert graph["pkg.core.a"] == {"pkg.core.b"}
    assert graph["pkg.core.c"] == {"pkg.core.a"}  # the TYPE_CHECKING import is not an edge, the else branch is
    assert graph["pkg.envs"] == {"pkg.core", "pkg.core.a"}
    assert import_cycles(graph) == [["pkg.core.a", "pkg.core.b"]]
    assert upward_imports(graph) == []


def test_checker_finds_upward_imports(tmp_path: Path) -> None:
    package_dir = _write_package(
        tmp_path,
        {
            "__init__.py": "from pkg.cli import main\n",  # the root may import anything
            "core/__init__.py": "",
            "core/sim.py": "def render():\n    from pkg.render.draw import draw\n",
            "render/__init__.py": "",
            "render/draw.py": "from pkg.core import sim\n",
            "cli.py": "import pkg.core.sim\n",
        },
    )
    graph = import_graph(package_dir)
    assert upward_imports(graph) == [("pkg.core.sim", "pkg.render.draw")]
    assert import_cycles(graph) == [["pkg.core.sim", "pkg.render.draw"]]


def test_checker_ranks_environment_folder_files_by_role(tmp_path: Path) -> None:
    package_dir = _write_package(
        tmp_path,
        {
            "__init__.py": "",
            "tasks/__init__.py": "",
            "tasks/base.py": "",
            "render/__init__.py": "",
            "envs/__init__.py": "",
            "envs/shell.py": "",
            "environments/__init__.py": "",
            "environments/foo/__init__.py": "",
            "environments/foo/task.py": "from pkg.tasks import base\n",
            "environments/foo/scene.py": "from pkg.environments.foo import task\n",  # down: render reads the task
            "environments/foo/env.py": "from pkg.envs import shell\nfrom . import scene, task\n",  # down
            "environments/foo/notes.py": "",  # no role
            "environments/bar/__init__.py": "",
            "environments/bar/task.py": "from pkg.environments.foo.task import X\n",  # across: another environment's task
        },
    )
    assert layer("pkg.environments.foo.task") == "tasks"
    assert layer("pkg.environments.foo.scene") == "render"
    assert layer("pkg.environments.foo.notes") == "environments.foo.notes"
    assert rank("pkg.environments.foo.notes") is None
    assert rank("pkg.environments.foo") == rank("pkg.environments") == 0
    graph = import_graph(package_dir)
    assert graph["pkg.environments.foo.env"] == {"pkg.envs", "pkg.envs.shell", "pkg.environments.foo.scene", "pkg.environments.foo.task"}
    assert upward_imports(graph) == []


def test_checker_finds_an_upward_import_inside_an_environment_folder(tmp_path: Path) -> None:
    package_dir = _write_package(
        tmp_path,
        {
            "__init__.py": "",
            "environments/__init__.py": "",
            "environments/foo/__init__.py": "",
            "environments/foo/task.py": "def draw():\n    from .scene import build\n",  # a task importing its scene: up
            "environments/foo/scene.py": "from pkg.environments.foo import env\n",  # a scene importing its environment: up
            "environments/foo/env.py": "",
            "environments/foo/controller.py": "from . import env, task\n",  # training reads envs and tasks: down
            "environments/bar/__init__.py": "",
            "environments/bar/task.py": "import pkg.environments.foo.env\n",  # another folder's env: up
        },
    )
    graph = import_graph(package_dir)
    assert upward_imports(graph) == [
        ("pkg.environments.bar.task", "pkg.environments.foo.env"),
        ("pkg.environments.foo.scene", "pkg.environments.foo.env"),
        ("pkg.environments.foo.task", "pkg.environments.foo.scene"),
    ]
