"""The layers of the package, read from its import graph.

The graph is built from the source of every module of ``cartan`` (every ``import`` and
``from ... import`` statement, at module level, inside functions and under ``TYPE_CHECKING``;
relative imports resolved; ``from package import name`` is an import of the module
``package.name`` when there is one, else of the package's ``__init__``).  Modules named by a
string and imported with :mod:`importlib` — the loop sources of
:data:`cartan.compiled.operators.LOOP_SOURCES`, the compiled plans a scheme names — are not
edges: they are chosen at run time, by name.

The rules (``docs/design.md``, "Layers"): no import cycle through a module of
``cartan.schemes`` or ``cartan.integrators``; schemes never import integrators; integrators
import no private module of the schemes (``cartan.schemes._*``), only their public operator
interface; :mod:`cartan.scene` and :mod:`cartan.simulate` import neither the other; the run's
state has its own module, below both schemes and integrators.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import pathlib
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "cartan"

#: Modules being retired, left out of the graph (with every import of them) until they are
#: deleted.  This list must shrink to empty: an entry whose file is gone fails
#: :func:`test_legacy_modules_still_exist`, so it is removed as the file goes, and the rules
#: then cover what used to import it.
LEGACY: tuple[str, ...] = ()


def module_name(path: pathlib.Path) -> str:
    """``cartan/schemes/base.py`` → ``cartan.schemes.base``; a package's ``__init__`` → the package."""
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules(exclude: tuple[str, ...] = LEGACY) -> dict[str, pathlib.Path]:
    """Every module of the package by name, without ``exclude`` (paths relative to the repository)."""
    skip = {(ROOT / p).resolve() for p in exclude}
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py")) if p.resolve() not in skip}


def _known(name: str, known: set[str], every: set[str]) -> str | None:
    """The module ``name`` names, or the innermost package holding it; None outside the package
    or for a module left out of the graph."""
    while name:
        if name in every:
            return name if name in known else None
        name = name.rpartition(".")[0]
    return None


def imports_of(path: pathlib.Path, name: str, known: set[str], every: set[str]) -> set[str]:
    """The modules of the package that the source of ``path`` (module ``name``) imports."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*base, *([node.module] if node.module else [])])
            else:
                base = node.module or ""
            # ``from package import module`` imports that module; ``from module import name`` the module
            targets = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in every else base for alias in node.names]
        else:
            continue
        for target in targets:
            module = _known(target, known, every)
            if module is not None and module != name:
                out.add(module)
    return out


def import_graph(exclude: tuple[str, ...] = LEGACY) -> dict[str, set[str]]:
    """``{module: modules it imports}`` over the package, without the modules of ``exclude``."""
    mods = modules(exclude)
    every = set(modules(()))
    return {name: imports_of(path, name, set(mods), every) for name, path in mods.items()}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 10 * len(graph) + 100))
    try:
        for v in sorted(graph):
            if v not in index:
                visit(v)
    finally:
        sys.setrecursionlimit(limit)
    return found


def cycle_through(graph: dict[str, set[str]], component: list[str]) -> list[str]:
    """One closed path ``[a, b, ..., a]`` inside a strongly connected ``component`` (for messages)."""
    members = set(component)
    start = component[0]
    paths = {start: [start]}
    frontier = [start]
    while frontier:  # breadth first: the shortest way back to start
        nxt = []
        for v in frontier:
            for w in sorted(graph[v] & members):
                if w == start:
                    return [*paths[v], start]
                if w not in paths:
                    paths[w] = [*paths[v], w]
                    nxt.append(w)
        frontier = nxt
    raise AssertionError(f"{component} is not strongly connected")  # pragma: no cover


def _in(name: str, package: str) -> bool:
    return name == package or name.startswith(package + ".")


def _report(graph: dict[str, set[str]], components: list[list[str]]) -> str:
    return "\n".join(f"  {' -> '.join(cycle_through(graph, c))}   (component {c})" for c in components)


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    return import_graph()


# ---------------------------------------------------------------------------- the graph itself
def test_the_graph_sees_every_kind_of_import(tmp_path):
    """Module-level, function-level and ``TYPE_CHECKING`` imports, relative and absolute,
    ``from package import module`` and ``from package import name`` (the package's
    ``__init__``); string imports are not edges."""
    source = tmp_path / "probe.py"
    source.write_text(
        "from __future__ import annotations\n"
        "import importlib\n"
        "from typing import TYPE_CHECKING\n"
        "import numpy as np\n"
        "from ..state import State\n"  # relative, two levels
        "from . import lattice\n"  # from package import module
        "from ..compiled import codegen, operators\n"
        "import cartan.limits\n"  # absolute
        "if TYPE_CHECKING:\n"
        "    from ..integrators.base import Integrator\n"
        "def f():\n"
        "    from .base import Scheme\n"  # function level
        "    from .. import plugins\n"
        "    from ..groups import SymmetryGroup\n"  # a name of a package: its __init__
        "    importlib.import_module('cartan.simulate')\n"  # by name: not an edge
    )
    every = set(modules(()))
    got = imports_of(source, "cartan.schemes.probe", every, every)
    assert got == {
        "cartan.state", "cartan.schemes.lattice", "cartan.compiled.codegen", "cartan.compiled.operators",
        "cartan.limits", "cartan.integrators.base", "cartan.schemes.base", "cartan.plugins", "cartan.groups",
    }
    # a module left out of the graph is no edge
    without = every - {"cartan.schemes.lattice"}
    assert "cartan.schemes.lattice" not in imports_of(source, "cartan.schemes.probe", without, every)
    g = import_graph(())
    assert "cartan.state" in g["cartan.schemes.base"]  # from ..state import State
    assert {"cartan.api", "cartan.groups"} <= g["cartan"]  # a package's __init__: from . import api
    assert "cartan.api" in g["cartan.scene"]  # inside Scene.run
    # the loop sources of the generated modules are imported by name, not counted
    assert not {"cartan.integrators.loops", "cartan.compiled.diagnostics"} & g["cartan.compiled.operators"]


def test_cycles_and_paths_on_a_small_graph():
    g = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert cycles(g) == [["a", "b", "c"]]
    assert cycle_through(g, ["a", "b", "c"]) == ["a", "b", "c", "a"]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_legacy_modules_still_exist():
    """Each entry of LEGACY names a file that is still there: remove entries as their files go."""
    gone = [p for p in LEGACY if not (ROOT / p).is_file()]
    assert not gone, f"delete these entries of LEGACY, their modules are gone: {gone}"


# ---------------------------------------------------------------------------- the rules
def test_no_cycle_through_schemes_or_integrators(graph):
    bad = [c for c in cycles(graph) if any(_in(m, "cartan.schemes") or _in(m, "cartan.integrators") for m in c)]
    assert not bad, "import cycles through cartan.schemes or cartan.integrators:\n" + _report(graph, bad)


def test_schemes_never_import_integrators(graph):
    bad = {m: sorted(d for d in deps if _in(d, "cartan.integrators"))
           for m, deps in graph.items() if _in(m, "cartan.schemes")}
    bad = {m: d for m, d in bad.items() if d}
    assert not bad, f"scheme modules importing integrators: {bad}"


def test_integrators_import_no_private_scheme_module(graph):
    bad = {m: sorted(d for d in deps if d.startswith("cartan.schemes._"))
           for m, deps in graph.items() if _in(m, "cartan.integrators")}
    bad = {m: d for m, d in bad.items() if d}
    assert not bad, f"integrator modules importing private scheme modules: {bad}"


def test_scene_and_simulate_import_neither_the_other():
    g = import_graph(())  # every module: this rule has no legacy exception
    assert "cartan.simulate" not in g["cartan.scene"], "cartan.scene imports cartan.simulate"
    assert "cartan.scene" not in g["cartan.simulate"], "cartan.simulate imports cartan.scene"


def test_state_is_below_schemes_and_integrators():
    g = import_graph(())
    assert g["cartan.state"] <= set(), f"cartan.state imports {sorted(g['cartan.state'])}"
    from cartan.schemes.base import State as Reexported
    from cartan.state import State

    assert Reexported is State and State.__module__ == "cartan.state"


def test_limits_are_below_scene_and_simulate():
    g = import_graph(())
    assert g["cartan.limits"] == set()
    assert "cartan.limits" in g["cartan.scene"] and "cartan.limits" in g["cartan.simulate"]
    limits = importlib.import_module("cartan.limits")
    scene = importlib.import_module("cartan.scene")  # the module, not the function cartan.scene

    for name in ("step_limit", "memory_limit", "check_memory", "state_bytes", "format_bytes"):
        assert getattr(scene, name) is getattr(limits, name)  # old imports keep working


# ---------------------------------------------------------------------------- Δt from the command line
def test_dt_reaches_the_loop_from_cartan_run_through_four_functions(tmp_path, monkeypatch):
    """``cartan run --dt`` reaches the step loop unchanged, through at most four functions of the
    package between the command and the loop call: :func:`cartan.simulate.simulate`, the
    resolution of the run (which returns Δt), the save loop and ``_advance``."""
    from click.testing import CliRunner

    from cartan.cli import main

    simulate_module = importlib.import_module("cartan.simulate")
    seen: list[tuple[float, list[str]]] = []

    class Stop(Exception):
        pass

    def advance(integrator, scheme, state, dt, nsteps, guard, compiled=True, whole=False):
        names = [f.function for f in inspect.stack()[1:]]
        seen.append((dt, names[: names.index("_run") if "_run" in names else len(names)]))
        raise Stop

    scene = tmp_path / "scene.toml"
    scene.write_text(
        'name = "chain"\nmedium = "cosserat-rod"\n[parameters]\nE = 1e4\npoisson = 0.5\nradius = 0.25\n'
        'density = 5000.0\n[grid]\nn = 5\nlength = 1.0\n'
        '[initial]\nkind = "arc"\ncurvature = 0.5\n[run]\ndt = 1e-3\nt_end = 0.01\n'
    )
    monkeypatch.setattr(simulate_module, "_advance", advance)
    res = CliRunner().invoke(main, ["run", str(scene), "-o", str(tmp_path / "out.nc"), "--dt", "0.00037"],
                             env={"CI": "1"})
    assert isinstance(res.exception, Stop), (res.output, res.exception)
    (dt, chain), = seen
    assert dt == 0.00037
    # between the command (cli_run._run) and _advance: simulate and the save loop; the
    # resolution returned Δt to simulate on the way: with _advance, four functions
    assert chain == ["_execute_run", "simulate"], chain
    assert len(chain) + 2 <= 4
