"""Per-node accumulators in the collocation scheme's generated loops (cartan/accumulators.py;
:func:`cartan.schemes._collocation_ops.collocation_operators` with the lattice's
``accumulate_fragment``; docs/media/relativistic-rod.md, "Proper time per node"): the elastic
string with clocks (the accumulator ``proper_time``, rate √(1 − |v⃗|²/c²) of the nodal velocity
N_i = N(S_i, X_i) the coupled set's ``op_state_velocity`` gives the loop) in the loops of
``rkmk4`` and ``lie-euler``.

The Nambu–Goto string's clocks too (``clocks=True``, opt-in there): its rate √(−⟨ṙ, ṙ⟩)/c with
ṙ = Λy_N is the Lorentz invariant √(−⟨y_N, y_N⟩)/c of the velocity alone, so its rate kernel
(``nambu_goto_proper_time_rate``) needs no node frame and its clocks run in the plain sets' loops
of both schemes (``lie-verlet`` included).

Fast: the declarations (the coupled set integrates the clocks in the loops it serves and accepts
a state that carries them; without clocks it takes none; the Nambu–Goto string with clocks in
every loop of its plain set) and the Nambu–Goto rate kernel against ``accumulator_rates`` bit for
bit.  Slow (they compile the coupled string's loops on the collocation, ≈ 80 s on a fresh cache;
and the plain sets' ``lie-verlet`` loops, ≈ 60–90 s each): the compiled run against the numpy run
— the same formulas in the same floating-point order, so every saved field, ``proper_time``
included, agrees to 1e-12 of its scale (round-off of 20 steps; measured: bit for bit on the
elastic string) — the spy that the loops took the steps, and a restart from the checkpoint bit for
bit; the collapsing Nambu–Goto loop through its collapse (every point at c, rate 0) on both
schemes.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_accumulators_compiled import (
    _problem,
    _same,
    _Timed,
    assert_clock_restart_is_exact,
    assert_clock_run_is_the_numpy_run,
)

import cartan
from cartan.schemes.collocation import Collocation
from cartan.schemes.lattice import Lattice

pytestmark = pytest.mark.filterwarnings("ignore::cartan.StabilityWarning")


# ---------------------------------------------------------------------------- declarations
def test_collocation_set_takes_the_clocks_of_the_elastic_string():
    """With clocks the coupled set integrates the accumulators in the loops it serves, loads them
    from the state (``pack``) and writes them back (``unpack``); without clocks it takes none; the
    Nambu–Goto string's clocks run in every loop of its plain set."""
    scheme = Collocation(_problem("clamped"))
    ops = scheme.compiled_operators()
    assert ops.accumulates == ("euler_loop", "rkmk_loop", "implicit_loop") and set(ops.accumulates) <= set(ops.loops)
    assert ops.key.endswith("-coupled-acc")
    state = cartan.accumulators.start(scheme, scheme.initial_state())
    assert "accumulator_proper_time" in state.arrays and ops.accepts(state)
    tau = np.linspace(0.0, 1.0, 9)
    state.arrays["accumulator_proper_time"] = tau.copy()
    C = ops.pack(state)
    assert np.array_equal(ops.data.acc[0], tau)
    ops.data.acc[0] += 1.0
    ops.unpack(state, C)
    assert np.array_equal(state.arrays["accumulator_proper_time"], tau + 1.0)
    plain = Collocation(_problem("clamped", clocks=False)).compiled_operators()
    assert plain.accumulates == () and plain.data.acc.shape == (0, 9) and not plain.key.endswith("-acc")
    rod = cartan.medium("relativistic-rod", clocks=True)
    grid = cartan.Grid(8, length=2 * math.pi, periodic=True)
    ng = Collocation(cartan.Problem(rod, grid, rod.initial_state(grid, "loop")))
    assert ng.compiled_operators().accumulates == ("lie_verlet_loop", "euler_loop", "rkmk_loop", "implicit_loop")
    assert ng.compiled_operators().accepts(cartan.accumulators.start(ng, ng.initial_state()))
    no_clocks = cartan.medium("relativistic-rod")
    assert no_clocks.point_kernels().accumulator_rate is None
    assert Collocation(cartan.Problem(no_clocks, grid, no_clocks.initial_state(grid, "loop"))).compiled_operators(
    ).accumulates == ()


def test_nambu_goto_rate_kernel_is_accumulator_rates_bit_for_bit():
    """The compiled rate at 500 velocities y_N (timelike, lightlike and spacelike: the clipped rate 0
    included) is the numpy ``accumulator_rates`` bit for bit, and that is √(−⟨Λy, Λy⟩)/c with the
    node's Lorentz frame Λ to round-off (a boost and a rotation: 1e-13 of the rate scale, the
    round-off of the products with a boost of γ ≈ 1.7)."""
    rod = cartan.medium("relativistic-rod", clocks=True, c=1.3)
    kernels = rod.point_kernels()
    rng = np.random.default_rng(3)
    N = rng.uniform(-1.0, 1.0, (500, 10))
    N[:, 0] = 1.3 * rng.uniform(0.5, 1.5, 500)
    ref = rod.accumulator_rates(None, None, N, None)["proper_time"]
    out, got = np.empty(1), np.empty(500)
    for i in range(500):
        kernels.accumulator_rate(N[i], kernels.params, out)
        got[i] = out[0]
    assert np.array_equal(got, ref) and np.any(ref == 0.0) and np.any(ref > 0.5)
    b, a = 0.8, 0.7  # a boost along x and a rotation about z: Λ ∈ SO(1, 3)
    g = 1.0 / math.sqrt(1.0 - b * b)
    boost = np.array([[g, g * b, 0, 0], [g * b, g, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
    rot = np.eye(4)
    rot[1:3, 1:3] = [[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]
    rdot = N[:, :4] @ (rot @ boost).T
    minus = rdot[:, 0] ** 2 - np.sum(rdot[:, 1:] ** 2, axis=1)
    framed = np.sqrt(np.maximum(minus, 0.0)) / rod.c
    timelike = minus > 1e-6
    assert np.abs(framed - ref)[timelike].max() <= 1e-13 * ref.max()


# ---------------------------------------------------------------------------- slow: compiled loops
@pytest.mark.slow
@pytest.mark.parametrize("kind", ["clamped", "ring"])
@pytest.mark.parametrize("name", ["rkmk4", "lie-euler"])
def test_compiled_collocation_run_with_clocks_is_the_numpy_run(generated_runs, name, kind):
    kw = dict(integrator=name, scheme="collocation", dt=0.01, t_end=0.2, save_every=5, progress=False)
    assert_clock_run_is_the_numpy_run(_problem(kind), kind, generated_runs, kw)


@pytest.mark.slow
def test_compiled_collocation_run_with_clocks_restarts_bit_for_bit(tmp_path, generated_runs):
    """8 steps in one block, and 4 steps then continued from the checkpoint: the state and the
    accumulated proper time agree bit for bit, every block in the generated loop."""
    assert_clock_restart_is_exact(tmp_path, generated_runs, integrator="rkmk4", scheme="collocation", dt=0.02,
                                  progress=False)


@pytest.mark.slow
def test_collocation_lie_verlet_loop_integrates_accumulators(generated_runs):
    """The plain (uncoupled) collocation set in the loop of ``lie-verlet``: the Nambu–Goto string
    with a test accumulator of the node's velocity alone (``test_accumulators_compiled._Timed``);
    the compiled run is the numpy run to 1e-12 of each field's scale (round-off)."""
    med = _Timed()
    grid = cartan.Grid(16, length=2 * math.pi, periodic=True)
    problem = cartan.Problem(med, grid, med.initial_state(grid, "loop"))
    ops = Collocation(problem).compiled_operators()
    assert ops.accumulates == ("lie_verlet_loop", "euler_loop", "rkmk_loop", "implicit_loop")
    calls = generated_runs
    kw = dict(integrator="lie-verlet", scheme="collocation", dt=grid.spacing[0] / 4, t_end=0.5, save_every=4,
              progress=False)
    compiled = cartan.simulate(problem, **kw)
    assert calls and all(calls)
    reference = cartan.simulate(problem, compiled=False, **kw)
    _same(compiled, reference, ("S", "frame", "speed", "kinetic_energy", "potential_energy", "energy"))
    assert np.all(np.diff(reference["speed"].values[:, 0]) > 0.1)  # (it accumulates: |N_{0:4}|² ≥ c²)


@pytest.mark.slow
@pytest.mark.parametrize("scheme", [Lattice, Collocation])
def test_nambu_goto_clocks_run_compiled_through_the_collapse(generated_runs, scheme):
    """The collapsing Nambu–Goto loop (32 nodes, ``lie-verlet``, Δt = h/2, to t = π: through the
    collapse at t = π/2, where every point moves at c and the rate is 0): the compiled run is the
    numpy run to 1e-12 of each field's scale (round-off; measured ≤ 4.4e-15 with 128 nodes on the
    lattice), every block in the generated loop, and τ is R₀ sin(ct/R₀) to the discretisation
    error before the collapse (≤ 3e-3 at 32 nodes, tests/test_relativistic_clocks.py)."""
    rod = cartan.medium("relativistic-rod", clocks=True)
    grid = cartan.Grid(32, length=2 * math.pi, periodic=True)
    problem = cartan.Problem(rod, grid, rod.initial_state(grid, "loop"))
    assert scheme(problem).compiled_operators().accumulates[0] == "lie_verlet_loop"
    calls = generated_runs
    name = "lattice" if scheme is Lattice else "collocation"
    kw = dict(integrator="lie-verlet", scheme=name, dt=grid.spacing[0] / 2, t_end=math.pi, save_every=8,
              progress=False)
    compiled = cartan.simulate(problem, **kw)
    assert calls and all(calls)
    reference = cartan.simulate(problem, compiled=False, **kw)
    _same(compiled, reference, ("S", "frame", "proper_time", "kinetic_energy", "potential_energy", "energy"))
    tau, t = reference["proper_time"].values, reference.time.values
    before = t <= 1.2
    assert np.abs(tau[before] - np.sin(t[before])[:, None]).max() < 3e-3
