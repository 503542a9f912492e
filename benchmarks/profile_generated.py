"""Where a generated lie-verlet step spends its time: the operators one by one.

For each case of :mod:`benchmarks.bench_generated` (and the T1 rod of
:mod:`benchmarks.compare`), the compiled operators of the generated module are called
directly on the case's packed configuration: ``op_force`` (edge logarithms or nodal strains,
medium stress, the transposed operators back to the nodes), the free flow (``op_free_flow``,
or the loop's ``_free_flow`` where the operator set has none), ``op_move`` (lattice: the edges
and frames follow the nodes), ``op_drift`` (collocation: one exact drift, strains and frames)
and ``op_velocity``; each is reported in ns per node, the median of several repetitions.  A
report for the terminal::

    python benchmarks/profile_generated.py [--scheme lattice|collocation] [--cpu] [case ...]

On the collocation scheme the T1 rod takes ``fd4`` with stepped frames (the scheme options of
``compare.T5_FD4``), the other cases ``fd2``.  ``--cpu`` times with the process's CPU time
instead of the wall clock (steadier on a shared machine).  Each operator is called from
Python, so every figure includes the call's unboxing of the problem data (tens of
microseconds per call: tens of ns per node at n = 1000), which the loops, calling the operators
from compiled code, do not pay.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time

import numpy as np

import cartan

ROOT = pathlib.Path(__file__).resolve().parents[1]
for _p in (ROOT / "tests", ROOT / "benchmarks"):
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))

CASES = ["t1-rod", "so3-quadratic-gen", "so3-quartic", "se3-coupled", "s3-sigma"]
SCHEMES = ("lattice", "collocation")


#: the clock of :func:`_median` (``main`` sets ``time.process_time`` for ``--cpu``)
CLOCK = time.perf_counter


def _median(call, reps: int = 7, inner: int = 10) -> float:
    times = []
    for _ in range(reps):
        t0 = CLOCK()
        for _ in range(inner):
            call()
        times.append((CLOCK() - t0) / inner)
    return float(np.median(times))


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


def profile(case: str, scheme_name: str = "lattice") -> dict[str, float]:
    """ns per node of each operator of one lie-verlet step of ``case`` on ``scheme_name``."""
    return profile_run(*_scheme(case, scheme_name), scheme_name=scheme_name)


def profile_run(scheme, integrator, state, dt: float, scheme_name: str = "lattice",
                inner: int = 10) -> dict[str, float]:
    """ns per node of each operator of one generated lie-verlet step of a built problem
    (``inner`` calls per timed repetition, on :data:`CLOCK`)."""
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
    if hasattr(module, "op_free_flow"):
        def flow():
            return module.op_free_flow(D, C, S.copy(), pieces, fracs, tiny, Dn, K)
    else:
        def flow():
            return module._free_flow(D, S.copy(), pieces, fracs, tiny, Dn)
    flow()
    cost = {
        "force": _median(inner=inner, call=lambda: module.op_force(D, C, 0.0, N, W, K)),
        "free flow": _median(flow, inner=inner),
    }
    if scheme_name == "lattice":
        cost["move"] = _median(inner=inner, call=lambda: module.op_move(D, C, Dn, K))
    else:
        cost["drift"] = _median(inner=inner, call=lambda: module.op_drift(D, C, tiny, N, K))
    cost["velocity"] = _median(inner=inner, call=lambda: module.op_velocity(D, S, N))
    return {k: v / n * 1e9 for k, v in cost.items()}


def main(argv: list[str] | None = None) -> None:  # pragma: no cover - a report for the terminal
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scheme", choices=SCHEMES, default="lattice")
    parser.add_argument("--cpu", action="store_true", help="time with the process's CPU time")
    parser.add_argument("cases", nargs="*", default=CASES)
    args = parser.parse_args(argv)
    if args.cpu:
        global CLOCK
        CLOCK = time.process_time
    for case in args.cases:
        cost = profile(case, args.scheme)
        parts = "  ".join(f"{k} {v:7.1f}" for k, v in cost.items())
        print(f"{case:20s} {parts}  (ns per node)")


if __name__ == "__main__":
    main(sys.argv[1:])
