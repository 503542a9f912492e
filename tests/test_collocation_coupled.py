"""Media whose Lagrangian couples N and X on the ``collocation`` scheme
(:mod:`cartan.schemes._collocation_coupled`; docs/design.md, "Media whose Lagrangian couples N
and X"; docs/media/relativistic-rod.md §3).

The pointwise discretisation N_i = ∂H/∂S(S_i, X_i), Q_i = ∂H/∂X(S_i, X_i), H_d = Σ w_i H(S_i, X_i):
ℓ = K − U through it is the collocation's own run; the SBP energy identity dH_d/dt = 0 at a
state; the elastic relativistic string's Hamiltonian error under ``implicit-midpoint`` at order 2
in Δt; the momentum map; the agreement with the lattice at order 2 in h; the refusals; the three
elastic scenes from the command line.  Numpy path (the compiled loops of ``rkmk4`` and ``lie-euler``:
tests/test_collocation_coupled_compiled.py).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from cartan_relativistic.string import RelativisticRod
from click.testing import CliRunner

import cartan
from cartan.cli import main
from cartan.integrators.explicit import RKMK4, Overdamped
from cartan.integrators.implicit import ImplicitMidpoint
from cartan.schemes.collocation import Collocation
from cartan.schemes.lattice import Lattice
from cartan.study import observed_order

pytestmark = pytest.mark.filterwarnings("ignore::cartan.StabilityWarning")

SCENES = "plugins/cartan_relativistic/scenes"


def _rod(k: float = 0.25):
    return cartan.medium("relativistic-rod", energy="elastic", stiffness=k)


def _loop(n: int, k: float = 0.1) -> cartan.Problem:
    """A closed string with no symmetry: a wobbly loop, stretched, with a non-uniform velocity."""
    rod = _rod(k)
    grid = cartan.Grid(n, length=2 * math.pi, periodic=True)
    u = grid.coordinates(0)
    x = np.stack([1.2 * np.cos(u) + 0.1 * np.cos(2 * u), 1.1 * np.sin(u), 0.1 * np.sin(3 * u)], -1)
    v = np.stack([0.1 * np.sin(2 * u), 0.25 * np.cos(u) + 0.05, 0.1 * np.cos(u)], -1)
    return cartan.Problem(rod, grid, rod.state_from(x, v))


def _open_string(n: int, clamped: bool) -> cartan.Problem:
    """An open string moving in 3-D (free ends, or clamped at u = 0)."""
    rod = _rod()
    grid = cartan.Grid(n, length=1.0)
    u = grid.coordinates(0)
    x = np.stack([1.1 * u, 0.05 * np.sin(np.pi * u), 0.02 * u * u], -1)
    v = np.stack([0.2 * np.cos(np.pi * u), 0.3 * np.sin(2 * np.pi * u), 0.1 * u], -1)
    if clamped:
        v = v * u[:, None]  # at rest at the clamp
    bounds = {"start": cartan.Clamped()} if clamped else {}
    return cartan.Problem(rod, grid, rod.state_from(x, v), boundaries=bounds)


def _energy(scheme, state) -> float:
    return scheme.kinetic_energy(state) + scheme.potential_energy(state)


class _CoupledNambuGoto(RelativisticRod):
    """The Nambu–Goto string declared as a coupled Lagrangian: the contract's K − U defaults
    (S = MN, Q = ∂U/∂X) through the coupled path."""

    coupled_lagrangian = True


# ---------------------------------------------------------------------------- the discretisation
@pytest.mark.parametrize("derivative", ["fd2", "fd4", "fourier"])
def test_k_minus_u_through_the_coupled_path_is_the_collocation_run(derivative):
    """ℓ = K(N) − U(X) declared coupled: N_i = M⁺S_i, Q_i = ∂U/∂X(X_i), H_d = Σ w (K + U), the
    collocation's own system, so five rkmk4 steps agree with the uncoupled run to round-off."""
    grid = cartan.Grid(16, length=2 * math.pi, periodic=True)
    runs = []
    for med in (RelativisticRod(), _CoupledNambuGoto()):
        scheme = Collocation(cartan.Problem(med, grid, med.initial_state(grid, "loop")), derivative=derivative)
        state = scheme.initial_state()
        assert scheme.coupled_lagrangian is isinstance(med, _CoupledNambuGoto)
        for _ in range(5):
            RKMK4().step(scheme, state, 0.1)
        runs.append((scheme.frames(state), state.S.copy(), scheme.velocity(state), _energy(scheme, state)))
    (Pa, Sa, Na, Ea), (Pb, Sb, Nb, Eb) = runs
    for a, b in ((Pa, Pb), (Sa, Sb), (Na, Nb)):
        assert np.allclose(a, b, rtol=0, atol=1e-13)
    assert abs(Ea - Eb) <= 1e-13 * abs(Ea)


def test_pointwise_legendre_map_hamiltonian_and_range():
    """N_i = velocity_at(S_i, X_i) (clamped node at zero), S₀ its inverse at the initial velocity,
    kinetic + potential = Σ w H(S, X); a superluminal velocity has no momentum (ValueError)."""
    problem = _open_string(9, clamped=True)
    scheme = Collocation(problem)
    state = scheme.initial_state()
    med, X = scheme.medium, state.arrays["X"]
    N = scheme.velocity(state)
    N0 = np.array(problem.initial.N, dtype=float)
    N0[0] = 0.0
    assert np.allclose(N[:, scheme.live], N0[:, scheme.live], rtol=0, atol=1e-12)  # the inverse of S₀ = S(N₀, X₀)
    assert np.array_equal(N[1:], med.velocity_at(state.S, X)[1:]) and not np.any(N[0])
    H = float(np.sum(scheme.weights * med.hamiltonian(state.S, X)))
    assert abs(_energy(scheme, state) - H) <= 1e-14 * abs(H)
    assert np.allclose(scheme.momentum(state, N), state.S, rtol=0, atol=1e-12)
    fast = N.copy()
    fast[4, 1] = 1.5  # |v| > c
    with pytest.raises(ValueError, match="outside the range of the Legendre map"):
        scheme.momentum(state, fast)


@pytest.mark.parametrize(("case", "derivative"), [("loop", "fd2"), ("loop", "fd4"), ("loop", "fourier"),
                                                  ("free", "fd2"), ("free", "fd4"), ("clamped", "fd2")])
def test_semi_discrete_hamiltonian_is_an_invariant(case, derivative):
    """dH_d/dt = Σ w [N·Ṡ + Σ_α Q^α·Ẋ_α] along Ṡ = ad_NᵀS + W, Ẋ = DN − ad_N X is zero at a
    generic state (the SBP identity of the module docstring: D skew on periodic axes, the free
    ends' penalty with P = 0, N = 0 at a clamp): round-off against the terms' size."""
    problem = _loop(16) if case == "loop" else _open_string(12, clamped=case == "clamped")
    scheme = Collocation(problem, derivative=derivative)
    state = scheme.initial_state()
    RKMK4().step(scheme, state, 0.05)  # a generic state, off the initial data
    g, med, X, S = scheme.group, scheme.medium, state.arrays["X"], state.S
    N = scheme.velocity(state)
    W = scheme.force(state, N, state.t)
    Sdot = np.einsum("...ji,...j->...i", g.ad(N), S) + W
    Sdot[..., ~scheme.live] = 0.0
    Sdot[scheme._clamped] = 0.0
    Q = med.stress_with(S, X)
    terms = scheme.weights[:, None] * N * Sdot
    for a, D in enumerate(scheme.D):
        Xdot = D(N, axis=0) - g.bracket(N, X[:, a, :])
        terms = terms + scheme.weights[:, None] * Q[:, a, :] * Xdot
    rate = float(np.sum(terms))
    assert abs(rate) <= 1e-13 * float(np.sum(np.abs(terms)))


# ---------------------------------------------------------------------------- time stepping
def test_implicit_midpoint_hamiltonian_error_is_second_order():
    """The wobbly loop (n = 12) to t = 1 by implicit-midpoint: max |H_d − H_d(0)| falls at order 2
    as Δt halves (measured 9.8e-7, 2.4e-7, 6.1e-8: 2.00, 2.00), and P⃗ (a translation-invariant
    L_d) changes by the Newton residual only (tol 1e-12: ≤ 3e-12 measured)."""
    dts, errs = [0.2, 0.1, 0.05], []
    for dt in dts:
        scheme = Collocation(_loop(12))
        state = scheme.initial_state()
        H0, P0 = _energy(scheme, state), scheme.total_momentum(state)
        integ, err = ImplicitMidpoint(tol=1e-12), 0.0
        for _ in range(round(1.0 / dt)):
            integ.step(scheme, state, dt)
            err = max(err, abs(_energy(scheme, state) - H0))
        errs.append(err)
        assert np.max(np.abs(scheme.total_momentum(state)[1:4] - P0[1:4])) < 1e-10
    assert errs[0] < 1e-5 * abs(H0)
    assert abs(observed_order(dts, errs) - 2.0) < 0.1


def test_momentum_map_on_the_collocation():
    """rkmk4 on the wobbly loop to t = 1: H_d to O(Δt⁴) (≤ 1e-11 measured 1e-12), P⃗ to round-off
    (Σ w D Q = 0 on a periodic axis: the translations' force sums to zero), J⃗ not exactly — the
    nodal strains are not those of the frames (integrability O(h²)), as for ℓ = K − U — but its
    change falls with h at order ≥ 2 (measured 1.0e-3, 1.5e-4 at n = 16, 32: order 2.8), where the
    lattice keeps it to round-off."""
    dJ = []
    for n in (16, 32):
        scheme = Collocation(_loop(n))
        state = scheme.initial_state()
        H0, P0 = _energy(scheme, state), scheme.total_momentum(state)
        for _ in range(50):
            RKMK4().step(scheme, state, 0.02)
        P = scheme.total_momentum(state)
        assert abs(_energy(scheme, state) - H0) < 1e-11
        assert np.max(np.abs(P[1:4] - P0[1:4])) < 1e-14
        dJ.append(float(np.max(np.abs(P[7:10] - P0[7:10]))))
    assert math.log2(dJ[0] / dJ[1]) > 2.0


def _ring(n: int) -> cartan.Problem:
    """The scene relativistic-elastic-ring (k = 0.1, radius 1.3, spinning at 0.4c) with n nodes."""
    rod = _rod(0.1)
    grid = cartan.Grid(n, length=2 * math.pi, periodic=True)
    return cartan.Problem(rod, grid, rod.initial_state(grid, "ring", radius=1.3, spin=0.4 / 1.3))


@pytest.mark.parametrize(("case", "dt"), [("loop", 0.02), ("ring", 0.04)])
def test_agrees_with_the_lattice_at_order_two(case, dt):
    """rkmk4, 50 steps, on both schemes: the lab positions differ by 0.109, 0.028, 0.0070 (the
    wobbly loop, to t = 1) and 0.096, 0.024, 0.0061 (the relativistic-elastic-ring scene, to
    t = 2) at n = 16, 32, 64: both schemes second order in h, observed 1.95, 2.00 and 1.98, 2.00."""
    hs, diffs = [], []
    for n in (16, 32, 64):
        pos = []
        for cls in (Collocation, Lattice):
            scheme = cls(_loop(n) if case == "loop" else _ring(n))
            state = scheme.initial_state()
            for _ in range(50):
                RKMK4().step(scheme, state, dt)
            pos.append(scheme.frames(state)[:, 2:5, 0])
        hs.append(2 * math.pi / n)
        diffs.append(float(np.max(np.abs(pos[0] - pos[1]))))
    assert abs(observed_order(hs, diffs) - 2.0) < 0.15


# ---------------------------------------------------------------------------- refusals, compiled, CLI
def test_refusals_and_the_compiled_loops_decline():
    problem = _open_string(9, clamped=False)
    scheme = Collocation(problem)
    ops = scheme.compiled_operators()  # (tests/test_collocation_coupled_compiled.py)
    assert not ops.ok and ops.loops == ("euler_loop", "rkmk_loop", "implicit_loop") and "coupling N and X" in ops.reason
    state = scheme.initial_state()
    before = state.copy()
    assert Overdamped().run_compiled_loop(scheme, state, 0.01, 3) is False
    assert np.array_equal(state.S, before.S)
    ref = cartan.Problem(problem.medium, problem.grid, problem.initial, reference=problem.initial)
    with pytest.raises(ValueError, match="reference"):
        Collocation(ref)
    held = cartan.Problem(problem.medium, problem.grid, problem.initial, boundaries={"start": cartan.Held([1])})
    with pytest.raises(ValueError, match="Held end"):
        Collocation(held)


@pytest.mark.parametrize("scene", ["ring", "clocks", "ring-rotating"])
def test_elastic_scenes_run_on_the_collocation_from_the_cli(tmp_path, scene):
    """``cartan run <scene> --scheme collocation`` to t = 0.2: recorded as a collocation run, its
    energy (kinetic + potential = H_d) kept to 1e-5 relative (the time error only, the
    semi-discrete H_d being invariant: rkmk4 at Δt = 0.02 measured 1.2e-6 on the clamped string
    released from rest, whose release excites the short waves, 4e-12 on the ring; the lattice's
    is 3.6e-6 at t = 0.4 on the former; implicit-midpoint at Δt = 0.1, the rotating ring: 5e-8),
    and the clamped end's clock at the lab time (τ = t, docs/media/relativistic-rod.md §4)."""
    import netCDF4
    import xarray as xr

    out = tmp_path / "run.nc"
    res = CliRunner().invoke(main, ["run", f"{SCENES}/relativistic-elastic-{scene}.toml", "--scheme", "collocation",
                                    "--t-end", "0.2", "--save-every", "5", "-o", str(out), "--no-progress"])
    assert res.exit_code == 0, res.output
    with netCDF4.Dataset(out) as f:
        assert '"scheme": "collocation"' in f.cartan_config
    with xr.open_dataset(out) as run:
        t = run["time"].values
        E = run["kinetic_energy"].values + run["potential_energy"].values
        assert t[-1] == pytest.approx(0.2) and np.all(np.isfinite(E))
        assert np.max(np.abs(E - E[0])) <= 1e-5 * abs(E[0])
        if scene == "clocks":
            assert np.allclose(run["proper_time"].values[:, 0], t, rtol=0, atol=1e-14)
