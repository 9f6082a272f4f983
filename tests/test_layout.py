"""The layout is the architecture (issue 24): no import cycle anywhere, and the layering STYLE.md names.

The graph is read from the sources with ``ast`` (nothing is imported): every ``import`` and ``from ...
import`` of our packages, at module level or inside a function, is an edge from the importing module to
the module it names (``from pkg import name`` names ``pkg.name`` when that is a module, else ``pkg``).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from tests.paths import REPO

PACKAGES = ("merger", "circsim")


def module_files(root: Path = REPO, packages=PACKAGES) -> dict[str, Path]:
    out = {}
    for pkg in packages:
        for p in sorted((root / pkg).rglob("*.py")):
            name = ".".join(p.relative_to(root).with_suffix("").parts)
            out[name.removesuffix(".__init__")] = p
    return out


def imported_names(module: str, path: Path) -> list[tuple[str, ...]]:
    """Per import statement of ``path``, the module names it may name (absolute; ours and others): for
    ``from pkg import name``, ``pkg.name`` (if it is a module) and ``pkg``."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    names = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names += [(a.name,) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            names += [(f"{target}.{a.name}", target) for a in node.names]
    return names


def import_graph(files: dict[str, Path] | None = None) -> dict[str, set[str]]:
    files = module_files() if files is None else files
    graph = {}
    for mod, path in files.items():
        deps = set()
        for candidates in imported_names(mod, path):
            name = next((c for c in candidates if c in files), candidates[-1])
            while name not in files and "." in name:
                name = name.rpartition(".")[0]
            if name in files and name != mod:
                deps.add(name)
        graph[mod] = deps
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``graph`` as a path (first node repeated at the end), or None."""
    state: dict[str, int] = {}  # 1: on the stack, 2: done
    stack: list[str] = []

    def visit(n):
        state[n] = 1
        stack.append(n)
        for m in sorted(graph[n]):
            if state.get(m) == 1:
                return stack[stack.index(m):] + [m]
            if m not in state and (c := visit(m)):
                return c
        stack.pop()
        state[n] = 2
        return None

    for n in sorted(graph):
        if n not in state and (c := visit(n)):
            return c
    return None


def test_the_cycle_finder_finds_a_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set(), "c": {"a", "b"}}) is None


def test_the_graph_sees_function_level_and_relative_imports(tmp_path):
    (tmp_path / "p" / "q").mkdir(parents=True)
    (tmp_path / "p" / "__init__.py").write_text("")
    (tmp_path / "p" / "a.py").write_text("def f():\n    from .q import b\n")
    (tmp_path / "p" / "q" / "__init__.py").write_text("from . import b\n")
    (tmp_path / "p" / "q" / "b.py").write_text("import p.a\n")
    g = import_graph(module_files(tmp_path, ("p",)))
    assert g["p.a"] == {"p.q.b"} and g["p.q"] == {"p.q.b"} and g["p.q.b"] == {"p.a"}
    assert find_cycle(g) == ["p.a", "p.q.b", "p.a"]


def test_no_import_cycle():
    cycle = find_cycle(import_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


@pytest.mark.slow
def test_the_layering():
    """merger never imports circsim; only the world imports pymunk and only the recorder rerun; the
    configuration's types import nothing of ours; the bench does not depend on a CLI module."""
    files = module_files()
    for mod, path in files.items():
        names = [c[-1] for c in imported_names(mod, path)]
        ours = {n.split(".")[0] for n in names} & set(PACKAGES)
        if mod.startswith("merger"):
            assert "circsim" not in ours, mod
        if any(n.split(".")[0] == "pymunk" for n in names):
            assert mod.startswith("circsim.world."), mod
        if any(n.split(".")[0] == "rerun" for n in names):
            assert mod.startswith("circsim.record."), mod
        if mod == "circsim.config.types":
            assert not ours, mod
        clis = {"circsim.cli", "circsim.experiments.cli"} | {m for m in files if m.split(".")[:2] == ["merger", "cli"]}
        if mod not in clis:
            assert not clis & import_graph({mod: path, **{c: files[c] for c in clis}})[mod], mod


def test_tests_do_not_import_benchmarks():
    for p in (REPO / "tests").rglob("*.py"):
        assert "benchmarks" not in {c[-1].split(".")[0] for c in imported_names("tests.x", p)}, p


def test_every_import_of_ours_names_something_that_exists():
    """Function-level imports run only when called: a moved module or name would break them silently."""
    import importlib

    files = {**module_files(), **module_files(REPO, ("tests",))}
    missing = []
    for mod, path in files.items():
        for candidates in imported_names(mod, path):
            target = candidates[-1]
            if target.split(".")[0] not in (*PACKAGES, "tests"):
                continue
            m = importlib.import_module(target)
            name = candidates[0].rpartition(".")[2] if len(candidates) == 2 else None
            if name and not hasattr(m, name) and candidates[0] not in files:
                missing.append(f"{path.relative_to(REPO)}: {target}.{name}")
    assert not missing, missing
