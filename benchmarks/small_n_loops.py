"""The generated lattice loops on small rods: the cost of a step at n = 11 … 1000.

Run it as a script::

    python benchmarks/small_n_loops.py [--sizes 11 41 101 1000] [--integrators lie-verlet rkmk4 lie-euler]

The scene ``stiff-rod-swing`` (examples/stiff-rod-swing.toml: a clamped cosserat-rod on SE(3)
under gravity, light damping) on ``n`` nodes, stepped by the generated loop of each integrator
(``Integrator.run_compiled_loop``, called directly: the scene's ``lie-verlet`` would otherwise
take the hand-written structure-of-arrays loop of SE(3) rods).  Per (integrator, n): one call
untimed (compiling the loop or loading it from the cache), then ``--repeat`` calls of ``--steps``
steps from the same state; the median process CPU time of a call per step, in µs.

``--refcounted`` times, in the same process and alternating call by call, the same loop in a
module generated without its first line ``D = unmanaged_(D)`` (:mod:`cartan.compiled.unmanaged`):
the operators then receive the data's arrays with their reference counts, as before that line;
it prints both medians and their ratio (the module compiles once, into the cache).
"""

from __future__ import annotations

import argparse
import copy
import os
import time

import numpy as np

import cartan

SCENE = os.path.join(os.path.dirname(__file__), os.pardir, "examples", "stiff-rod-swing.toml")
#: Δt of each integrator (stable on the scene's rods up to n = 1000 for the steps timed)
DT = {"lie-verlet": 1e-6, "rkmk4": 1e-6, "lie-euler": 1e-7}


def problem(n: int):
    import tomllib

    with open(SCENE, "rb") as fh:
        spec = tomllib.load(fh)
    spec["grid"]["n"] = int(n)
    return cartan.load_scene(spec).problem


def measure(name: str, n: int, steps: int, repeat: int) -> float:
    """Median CPU µs per step of the generated loop of ``name`` on the scene at ``n`` nodes."""
    scheme = cartan.registry("schemes")["lattice"](problem(n))
    integrator = cartan.registry("integrators")[name]()
    state0 = scheme.initial_state()
    state = copy.deepcopy(state0)
    if not integrator.run_compiled_loop(scheme, state, DT[name], 2):
        raise RuntimeError(f"{name}: no generated loop")
    times = []
    for _ in range(repeat):
        state = copy.deepcopy(state0)
        c0 = time.process_time()
        integrator.run_compiled_loop(scheme, state, DT[name], steps)
        times.append(time.process_time() - c0)
    return float(np.median(times)) / steps * 1e6


def _refcounted(ops):
    """The module of ``ops`` with every loop's ``D = unmanaged_(D)`` line left out."""
    import importlib

    from cartan.compiled.codegen import Fragment, generate
    from cartan.compiled.operators import LOOP_SOURCES

    loops = [importlib.import_module(name).loop_fragment() for name in LOOP_SOURCES]
    loops = [Fragment(f.imports, f.constants, "\n".join(ln for ln in f.source.splitlines()
                                                        if ln.strip().split("  #")[0] != "D = unmanaged_(D)"),
                      f.parallel) for f in loops]
    return generate(f"ops-refcounted-{ops.key}", [*ops.fragments, *loops, *ops.late])


def measure_pair(name: str, n: int, steps: int, repeat: int) -> tuple[float, float, bool]:
    """Median CPU µs per step of the loop of ``name`` with the data unmanaged (the set's module) and
    refcounted (:func:`_refcounted`), calls alternated; and whether both end bit for bit equal."""
    scheme = cartan.registry("schemes")["lattice"](problem(n))
    integrator = cartan.registry("integrators")[name]()
    ops = scheme.compiled_operators()
    state0 = scheme.initial_state()
    loop, args = integrator.compiled_loop(scheme, state0, DT[name])
    fns = (getattr(ops.generated(), loop), getattr(_refcounted(ops), loop))

    def call(fn, nsteps):
        state = copy.deepcopy(state0)
        config = ops.pack(state)
        S = np.ascontiguousarray(state.S, dtype=float).reshape(ops.nodes, -1).copy()
        a = copy.deepcopy(args)
        c0 = time.process_time()
        res = fn(ops.data, config, S, *a, float(state.t), DT[name], nsteps, 0.0, 0.0, 1, np.inf)
        return time.process_time() - c0, (res, S, *config)

    ends = [call(fn, 2)[1] for fn in fns]  # (compiles, or loads from the cache)
    same = all(np.array_equal(np.asarray(x), np.asarray(y)) for x, y in zip(ends[0][1:], ends[1][1:])) and (
        ends[0][0] == ends[1][0])
    times = ([], [])
    for r in range(repeat):
        for k in ((0, 1) if r % 2 == 0 else (1, 0)):
            times[k].append(call(fns[k], steps)[0])
    return (float(np.median(times[0])) / steps * 1e6, float(np.median(times[1])) / steps * 1e6, same)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[11, 41, 101, 1000])
    ap.add_argument("--integrators", nargs="+", default=["lie-verlet", "rkmk4", "lie-euler"])
    ap.add_argument("--steps", type=int, default=0, help="steps per call (0: ≈ 20000 node-steps, at least 50)")
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--refcounted", action="store_true", help="against the loops without unmanaged data, alternated")
    args = ap.parse_args()
    print(f"load {os.getloadavg()[0]:.2f}")
    for name in args.integrators:
        for n in args.sizes:
            steps = args.steps or max(50, 20000 // n)
            if args.refcounted:
                new, old, same = measure_pair(name, n, steps, args.repeat)
                print(f"{name:12s} n={n:5d} steps={steps:5d}  refcounted {old:9.2f} → unmanaged {new:9.2f} µs/step"
                      f"  ({new / old:.3f}; same results: {same})", flush=True)
                continue
            us = measure(name, n, steps, args.repeat)
            print(f"{name:12s} n={n:5d} steps={steps:5d}  {us:9.2f} µs/step  {us * 1e3 / n:8.1f} ns/node-step",
                  flush=True)


if __name__ == "__main__":
    main()
