"""Per-node accumulators in the generated loops (cartan/accumulators.py; docs/design.md,
"Per-node accumulators"; docs/media/relativistic-rod.md §3–§4): the elastic relativistic string
with clocks (the accumulator ``proper_time``, rate √(1 − |v⃗|²/c²) from the node's velocity)
integrated by the trapezoidal rule inside the loops of ``rkmk4`` and ``lie-euler``.

Fast: the declarations (the rate kernel, the operator set's loops that take the accumulators,
a medium without a rate kernel — the Nambu–Goto string without clocks — taking none) and the
rate kernel against ``accumulator_rates`` bit for bit.  Slow (they
compile the coupled string's loops, ≈ 60 s and 10 s on a fresh cache; and the Nambu–Goto
string's ``lie-verlet`` loop with a test accumulator, ≈ 45 s): the compiled run against the numpy
run — the same formulas in the same floating-point order (the rate, the trapezoidal update
``a + ½Δt (r₀ + r₁)`` of ``cartan.accumulators.add``), so every saved field, ``proper_time``
included, agrees to 1e-12 of its scale (round-off of 20 steps; measured: bit for bit) — the spy
that the loops took the steps, and a restart from the checkpoint bit for bit.  The same for
``implicit-midpoint``'s Newton blocks (``implicit_loop``; lattice and collocation, ≈ 60–150 s each
to compile), whose states agree with the numpy run's to the round-off of the Newton tolerance.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from cartan_relativistic.string import RelativisticRod
from numba import njit
from toys import elastic_string

import cartan
from cartan.integrators.explicit import RKMK4, LieEuler
from cartan.medium import MediumKernels
from cartan.schemes.lattice import Lattice

pytestmark = pytest.mark.filterwarnings("ignore::cartan.StabilityWarning")


def _problem(kind: str, clocks: bool = True, n: int = 9):
    """The elastic string (quadratic law, k = 0.25): ``clamped`` or ``ring`` (:func:`toys.elastic_string`)."""
    return elastic_string(kind, n, clocks=clocks)


# ---------------------------------------------------------------------------- declarations
def test_operator_set_takes_the_clocks_of_the_elastic_string():
    """With clocks the coupled set integrates the accumulators in its loops and accepts a state
    that carries them; without clocks it takes none; the Nambu–Goto string's clocks (a Lorentz
    invariant of the velocity, its rate kernel given with ``clocks=True`` only) run in every loop
    of its plain set."""
    scheme = Lattice(_problem("clamped"))
    ops = scheme.compiled_operators()
    assert ops.accumulates == ("euler_loop", "rkmk_loop", "implicit_loop") and set(ops.accumulates) <= set(ops.loops)
    assert "ACCUMULATES_" in ops.late[-1].constants  # (implicit_loop computes the velocities the rates need)
    state = cartan.accumulators.start(scheme, scheme.initial_state())
    assert "accumulator_proper_time" in state.arrays and ops.accepts(state)
    plain = Lattice(_problem("clamped", clocks=False)).compiled_operators()
    assert plain.accumulates == () and plain.data.acc.shape == (0, 9)
    rod = cartan.medium("relativistic-rod", clocks=True)
    grid = cartan.Grid(8, length=2 * math.pi, periodic=True)
    ng = Lattice(cartan.Problem(rod, grid, rod.initial_state(grid, "loop")))
    assert ng.compiled_operators().accumulates == ("lie_verlet_loop", "euler_loop", "rkmk_loop", "implicit_loop")
    assert ng.compiled_operators().accepts(cartan.accumulators.start(ng, ng.initial_state()))
    assert cartan.medium("relativistic-rod").point_kernels().accumulator_rate is None


def test_rate_kernel_is_accumulator_rates_bit_for_bit():
    """The compiled rate at 500 velocities (|v⃗| up to 1.3c: the clipped rate 0 included) is the
    numpy ``accumulator_rates`` bit for bit (the same operations in the same order)."""
    rod = cartan.medium("relativistic-rod", energy="elastic", stiffness=0.25, c=1.3)
    kernels = rod.point_kernels()
    rng = np.random.default_rng(7)
    N = np.zeros((500, 10))
    N[:, 0] = 1.3
    N[:, 1:4] = rng.uniform(-1.0, 1.0, (500, 3))
    ref = rod.accumulator_rates(None, None, N, None)["proper_time"]
    out, got = np.empty(1), np.empty(500)
    for i in range(500):
        kernels.accumulator_rate(N[i], kernels.params, out)
        got[i] = out[0]
    assert np.array_equal(got, ref) and np.any(ref == 0.0) and np.any(ref > 0.5)


# ---------------------------------------------------------------------------- slow: compiled loops
def _same(a, b, keys=None):
    """Every saved field (or those of ``keys``) of two runs agrees to 1e-12 of its scale
    (round-off; see the module)."""
    assert a.sizes["time"] == b.sizes["time"]
    for key in keys or b.data_vars:
        x, y = a[key].values, b[key].values
        assert np.abs(x - y).max() <= 1e-12 * max(np.abs(y).max(), 1e-300), key


def assert_clock_run_is_the_numpy_run(problem, kind: str, calls: list, kw: dict, keys=None):
    """``simulate(problem, **kw)`` runs every block in the generated loop (``calls``) and equals the
    numpy run (:func:`_same`: every saved field, or those of ``keys``); the moving clocks lag the
    lab time and a clamped end's is τ = t exactly.  Returns the compiled run."""
    compiled = cartan.simulate(problem, **kw)
    assert calls and all(calls)  # every block ran in the generated loop
    calls.clear()
    reference = cartan.simulate(problem, compiled=False, **kw)
    assert not calls
    _same(compiled, reference, keys)
    tau, t = reference["proper_time"].values, reference.time.values
    moving = slice(1, None) if kind == "clamped" else slice(None)
    assert np.all(tau[-1, moving] < t[-1] - 1e-4)  # (the moving clocks lag the lab time)
    if kind == "clamped":  # the clamped end is at rest in the lab: τ = t exactly, on both paths
        assert np.array_equal(compiled["proper_time"].values[:, 0], t)
    return compiled


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["clamped", "ring"])
@pytest.mark.parametrize(("name", "cls"), [("rkmk4", RKMK4), ("lie-euler", LieEuler)])
def test_compiled_run_with_clocks_is_the_numpy_run(generated_runs, name, cls, kind):
    kw = dict(integrator=name, dt=0.01, t_end=0.2, save_every=5, progress=False)
    compiled = assert_clock_run_is_the_numpy_run(_problem(kind), kind, generated_runs, kw)
    # the state is that of the run without clocks (numpy path; to round-off as above)
    plain = cartan.simulate(_problem(kind, clocks=False), compiled=False, **kw)
    for key in ("S", "frame", "kinetic_energy", "potential_energy"):
        x, y = compiled[key].values, plain[key].values
        assert np.abs(x - y).max() <= 1e-12 * np.abs(y).max(), key


@pytest.mark.slow
def test_compiled_run_with_clocks_restarts_bit_for_bit(tmp_path, generated_runs):
    """8 steps in one block, and 4 steps then continued from the checkpoint (the rates computed
    afresh from the state there, as the loop kept them): the state and the accumulated proper time
    agree bit for bit, every block in the generated loop."""
    assert_clock_restart_is_exact(tmp_path, generated_runs, integrator="rkmk4", dt=0.02, progress=False)


def assert_clock_restart_is_exact(tmp_path, calls: list, whole_every: int = 8, **kw) -> None:
    """The ring run to t = 0.16 in one block (``whole_every`` steps a save) equals the run to 0.08
    continued from its checkpoint, bit for bit in the proper time, S and the frames; every block in
    the generated loop."""
    whole = cartan.simulate(_problem("ring"), t_end=0.16, save_every=whole_every, **kw)
    cartan.simulate(_problem("ring"), t_end=0.08, save_every=4, output=tmp_path / "part.nc", **kw)
    cont = cartan.simulate(_problem("ring"), restart=tmp_path / "part.nc", t_end=0.16, save_every=4,
                           output=tmp_path / "cont.nc", **kw)
    assert calls and all(calls)
    for key in ("proper_time", "S", "frame"):
        assert np.array_equal(cont[key].values[-1], whole[key].values[-1]), key
    assert np.all(cont["proper_time"].values[-1] < 0.16 - 1e-3)


@njit(cache=True)
def _speed_rate(N, p, out):  # pragma: no cover - compiled
    """The test accumulator's rate |N_{0:4}|² (in the order of ``_Timed.accumulator_rates``)."""
    out[0] = N[0] * N[0] + N[1] * N[1] + N[2] * N[2] + N[3] * N[3]


class _Timed(RelativisticRod):
    """The Nambu–Goto string with an accumulator whose rate is a function of the node's velocity
    alone, ∫ |N_{0:4}|² dt, and its rate kernel: the ``lie-verlet`` loop integrates it."""

    def accumulators(self):
        return {"speed": ("∫ |N_{0:4}|² dt", "1")}

    def accumulator_rates(self, q, X, N, grid):
        n = np.asarray(N, dtype=float)
        return {"speed": ((n[..., 0] * n[..., 0] + n[..., 1] * n[..., 1]) + n[..., 2] * n[..., 2])
                + n[..., 3] * n[..., 3]}

    def point_kernels(self):
        base = super().point_kernels()
        return MediumKernels(base.energy, base.stress, base.params, accumulator_rate=_speed_rate)


@pytest.mark.slow
def test_lie_verlet_loop_integrates_accumulators(generated_runs):
    """The loop of ``lie-verlet`` (a medium without coupled Lagrangian, the plain operator set):
    the compiled run is the numpy run to round-off (the loop and the numpy step agree to round-off
    on the state; the accumulator's rate and update are the same operations): the state, the
    energies and the accumulator to 1e-12 of their scale (the integrability residual, itself
    round-off, is left out)."""
    med = _Timed()
    grid = cartan.Grid(16, length=2 * math.pi, periodic=True)
    problem = cartan.Problem(med, grid, med.initial_state(grid, "loop"))
    loops = ("lie_verlet_loop", "euler_loop", "rkmk_loop", "implicit_loop")
    assert Lattice(problem).compiled_operators().accumulates == loops
    calls = generated_runs
    kw = dict(integrator="lie-verlet", dt=grid.spacing[0] / 2, t_end=0.5, save_every=4, progress=False)
    compiled = cartan.simulate(problem, **kw)
    assert calls and all(calls)
    reference = cartan.simulate(problem, compiled=False, **kw)
    _same(compiled, reference, ("S", "frame", "speed", "kinetic_energy", "potential_energy", "energy"))
    assert np.all(np.diff(reference["speed"].values[:, 0]) > 0.1)  # (it accumulates: |N_{0:4}|² ≥ c²)


# ---------------------------------------------------------------------------- slow: implicit-midpoint
@pytest.fixture
def implicit_blocks(monkeypatch) -> list:
    """What ``ImplicitMidpoint.compiled_advance`` returned, call by call (True: its Newton blocks,
    ``implicit_loop``, took the steps)."""
    from conftest import record_returns

    from cartan.integrators import ImplicitMidpoint

    return record_returns(monkeypatch, ImplicitMidpoint, "compiled_advance")


#: the fields compared between the compiled and the numpy implicit-midpoint runs (those of scale ≫ round-off)
_IMPLICIT_KEYS = ("X", "N", "S", "position", "frame", "kinetic_energy", "potential_energy", "energy",
                  "total_momentum", "angular_momentum_z", "lorentz_factor", "stretch", "tension", "proper_time")


@pytest.mark.slow  # (the coupled sets' Newton loops with clocks compile on first use: 60–120 s each)
@pytest.mark.parametrize(("scheme", "kind"), [("lattice", "ring"), ("lattice", "clamped"), ("collocation", "ring")])
def test_implicit_midpoint_with_clocks_is_the_numpy_run(implicit_blocks, scheme, kind):
    """``implicit-midpoint``'s Newton blocks integrate the clocks (the rates at the start and the end
    of each step, the update of ``cartan.accumulators.add``): every block compiled, every field,
    ``proper_time`` included, the numpy run's to 1e-12 of its scale — both paths converge Newton's
    method to the same iterations and invert the Legendre map to 1e-14 of the velocity scale
    (tests/test_coupled_compiled_implicit.py), and the rates and the update are the same operations —
    and the state the run's without clocks to 1e-12 (the clocks do not act on the motion).  The
    fields whose values are themselves round-off on the ring (≈ 1e-16–1e-25: the residuals, the
    momentum along x, y, z, J_x, J_y, lab z) are left out (:data:`_IMPLICIT_KEYS`)."""
    kw = dict(integrator="implicit-midpoint", scheme=scheme, dt=0.01, t_end=0.2, save_every=5, progress=False)
    compiled = assert_clock_run_is_the_numpy_run(_problem(kind), kind, implicit_blocks, kw, keys=_IMPLICIT_KEYS)
    plain = cartan.simulate(_problem(kind, clocks=False), compiled=False, **kw)
    for key in ("S", "frame", "kinetic_energy", "potential_energy"):
        x, y = compiled[key].values, plain[key].values
        assert np.abs(x - y).max() <= 1e-12 * np.abs(y).max(), key


@pytest.mark.slow
@pytest.mark.parametrize("scheme", ["lattice", "collocation"])
def test_implicit_midpoint_with_clocks_restarts_bit_for_bit(tmp_path, implicit_blocks, scheme):
    """4 steps a save in one run, and the same run stopped after 4 steps and continued from its
    checkpoint (the Newton blocks forget the kept Jacobian at every save, ``begin_block``; the rates
    computed afresh from the state there): the state and the proper time bit for bit."""
    assert_clock_restart_is_exact(tmp_path, implicit_blocks, whole_every=4, integrator="implicit-midpoint",
                                  scheme=scheme, dt=0.02, progress=False)
