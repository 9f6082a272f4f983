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


def _type_checking_only(tree: ast.AST) -> set[int]:
    """The ids of the statements under ``if TYPE_CHECKING:`` (imported for annotations, never at run time)."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and (getattr(node.test, "id", None) == "TYPE_CHECKING"
                                         or getattr(node.test, "attr", None) == "TYPE_CHECKING"):
            out |= {id(n) for stmt in node.body for n in ast.walk(stmt)}
    return out


def imported_names(module: str, path: Path, type_checking: bool = True) -> list[tuple[str, ...]]:
    """Per import statement of ``path``, the module names it may name (absolute; ours and others): for
    ``from pkg import name``, ``pkg.name`` (if it is a module) and ``pkg``. ``type_checking`` false: without
    the imports under ``if TYPE_CHECKING:`` (the run-time imports only)."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    names = []
    tree = ast.parse(path.read_text(), str(path))
    skip = set() if type_checking else _type_checking_only(tree)
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
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


def import_graph(files: dict[str, Path] | None = None, type_checking: bool = True) -> dict[str, set[str]]:
    files = module_files() if files is None else files
    graph = {}
    for mod, path in files.items():
        deps = set()
        for candidates in imported_names(mod, path, type_checking):
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


TEAM = "merger.team"


def team_layers(doc: Path = REPO / "docs" / "design" / "layout.md") -> dict[str, int]:
    """merger/team/'s layers as docs/design/layout.md lists them (the code block after ``<!-- team-layers -->``):
    module (full name) -> layer, lowest 0."""
    lines = doc.read_text().splitlines()
    k = lines.index("<!-- team-layers -->")
    assert lines[k + 1] == "```", "the layers' block follows its marker"
    layers = {}
    for line in lines[k + 2:lines.index("```", k + 2)]:
        if line[:1].isdigit():  # "N  a, b, c   what they are" (a wrapped description starts with spaces)
            number, _, rest = line.partition("  ")
            for name in rest.strip().split("   ")[0].split(","):
                layers[f"{TEAM}.{name.strip()}"] = int(number)
    return layers


def layering_faults(graph: dict[str, set[str]], layers: dict[str, int]) -> list[str]:
    """Every import of a module of ``layers`` that names a module of the same or a higher layer."""
    return [f"{m} (layer {layers[m]}) imports {d} (layer {layers[d]})"
            for m in sorted(layers) for d in sorted(graph.get(m, ())) if d in layers and layers[d] >= layers[m]]


def test_the_layer_reader_and_checker():
    layers = team_layers()
    assert layers[f"{TEAM}.defaults"] == 0 and layers[f"{TEAM}.params"] == 1 and layers[f"{TEAM}.online"] == 7
    assert layering_faults({"a": {"b"}, "b": {"c"}, "c": set()}, {"a": 2, "b": 1, "c": 0}) == []
    assert layering_faults({"a": {"b"}, "b": {"a"}}, {"a": 1, "b": 1}) == ["a (layer 1) imports b (layer 1)",
                                                                           "b (layer 1) imports a (layer 1)"]
    assert layering_faults({"c": {"a"}}, {"a": 1, "c": 0}) == ["c (layer 0) imports a (layer 1)"]


def test_params_imports_no_module_that_reads_its_settings():
    """Settings flow down (issue 45): track, verify and evidence read their defaults from merger.team.defaults
    (as params does); params, at the bottom with it, imports none of them at run time."""
    files = module_files()
    graph = import_graph({m: p for m, p in files.items() if m.startswith(TEAM)}, type_checking=False)
    assert graph[f"{TEAM}.params"] == {f"{TEAM}.defaults"}
    for low in ("track", "verify", "evidence"):
        assert f"{TEAM}.params" not in graph[f"{TEAM}.{low}"], low
        assert f"{TEAM}.defaults" in graph[f"{TEAM}.{low}"], low


def test_merger_team_imports_flow_down_its_documented_layers():
    """A module of merger/team/ imports (at run time) only modules of lower layers (docs/design/layout.md);
    every module of merger/team/ has its layer."""
    files = {m: p for m, p in module_files().items() if m.startswith(TEAM + ".")}
    layers = team_layers()
    assert set(files) == set(layers), f"modules without a layer: {sorted(set(files) - set(layers))}; " \
                                      f"layers without a module: {sorted(set(layers) - set(files))}"
    assert not layering_faults(import_graph(files, type_checking=False), layers)


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
