"""Threads of the compiled loops: the setting (``CARTAN_THREADS``, ``cartan.set_threads``) and
results that do not depend on it.

Every pass of the threaded loops (the structure-of-arrays SE(3) rod loops) works on fixed
chunks of nodes or edges and sums over the grid add the chunks' partial sums in chunk order,
so the threaded loops must reproduce the serial ones bit for bit; a subprocess with
``CARTAN_THREADS=2`` compares them on a rod above the threshold
:data:`cartan._threads.MIN_NODES`, and checks that the setting leaves the results of the
serial generated loops (the sigma model on a 2D grid) unchanged.
"""

from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys
import textwrap

import pytest

import cartan
from cartan import _threads

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_default_is_serial(monkeypatch):
    monkeypatch.delenv(_threads.ENV, raising=False)
    assert cartan.get_threads() == 1
    assert _threads.loop_threads(10**7) == 1


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "2", None])
def test_set_threads_validates(bad):
    if bad is None:  # None is valid: back to the environment
        cartan.set_threads(None)
        return
    with pytest.raises(ValueError, match=r"threads must be an integer in 1\.\.\d+"):
        cartan.set_threads(bad)
    with pytest.raises(ValueError, match="threads must be an integer"):
        cartan.set_threads(_threads.max_threads() + 1)


@pytest.mark.parametrize("value", ["two", "0", "1.5", "100000"])
def test_environment_is_validated(monkeypatch, value):
    monkeypatch.setenv(_threads.ENV, value)
    with pytest.raises(ValueError, match=r"CARTAN_THREADS must be an integer in 1\.\.\d+"):
        cartan.get_threads()


def test_environment_and_overrides(monkeypatch):
    monkeypatch.setenv(_threads.ENV, " 1 ")
    assert cartan.get_threads() == 1
    with cartan.use_threads(1):
        assert cartan.get_threads() == 1
    cartan.set_threads(1)
    try:
        monkeypatch.setenv(_threads.ENV, "not read while set_threads holds")
        assert cartan.get_threads() == 1
    finally:
        cartan.set_threads(None)


@pytest.mark.skipif(_threads.max_threads() < 2, reason="numba has a single thread here (NUMBA_NUM_THREADS = 1)")
def test_threads_only_above_the_threshold():
    with cartan.use_threads(2):
        assert cartan.get_threads() == 2
        assert _threads.loop_threads(_threads.MIN_NODES - 1) == 1
        assert _threads.loop_threads(_threads.MIN_NODES) == 2
    assert cartan.get_threads() == 1


THREADS_SCRIPT = textwrap.dedent(
    """
    import json, sys
    import numpy as np
    import cartan
    from cartan import _threads
    from cartan.grid import Grid
    from cartan.integrators import LieEuler, LieVerlet, Overdamped, RKMK4
    from cartan.problem import Clamped, Damping, Free, Problem
    from cartan.schemes import _lattice_compiled as lc
    from cartan.schemes.lattice import Lattice

    def run(problem, make, dt, steps, threads):
        scheme = Lattice(problem)
        state = scheme.initial_state()
        integ = make()
        with cartan.use_threads(threads):
            assert scheme.compiled_advance(integ, state, dt, steps) or integ.run_compiled_loop(scheme, state, dt,
                                                                                               steps)
        return state

    def same(a, b):
        arrays = [(a.S, b.S)] + [(a.arrays[k], b.arrays[k]) for k in a.arrays]
        return bool(all(np.array_equal(x, y) for x, y in arrays) and a.scalars == b.scalars)

    every = sys.argv[1] == "every"
    # the sigma model on S² on a 2D grid just above the threshold, open along v: a clamped
    # face, a dead load on the other one
    sigma = cartan.medium("sigma-model", n=2, d=2)
    side = int(np.ceil(np.sqrt(_threads.MIN_NODES)))
    grid = Grid((side, side), 1.0, periodic=(True, False))
    init = sigma.initial_state(grid, "random-smooth", amplitude=0.6, gauge_amplitude=0.2, velocity_amplitude=0.4)
    boundaries = {"v-start": Clamped(), "v-end": Free(load=[0.1, 0.2, 0.0], follower=False)}
    drag = [sigma.make_load("drag")]
    cases = [("sigma lie-verlet", LieVerlet, 1e-3, 4, [])]
    if every:
        cases += [("sigma lie-verlet damped", LieVerlet, 1e-3, 3, drag),
                  ("sigma overdamped", Overdamped, 1e-6, 3, drag), ("sigma rkmk4", RKMK4, 1e-3, 2, drag),
                  ("sigma lie-euler", LieEuler, 1e-4, 2, drag)]
    results = {}
    for name, make, dt, steps, loads in cases:
        problem = Problem(sigma, grid, init, boundaries, loads)
        results[name] = same(run(problem, make, dt, steps, 1), run(problem, make, dt, steps, 2))
    # an SE(3) rod (the vectorised loop) with gravity, damping and a dead end load
    rod = cartan.medium("cosserat-rod", E=1e6, poisson=0.5, radius=0.02, density=1000.0)
    grid = Grid(_threads.MIN_NODES, length=1.0)
    problem = Problem(rod, grid, rod.initial_state(grid, "arc", curvature=1.0, velocity=[0, 0.1, 0, 0, 0, 0.2]),
                      {"start": Clamped(), "end": Free(load=[0, 0, -1e-3, 0, 0, 0], follower=False)},
                      [Damping(0.5), rod.make_load("gravity", g=[0.0, 0.0, -9.81])])
    results["rod lie-verlet"] = same(run(problem, LieVerlet, 1e-8, 4, 1), run(problem, LieVerlet, 1e-8, 4, 2))
    # without damping: steps in blocks of steps, chunk by chunk, on each thread's half (from 2
    # chunks per thread here)
    free = Problem(rod, grid, problem.initial, problem.boundaries, [rod.make_load("gravity", g=[0.0, 0.0, -9.81])])
    lc.soa.THREAD_BLOCK_CHUNKS = 2
    results["rod lie-verlet blocked"] = same(run(free, LieVerlet, 1e-8, 11, 1), run(free, LieVerlet, 1e-8, 11, 2))
    if every:
        results["rod overdamped"] = same(run(problem, Overdamped, 1e-10, 3, 1), run(problem, Overdamped, 1e-10, 3, 2))
    used = [name for name, f in lc.soa.THREADED.items() if f.signatures]
    print(json.dumps({"threads": cartan.get_threads(), "same": results, "threaded": sorted(used)}))
    """
)


def _run_threaded(which: str) -> dict:
    env = dict(os.environ, CARTAN_THREADS="2", NUMBA_NUM_THREADS="2")
    run = subprocess.run([sys.executable, "-c", THREADS_SCRIPT, which], capture_output=True, text=True, cwd=ROOT,
                         env=env, timeout=1800)
    assert run.returncode == 0, run.stderr
    return json.loads(run.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_threaded_loops_equal_the_serial_ones():
    """``CARTAN_THREADS=2`` in a new process: the threaded ``lie-verlet`` loop of the vectorised
    SE(3) rod runs above the threshold and gives the serial results bit for bit; the sigma
    model on a 2D grid (the serial generated loop) gives the same results under either
    setting.  (The first run compiles the threaded loops into numba's cache.)"""
    out = _run_threaded("lie-verlet")
    assert out["threads"] == 2
    assert {"lie_verlet_se3_loop"} <= set(out["threaded"])
    assert all(out["same"].values()), out["same"]


@pytest.mark.slow
def test_every_threaded_integrator_equals_the_serial_one():
    """The same for damping and for the other integrators (``overdamped``, ``rkmk4``,
    ``lie-euler``), whose loops take minutes to compile on an empty cache."""
    out = _run_threaded("every")
    assert {"lie_verlet_se3_loop", "overdamped_se3_loop"} <= set(out["threaded"])
    assert len(out["same"]) == 8 and all(out["same"].values()), out["same"]
