"""Where a generated lie-verlet step spends its time: the operators one by one.

For each case of :mod:`benchmarks.bench_generated` (and the T1 rod of
:mod:`benchmarks.compare`), the compiled operators of the generated module are called
directly on the case's packed configuration: ``op_force`` (edge logarithms or nodal strains,
medium stress, the transposed operators back to the nodes), the free flow (``op_free_flow``,
or the loop's ``_free_flow`` where the operator set has none), ``op_move`` (lattice: the edges
and frames follow the nodes), ``op_drift`` (collocation: one exact drift, strains and frames)
and ``op_velocity``; on the lattice also the force's two group passes over the edges alone
(``force: logarithms``, ``g_log_chunk``; ``force: dexp⁻¹ᵀ pairs``, ``g_dexp_inv_T_pair_chunk``:
the rest of ``force`` is the medium's stress per edge or corner with its gather and scatter,
and the sum to the nodes); each is reported in ns per node, the median of several repetitions.  A
report for the terminal::

    python benchmarks/profile_generated.py [--scheme lattice|collocation] [--wall] [--gross] [case ...]

On the collocation scheme the T1 rod takes ``fd4`` with stepped frames (the scheme options of
``compare.T5_FD4``), the other cases ``fd2``.  The clock is the process's CPU time
(``time.process_time``: every thread of the process, steadier than the wall clock on a shared
machine); ``--wall`` times with the wall clock instead (``--cpu``, the former switch, is
accepted and is the default).

Each operator is called from Python, which costs what the loops, calling the operators from
compiled code, do not pay: the dispatch and the unboxing of the arguments (the problem data
``D`` is a tuple of tens of arrays: 10–50 µs per call, 10–50 ns per node at n = 1000).  That
cost is measured for each operator by calling a compiled function that does nothing with the
same arguments (:func:`call_cost`), and subtracted from the operator's figure; the report
states it (``call``: one call's cost in ns per node, the largest over the operators).
``--gross`` reports the figures with the call included.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time

import numpy as np
from numba import njit

import cartan

ROOT = pathlib.Path(__file__).resolve().parents[1]
for _p in (ROOT / "tests", ROOT / "benchmarks"):
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))

CASES = ["t1-rod", "so3-quadratic-gen", "so3-quartic", "se3-coupled", "s3-sigma"]
SCHEMES = ("lattice", "collocation")


#: the clock of :func:`_median`: CPU time of the process (``main`` sets ``time.perf_counter`` for
#: ``--wall``)
CLOCK = time.process_time


def _median(call, reps: int = 7, inner: int = 10) -> float:
    times = []
    for _ in range(reps):
        t0 = CLOCK()
        for _ in range(inner):
            call()
        times.append((CLOCK() - t0) / inner)
    return float(np.median(times))


@njit
def _null3(a, b, c):  # pragma: no cover - compiled
    return None


@njit
def _null4(a, b, c, d):  # pragma: no cover - compiled
    return None


@njit
def _null5(a, b, c, d, e):  # pragma: no cover - compiled
    return None


@njit
def _null6(a, b, c, d, e, f):  # pragma: no cover - compiled
    return None


@njit
def _null7(a, b, c, d, e, f, g):  # pragma: no cover - compiled
    return None


@njit
def _null8(a, b, c, d, e, f, g, h):  # pragma: no cover - compiled
    return None


#: a compiled function that does nothing, by number of arguments
_NULL = {3: _null3, 4: _null4, 5: _null5, 6: _null6, 7: _null7, 8: _null8}


def call_cost(args, inner: int = 10) -> float:
    """Seconds (on :data:`CLOCK`) of one call from Python of a compiled function that does nothing
    with the arguments ``args()`` (a callable, so that copies made per call are counted too): the
    dispatch and unboxing that every operator call of :func:`profile_run` pays."""
    null = _NULL[len(args())]
    null(*args())  # compile for these types
    return _median(lambda: null(*args()), inner=inner)


def _scheme(case: str, scheme_name: str = "lattice"):
    """The scheme, integrator, state and Δt of a case."""
    options = {}
    if case == "t1-rod":
        import compare

        n = 1000
        problem, dt = compare.cartan_problem(n, compare.t1_velocity(n)), compare.step_size(n)
        if scheme_name == "collocation":
            options = dict(compare.T5_FD4)
    else:
        import bench_generated

        problem, dt = bench_generated._problem(case), 1e-5
    scheme = cartan.registry("schemes")[scheme_name](problem, **options)
    integrator = cartan.registry("integrators")["lie-verlet"]()
    state = scheme.initial_state()
    if not integrator.run_compiled_loop(scheme, state, dt, 1):
        raise NotImplementedError(f"{case}: no generated loop on the {scheme_name} scheme")
    return scheme, integrator, state, dt


def profile(case: str, scheme_name: str = "lattice", subtract_call: bool = True) -> dict[str, float]:
    """ns per node of each operator of one lie-verlet step of ``case`` on ``scheme_name``
    (:func:`profile_run`)."""
    return profile_run(*_scheme(case, scheme_name), scheme_name=scheme_name, subtract_call=subtract_call)


def profile_run(scheme, integrator, state, dt: float, scheme_name: str = "lattice",
                inner: int = 10, subtract_call: bool = True) -> dict[str, float]:
    """ns per node of each operator of one generated lie-verlet step of a built problem
    (``inner`` calls per timed repetition, on :data:`CLOCK`).

    With ``subtract_call`` (the default) each figure is net of the cost of calling the operator
    from Python (:func:`call_cost` with the operator's arguments), and the entry ``"call"`` is
    that cost, per node, the largest over the operators; without, the figures include it."""
    ops = scheme.compiled_operators()
    module = ops.generated() if hasattr(ops, "generated") else ops.module
    D = ops.data
    C = ops.pack(state)
    K = module.op_work(D)
    n, r, m = ops.nodes, D.r, D.m
    S = np.ascontiguousarray(state.S, dtype=float).reshape(n, -1).copy()
    N, W = np.empty((n, r)), np.empty((n, r))
    module.op_velocity(D, S, N)
    pieces, fracs = integrator.compiled_loop(scheme, state, dt)[1][3:5]
    Dn = np.empty((n, m, m))
    tiny = 1e-9 * dt  # the free flow barely moves S (and C) between repetitions
    # each operator: (the compiled function, its arguments made per call)
    calls = {"force": (module.op_force, lambda: (D, C, 0.0, N, W, K))}
    if hasattr(module, "op_free_flow"):
        calls["free flow"] = (module.op_free_flow, lambda: (D, C, S.copy(), pieces, fracs, tiny, Dn, K))
    else:
        calls["free flow"] = (module._free_flow, lambda: (D, S.copy(), pieces, fracs, tiny, Dn))
    if scheme_name == "lattice":
        calls["move"] = (module.op_move, lambda: (D, C, Dn, K))
    else:
        calls["drift"] = (module.op_drift, lambda: (D, C, tiny, N, K))
    calls["velocity"] = (module.op_velocity, lambda: (D, S, N))
    if scheme_name == "lattice":  # the force's two group passes over the edges, alone
        G, XI, QE, VT, VH = C[0], K[2], K[3], K[4], K[5]
        ne = G.shape[0]
        scale = np.empty(0) if D.coupled else D.escale
        calls["force: logarithms"] = (module.g_log_chunk, lambda: (G, 0, ne, XI))
        calls["force: dexp⁻¹ᵀ pairs"] = (module.g_dexp_inv_T_pair_chunk, lambda: (XI, QE, scale, 0, ne, VT, VH))
    cost, overhead = {}, {}
    for name, (func, args) in calls.items():
        func(*args())  # compiled (or loaded) before timing
        cost[name] = _median(lambda func=func, args=args: func(*args()), inner=inner)
        if subtract_call:
            overhead[name] = call_cost(args, inner=inner)
            cost[name] -= overhead[name]
    out = {k: v / n * 1e9 for k, v in cost.items()}
    if subtract_call:
        out["call"] = max(overhead.values()) / n * 1e9
    return out


def main(argv: list[str] | None = None) -> None:  # pragma: no cover - a report for the terminal
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scheme", choices=SCHEMES, default="lattice")
    clock = parser.add_mutually_exclusive_group()
    clock.add_argument("--wall", action="store_true", help="time with the wall clock (default: CPU time)")
    clock.add_argument("--cpu", action="store_true", help="time with the process's CPU time (the default)")
    parser.add_argument("--gross", action="store_true",
                        help="include the cost of calling each operator from Python (default: subtracted)")
    parser.add_argument("cases", nargs="*", default=CASES)
    args = parser.parse_args(argv)
    global CLOCK
    CLOCK = time.perf_counter if args.wall else time.process_time
    what = ("wall" if args.wall else "CPU") + " time, ns per node" + (
        ", the Python call included" if args.gross else ", net of the Python call")
    for case in args.cases:
        cost = profile(case, args.scheme, subtract_call=not args.gross)
        call = cost.pop("call", None)
        parts = "  ".join(f"{k} {v:7.1f}" for k, v in cost.items())
        tail = f"  (call {call:5.1f} subtracted)" if call is not None else ""
        print(f"{case:20s} {parts}{tail}  ({what})")


if __name__ == "__main__":
    main(sys.argv[1:])
