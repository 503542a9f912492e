"""The threaded build of the generated compiled loops (docs/performance.md, "Threads").

With threads requested on a large enough grid, ``Integrator.run_compiled_loop`` runs the
operator set's threaded module (``OperatorSet.generated(threaded=True)``): the lattice's passes
over nodes, edges and corners as ``prange`` loops over fixed chunks, the force gathered per node
over its edges in increasing edge order (no write conflicts), so that the states and the energy
accumulators equal the serial build's bit for bit.  The fast tests compile nothing; the slow
ones compile the threaded builds of a surface and of a d = 1 medium and compare them with the
serial builds.
"""

from __future__ import annotations

import numpy as np
import pytest

import cartan
from cartan import _threads
from cartan.compiled.codegen import Fragment, _render
from cartan.grid import Grid
from cartan.integrators import RKMK4, LieVerlet
from cartan.problem import Clamped, Damping, Free, InitialState, Problem
from cartan.schemes import _lattice_ops
from cartan.schemes.lattice import Lattice

two_threads = pytest.mark.skipif(_threads.max_threads() < 2, reason="numba has a single thread here")


# ---------------------------------------------------------------------------- fast: nothing compiles
def test_incidence_lists_each_rows_items_in_increasing_order():
    """``_t_incidence`` (plain Python here): row i lists the p with ``keys[p] == i``, increasing
    — the order in which the serial force adds the edges' contributions to a node."""
    rng = np.random.default_rng(1)
    keys = rng.integers(0, 7, size=40)
    ptr, item = _lattice_ops._t_incidence(keys, keys.size, 7)
    assert ptr[0] == 0 and ptr[-1] == keys.size
    for i in range(7):
        assert list(item[ptr[i]:ptr[i + 1]]) == [p for p in range(keys.size) if keys[p] == i]


def test_render_marks_only_the_named_functions_parallel():
    serial = _render([Fragment(source="def op_a(x):\n    return x\n")])
    assert "prange" not in serial and "parallel=True" not in serial
    both = _render([Fragment(source="def op_a(x):\n    return x\n"),
                    Fragment(source="def op_b(x):\n    return x\n", parallel=("op_b",))])
    assert "from numba import njit, prange" in both
    head_a, head_b = (both.split(f"def {name}")[0].splitlines()[-1] for name in ("op_a", "op_b"))
    assert "parallel=True" not in head_a and "parallel=True" in head_b


def test_threaded_module_rebinds_the_operators():
    """The threaded module holds the serial one's functions and rebinds the operators the loops
    call to their threaded passes; the serial module is not changed by it (importing a generated
    module compiles nothing: numba compiles on first call)."""
    sigma = cartan.medium("sigma-model", n=2, d=2)
    grid = Grid((4, 4), 1.0, periodic=True)
    ops = Lattice(Problem(sigma, grid, sigma.initial_state(grid, "random-smooth"))).compiled_operators()
    serial, threaded = ops.generated(), ops.generated(threaded=True)
    assert serial is not threaded and ops.generated() is serial
    for name in _lattice_ops._REPLACED:
        assert getattr(threaded, name) is getattr(threaded, f"{name}_threaded")
        assert not hasattr(serial, f"{name}_threaded")
    assert threaded.op_force.targetoptions.get("parallel") is True
    assert not serial.lie_verlet_loop.signatures


def test_generated_loops_ask_without_counting():
    """The generated loops ask :func:`loop_threads` with ``count=False``: ``cartan warm`` does
    not rerun them threaded (their threaded builds compile on first threaded use)."""
    before = _threads.thread_queries()
    with cartan.use_threads(1):
        assert _threads.loop_threads(10**6, count=False) == 1
    assert _threads.thread_queries() == before


# ---------------------------------------------------------------------------- slow: threaded = serial
def _same(a, b) -> bool:
    arrays = [(a.S, b.S)] + [(a.arrays[k], b.arrays[k]) for k in a.arrays]
    return bool(all(np.array_equal(x, y) for x, y in arrays) and a.scalars == b.scalars)


def _run(problem: Problem, make, dt: float, steps: int, threaded: bool):
    scheme = Lattice(problem)
    state = scheme.initial_state()
    integrator = make()
    if threaded:
        with _threads.threaded_everywhere(2):
            assert integrator.run_compiled_loop(scheme, state, dt, steps)
        module = scheme.compiled_operators().threaded_module
        assert module is not None and getattr(module, integrator.compiled_loop(scheme, state, dt)[0]).signatures
    else:
        assert integrator.run_compiled_loop(scheme, state, dt, steps)
    return state


@pytest.mark.slow
@two_threads
def test_threaded_surface_equals_the_serial_one():
    """A Cosserat surface (corner energies: the coupled passes) on a 40 × 36 grid (several
    chunks of nodes, edges and corners), clamped along one edge, under gravity and damping,
    with a transverse velocity: ``lie-verlet`` gives the serial states and energies bit for bit."""
    medium = cartan.medium("cosserat-surface", E=1.0, poisson=0.3, thickness=0.05, density=1.0)
    grid = Grid((40, 36), length=(1.0, 0.9))
    flat = medium.initial_state(grid, "flat")
    u = np.stack(np.meshgrid(*[grid.coordinates(a) for a in range(2)], indexing="ij"), axis=-1)
    N = np.zeros((*grid.shape, medium.group.dim))
    N[..., 2] = 1e-2 * np.sin(np.pi * u[..., 0]) * np.cos(2 * np.pi * u[..., 1])  # transverse velocity
    loads = [medium.make_load("gravity", g=[0.0, 0.0, -1e-3]), Damping(0.3)]
    problem = Problem(medium, grid, InitialState(Phi=flat.Phi, N=N), {"u-start": Clamped()}, loads)
    assert Lattice(problem).coupled
    dt = 0.1 * grid.spacing[0]  # below the CFL limit of the bending waves at this spacing
    assert _same(_run(problem, LieVerlet, dt, 6, False), _run(problem, LieVerlet, dt, 6, True))


@pytest.mark.slow
@two_threads
def test_threaded_d1_medium_equals_the_serial_one():
    """The sigma model on S² along a line (SO(3) frames: the generated loops, d = 1) of 1500
    nodes, clamped at the start with a dead load at the end and drag: ``lie-verlet`` and
    ``rkmk4`` (the threaded drift) give the serial states and energies bit for bit."""
    sigma = cartan.medium("sigma-model", n=2, d=1)
    grid = Grid(1500, 1.0)
    init = sigma.initial_state(grid, "random-smooth", amplitude=0.6, gauge_amplitude=0.2, velocity_amplitude=0.4)
    problem = Problem(sigma, grid, init, {"start": Clamped(), "end": Free(load=[0.1, 0.2, 0.0], follower=False)},
                      [sigma.make_load("drag")])
    for make, dt, steps in ((LieVerlet, 1e-4, 5), (RKMK4, 1e-4, 3)):
        assert _same(_run(problem, make, dt, steps, False), _run(problem, make, dt, steps, True)), make.__name__
