"""Warming numba's on-disk cache: ``cartan warm`` and :func:`warm`.

Every compiled kernel of cartan is ``@njit(cache=True)``: numba compiles it on first use and
writes the machine code next to the source (``__pycache__``, or ``NUMBA_CACHE_DIR``), and a
later process loads it from there in milliseconds.  Compiling everything from an empty cache
takes minutes; :func:`warm` does it once, at install time (``make install`` runs
``cartan warm``), so that no run and no timing ever includes compilation.

What is compiled, all through the public entry points and the registries (so plugins are
warmed too):

``groups``
    every registered group (``SO`` for n = 4 and 5: n = 2, 3 use the SO(2), SO(3) kernels)
    calls each operation it has a numba batch kernel for, on a few points;
``cases``
    every registered verification case at its coarsest level runs three steps with every
    integrator (but ``kinematic``, which needs a velocity field) on every scheme through
    :func:`cartan.simulate` — the compiled step loops, the CFL estimate, the blow-up guard
    and the frame output, on every group the media use; combinations a case does not
    support (e.g. ``overdamped`` without drag) are skipped.  A static case (``case.static``)
    is solved once by its own solver (``case.run``).
``grids``
    the registered cases are rods (d = 1), so the d = 2 and 3 builds of the step loops are
    compiled on small periodic grids (:data:`GRID_SHAPES`) of a core quadratic continuum on
    SE(3) with damping: three steps of every integrator (but ``kinematic``) on every scheme
    through :func:`cartan.simulate`, as for the cases (the loops' machine code depends on d,
    not on the medium, group or loads, which they take as data);
``threads``
    the threaded builds of the compiled loops (the ``prange`` twins of
    :func:`cartan._threads.threaded_twins`, which a loop runs with ``CARTAN_THREADS`` > 1 on
    grids of at least :data:`cartan._threads.MIN_NODES` nodes): a case runs again, on its
    small grid, inside :func:`cartan._threads.threaded_everywhere` (two threads, the node
    threshold lowered to one node), so that no large problem is needed.  With ``cases`` in
    the same call, only the runs whose serial run reached a loop with a threaded build (one
    that asked :func:`cartan._threads.loop_threads` for its thread count) run again;
    alone, every dynamic case × integrator × scheme does (and the same for ``grids``).  These runs take one step (enough
    for numba, which compiles a whole loop for its argument types at the first call), through
    :func:`cartan.simulate` like a threaded run.  Skipped when numba has a single thread
    (``NUMBA_NUM_THREADS = 1``: no run can use them); ``cartan warm --no-threads`` leaves them
    out (a loop's threaded build then compiles on its first threaded run, about a minute).

:func:`kernel_inventory` lists the cached kernels of the loaded cartan modules (the threaded
twins included) with their compiled signatures and cache hits and misses (after a warm
process, a second one has no misses).  Bad input raises ``ValueError`` naming the parameter.
"""

from __future__ import annotations

import contextlib
import sys
import time
import warnings
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import click
import numpy as np

__all__ = ["KernelInfo", "WarmStep", "kernel_inventory", "register", "warm", "warm_cmd"]

#: what :func:`warm` can compile
PARTS = ("groups", "cases", "grids", "threads")
#: threads of the ``threads`` workload (the compiled code does not depend on the count)
WARM_THREADS = 2
#: parameters of registered groups that need them (name → list of keyword sets)
GROUP_PARAMETERS: dict[str, list[dict[str, Any]]] = {"SO": [{"n": 4}, {"n": 5}]}
#: integrators that need options a generic case cannot supply
SKIP_INTEGRATORS = ("kinematic",)
#: steps per warm-up run (three steps reach every code path of the loops and the guard)
WARM_STEPS = 3
#: steps per threaded warm-up run: numba compiles a whole loop for its argument types at the
#: first call, so one step compiles (or loads) it; each step opens parallel regions, which on
#: a busy machine wait for a core
WARM_THREADED_STEPS = 1


@dataclass
class WarmStep:
    """One workload of :func:`warm`.

    Attributes
    ----------
    part : str
        ``"groups"``, ``"cases"`` or ``"threads"``.
    name : str
        What ran, e.g. ``"SE3"`` or ``"rod-axial-wave / lie-verlet / lattice"``.
    seconds : float
        Wall time (compilation or cache loading included).
    status : str
        ``"ok"``, ``"skipped"`` (a combination the workload does not support) or ``"failed"``.
    message : str
        The reason for ``"skipped"`` or ``"failed"``.
    """

    part: str
    name: str
    seconds: float
    status: str = "ok"
    message: str = ""


@dataclass
class KernelInfo:
    """A cached numba kernel of a loaded cartan module.

    Attributes
    ----------
    module, name : str
    signatures : int
        Compiled (or cache-loaded) type signatures in this process.
    hits, misses : int
        numba's cache hits (loaded from disk) and misses (compiled here) in this process.
    """

    module: str
    name: str
    signatures: int
    hits: int
    misses: int


# ---------------------------------------------------------------------------- inventory
def _cartan_modules() -> list[Any]:
    prefixes = ("cartan", "cartan_")
    return [m for name, m in sorted(sys.modules.items())
            if m is not None and (name == "cartan" or name.startswith(prefixes))]


def kernel_inventory() -> list[KernelInfo]:
    """Every cached numba kernel (``cache=True``) defined in a loaded cartan module.

    Returns
    -------
    list of KernelInfo
        One entry per kernel, in module order; kernels imported into another module are
        listed once, under the module that defines them.  Kernels kept in a module-level
        dict (the threaded twins, ``THREADED``) are listed under their qualified name
        (``<name>__threaded``).
    """
    from numba.core.caching import NullCache
    from numba.core.dispatcher import Dispatcher

    seen: set[int] = set()
    out = []
    for module in _cartan_modules():
        found = []
        for name, obj in list(vars(module).items()):
            if isinstance(obj, Dispatcher):
                found.append((name, obj))
            elif isinstance(obj, dict):
                found.extend((kernel.py_func.__qualname__, kernel) for kernel in list(obj.values())
                             if isinstance(kernel, Dispatcher))
        for name, obj in found:
            if id(obj) in seen or getattr(obj.py_func, "__module__", None) != module.__name__:
                continue
            seen.add(id(obj))
            if isinstance(getattr(obj, "_cache", None), NullCache):
                continue
            stats = obj.stats
            out.append(KernelInfo(module.__name__, name, len(obj.signatures),
                                  int(sum(stats.cache_hits.values())), int(sum(stats.cache_misses.values()))))
    return out


# ---------------------------------------------------------------------------- workloads
def _group_instances(select: Sequence[str] | None) -> Iterable[tuple[str, Any, str]]:
    """``(label, group or None, reason)`` for every registered group (or the selected ones)."""
    import cartan

    table = cartan.registry("groups")
    names = sorted(table) if select is None else list(select)
    for name in names:
        if name not in table:
            raise ValueError(f"groups: unknown group {name!r} (registered: {', '.join(sorted(table))})")
        for params in GROUP_PARAMETERS.get(name, [{}]):
            label = name + ("(" + ", ".join(f"{k}={v}" for k, v in params.items()) + ")" if params else "")
            try:
                yield label, cartan.group(name, **params), ""
            except (TypeError, ValueError) as exc:  # a plugin group that needs parameters
                yield label, None, f"cannot construct with {params or 'no parameters'}: {exc}"


def _exercise_group(group) -> None:
    """Call every operation the group has a numba kernel for (compiling or loading it)."""
    rng = np.random.default_rng(0)
    xi = 0.3 * rng.standard_normal((4, group.dim))
    g = group.exp(xi)
    ops: dict[str, Callable[[], Any]] = {
        "hat": lambda: group.hat(xi),
        "vee": lambda: group.vee(group.hat(xi)),
        "compose": lambda: group.compose(g, g),
        "inverse": lambda: group.inverse(g),
        "act": lambda: group.act(g, np.ones((4, group.space_dim))),
        "exp": lambda: group.exp(xi),
        "log": lambda: group.log(g),
        "Ad": lambda: group.Ad(g),
        "ad": lambda: group.ad(xi),
        "bracket": lambda: group.bracket(xi, xi[::-1]),
        "dexp": lambda: group.dexp(xi),
        "dexp_inv": lambda: group.dexp_inv(xi),
        "E": lambda: group.E(0.01, xi),
    }
    for op in group._kernels:
        if op in ops:
            ops[op]()
    group.defect(g)


def _selection(kind: str, select: Sequence[str] | None, skip: Sequence[str] = ()) -> list[str]:
    """The registered names of ``kind`` (all but ``skip``, or the selected ones, checked)."""
    import cartan

    table = cartan.registry(kind)
    if select is None:
        return [name for name in sorted(table) if name not in skip]
    for name in select:
        if name not in table:
            raise ValueError(f"{kind}: unknown {kind[:-1]} {name!r} (registered: {', '.join(sorted(table)) or 'none'})")
    return list(select)


def _case_runs(select: Sequence[str] | None, integrators: Sequence[str] | None = None,
               schemes: Sequence[str] | None = None, threaded: bool = False
               ) -> Iterable[tuple[str, Callable[[], Any]]]:
    """``(label, run)`` for every registered case × integrator × scheme (or the selected ones).

    With ``threaded``, the dynamic cases only, for :data:`WARM_THREADED_STEPS` steps inside
    :func:`cartan._threads.threaded_everywhere` (:data:`WARM_THREADS` threads on any grid).
    """
    import cartan
    from cartan._threads import threaded_everywhere

    cases = cartan.registry("cases")
    names = _selection("cases", select)
    integrators = _selection("integrators", integrators, SKIP_INTEGRATORS)
    schemes = _selection("schemes", schemes)
    for name in names:
        case = cases[name]() if isinstance(cases[name], type) else cases[name]
        level = min(getattr(case, "levels", (0,)) or (0,))
        if getattr(case, "static", False) and threaded:  # no step loop
            continue
        if getattr(case, "static", False):  # solved for equilibria by the case's own solver
            def solve(case=case, level=level):
                case.run(*case.problem(level, "lattice"))

            yield f"{name} / static solver / lattice", solve
            continue
        for scheme in schemes:
            for integrator in integrators:
                def run(case=case, level=level, scheme=scheme, integrator=integrator):
                    if not threaded:
                        _simulate_case(case, level, scheme, integrator, WARM_STEPS)
                        return
                    with threaded_everywhere(WARM_THREADS):
                        _simulate_case(case, level, scheme, integrator, WARM_THREADED_STEPS)

                yield f"{name} / {integrator} / {scheme}", run


#: node shapes of the ``grids`` workload (d = 2 and 3)
GRID_SHAPES = ((6, 5), (4, 4, 3))


def _grid_problem(shape: tuple[int, ...]):
    """A quadratic SE(3) continuum on the periodic unit grid ``shape``: a smooth closed
    configuration, a velocity and damping."""
    import cartan
    from cartan.medium import QuadraticMedium

    class WarmContinuum(QuadraticMedium):
        """``U = ½Σ_α(X_α − X₀_α)ᵀC(X_α − X₀_α)`` with diagonal C, unit inertia, on SE(3)."""

        name = "warm-continuum"
        material_dim = len(shape)
        separable_axes = True  # U is a sum over the axes (the lattice's condition for d ≥ 2)

        def __init__(self):
            self.group = cartan.group("SE3")
            self.space = None
            rest = np.zeros((self.material_dim, 6))
            for a in range(self.material_dim):
                rest[a, a] = 1.0
            self._set_energy(rest, np.linspace(4.0, 1.0, 6))

        def inertia(self):
            return np.ones(6)

    medium = WarmContinuum()
    grid = cartan.Grid(shape, 1.0, periodic=True)
    u = np.stack(np.meshgrid(*[grid.coordinates(a) for a in range(grid.d)], indexing="ij"), axis=-1)
    wave = np.sin(2 * np.pi * u.sum(axis=-1))[..., None]
    Phi = medium.group.exp(0.2 * wave * np.linspace(0.5, 1.0, 6))
    return cartan.Problem(medium, grid, cartan.InitialState(Phi=Phi, N=0.1 * wave * np.ones(6)),
                          loads=[cartan.Damping(0.5)], name=f"warm grid {shape}")


def _grid_runs(integrators: Sequence[str] | None = None, schemes: Sequence[str] | None = None,
               threaded: bool = False) -> Iterable[tuple[str, Callable[[], Any]]]:
    """``(label, run)`` for every grid of :data:`GRID_SHAPES` × integrator × scheme (threaded:
    as in :func:`_case_runs`)."""
    import cartan
    from cartan._threads import threaded_everywhere

    integrators = _selection("integrators", integrators, SKIP_INTEGRATORS)
    schemes = _selection("schemes", schemes)
    for shape in GRID_SHAPES:
        for scheme in schemes:
            for integrator in integrators:
                def run(shape=shape, scheme=scheme, integrator=integrator):
                    problem = _grid_problem(shape)
                    sch = cartan.registry("schemes")[scheme](problem)
                    integ = cartan.registry("integrators")[integrator]()
                    with np.errstate(all="ignore"):
                        cfl = float(integ.dt_max(sch, sch.initial_state()))
                    dt = 0.5 * cfl if 0 < cfl < 2e-3 else 1e-3
                    steps = WARM_THREADED_STEPS if threaded else WARM_STEPS
                    with warnings.catch_warnings(), (threaded_everywhere(WARM_THREADS) if threaded
                                                     else contextlib.nullcontext()):
                        warnings.simplefilter("ignore")
                        cartan.simulate(problem, integrator=integrator, scheme=scheme, dt=dt, t_end=steps * dt,
                                        save_every=1, progress=False)

                yield f"grid {'x'.join(map(str, shape))} / {integrator} / {scheme}", run


def _simulate_case(case: Any, level: int, scheme: str, integrator: str, steps: int) -> None:
    """``steps`` steps of a verification case at ``level`` through :func:`cartan.simulate` (the
    case's integrator options apply to its default integrator only)."""
    import cartan

    problem, settings = case.problem(level, scheme)
    options = dict(settings.get("integrator_options") or {})
    if options and integrator != (getattr(case, "default_integrators", None) or ("",))[0]:
        options = {}
    sch = cartan.registry("schemes")[scheme](problem)
    integ = cartan.registry("integrators")[integrator](**options)
    # the case's Δt, or half the CFL estimate of this integrator when smaller
    dt = float(settings["dt"])
    with np.errstate(all="ignore"):
        cfl = float(integ.dt_max(sch, sch.initial_state()))
    if 0 < cfl < 2 * dt:
        dt = 0.5 * cfl
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cartan.simulate(problem, integrator=integrator, scheme=scheme, dt=dt, t_end=steps * dt, save_every=1,
                        progress=False, integrator_options=options or None)


def warm(parts: Sequence[str] = PARTS, *, groups: Sequence[str] | None = None, cases: Sequence[str] | None = None,
         integrators: Sequence[str] | None = None, schemes: Sequence[str] | None = None,
         log: Callable[[str], None] | None = None) -> list[WarmStep]:
    """Compile (or load from numba's cache) every cached kernel cartan and its plugins use.

    Parameters
    ----------
    parts : sequence of {"groups", "cases", "grids", "threads"}
        The workloads to run (module docstring); default all four.
    groups : sequence of str, optional
        Registered group names to warm (default: all).
    cases : sequence of str, optional
        Registered verification cases to run (default: all).
    integrators, schemes : sequence of str, optional
        Registered integrators and schemes the cases run with, serially and threaded
        (default: all integrators but ``kinematic``, all schemes).
    log : callable, optional
        Called with one line per workload.

    Returns
    -------
    list of WarmStep
        One entry per workload, in order.  A workload that fails with an error other than the
        ``ValueError``/``NotImplementedError`` of an unsupported combination is reported as
        ``"failed"`` and the others still run.

    Raises
    ------
    ValueError
        For an unknown part, or an unknown group, case, integrator or scheme name.
    """
    import cartan

    parts = list(parts)
    unknown = sorted(set(parts) - set(PARTS))
    if unknown:
        raise ValueError(f"parts must be among {PARTS}, got {unknown}")
    steps: list[WarmStep] = []

    def record(step: WarmStep) -> None:
        steps.append(step)
        if log is not None:
            extra = f" ({step.message})" if step.message else ""
            log(f"{step.part:7s} {step.name:58s} {step.seconds:7.2f} s  {step.status}{extra}")

    with cartan.use_backend("numba"):
        if "groups" in parts:
            for label, group, reason in _group_instances(groups):
                t0 = time.perf_counter()
                if group is None:
                    record(WarmStep("groups", label, 0.0, "skipped", reason))
                    continue
                try:
                    _exercise_group(group)
                    record(WarmStep("groups", label, time.perf_counter() - t0))
                except Exception as exc:  # noqa: BLE001 - report and carry on
                    record(WarmStep("groups", label, time.perf_counter() - t0, "failed",
                                    f"{type(exc).__name__}: {_first_line(exc)}"))
        threaded: set[str] | None = None  # the runs that reached a loop with a threaded build
        if "cases" in parts:
            threaded = _run_cases("cases", _case_runs(cases, integrators, schemes), record)
        threaded_grids: set[str] | None = None
        if "grids" in parts:
            threaded_grids = _run_cases("grids", _grid_runs(integrators, schemes), record)
        if "threads" in parts:
            from cartan._threads import max_threads

            if max_threads() < WARM_THREADS:
                record(WarmStep("threads", "threaded builds", 0.0, "skipped",
                                f"numba has {max_threads()} thread(s) here (NUMBA_NUM_THREADS): no run can use them"))
            else:
                runs = _case_runs(cases, integrators, schemes, threaded=True)
                _run_cases("threads", (r for r in runs if threaded is None or r[0] in threaded), record)
                if "grids" in parts or cases is None:
                    runs = _grid_runs(integrators, schemes, threaded=True)
                    _run_cases("threads", (r for r in runs if threaded_grids is None or r[0] in threaded_grids),
                               record)
    return steps


def _run_cases(part: str, runs: Iterable[tuple[str, Callable[[], Any]]], record: Callable[[WarmStep], None]
               ) -> set[str]:
    """Run each ``(label, run)`` and record it: ``"skipped"`` for the ``ValueError`` or
    ``NotImplementedError`` of a combination the case does not support, ``"failed"`` for any
    other error (the other runs still run).  Returns the labels of the runs during which a
    compiled loop asked for its thread count (:func:`cartan._threads.thread_queries`)."""
    from cartan._threads import thread_queries

    asked = set()
    for label, run in runs:
        t0 = time.perf_counter()
        queries = thread_queries()
        try:
            run()
            record(WarmStep(part, label, time.perf_counter() - t0))
        except (ValueError, NotImplementedError) as exc:
            record(WarmStep(part, label, time.perf_counter() - t0, "skipped", _first_line(exc)))
        except Exception as exc:  # noqa: BLE001 - report and carry on
            record(WarmStep(part, label, time.perf_counter() - t0, "failed",
                            f"{type(exc).__name__}: {_first_line(exc)}"))
        if thread_queries() != queries:
            asked.add(label)
    return asked


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


# ---------------------------------------------------------------------------- command
@click.command("warm")
@click.option("--part", "parts", multiple=True, type=click.Choice(PARTS),
              help="Only these workloads (repeatable; default: groups, cases, grids and threads).")
@click.option("--group", "groups", multiple=True, help="Only these registered groups (repeatable).")
@click.option("--case", "cases", multiple=True, help="Only these registered verification cases (repeatable).")
@click.option("--integrator", "integrators", multiple=True, help="Run the cases with these integrators (repeatable).")
@click.option("--scheme", "schemes", multiple=True, help="Run the cases on these schemes only (repeatable).")
@click.option("--no-threads", is_flag=True,
              help="Leave out the threaded builds (used with CARTAN_THREADS > 1; they then compile on first use).")
@click.option("--strict", is_flag=True, help="Exit with status 1 when a workload fails.")
@click.option("-v", "--verbose", is_flag=True, help="One line per workload and the kernel inventory.")
def warm_cmd(parts: tuple[str, ...], groups: tuple[str, ...], cases: tuple[str, ...], integrators: tuple[str, ...],
             schemes: tuple[str, ...], no_threads: bool, strict: bool, verbose: bool) -> None:
    """Compile every numba kernel into the on-disk cache, so that no run compiles.

    Run once after installing (make install does); later runs load the machine code from
    the cache.  A second cartan warm loads everything and takes seconds.  The threaded
    builds of the step loops (CARTAN_THREADS > 1) are compiled too, on small problems,
    unless --no-threads is given.
    """
    t0 = time.perf_counter()
    selected = [p for p in (parts or PARTS) if not (no_threads and p == "threads")]
    if not selected:
        raise click.UsageError("--no-threads leaves no workload of the selected --part")
    try:
        steps = warm(selected, groups=groups or None, cases=cases or None, integrators=integrators or None,
                     schemes=schemes or None, log=click.echo if verbose else None)
    except ValueError as exc:
        raise click.UsageError(str(exc)) from None
    kernels = kernel_inventory()
    compiled = sum(k.misses for k in kernels)
    loaded = sum(k.hits for k in kernels)
    failed = [s for s in steps if s.status == "failed"]
    if verbose:
        for k in kernels:
            click.echo(f"kernel {k.module}.{k.name}: {k.signatures} signature(s), {k.hits} loaded, {k.misses} compiled")
    click.echo(f"cartan warm: {len(steps)} workloads in {time.perf_counter() - t0:.1f} s; "
               f"{len(kernels)} cached kernels, {compiled} signature(s) compiled, {loaded} loaded from the cache"
               + (f"; {len(failed)} failed" if failed else ""))
    for s in failed:
        click.echo(f"cartan warm: {s.part} {s.name} failed: {s.message}", err=True)
    if failed and strict:
        sys.exit(1)


def register(main: click.Group) -> None:
    """Add the ``warm`` command to the click group ``main``."""
    main.add_command(warm_cmd)
