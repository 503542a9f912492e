"""cartan against PyElastica (and the paper's own method) on the targets T1, T2, T3, T5, T6.

Run it as a script::

    python benchmarks/compare.py [--quick] [--out DIR] [--t2-elastica]

Targets (PERFORMANCE.md §2):

T1  free straight rod, PyElastica's Timoshenko-beam material (L = 3, radius 0.25, E = 1e6,
    G = 1e4, ρ = 5000), n = 100 and 1000 elements, 2000 steps of the same Δt = 0.5·dx/c
    (c = √(E/ρ), dx = L/n): cartan ``lie-verlet`` on the ``lattice`` scheme against
    PyElastica's ``PositionVerlet``.  Wall time per step and per element-step (medians over
    alternating repetitions, after a warm-up so that no compilation is timed), the fixed
    per-step overhead a and the cost per element b of the fit t = a + b·n, and the ratio
    cartan / PyElastica.  The rod starts straight with a small smooth velocity field (axial
    and both transverse directions), the same in both codes, so that neither steps a
    trivial rest state; the final centrelines of the two codes are compared as a check
    that the scenes agree.

T5  work-precision: the first free–free axial mode of the same rod at small amplitude
    (strain 1e-5, linear regime), against the continuum solution
    u(s, t) = (A/ω) cos(πs/L) sin(ωt), ω = πc/L, after one period.  Error = max of the
    nodal displacement and velocity errors, relative to their amplitudes, the same norm at
    the same n + 1 nodes for every method; n is refined at a fixed Courant number 0.5
    (``--t5-courant``), the same for every method.  Methods: cartan ``lattice`` and
    ``collocation`` with ``fd4`` (fourth order in the interior, summation-by-parts closures
    on the free ends, frames stepped), each with ``lie-verlet`` and ``rkmk4``, through
    ``cartan.simulate``; PyElastica's ``PositionVerlet``.  Each run is timed whole (cartan:
    building the problem and ``cartan.simulate`` with its CFL estimate, guard, initial and
    final frames and Dataset; PyElastica: building and finalising the rod system and
    stepping) and by its stepping alone (cartan: the integrator's ``wall_time`` counter;
    PyElastica: the loop of ``step`` calls).  The wall time and n at a relative error of
    1e-4 (and, where measured, 1e-6) are interpolated log–log for each method, with the
    observed orders in n.

Saves  ``cartan.simulate`` of the T1 rod at the largest T1 size over 2000 steps with
    ``save_every`` = 20, 100, 1000 (``--save-every``): the cost of the saved frames and of the
    blow-up guard's energy tests against the steps.

T2  the Timoshenko cantilever (VERIFICATION.md §4; the registered case
    ``rod-timoshenko-static``): wall time of building and solving the equilibrium with
    ``cartan.solve_static`` (through the case's solver) at n = 12, 24, 48, 96 elements, the
    relative tip error against the geometrically exact deflection, and the coarsest n that
    reaches 1e-4.  PyElastica has no static solver: its Timoshenko example relaxes the
    damped dynamics for 2.4 M steps (final time 5000, n = 100).  That run takes minutes, so
    it runs only with ``--t2-elastica``; otherwise the figure of PERFORMANCE.md §1 (166 s
    for a tip error of 1.0 %) is quoted, and the output says so.

T3  a closed rod relaxing by overdamped (gradient) dynamics: the registered scene
    ``rod-ring-relax`` with N = 1000 nodes (``--t3-nodes``), ms per step at the same Δt (half
    the overdamped CFL estimate), steps only.  PyCoss, the paper's authors' code, is not on
    PyPI; its method — collocation in space, Lie–Euler in time, pure numpy — is cartan's
    ``collocation`` scheme with ``overdamped`` (order 1: the Lie–Euler step of the gradient
    flow) on the numpy path (``compiled=False``), the "PyCoss equivalent" of the table and
    the reference of its ratios; PERFORMANCE.md's PyCoss timings are quoted beside it.  The
    ring closure residual at the end of each run is reported too.

T6  start-up: ``import cartan`` and a first 100-step rod simulation in fresh processes
    from a warm numba cache (``benchmarks/startup.py``).

cartan is timed along every path it offers: ``cartan.simulate`` (what a user calls;
including its setup and the blow-up guard), ``cartan.simulate(compiled=False)`` when
``simulate`` accepts that option, a bare loop of ``LieVerlet.step`` on a ``Lattice``
(``step loop``), and ``Lattice.compiled_advance`` (the scheme's compiled loop without
``simulate`` around it) when the lattice has one.  A path that fails in the warm-up is
reported and left out.  Results go to ``DIR/compare.nc`` (every sample, CF attributes; T2,
T3, T6 and the saves table as variables with their own dimensions) and ``DIR/compare.png``
(T1 and T5); tables of medians and ratios are printed.

PyElastica is the optional extra ``compare`` (``pip install 'cartan[compare]'``); without it
only cartan is timed.  ``--quick`` (200 T1 steps, T5 on n ≤ 200 once, 50 T3 steps, 3 T6
processes) runs in about a minute.  ``--only t5`` (or any list of t1, t5, saves, t2, t3, t6)
runs just those parts.
"""

from __future__ import annotations

import argparse
import datetime
import gc
import inspect
import json
import math
import pathlib
import platform
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

# ---------------------------------------------------------------------------- the scene
#: PyElastica's Timoshenko beam example: L = 3, radius 0.25, E = 1e6, density 5000 and a
#: Poisson ratio of 99, i.e. G = E/(1 + ν) = 1e4 (its convention); α_c = 27/28 in both codes.
LENGTH = 3.0
RADIUS = 0.25
YOUNG = 1e6
SHEAR = 1e4
DENSITY = 5000.0
WAVE_SPEED = math.sqrt(YOUNG / DENSITY)
COURANT = 0.5

#: T1 initial velocity amplitude (m/s): strains of order amplitude / c ≈ 7e-4
T1_AMPLITUDE = 1e-2
#: T5 axial velocity amplitude, as the strain A/c.  PyElastica's axial force carries a 1/e
#: factor (nonlinear at O(strain)) and it computes strains from node positions, whose
#: round-off relative to the strain grows as 1/(strain·dx): at 1e-5 the first changes the
#: errors measured by < 1 % of themselves, the second keeps the whole velocity error ≤ 1e-6
#: up to n = 800 (at 1e-7 it reaches 3e-5 at n = 400 and swamps the comparison).
T5_STRAIN = 1e-5
T5_TARGET = 1e-4
#: a second accuracy level reported beside the target (not part of T5): where the cost of the
#: steps, not of the per-run setup, decides
T5_FINE = 1e-6
#: observed orders are fitted over the runs with an error above this: at strain 1e-5 the
#: round-off of cartan's runs is ≈ 1e-9 of the amplitudes (at n = 400 … 1400), so smaller
#: errors no longer measure the discretisation
T5_ORDER_FLOOR = 1e-8

PEER = "PyElastica PositionVerlet"
#: the parts of the comparison, for ``--only``
PARTS = ("t1", "t5", "saves", "t2", "t3", "t6")
#: T5 element counts: dense where the fourth-order methods cross 1e-4 (n ≈ 20–30), up to where
#: the second-order ones do (n ≈ 140) and beyond.  All even: with fd4 an odd n has about twice
#: the error of its even neighbours (docs/benchmarks.md), which would make the curve zigzag.
T5_SIZES = (16, 20, 24, 28, 32, 40, 50, 64, 100, 140, 200, 400)
T5_SIZES_QUICK = (16, 24, 32, 50, 100, 200)
NO_PEER = "PyElastica is not installed: pip install 'cartan[compare]'; timing cartan only"


def step_size(n: int, courant: float = COURANT) -> float:
    """Δt = courant · dx / c for n elements."""
    return courant * (LENGTH / n) / WAVE_SPEED


def node_coordinates(n: int) -> np.ndarray:
    return np.linspace(0.0, LENGTH, n + 1)


def t1_velocity(n: int) -> np.ndarray:
    """Lab-frame nodal velocity ``(n + 1, 3)`` of T1: one smooth mode per direction, each of
    zero mean (the rod barely drifts)."""
    s = node_coordinates(n) / LENGTH
    return T1_AMPLITUDE * np.stack(
        [np.cos(np.pi * s), 0.5 * np.cos(2 * np.pi * s), 0.25 * np.cos(3 * np.pi * s)], axis=-1
    )


def t5_velocity(n: int) -> np.ndarray:
    """Lab-frame nodal velocity of T5: the first free–free axial mode, amplitude c·strain."""
    s = node_coordinates(n) / LENGTH
    v = np.zeros((n + 1, 3))
    v[:, 0] = T5_STRAIN * WAVE_SPEED * np.cos(np.pi * s)
    return v


def t5_exact(n: int, t: float) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Continuum axial displacement and velocity at the nodes at time t, and their amplitudes."""
    s = node_coordinates(n)
    A = T5_STRAIN * WAVE_SPEED
    omega = np.pi * WAVE_SPEED / LENGTH
    shape = np.cos(np.pi * s / LENGTH)
    u = np.zeros((n + 1, 3))
    v = np.zeros((n + 1, 3))
    u[:, 0] = A / omega * shape * math.sin(omega * t)
    v[:, 0] = A * shape * math.cos(omega * t)
    return u, v, A / omega, A


def t5_period() -> float:
    return 2.0 * LENGTH / WAVE_SPEED


# ---------------------------------------------------------------------------- cartan
def cartan_problem(n: int, velocity: np.ndarray):
    """Straight rod along x with n elements (n + 1 nodes) and the lab-frame nodal velocity."""
    import cartan

    rod = cartan.medium("cosserat-rod", E=YOUNG, G=SHEAR, radius=RADIUS, density=DENSITY)
    grid = cartan.Grid(n + 1, length=LENGTH)
    straight = rod.initial_state(grid, "straight")
    Phi = np.asarray(straight.Phi)
    R = Phi[:, 1:, 1:]
    N = np.zeros((n + 1, rod.group.dim))
    N[:, :3] = np.einsum("nji,nj->ni", R, velocity)  # body components V = Rᵀv
    return cartan.Problem(medium=rod, grid=grid, initial=cartan.InitialState(Phi=Phi, N=N),
                          name=f"straight rod n={n}")


def simulate_options() -> dict[str, Any]:
    import cartan

    return dict(inspect.signature(cartan.simulate).parameters)


@dataclass
class Outcome:
    """One timed run: wall time of the timed part, final node positions and velocities."""

    seconds: float
    position: np.ndarray
    velocity: np.ndarray
    info: dict[str, Any] = field(default_factory=dict)
    #: wall time of the time stepping alone, when the run reports it (cartan: the integrator's
    #: ``wall_time`` counter, i.e. the compiled loops; PyElastica: the loop of ``step`` calls)
    step_seconds: float = math.nan


def run_cartan_simulate(problem, dt: float, nsteps: int, integrator: str = "lie-verlet",
                        collect: bool = True, scheme: str = "lattice",
                        scheme_options: dict[str, Any] | None = None, **options: Any) -> Outcome:
    """``cartan.simulate`` from t = 0 to nsteps·Δt, one saved frame at the end; the whole call is
    timed, and the stepping alone is read from the integrator's ``wall_time`` counter."""
    import cartan

    if collect:
        gc.collect()
    t0 = time.perf_counter()
    ds = cartan.simulate(problem, integrator=integrator, scheme=scheme, dt=dt, t_end=nsteps * dt,
                         save_every=nsteps, progress=False, scheme_options=scheme_options, **options)
    seconds = time.perf_counter() - t0
    steps = int(ds["step"].values[-1])
    if steps != nsteps:
        raise RuntimeError(f"cartan.simulate took {steps} steps, expected {nsteps}")
    R = ds["frame"].values[-1]
    V = ds["N"].values[-1][:, :3]
    info, step_seconds = {}, math.nan
    try:
        config = json.loads(ds.attrs.get("cartan_config", "{}"))
        run = config.get("run", {})
        info = {k: v for k, v in run.items() if "compil" in k or k in ("loop", "engine", "path", "backend")}
        step_seconds = float(config.get("counters", {}).get("wall_time", math.nan))
    except (TypeError, ValueError):
        pass
    return Outcome(seconds, ds["position"].values[-1].copy(), np.einsum("nij,nj->ni", R, V), info,
                   step_seconds)


def run_cartan_loop(problem, dt: float, nsteps: int, integrator: str = "lie-verlet",
                    collect: bool = True) -> Outcome:
    """A bare loop of ``Integrator.step`` on a ``Lattice``; only the loop is timed."""
    import cartan

    scheme = cartan.registry("schemes")["lattice"](problem)
    integ = cartan.registry("integrators")[integrator]()
    state = scheme.initial_state()
    step = integ.step
    if collect:
        gc.collect()
    t0 = time.perf_counter()
    for _ in range(nsteps):
        step(scheme, state, dt)
    seconds = time.perf_counter() - t0
    Phi = scheme.frames(state)
    R = Phi[:, 1:, 1:]
    V = scheme.velocity(state)[:, :3]
    return Outcome(seconds, Phi[:, 1:, 0].copy(), np.einsum("nij,nj->ni", R, V))


def run_cartan_compiled(problem, dt: float, nsteps: int, integrator: str = "lie-verlet",
                        collect: bool = True) -> Outcome:
    """``Lattice.compiled_advance`` over all the steps at once (the scheme's compiled loop,
    without ``simulate`` around it); only the call is timed.  Raises NotImplementedError when
    the scheme has no compiled loop or declines the problem."""
    import cartan

    scheme = cartan.registry("schemes")["lattice"](problem)
    advance = getattr(scheme, "compiled_advance", None)
    if advance is None:
        raise NotImplementedError("the lattice scheme has no compiled_advance")
    integ = cartan.registry("integrators")[integrator]()
    state = scheme.initial_state()
    start = int(state.scalars.get("nstep", 0))
    if collect:
        gc.collect()
    t0 = time.perf_counter()
    ok = advance(integ, state, dt, nsteps)
    seconds = time.perf_counter() - t0
    if not ok:
        raise NotImplementedError("Lattice.compiled_advance declined this problem")
    done = int(state.scalars.get("nstep", start + nsteps)) - start
    if done != nsteps:
        raise RuntimeError(f"Lattice.compiled_advance took {done} steps, expected {nsteps}")
    Phi = scheme.frames(state)
    R = Phi[:, 1:, 1:]
    V = scheme.velocity(state)[:, :3]
    return Outcome(seconds, Phi[:, 1:, 0].copy(), np.einsum("nij,nj->ni", R, V))


# ---------------------------------------------------------------------------- PyElastica
def import_elastica():
    """The ``elastica`` module, or None when PyElastica is not installed."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            import elastica
    except ImportError:
        return None
    return elastica


def elastica_version(ea) -> str:
    try:
        from elastica.version import VERSION

        return str(VERSION)
    except ImportError:  # pragma: no cover - older layouts
        return str(getattr(ea, "__version__", "unknown"))


def elastica_system(ea, n: int, velocity: np.ndarray):
    """A finalised PyElastica system holding the straight rod along x, and its rod."""

    class RodSimulator(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping, ea.CallBacks):
        pass

    sim = RodSimulator()
    rod = ea.CosseratRod.straight_rod(
        n,
        np.zeros(3),
        np.array([1.0, 0.0, 0.0]),
        np.array([0.0, 1.0, 0.0]),
        LENGTH,
        RADIUS,
        DENSITY,
        youngs_modulus=YOUNG,
        shear_modulus=SHEAR,
    )
    rod.velocity_collection[...] = velocity.T
    sim.append(rod)
    sim.finalize()
    return sim, rod


def run_elastica(ea, n: int, velocity: np.ndarray, dt: float, nsteps: int, collect: bool = True) -> Outcome:
    """PositionVerlet stepped by hand (no ``integrate`` progress bar or callbacks); only the loop is timed."""
    sim, rod = elastica_system(ea, n, velocity)
    stepper = ea.PositionVerlet()
    step = stepper.step
    t = np.float64(0.0)
    h = np.float64(dt)
    if collect:
        gc.collect()
    t0 = time.perf_counter()
    for _ in range(nsteps):
        t = step(sim, t, h)
    seconds = time.perf_counter() - t0
    return Outcome(seconds, rod.position_collection.T.copy(), rod.velocity_collection.T.copy(),
                   step_seconds=seconds)


def warm_elastica(ea) -> float:
    """Compile PyElastica's numba kernels (or load them from its cache); returns the seconds taken."""
    t0 = time.perf_counter()
    run_elastica(ea, 8, np.zeros((9, 3)), step_size(8), 3)
    return time.perf_counter() - t0


# ---------------------------------------------------------------------------- measuring
@dataclass
class Path:
    """One timed way of running a scene."""

    name: str
    code: str  # "cartan" or "PyElastica"
    run: Callable[[int, np.ndarray, float, int], Outcome]


def t1_paths(ea) -> list[Path]:
    opts = simulate_options()
    paths = [
        Path("cartan.simulate", "cartan",
             lambda n, v, dt, k: run_cartan_simulate(cartan_problem(n, v), dt, k)),
    ]
    if "compiled" in opts:
        paths.append(Path("cartan.simulate(compiled=False)", "cartan",
                          lambda n, v, dt, k: run_cartan_simulate(cartan_problem(n, v), dt, k, compiled=False)))
    paths.append(Path("cartan step loop", "cartan",
                      lambda n, v, dt, k: run_cartan_loop(cartan_problem(n, v), dt, k)))
    if _lattice_has_compiled_loop():
        paths.append(Path("cartan Lattice.compiled_advance", "cartan",
                          lambda n, v, dt, k: run_cartan_compiled(cartan_problem(n, v), dt, k)))
    if ea is not None:
        paths.append(Path(PEER, "PyElastica", lambda n, v, dt, k: run_elastica(ea, n, v, dt, k)))
    return paths


def _lattice_has_compiled_loop() -> bool:
    import cartan

    return hasattr(cartan.registry("schemes")["lattice"], "compiled_advance")


def alternate(paths: Sequence[Path], rep: int) -> list[Path]:
    """Forward order on even repetitions, reversed on odd ones (no path always runs first)."""
    return list(paths) if rep % 2 == 0 else list(reversed(paths))


def warm_up(paths: list[Path], sizes: Sequence[int], velocity: Callable[[int], np.ndarray], log=print
            ) -> tuple[list[Path], dict[str, dict]]:
    """Run every path for a few steps at every size (compiling or loading every kernel) before
    any timing; a path that fails is reported and dropped, so that the others are still timed."""
    kept, infos = [], {}
    for p in paths:
        try:
            for n in sizes:
                out = p.run(n, velocity(n), step_size(n), 3)
                infos.setdefault(p.name, out.info)
        except Exception as exc:  # noqa: BLE001 - report any failure and carry on
            log(f"  {p.name} failed in the warm-up and is not timed: {type(exc).__name__}: {exc}")
            continue
        kept.append(p)
    return kept, infos


def measure_t1(paths: list[Path], sizes: Sequence[int], nsteps: int, reps: int, log=print) -> dict[str, Any]:
    """Seconds per step ``[path, n, rep]``, the final states of the last repetition and the
    paths that ran."""
    log(f"T1 warm-up ({', '.join(p.name for p in paths)})")
    paths, infos = warm_up(paths, sizes, t1_velocity, log)
    seconds = np.full((len(paths), len(sizes), reps), np.nan)
    finals: dict[tuple[str, int], Outcome] = {}
    for rep in range(reps):
        for j, n in enumerate(sizes):
            v, dt = t1_velocity(n), step_size(n)
            for p in alternate(paths, rep + j):
                i = paths.index(p)
                out = p.run(n, v, dt, nsteps)
                seconds[i, j, rep] = out.seconds / nsteps
                finals[(p.name, n)] = out
        med = np.median(seconds[:, :, : rep + 1], axis=-1)
        log(f"  repetition {rep + 1}/{reps}: " + "; ".join(
            f"{p.name} " + "/".join(f"{1e6 * med[i, j]:.0f}" for j in range(len(sizes))) + " µs"
            for i, p in enumerate(paths)))
    return {"seconds": seconds, "finals": finals, "infos": infos, "paths": paths}


def fit_overhead(sizes: Sequence[int], per_step: np.ndarray) -> tuple[float, float]:
    """Least-squares t = a + b·n over the sizes: (a seconds per step, b seconds per element-step)."""
    if len(sizes) < 2 or not np.all(np.isfinite(per_step)):
        return math.nan, math.nan
    b, a = np.polyfit(np.asarray(sizes, dtype=float), per_step, 1)
    return float(a), float(b)


def scene_agreement(finals: dict[tuple[str, int], Outcome], sizes: Sequence[int], ref: str) -> dict[int, float]:
    """max |r_cartan − r_PyElastica| / max |r_PyElastica − r₀| at the end of T1, per n."""
    out = {}
    for n in sizes:
        a, b = finals.get((ref, n)), finals.get((PEER, n))
        if a is None or b is None:
            continue
        r0 = np.zeros((n + 1, 3))
        r0[:, 0] = node_coordinates(n)
        disp = float(np.max(np.linalg.norm(b.position - r0, axis=-1)))
        out[n] = float(np.max(np.linalg.norm(a.position - b.position, axis=-1))) / disp
    return out


#: The cartan methods of T5, (label, scheme, scheme options, integrator): every scheme with every
#: integrator of order ≥ 2 that the compiled loops run.  The lattice is second order in space
#: (like PyElastica); collocation with ``fd4`` is fourth order in the interior, with
#: summation-by-parts closures on the free ends (docs/schemes.md).  fd4 steps the frames
#: (``track_frames``): frames rebuilt from the strains are only second order.
T5_FD4 = {"derivative": "fd4", "track_frames": True}
T5_CARTAN: tuple[tuple[str, str, dict[str, Any] | None, str], ...] = (
    ("cartan lattice lie-verlet", "lattice", None, "lie-verlet"),
    ("cartan lattice rkmk4", "lattice", None, "rkmk4"),
    ("cartan collocation fd4 lie-verlet", "collocation", T5_FD4, "lie-verlet"),
    ("cartan collocation fd4 rkmk4", "collocation", T5_FD4, "rkmk4"),
)


def t5_methods(ea) -> list[Path]:
    """T5 runs are timed whole by :func:`measure_t5` — cartan: building the problem,
    ``cartan.simulate`` (scheme, initial state, CFL estimate, guard, the initial and final
    frames, the Dataset), reading the result; PyElastica: building and finalising the rod
    system, stepping, reading the result — and each run also reports its stepping alone."""
    methods = [
        Path(label, "cartan", lambda n, v, dt, k, s=scheme, o=opts, i=integrator: run_cartan_simulate(
            cartan_problem(n, v), dt, k, i, collect=False, scheme=s, scheme_options=o))
        for label, scheme, opts, integrator in T5_CARTAN
    ]
    if ea is not None:
        methods.append(Path(PEER, "PyElastica", lambda n, v, dt, k: run_elastica(ea, n, v, dt, k, collect=False)))
    return methods


def t5_error(n: int, out: Outcome, t: float) -> float:
    """max(|u − u_exact|∞ / (A/ω), |v − v_exact|∞ / A) over the n + 1 nodes and the three
    components: the same norm, at the same nodes, for every method (cartan: positions and
    lab-frame velocities R·V of the saved frame; PyElastica: its position and velocity
    collections)."""
    u_ex, v_ex, u_amp, v_amp = t5_exact(n, t)
    r0 = np.zeros((n + 1, 3))
    r0[:, 0] = node_coordinates(n)
    eu = np.max(np.abs(out.position - r0 - u_ex)) / u_amp
    ev = np.max(np.abs(out.velocity - v_ex)) / v_amp
    return float(max(eu, ev))


def measure_t5(methods: list[Path], sizes: Sequence[int], reps: int, log=print,
               budget: float = math.inf, courant: float = COURANT) -> dict[str, Any]:
    """Wall time of the whole run and of the stepping alone ``[method, n, rep]`` and the relative
    error ``[method, n]`` after one period, at Δt = courant·dx/c (rounded down to divide the period)."""
    T = t5_period()
    dts = np.full(len(sizes), np.nan)
    steps = np.zeros(len(sizes), dtype=int)
    for j, n in enumerate(sizes):
        steps[j] = math.ceil(T / step_size(n, courant) - 1e-9)
        dts[j] = T / steps[j]
    methods, _ = warm_up(methods, [8], t5_velocity, log)
    seconds = np.full((len(methods), len(sizes), reps), np.nan)
    step_seconds = np.full_like(seconds, np.nan)
    error = np.full((len(methods), len(sizes)), np.nan)
    start = time.perf_counter()
    for rep in range(reps):
        for j, n in enumerate(sizes):
            v = t5_velocity(n)
            for m in alternate(methods, rep + j):
                i = methods.index(m)
                gc.collect()
                t0 = time.perf_counter()
                out = m.run(n, v, float(dts[j]), int(steps[j]))
                seconds[i, j, rep] = time.perf_counter() - t0
                step_seconds[i, j, rep] = out.step_seconds
                error[i, j] = t5_error(n, out, steps[j] * dts[j])
        log(f"  repetition {rep + 1}/{reps} done ({time.perf_counter() - start:.0f} s)")
        if time.perf_counter() - start > budget and rep + 1 < reps:
            log(f"  T5 time budget of {budget:.0f} s reached: {rep + 1} repetition(s) kept")
            seconds = seconds[:, :, : rep + 1]
            step_seconds = step_seconds[:, :, : rep + 1]
            break
    return {"seconds": seconds, "step_seconds": step_seconds, "error": error, "dt": dts, "steps": steps,
            "methods": methods, "courant": courant}


def seconds_at_error(seconds: np.ndarray, error: np.ndarray, target: float,
                     sizes: Sequence[int] | None = None, extrapolate: bool = True) -> tuple[float, bool]:
    """Wall time (or any cost, e.g. n) at ``target`` error, log–log interpolated between the
    bracketing runs, or extrapolated along the two most accurate runs when none reaches it;
    ``(seconds, extrapolated)``.  The runs are taken in the order of ``sizes`` (refinement) when
    given, else of ``seconds``; with several crossings of the target (errors that are not
    monotone at coarse n) the last one counts, beyond which every run is below the target.
    ``extrapolate=False`` returns NaN instead of an extrapolation."""
    seconds, error = np.asarray(seconds, dtype=float), np.asarray(error, dtype=float)
    ok = np.isfinite(seconds) & np.isfinite(error) & (error > 0) & (seconds > 0)
    if ok.sum() < 2:
        return math.nan, False
    key = np.asarray(sizes, dtype=float)[ok] if sizes is not None else seconds[ok]
    order = np.argsort(key, kind="stable")
    s, e = np.log(seconds[ok][order]), np.log(error[ok][order])
    lt = math.log(target)
    for k in reversed(range(len(s) - 1)):
        if (e[k] - lt) * (e[k + 1] - lt) <= 0 and e[k] != e[k + 1]:
            return float(math.exp(s[k] + (lt - e[k]) * (s[k + 1] - s[k]) / (e[k + 1] - e[k]))), False
    if not extrapolate:
        return math.nan, False
    best = np.argsort(e)[:2]
    (s0, s1), (e0, e1) = s[best], e[best]
    if e0 == e1 or not (e0 > lt):  # no trend to follow, or the target lies above every error
        return math.nan, False
    return float(math.exp(s0 + (lt - e0) * (s1 - s0) / (e1 - e0))), True


def observed_order(sizes: Sequence[int], error: np.ndarray, floor: float = 0.0) -> float:
    """Least-squares slope of −log(error) against log(n), over the errors above ``floor``."""
    error = np.asarray(error, dtype=float)
    ok = np.isfinite(error) & (error > floor)
    if ok.sum() < 2:
        return math.nan
    return float(-np.polyfit(np.log(np.asarray(sizes)[ok]), np.log(error[ok]), 1)[0])


def finest_order(sizes: Sequence[int], error: np.ndarray, floor: float = 0.0) -> float:
    """−log(e₂/e₁)/log(n₂/n₁) between the two finest sizes with an error above ``floor``."""
    n, e = np.asarray(sizes, dtype=float), np.asarray(error, dtype=float)
    ok = np.flatnonzero(np.isfinite(e) & (e > floor))
    if len(ok) < 2:
        return math.nan
    i, j = ok[np.argsort(n[ok])[-2:]]
    return float(-math.log(e[j] / e[i]) / math.log(n[j] / n[i]))


# ---------------------------------------------------------------------------- saves
def measure_saves(n: int, nsteps: int, save_everys: Sequence[int], reps: int, log=print) -> dict[str, Any]:
    """``cartan.simulate`` of the T1 rod (n elements, ``nsteps`` steps) saving every
    ``save_every`` steps: seconds per step ``[save_every, rep]`` of the whole call."""
    import cartan

    v, dt = t1_velocity(n), step_size(n)
    run_cartan_simulate(cartan_problem(n, v), dt, 4)  # compile or load every kernel
    seconds = np.full((len(save_everys), reps), np.nan)
    for rep in range(reps):
        for i in (range(len(save_everys)) if rep % 2 == 0 else reversed(range(len(save_everys)))):
            problem = cartan_problem(n, v)
            gc.collect()
            t0 = time.perf_counter()
            cartan.simulate(problem, integrator="lie-verlet", scheme="lattice", dt=dt, t_end=nsteps * dt,
                            save_every=int(save_everys[i]), progress=False)
            seconds[i, rep] = (time.perf_counter() - t0) / nsteps
    med = np.median(seconds, axis=-1)
    log("  " + "; ".join(f"save_every {k}: {1e6 * m:.1f} µs/step" for k, m in zip(save_everys, med)))
    return {"seconds": seconds, "save_every": np.asarray(save_everys), "n": n, "steps": nsteps}


# ---------------------------------------------------------------------------- T2
#: the registered static case of the Timoshenko cantilever (VERIFICATION.md §4)
T2_CASE = "rod-timoshenko-static"
T2_TARGET = 1e-4
#: PERFORMANCE.md §1: PyElastica's damped dynamic relaxation of the same cantilever, n = 100
#: elements, 2.4 M PositionVerlet steps (its example's final time 5000 at Δt = 0.07·dx)
ELASTICA_T2_QUOTED = {"seconds": 166.0, "error": 1.0e-2, "n": 100, "steps": 2.4e6}


def t2_case():
    """The registered Timoshenko cantilever case, or None when it is not registered."""
    import cartan

    cases = cartan.registry("cases")
    if T2_CASE not in cases:
        return None
    obj = cases[T2_CASE]
    return obj() if isinstance(obj, type) else obj


def measure_t2(case, levels: Sequence[int], reps: int, log=print) -> dict[str, Any]:
    """``cartan.solve_static`` (through the case's solver) at the case's levels: wall time of
    building the problem and solving it ``[level, rep]``, the relative tip error and the Newton
    iterations per level."""
    case.solve(*case.problem(levels[0]))  # warm-up: loads every kernel
    seconds = np.full((len(levels), reps), np.nan)
    error = np.full(len(levels), np.nan)
    iterations = np.zeros(len(levels), dtype=int)
    nodes = np.zeros(len(levels), dtype=int)
    for rep in range(reps):
        for j in (range(len(levels)) if rep % 2 == 0 else reversed(range(len(levels)))):
            gc.collect()
            t0 = time.perf_counter()
            problem, settings = case.problem(levels[j])
            ds = case.solve(problem, settings)
            seconds[j, rep] = time.perf_counter() - t0
            error[j] = case.error(ds, problem)
            iterations[j] = int(ds.attrs.get("newton_iterations", 0))
            nodes[j] = problem.grid.shape[0]
    med = np.median(seconds, axis=-1)
    for j in range(len(levels)):
        log(f"  n = {nodes[j] - 1} elements: tip error {error[j]:.2e}, {iterations[j]} Newton iterations, "
            f"{1e3 * med[j]:.1f} ms")
    return {"seconds": seconds, "error": error, "iterations": iterations, "nodes": nodes}


def t2_at_target(t2: dict[str, Any]) -> tuple[int, float, float]:
    """(elements, seconds, error) of the coarsest level that reaches :data:`T2_TARGET`."""
    med = np.median(t2["seconds"], axis=-1)
    for j in np.argsort(t2["nodes"]):
        if t2["error"][j] <= T2_TARGET:
            return int(t2["nodes"][j] - 1), float(med[j]), float(t2["error"][j])
    return -1, math.nan, math.nan


def run_elastica_timoshenko(ea, exact: float, n_elem: int = 100, final_time: float = 5000.0,
                            log=print) -> dict[str, float]:
    """PyElastica's Timoshenko-beam example (damped dynamic relaxation): the same cantilever
    (L = 3, radius 0.25, E = 1e6, G = 1e4, ρ = 5000, tip force 15 ramped up over half the run,
    ``AnalyticalLinearDamper`` with ν = 0.1/7/ρ/A, Δt = 0.07·dx, ``PositionVerlet``), stepped by
    hand to ``final_time``; wall time of the stepping and relative tip error against ``exact``."""

    class Simulator(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.CallBacks, ea.Damping):
        pass

    sim = Simulator()
    area = math.pi * RADIUS**2
    rod = ea.CosseratRod.straight_rod(n_elem, np.zeros(3), np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0]),
                                      LENGTH, RADIUS, DENSITY, youngs_modulus=YOUNG, shear_modulus=SHEAR)
    sim.append(rod)
    dt = 0.07 * LENGTH / n_elem
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # its deprecated damping_constant keyword, as the example uses it
        sim.dampen(rod).using(ea.AnalyticalLinearDamper, damping_constant=0.1 / 7 / DENSITY / area, time_step=dt)
    sim.constrain(rod).using(ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,))
    force = np.array([-15.0, 0.0, 0.0])
    sim.add_forcing_to(rod).using(ea.EndpointForces, 0.0 * force, force, ramp_up_time=final_time / 2.0)
    sim.finalize()
    stepper = ea.PositionVerlet()
    steps = int(final_time / dt)
    t = np.float64(0.0)
    h = np.float64(dt)
    log(f"  PyElastica: {steps} PositionVerlet steps of {dt:g} s to t = {final_time:g} ...")
    t0 = time.perf_counter()
    for k in range(steps):
        t = stepper.step(sim, t, h)
        if (k + 1) % max(1, steps // 10) == 0:
            log(f"    {100 * (k + 1) // steps} % ({time.perf_counter() - t0:.0f} s)")
    seconds = time.perf_counter() - t0
    tip = -float(rod.position_collection[0, -1])
    return {"seconds": seconds, "error": abs(tip - exact) / exact, "n": n_elem, "steps": steps, "tip": tip}


# ---------------------------------------------------------------------------- T3
#: the registered overdamped closed-rod scene (PERFORMANCE.md T3: closed rod relaxing, N = 1000)
T3_SCENE = "rod-ring-relax"
#: PERFORMANCE.md §1: PyCoss's SE(3) Lie–Euler step at N = 100–1000 points
PYCOSS_QUOTED_MS = (1.7, 3.8)
#: T3 rows: (label, scheme, integrator, compiled); the first is cartan's best, the third the
#: paper's method on cartan's numpy path (the PyCoss equivalent, the reference of the ratio)
T3_PATHS = [
    ("cartan lattice + overdamped (compiled)", "lattice", "overdamped", True),
    ("cartan collocation + overdamped (compiled)", "collocation", "overdamped", True),
    ("PyCoss equivalent: collocation + overdamped Lie–Euler (numpy)", "collocation", "overdamped", False),
    ("cartan lattice + overdamped (numpy)", "lattice", "overdamped", False),
    ("collocation + lie-euler, damped inertial (numpy)", "collocation", "lie-euler", False),
    ("cartan lattice + lie-euler, damped inertial (compiled)", "lattice", "lie-euler", True),
]
T3_REFERENCE = 2


def t3_problem(nodes: int):
    """The ``rod-ring-relax`` scene (a perturbed closed ring, drag, overdamped) with ``nodes`` nodes."""
    import cartan

    src = dict(cartan.scene(T3_SCENE).source)
    src["grid"] = {**src["grid"], "n": int(nodes)}
    return cartan.load_scene(src).problem


def run_t3_path(problem, scheme_name: str, integrator: str, compiled: bool, dt: float, nsteps: int
                ) -> tuple[float, float, float]:
    """Steps only (no ``simulate`` around them): a compiled loop — the scheme's hand-written
    one (``compiled_advance``) when it has one, else the integrator's generated loop over the
    scheme's operators (``run_compiled_loop``) — or a loop of ``Integrator.step``; (seconds,
    closure residual, potential energy) at the end.  Raises NotImplementedError when a compiled
    loop is asked for and neither runs the problem."""
    import cartan

    scheme = cartan.registry("schemes")[scheme_name](problem)
    integ = cartan.registry("integrators")[integrator]()
    state = scheme.initial_state()
    gc.collect()
    t0 = time.perf_counter()
    if compiled:
        advance = getattr(scheme, "compiled_advance", None)
        ran = advance is not None and advance(integ, state, dt, nsteps)
        if not ran and not integ.run_compiled_loop(scheme, state, dt, nsteps):
            raise NotImplementedError(f"{scheme_name} has no compiled loop for {integrator} here")
    else:
        for _ in range(nsteps):
            integ.step(scheme, state, dt)
    seconds = time.perf_counter() - t0
    closure = getattr(scheme, "closure_residual", None)
    return seconds, float(closure(state)) if closure is not None else math.nan, float(scheme.potential_energy(state))


def measure_t3(nodes: int, nsteps: int, reps: int, log=print) -> dict[str, Any]:
    """ms per step ``[path, rep]`` of :data:`T3_PATHS` at the same Δt (half the overdamped CFL
    estimate), the closure residual and potential energy at the end of each path."""
    import cartan

    problem = t3_problem(nodes)
    scheme = cartan.registry("schemes")["lattice"](problem)
    integ = cartan.registry("integrators")["overdamped"]()
    dt = 0.5 * float(integ.dt_max(scheme, scheme.initial_state()))
    labels = [p[0] for p in T3_PATHS]
    seconds = np.full((len(T3_PATHS), reps), np.nan)
    closure = np.full(len(T3_PATHS), np.nan)
    energy = np.full(len(T3_PATHS), np.nan)
    ok = []
    for i, (label, sch, name, comp) in enumerate(T3_PATHS):
        try:
            run_t3_path(problem, sch, name, comp, dt, 2)  # compile or load every kernel
            ok.append(i)
        except NotImplementedError as exc:
            log(f"  {label}: n/a ({exc})")
        except Exception as exc:  # noqa: BLE001 - report any failure and carry on
            log(f"  {label} failed in the warm-up and is not timed: {type(exc).__name__}: {exc}")
    for rep in range(reps):
        for i in (ok if rep % 2 == 0 else list(reversed(ok))):
            _, sch, name, comp = T3_PATHS[i]
            sec, closure[i], energy[i] = run_t3_path(problem, sch, name, comp, dt, nsteps)
            seconds[i, rep] = sec / nsteps
    med = np.median(seconds, axis=-1)
    for i in ok:
        log(f"  {labels[i]}: {1e3 * med[i]:.3f} ms/step, closure {closure[i]:.1e}")
    return {"seconds": seconds, "closure": closure, "energy": energy, "labels": labels, "dt": dt,
            "nodes": nodes, "steps": nsteps}


# ---------------------------------------------------------------------------- T6
def measure_t6(reps: int, log=print) -> dict[str, np.ndarray]:
    """Fresh-process start-up (``benchmarks/startup.py``): import + first simulation."""
    try:
        from .startup import measure
    except ImportError:  # run as a script from benchmarks/
        from startup import measure
    return measure(reps=reps, log=log)


# ---------------------------------------------------------------------------- output
def build_dataset(t1: dict[str, Any] | None, paths: list[Path], sizes: Sequence[int], nsteps: int,
                  t5: dict[str, Any] | None, methods: list[Path], t5_sizes: Sequence[int],
                  meta: dict[str, Any]):
    import xarray as xr

    agree = meta.pop("agreement", {})
    ds = xr.Dataset()
    if t1 is not None:
        sec = t1["seconds"]
        med = np.median(sec, axis=-1)
        names = [p.name for p in paths]
        n_arr = np.asarray(sizes)
        peer = names.index(PEER) if PEER in names else None
        ratio = med / med[peer] if peer is not None else np.full_like(med, np.nan)
        fits = np.array([fit_overhead(sizes, med[i]) for i in range(len(paths))]).reshape(len(paths), 2)
        ds = xr.Dataset(
            coords={
                "path": ("path", np.array(names, dtype=object), {"long_name": "timed code path"}),
                "n": ("n", n_arr, {"long_name": "number of rod elements", "units": "1"}),
                "rep": ("rep", np.arange(sec.shape[-1]), {"long_name": "repetition (alternating order)"}),
            }
        )
        ds["code"] = ("path", np.array([p.code for p in paths], dtype=object), {"long_name": "code"})
        ds["dt"] = ("n", np.array([step_size(n) for n in sizes]),
                    {"long_name": "time step, Courant number 0.5 of the axial wave", "units": "s"})
        ds["step_time"] = (("path", "n", "rep"), sec, {"long_name": "wall time per step", "units": "s"})
        ds["step_time_median"] = (("path", "n"), med, {"long_name": "median wall time per step", "units": "s"})
        ds["element_step_time_median"] = (
            ("path", "n"), med / n_arr, {"long_name": "median wall time per element and step", "units": "s"})
        ds["ratio_to_peer"] = (("path", "n"), ratio, {
            "long_name": f"median wall time per step relative to {PEER}", "units": "1"})
        ds["fixed_overhead"] = ("path", fits[:, 0], {
            "long_name": "per-step overhead a of the fit t = a + b·n", "units": "s"})
        ds["element_cost"] = ("path", fits[:, 1], {
            "long_name": "per-element cost b of the fit t = a + b·n", "units": "s"})
        ds["scene_agreement"] = ("n", np.array([agree.get(n, np.nan) for n in sizes]), {
            "long_name": "max |r_cartan - r_PyElastica| / max |r_PyElastica - r0| at the end of T1",
            "units": "1"})
    if t5 is not None:
        ds = ds.assign_coords(
            wp_method=("wp_method", np.array([m.name for m in methods], dtype=object), {"long_name": "T5 method"}),
            wp_n=("wp_n", np.asarray(t5_sizes), {"long_name": "T5 number of rod elements", "units": "1"}),
            wp_rep=("wp_rep", np.arange(t5["seconds"].shape[-1]), {"long_name": "T5 repetition"}),
        )
        ds["wp_seconds"] = (("wp_method", "wp_n", "wp_rep"), t5["seconds"], {
            "long_name": "T5 wall time of the whole run (one period of the axial mode)", "units": "s"})
        ds["wp_seconds_median"] = (("wp_method", "wp_n"), np.median(t5["seconds"], axis=-1), {
            "long_name": "T5 median wall time of the whole run", "units": "s"})
        ds["wp_error"] = (("wp_method", "wp_n"), t5["error"], {
            "long_name": "T5 max relative error of nodal displacement and velocity after one period",
            "units": "1"})
        ds["wp_dt"] = ("wp_n", t5["dt"], {"long_name": "T5 time step", "units": "s"})
        ds["wp_steps"] = ("wp_n", t5["steps"], {"long_name": "T5 number of steps", "units": "1"})
        ds["wp_step_seconds"] = (("wp_method", "wp_n", "wp_rep"), t5["step_seconds"], {
            "long_name": "T5 wall time of the time stepping alone (cartan: the integrator's wall_time counter, "
                         "the compiled loops; PyElastica: the loop of PositionVerlet.step)", "units": "s"})
        ds["wp_courant"] = ((), float(t5["courant"]), {"long_name": "T5 Courant number c·Δt/dx", "units": "1"})
        med5 = np.median(t5["seconds"], axis=-1)
        step5 = np.median(t5["step_seconds"], axis=-1)
        sizes5 = np.asarray(t5_sizes, dtype=float)
        for tag, target in (("target", T5_TARGET), ("fine", T5_FINE)):
            # the target may be extrapolated (flagged); the second level is reported only where measured
            ex = tag == "target"
            at = [seconds_at_error(med5[i], t5["error"][i], target, t5_sizes, ex) for i in range(len(methods))]
            ds[f"wp_seconds_at_{tag}"] = ("wp_method", np.array([a for a, _ in at]), {
                "long_name": f"T5 wall time of the whole run at relative error {target:g} "
                             "(log-log interpolation between the bracketing n)", "units": "s"})
            ds[f"wp_extrapolated_{tag}"] = ("wp_method", np.array([int(x) for _, x in at], dtype=np.int8), {
                "long_name": f"1 when the values at relative error {target:g} are extrapolated beyond the most "
                             "accurate run", "units": "1"})
            steps_at = [seconds_at_error(step5[i], t5["error"][i], target, t5_sizes, ex)[0]
                        for i in range(len(methods))]
            ds[f"wp_step_seconds_at_{tag}"] = ("wp_method", np.array(steps_at), {
                "long_name": f"T5 wall time of the stepping alone at relative error {target:g}", "units": "s"})
            n_at = [seconds_at_error(sizes5, t5["error"][i], target, t5_sizes, ex)[0] for i in range(len(methods))]
            ds[f"wp_n_at_{tag}"] = ("wp_method", np.array(n_at), {
                "long_name": f"T5 number of elements at relative error {target:g} (log-log interpolation)",
                "units": "1"})
        ds["wp_order"] = ("wp_method", np.array([observed_order(t5_sizes, e, T5_ORDER_FLOOR)
                                                  for e in t5["error"]]), {
            "long_name": f"T5 observed order of the error in n (least squares over the n with error > "
                         f"{T5_ORDER_FLOOR:g})",
            "units": "1"})
        ds["wp_order_finest"] = ("wp_method", np.array([finest_order(t5_sizes, e, T5_ORDER_FLOOR)
                                                        for e in t5["error"]]), {
            "long_name": f"T5 observed order of the error in n between the two finest n with error > "
                         f"{T5_ORDER_FLOOR:g}", "units": "1"})
    ds.attrs.update({
        "Conventions": "CF-1.11",
        "title": ("cartan vs PyElastica and the paper's method: cost per step of a free Cosserat rod (T1), "
                  "static time to accuracy (T2), closed rod relaxing (T3), work-precision (T5), start-up (T6)"),
        "institution": "cartan benchmarks",
        "source": meta["source"],
        "history": meta["history"],
        "references": ("PERFORMANCE.md targets T1, T2, T3, T5, T6; PyElastica's Timoshenko beam example for the "
                       "material; VERIFICATION.md §4 for the cantilever"),
        "comment": meta["comment"],
        "scene": json.dumps(meta["scene"]),
        "cartan_paths": json.dumps(meta["paths"]),
    })
    return ds


def plot(ds, path: pathlib.Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    has_wp = "wp_method" in ds.coords
    has_t1 = "path" in ds.coords
    panels = int(has_t1) + int(has_wp)
    if panels == 0:
        return
    fig, axes = plt.subplots(1, panels, figsize=(5.5 * panels, 4.5), squeeze=False)
    if has_t1:
        ax = axes[0, 0]
        n = ds["n"].values
        for name in ds["path"].values:
            per = ds["step_time"].sel(path=name).values / n[:, None] * 1e9
            med = np.median(per, axis=-1)
            style = "s--" if name == PEER else "o-"
            ax.errorbar(n, med, yerr=[med - per.min(-1), per.max(-1) - med], fmt=style, capsize=3, label=name)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("elements n")
        ax.set_ylabel("wall time per element-step [ns]")
        ax.set_title("T1: free straight rod, same Δt = 0.5·dx/c")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    if has_wp:
        ax = axes[0, panels - 1]
        for name in ds["wp_method"].values:
            t = ds["wp_seconds_median"].sel(wp_method=name).values
            e = ds["wp_error"].sel(wp_method=name).values
            ax.loglog(t, e, "s--" if name == PEER else "o-", label=name)
            for tk, ek, nk in zip(t, e, ds["wp_n"].values):
                ax.annotate(str(nk), (tk, ek), fontsize=6, textcoords="offset points", xytext=(3, 3))
        ax.axhline(T5_TARGET, color="grey", lw=0.8, ls=":")
        ax.axhline(T5_FINE, color="grey", lw=0.5, ls=":")
        ax.set_xlabel("wall time of the run [s]")
        ax.set_ylabel("relative error after one period")
        ax.set_title("T5: axial mode of the free rod (labels: n)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def fmt(x: float, scale: float, digits: int = 1) -> str:
    return "—" if not math.isfinite(x) else f"{x * scale:.{digits}f}"


def print_t1_table(ds, log=print) -> None:
    n = ds["n"].values
    head = "| path | " + " | ".join(f"µs/step n={k}" for k in n) + " | " + " | ".join(
        f"ns/elem-step n={k}" for k in n) + " | " + " | ".join(f"ratio n={k}" for k in n) + \
        " | overhead a [µs] | per element b [ns] |"
    log(head)
    log("|" + "---|" * (head.count("|") - 1))
    for name in ds["path"].values:
        med = ds["step_time_median"].sel(path=name).values
        rat = ds["ratio_to_peer"].sel(path=name).values
        log(f"| {name} | " + " | ".join(fmt(x, 1e6) for x in med) + " | "
            + " | ".join(fmt(x / k, 1e9) for x, k in zip(med, n)) + " | "
            + " | ".join(fmt(x, 1.0, 2) for x in rat) + " | "
            + fmt(float(ds["fixed_overhead"].sel(path=name)), 1e6) + " | "
            + fmt(float(ds["element_cost"].sel(path=name)), 1e9, 2) + " |")


def print_t5_table(ds, log=print) -> None:
    """Errors and wall times per n, then the work at the target error (and at ``T5_FINE``) with
    the ratios PyElastica / method: of the whole runs and of the stepping alone."""
    sizes = ds["wp_n"].values
    names = ds["wp_method"].values
    for title, var, cell in (("relative error after one period", "wp_error", lambda x: f"{x:.2e}"),
                             ("wall time of the whole run [ms]", "wp_seconds_median", lambda x: fmt(x, 1e3, 2)),
                             ("wall time of the stepping alone [ms]", "wp_step_seconds", lambda x: fmt(x, 1e3, 2))):
        log(f"{title}:")
        log("| method | " + " | ".join(f"n={k}" for k in sizes) + " |")
        log("|" + "---|" * (len(sizes) + 1))
        for name in names:
            values = ds[var].sel(wp_method=name).values
            if values.ndim == 2:
                values = np.median(values, axis=-1)
            log(f"| {name} | " + " | ".join(cell(x) for x in values) + " |")
    peer = PEER in names

    def ratio(var: str, name: str) -> str:
        if not peer:
            return "—"
        x = float(ds[var].sel(wp_method=PEER)) / float(ds[var].sel(wp_method=name))
        return fmt(x, 1.0, 2)

    log(f"work at relative error {T5_TARGET:g} (and {T5_FINE:g}, where measured); ratio = PyElastica / method; "
        f"* = extrapolated beyond the most accurate run; orders over the runs with error > {T5_ORDER_FLOOR:g} "
        "(below it round-off contributes):")
    log(f"| method | n at {T5_TARGET:g} | whole run [ms] | ratio | stepping [ms] | ratio | order (all n) | "
        f"order (finest two) | n at {T5_FINE:g} | whole run [ms] | ratio | stepping [ms] | ratio |")
    log("|" + "---|" * 13)
    for name in names:
        cells = []
        for tag in ("target", "fine"):
            mark = "*" if bool(ds[f"wp_extrapolated_{tag}"].sel(wp_method=name)) else ""
            cells.append([fmt(float(ds[f"wp_n_at_{tag}"].sel(wp_method=name)), 1.0, 0) + mark,
                          fmt(float(ds[f"wp_seconds_at_{tag}"].sel(wp_method=name)), 1e3, 2) + mark,
                          ratio(f"wp_seconds_at_{tag}", name),
                          fmt(float(ds[f"wp_step_seconds_at_{tag}"].sel(wp_method=name)), 1e3, 2) + mark,
                          ratio(f"wp_step_seconds_at_{tag}", name)])
        orders = [fmt(float(ds["wp_order"].sel(wp_method=name)), 1.0, 2),
                  fmt(float(ds["wp_order_finest"].sel(wp_method=name)), 1.0, 2)]
        log(f"| {name} | " + " | ".join(cells[0] + orders + cells[1]) + " |")


def t5_summary(ds) -> str | None:
    """PyElastica's wall time at the target error over the best cartan method's (whole runs, and
    the stepping alone)."""
    if "wp_method" not in ds.coords or PEER not in ds["wp_method"].values:
        return None
    cartan_names = [m for m in ds["wp_method"].values if m != PEER]
    lines = []
    for var, what in (("wp_seconds_at_target", "whole runs"), ("wp_step_seconds_at_target", "stepping alone")):
        at = ds[var]
        finite = [m for m in cartan_names if math.isfinite(float(at.sel(wp_method=m)))]
        if not finite or not math.isfinite(float(at.sel(wp_method=PEER))):
            lines.append(f"wall time at error {T5_TARGET:g} ({what}): not determined "
                         "(the runs neither reach nor approach it)")
            continue
        best = min(finite, key=lambda m: float(at.sel(wp_method=m)))
        ratio = float(at.sel(wp_method=PEER)) / float(at.sel(wp_method=best))
        extrapolated = any(bool(ds["wp_extrapolated_target"].sel(wp_method=m)) for m in (best, PEER))
        lines.append(f"wall time at error {T5_TARGET:g} ({what}): PyElastica / best cartan ({best}) = {ratio:.3g}"
                     f"; target ≥ 10: {'met' if ratio >= 10 else 'not met'}"
                     + (" (extrapolated: refine n until both reach the target)" if extrapolated else ""))
    return "\n".join(lines)


def add_targets(ds, saves: dict[str, Any] | None, t2: dict[str, Any] | None, t2_peer: dict[str, Any] | None,
                t3: dict[str, Any] | None, t6: dict[str, np.ndarray] | None):
    """The saves table, T2, T3 and T6 as variables of the output Dataset (own dimensions)."""
    if saves is not None:
        ds = ds.assign_coords(save_every=("save_every", saves["save_every"], {
            "long_name": "steps between saved frames of cartan.simulate", "units": "1"}))
        ds["saves_step_time"] = (("save_every", "saves_rep"), saves["seconds"], {
            "long_name": f"cartan.simulate wall time per step, T1 rod n = {saves['n']}, {saves['steps']} steps",
            "units": "s"})
    if t2 is not None:
        ds = ds.assign_coords(t2_n=("t2_n", t2["nodes"] - 1, {"long_name": "T2 rod elements", "units": "1"}))
        ds["t2_seconds"] = (("t2_n", "t2_rep"), t2["seconds"], {
            "long_name": "T2 wall time of building and solving the cantilever (cartan.solve_static)", "units": "s"})
        ds["t2_error"] = ("t2_n", t2["error"], {
            "long_name": "T2 relative tip deflection error against the geometrically exact solution", "units": "1"})
        ds["t2_newton_iterations"] = ("t2_n", t2["iterations"], {"long_name": "T2 Newton iterations", "units": "1"})
    if t2_peer is not None:
        for key in ("seconds", "error", "n", "steps"):
            ds[f"t2_peer_{key}"] = ((), float(t2_peer[key]), {
                "long_name": f"T2 PyElastica dynamic relaxation: {key}",
                "comment": "measured in this run" if t2_peer.get("measured") else "quoted from PERFORMANCE.md §1",
                "units": "s" if key == "seconds" else "1"})
    if t3 is not None:
        ds = ds.assign_coords(t3_path=("t3_path", np.array(t3["labels"], dtype=object), {"long_name": "T3 path"}))
        ds["t3_step_time"] = (("t3_path", "t3_rep"), t3["seconds"], {
            "long_name": f"T3 wall time per step, closed rod relaxing, N = {t3['nodes']}", "units": "s"})
        ds["t3_closure"] = ("t3_path", t3["closure"], {"long_name": "T3 ring closure residual at the end",
                                                       "units": "1"})
        ds["t3_potential_energy"] = ("t3_path", t3["energy"], {"long_name": "T3 potential energy at the end",
                                                               "units": "energy"})
        ds["t3_dt"] = ((), t3["dt"], {"long_name": "T3 time step", "units": "s"})
    if t6 is not None:
        for key, long_name in (("import", "import cartan"), ("simulation", "first simulation (T1 rod, 100 steps)"),
                               ("process", "whole fresh process"), ("misses", "numba signatures compiled")):
            ds[f"t6_{key}"] = ("t6_rep", t6[key], {"long_name": f"T6 {long_name}",
                                                   "units": "1" if key == "misses" else "s"})
    return ds


def print_saves_table(saves: dict[str, Any], log=print) -> None:
    med = np.median(saves["seconds"], axis=-1)
    log("| save_every | " + " | ".join(str(int(k)) for k in saves["save_every"]) + " |")
    log("|---|" + "---|" * len(med))
    log("| µs per step | " + " | ".join(f"{1e6 * m:.1f}" for m in med) + " |")


def print_t2_table(t2: dict[str, Any], peer: dict[str, Any], log=print) -> None:
    med = np.median(t2["seconds"], axis=-1)
    log("| code | elements n | tip error | wall time |")
    log("|---|---|---|---|")
    for j in np.argsort(t2["nodes"]):
        log(f"| cartan.solve_static | {t2['nodes'][j] - 1} | {t2['error'][j]:.2e} | {1e3 * med[j]:.1f} ms |")
    how = "measured" if peer.get("measured") else "quoted from PERFORMANCE.md §1; not run here, --t2-elastica runs it"
    log(f"| PyElastica dynamic relaxation ({how}) | {int(peer['n'])} | {peer['error']:.2e} | {peer['seconds']:.1f} s |")
    n, sec, err = t2_at_target(t2)
    if n > 0:
        log(f"T2: cartan reaches {T2_TARGET:g} at n = {n} in {sec:.3f} s (error {err:.2e}); PyElastica's "
            f"{peer['error']:.1%} took {peer['seconds']:.0f} s: {peer['seconds'] / sec:.0f}× the time for "
            f"{peer['error'] / err:.0f}× the error")


def print_t3_table(t3: dict[str, Any], log=print) -> None:
    med = np.median(t3["seconds"], axis=-1)
    ref = med[T3_REFERENCE]
    log("| path | ms/step | vs PyCoss equivalent | closure residual |")
    log("|---|---|---|---|")
    for i, label in enumerate(t3["labels"]):
        ratio = ref / med[i] if math.isfinite(med[i]) and math.isfinite(ref) else math.nan
        log(f"| {label} | {fmt(med[i], 1e3, 3)} | {fmt(ratio, 1.0, 1)}× | {t3['closure'][i]:.1e} |")
    log(f"PyCoss itself (PERFORMANCE.md §1, not installable from PyPI): {PYCOSS_QUOTED_MS[0]}–{PYCOSS_QUOTED_MS[1]} ms "
        "per SE(3) Lie–Euler step at N = 100–1000")


# ---------------------------------------------------------------------------- main
def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer steps and repetitions (about a minute)")
    ap.add_argument("--out", default="out/compare", help="output directory (default: out/compare)")
    ap.add_argument("--steps", type=int, default=None, help="T1 steps per run (default 2000; --quick 200)")
    ap.add_argument("--reps", type=int, default=None, help="T1 repetitions (default 5; --quick 3)")
    ap.add_argument("--sizes", type=int, nargs="+", default=[100, 1000], help="T1 element counts")
    ap.add_argument("--only", nargs="+", choices=PARTS, default=None, metavar="PART",
                    help=f"run only these parts ({', '.join(PARTS)}); e.g. --only t5")
    ap.add_argument("--skip-t5", action="store_true", help="skip the work-precision comparison")
    ap.add_argument("--t5-budget", type=float, default=None,
                    help="stop T5 repetitions after this many seconds (default 300; --quick 15)")
    ap.add_argument("--t5-sizes", type=int, nargs="+", default=None,
                    help=f"T5 element counts (default {' '.join(map(str, T5_SIZES))}; --quick "
                         f"{' '.join(map(str, T5_SIZES_QUICK))})")
    ap.add_argument("--t5-reps", type=int, default=None, help="T5 repetitions (default 5; --quick 1)")
    ap.add_argument("--t5-courant", type=float, default=COURANT,
                    help=f"T5 Courant number c·Δt/dx, the same for every method (default {COURANT})")
    ap.add_argument("--cartan-only", action="store_true", help="do not time PyElastica")
    ap.add_argument("--save-every", type=int, nargs="+", default=[20, 100, 1000],
                    help="save intervals of the simulate-with-saves table (T1 rod at the largest size, 2000 steps)")
    ap.add_argument("--skip-saves", action="store_true", help="skip the simulate-with-saves table")
    ap.add_argument("--skip-t2", action="store_true", help="skip the static cantilever (T2)")
    ap.add_argument("--t2-elastica", action="store_true",
                    help="also run PyElastica's dynamic relaxation of the T2 cantilever (≈ 3 min at final time 5000)")
    ap.add_argument("--t2-elastica-time", type=float, default=5000.0,
                    help="final time of that run (default 5000, its example's; 2.4 M steps)")
    ap.add_argument("--skip-t3", action="store_true", help="skip the closed rod relaxing (T3)")
    ap.add_argument("--t3-nodes", type=int, default=1000, help="T3 ring nodes (default 1000)")
    ap.add_argument("--t3-steps", type=int, default=None, help="T3 steps per run (default 200; --quick 50)")
    ap.add_argument("--skip-t6", action="store_true", help="skip the start-up time (T6)")
    ap.add_argument("--t6-reps", type=int, default=None, help="T6 fresh processes (default 5; --quick 3)")
    args = ap.parse_args(argv)
    for name in ("steps", "reps", "t3_steps", "t6_reps", "t5_reps"):
        value = getattr(args, name)
        if value is not None and value < 1:
            ap.error(f"--{name.replace('_', '-')} must be ≥ 1, got {value}")
    if args.t3_nodes < 8 or any(k < 1 for k in args.save_every) or any(k < 2 for k in args.sizes):
        ap.error("--t3-nodes must be ≥ 8, --save-every ≥ 1 and --sizes ≥ 2")
    if not args.t2_elastica_time > 0:
        ap.error(f"--t2-elastica-time must be > 0, got {args.t2_elastica_time}")
    if args.t5_sizes is not None and any(k < 8 for k in args.t5_sizes):
        ap.error(f"--t5-sizes must be ≥ 8 (fd4 needs 9 nodes on an open axis), got {args.t5_sizes}")
    if not 0 < args.t5_courant <= 1.0:
        ap.error(f"--t5-courant must be in (0, 1] (PyElastica's stability limit is 1), got {args.t5_courant}")
    if args.only is not None:
        for part in PARTS:
            if part != "t1" and part not in args.only:
                setattr(args, f"skip_{part}", True)
    run_t1 = args.only is None or "t1" in args.only

    nsteps = args.steps or (200 if args.quick else 2000)
    reps = args.reps or (3 if args.quick else 5)
    sizes = sorted(set(args.sizes))
    t5_sizes = sorted(set(args.t5_sizes or (T5_SIZES_QUICK if args.quick else T5_SIZES)))
    t5_reps = args.t5_reps or (1 if args.quick else 5)
    t5_budget = args.t5_budget if args.t5_budget is not None else (15.0 if args.quick else 300.0)
    outdir = pathlib.Path(args.out)
    outdir.mkdir(parents=True, exist_ok=True)
    log = print
    wall0 = time.perf_counter()

    import cartan

    ea = None if args.cartan_only else import_elastica()
    if ea is None:
        log(NO_PEER if not args.cartan_only else "--cartan-only: timing cartan only")
        peer_version = "not installed" if not args.cartan_only else "not timed"
    else:
        peer_version = elastica_version(ea)
        log(f"PyElastica {peer_version}: warming its numba kernels ...", end=" ", flush=True)
        log(f"{warm_elastica(ea):.1f} s (compilation or cache load, not timed)")
    has_compiled = "compiled" in simulate_options()

    log(f"cartan {cartan.__version__}, numpy {np.__version__}, Python {platform.python_version()}, "
        f"{platform.machine()}")
    log(f"scene: L = {LENGTH}, radius = {RADIUS}, E = {YOUNG:g}, G = {SHEAR:g}, ρ = {DENSITY:g}; "
        f"c = {WAVE_SPEED:.4g} m/s; Δt = {COURANT}·dx/c = "
        + ", ".join(f"{step_size(n):.3e} s (n = {n})" for n in sizes))
    t1, paths, agreement = None, [], {}
    if run_t1:
        log(f"T1: {nsteps} steps per run, {reps} alternating repetition(s), sizes {sizes}")
        if not has_compiled:
            log("cartan.simulate takes no 'compiled' option: timing simulate as it is and a bare step loop")
        t1 = measure_t1(t1_paths(ea), sizes, nsteps, reps, log)
        paths = t1["paths"]
        if not paths:
            log("no path could be run: nothing to report")
            return 1
        agreement = scene_agreement(t1["finals"], sizes, "cartan step loop")
    else:
        log("T1: skipped (--only)")

    t5 = None
    methods: list[Path] = []
    if not args.skip_t5:
        methods = t5_methods(ea)
        log(f"T5: axial mode, n = {t5_sizes}, one period ({t5_period():.4f} s) at Courant number "
            f"{args.t5_courant}, {t5_reps} repetition(s), budget {t5_budget:.0f} s")
        t5 = measure_t5(methods, t5_sizes, t5_reps, log, budget=t5_budget, courant=args.t5_courant)
        methods = t5["methods"]
    else:
        log("T5: skipped (--skip-t5)")

    saves = None
    if not args.skip_saves:
        log(f"simulate with saves: T1 rod n = {sizes[-1]}, 2000 steps, save_every {args.save_every}, "
            f"{reps} repetition(s)")
        saves = measure_saves(sizes[-1], 2000, args.save_every, reps, log)

    t2 = t2_peer = None
    case = None if args.skip_t2 else t2_case()
    if args.skip_t2:
        log("T2: skipped (--skip-t2)")
    elif case is None:
        log(f"T2: the verification case {T2_CASE!r} is not registered: skipped")
    else:
        log(f"T2: Timoshenko cantilever ({T2_CASE}), cartan.solve_static, {reps} repetition(s)")
        t2 = measure_t2(case, list(case.levels), reps, log)
        t2_peer = {**ELASTICA_T2_QUOTED, "measured": False}
        if args.t2_elastica and ea is not None:
            t2_peer = {**run_elastica_timoshenko(ea, case.exact(), final_time=args.t2_elastica_time, log=log),
                       "measured": True}
        elif args.t2_elastica:
            log(f"T2: {NO_PEER}")

    t3 = None
    if not args.skip_t3:
        t3_steps = args.t3_steps or (50 if args.quick else 200)
        log(f"T3: closed rod relaxing ({T3_SCENE}), N = {args.t3_nodes}, {t3_steps} steps, {reps} repetition(s)")
        t3 = measure_t3(args.t3_nodes, t3_steps, reps, log)
    else:
        log("T3: skipped (--skip-t3)")

    t6 = None
    if not args.skip_t6:
        t6_reps = args.t6_reps or (3 if args.quick else 5)
        log(f"T6: import + first simulation in {t6_reps} fresh processes")
        t6 = measure_t6(t6_reps, log)
    else:
        log("T6: skipped (--skip-t6)")

    cmd = " ".join([pathlib.Path(sys.argv[0]).name if argv is None else "compare.main", *(
        sys.argv[1:] if argv is None else list(argv))])
    stamp = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")
    meta = {
        "source": f"cartan {cartan.__version__}; PyElastica {peer_version}; numpy {np.__version__}; "
                  f"Python {platform.python_version()}; {platform.platform()}",
        "history": f"{stamp} python benchmarks/{cmd}",
        "comment": (
            "Medians over alternating repetitions in one process after a warm-up (no compilation timed). "
            "cartan.simulate is timed whole (setup, guard, one saved frame); 'cartan step loop' and "
            "PyElastica time the stepping loop only. Compare ratios, not absolute times."),
        "scene": {"length": LENGTH, "radius": RADIUS, "E": YOUNG, "G": SHEAR, "density": DENSITY,
                  "courant": COURANT, "steps": nsteps, "t1_velocity_amplitude": T1_AMPLITUDE,
                  "t5_strain": T5_STRAIN},
        "paths": {"simulate_accepts_compiled": has_compiled, "simulate_run_config": (t1 or {}).get(
            "infos", {}).get("cartan.simulate", {})},
        "agreement": agreement,
    }
    ds = build_dataset(t1, paths, sizes, nsteps, t5, methods, t5_sizes, meta)
    ds = add_targets(ds, saves, t2, t2_peer, t3, t6)
    nc = outdir / "compare.nc"
    png = outdir / "compare.png"
    ds.to_netcdf(nc)
    plot(ds, png)

    if t1 is not None:
        log("")
        log(f"T1 — free straight rod, {nsteps} steps, medians of {reps} "
            + (f"(ratio = path / {PEER}):" if any(p.name == PEER for p in paths) else "(PyElastica not timed):"))
        print_t1_table(ds, log)
        if agreement:
            log("scene check, max |r_cartan − r_PyElastica| / max displacement at the end: "
                + ", ".join(f"{v:.2e} (n = {k})" for k, v in agreement.items()))
        loop = "cartan step loop"
        for p in paths:
            if p.code != "cartan" or p.name == loop:
                continue
            pairs = [(t1["finals"][(p.name, n)], t1["finals"][(loop, n)]) for n in sizes
                     if (p.name, n) in t1["finals"] and (loop, n) in t1["finals"]]
            diffs = [float(np.max(np.abs(a.position - b.position))) for a, b in pairs]
            if diffs:
                log(f"{p.name} against the step loop: max |Δr| = {max(diffs):.1e} at the end")
        info = t1["infos"].get("cartan.simulate")
        log("cartan paths timed: " + ", ".join(p.name for p in paths if p.code == "cartan")
            + ("" if has_compiled else " (simulate has no 'compiled' option yet)")
            + (f"; simulate run config {info}" if info else ""))
    if t5 is not None:
        log("")
        log(f"T5 — work-precision, first axial mode after one period, Courant number {t5['courant']}, "
            f"medians of {t5['seconds'].shape[-1]}:")
        print_t5_table(ds, log)
        summary = t5_summary(ds)
        if summary:
            log(summary)
    if saves is not None:
        log("")
        log(f"cartan.simulate with saves — T1 rod, n = {saves['n']}, {saves['steps']} steps, medians of {reps}:")
        print_saves_table(saves, log)
    if t2 is not None:
        log("")
        log(f"T2 — Timoshenko cantilever, time to a relative tip error of {T2_TARGET:g} (medians of {reps}):")
        print_t2_table(t2, t2_peer, log)
    if t3 is not None:
        log("")
        log(f"T3 — closed rod relaxing, N = {t3['nodes']}, {t3['steps']} steps of {t3['dt']:.3g} (medians of {reps}; "
            "steps only, no simulate around them):")
        print_t3_table(t3, log)
    if t6 is not None:
        try:
            from .startup import summary
        except ImportError:
            from startup import summary
        log("")
        log(summary(t6))
    log("")
    log(f"wrote {nc} and {png} ({time.perf_counter() - wall0:.0f} s in all)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
