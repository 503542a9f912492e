"""Static equilibria by Newton's method on the group (cartan.solve_static)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from cartan_verification.references import ELASTICA_TABLE as ELASTICA
from cartan_verification.references import timoshenko_linear_tip

import cartan
from cartan.statics import ConvergenceError, solve_static

# Timoshenko cantilever (VERIFICATION.md §4): L = 3, r = 0.25, E = 1e6, G = 1e4, α_c = 27/28
L, RADIUS, E, G, F = 3.0, 0.25, 1e6, 1e4, 15.0
ALPHA_C = 27.0 / 28.0


def _cantilever(rod, n, length, load):
    grid = cartan.Grid(n, length=length)
    return cartan.Problem(
        rod,
        grid,
        rod.initial_state(grid, "straight"),
        {"start": cartan.Clamped(), "end": cartan.Free(load=load)},
    )


def _timoshenko(n):
    rod = cartan.medium("cosserat-rod", E=E, G=G, radius=RADIUS, density=5000.0, shear_coefficient=ALPHA_C)
    # the rod lies along e₁ = x; the dead tip force points along −z
    return solve_static(_cantilever(rod, n, L, [0.0, 0.0, -F, 0.0, 0.0, 0.0]))


def _elastica(alpha, n=101, stiff=1e6, load_steps=4, **kw):
    rod = cartan.medium(
        "cosserat-rod", stretch_shear=[stiff] * 3, bend_twist=[1.0, 1.0, 1.0], mass=1.0, rotational_inertia=[1.0] * 3
    )
    return solve_static(_cantilever(rod, n, 1.0, [0.0, 0.0, -alpha, 0.0, 0.0, 0.0]), load_steps=load_steps, **kw)


def test_timoshenko_cantilever_second_order_and_linear_theory():
    """Tip deflections at 51, 101, 201 nodes: observed order 2.00; the converged deflection is below
    the linear Timoshenko value FL/(α_cGA) + FL³/(3EI) = 0.0677703 by 3.2e-4 relative (the geometric
    nonlinearity; 3.88e-4 at n = 51, 3.39e-4 at 101, 3.27e-4 at 201)."""
    A = math.pi * RADIUS**2
    I = math.pi * RADIUS**4 / 4.0
    w_lin = timoshenko_linear_tip(L, F, E * I, ALPHA_C * G * A)
    tips = []
    for n in (51, 101, 201):
        ds = _timoshenko(n)
        x = ds["position"].isel(time=0, node=-1).values
        tips.append(-float(x[2]))
        assert ds.attrs["newton_iterations"] <= 10
    order = math.log2((tips[0] - tips[1]) / (tips[1] - tips[2]))
    assert 1.8 <= order <= 2.3, (tips, order)
    rich = tips[2] + (tips[2] - tips[1]) / 3.0
    rel = (rich - w_lin) / w_lin
    assert -4e-4 < rel < -2.5e-4, (tips, rich, w_lin, rel)


@pytest.mark.parametrize(
    ("alpha", "stiff", "steps"),
    [(1.0, 1e6, 4), (2.0, 1e6, 4), (10.0, 1e5, 10)],
)
def test_cantilever_elastica_tip(alpha, stiff, steps):
    """Inextensible, unshearable limit (stretch and shear stiffness 1e6 or 1e5 × B/L²), load stepping
    from the straight rod, n = 101.  Measured errors against the tabulated elastica: vertical
    −4.9e-6, −9.8e-6, 8.2e-5 and shortening 1.2e-6, −2.9e-6, −1.4e-5 for PL²/B = 1, 2, 10 (the
    10 case is dominated by the finite stretch stiffness, P/(EA) = 1e-4)."""
    ds = _elastica(alpha, stiff=stiff, load_steps=steps)
    x = ds["position"].isel(time=0, node=-1).values
    vertical, shortening = -float(x[2]), 1.0 - float(x[0])
    ref_v, ref_s = ELASTICA[alpha]
    assert abs(vertical - ref_v) < 1e-3, (vertical, ref_v)
    assert abs(shortening - ref_s) < 1e-3, (shortening, ref_s)
    assert ds["load_factor"].values[-1] == 1.0


def test_newton_converges_quadratically():
    """Above the round-off floor the residual falls as r_{k+1} ≤ C r_k² (history in the message).

    The elastica at PL²/B = 1 with EA = 1e4·B/L² in one load step: measured history 1.0, 68.4,
    0.917, 1.82e-4, 2.3e-11 (the 68.4 is the stretch force of the first step's chord error, which
    the mixed iteration ignores); r_(k+1)/r_k² = 2.0e-4 and 2.2e-4 on the last two pairs, in units of
    1/P with P = 1.  The bound C < 1e-2 is that of a Newton iteration in its basin (a linearly
    converging one has r_(k+1)/r_k² → ∞); the last contraction 1.3e-7 is far below 1e-2."""
    ds = _elastica(1.0, stiff=1e4, load_steps=1)
    hist = ds["newton_residual"].values
    floor = 1e-8 * hist[0]
    pairs = [(a, b) for a, b in zip(hist[:-1], hist[1:], strict=True) if b > floor]
    ratios = [b / a**2 for a, b in pairs[-2:]]
    msg = f"residual history {np.array2string(hist, precision=3)}; r_(k+1)/r_k² = {ratios}"
    assert len(pairs) >= 2, msg
    assert all(r < 1e-2 for r in ratios), msg
    assert pairs[-1][1] / pairs[-1][0] < 1e-2, msg
    assert hist[-1] < 1e-9 * max(hist), msg


def test_dataset_layout():
    ds = _timoshenko(21)
    assert ds.sizes["time"] == 1
    for name in ("position", "frame", "X", "potential_energy", "newton_residual", "load_factor"):
        assert name in ds, name
    assert ds.attrs["newton_iterations"] == ds.sizes["newton_step"]
    # the clamped end stays put and the frames stay in SO(3)
    assert np.allclose(ds["position"].isel(time=0, node=0).values, 0.0)
    R = ds["frame"].isel(time=0).values
    assert np.allclose(np.einsum("nji,njk->nik", R, R), np.eye(3), atol=1e-12)
    # seeding from a previous equilibrium converges at once
    again = solve_static(_cantilever(
        cartan.medium("cosserat-rod", E=E, G=G, radius=RADIUS, density=5000.0), 21, L, [0, 0, -F, 0, 0, 0]
    ), initial=ds)
    assert again.attrs["newton_iterations"] <= 1


@pytest.mark.parametrize("follower", [False, True])
def test_free_rod_under_unbalanced_load_raises(follower):
    rod = cartan.medium("cosserat-rod", E=E, G=G, radius=RADIUS, density=5000.0)
    grid = cartan.Grid(50, length=L)
    prob = cartan.Problem(
        rod,
        grid,
        rod.initial_state(grid, "straight"),
        {"end": cartan.Free(load=[0, 0, -F, 0, 0, 0], follower=follower)},
    )
    # the rigid motions the supports leave free are found on the first Jacobian, before any Newton
    # step, and the load has power along them (cartan.rigid_modes)
    with pytest.raises(ValueError, match=r"leave the rigid motion\(s\) translation along .* free and the external "
                                         r"loads have power along"):
        solve_static(prob)


def test_iteration_limit_is_reported():
    with pytest.raises(ConvergenceError, match="max_iter = 1"):
        _elastica(2.0, stiff=1e4, load_steps=1, max_iter=1)


def test_options_are_validated():
    rod = cartan.medium("cosserat-rod", E=E, G=G, radius=RADIUS, density=5000.0)
    prob = _cantilever(rod, 11, L, [0, 0, -F, 0, 0, 0])
    with pytest.raises(ValueError, match="lattice"):
        solve_static(prob, scheme="collocation")
    for bad in ("exact", "FD", None):
        with pytest.raises(ValueError, match="jacobian must be one of 'auto', 'analytic', 'fd'"):
            solve_static(prob, jacobian=bad)
    with pytest.raises(ValueError, match="load_steps"):
        solve_static(prob, load_steps=0)


# ---------------------------------------------------------------- analytic Jacobians (Medium.static_jacobian)
def _chain_at(theta, periodic=False, **kw):
    """The torsion-chain problem (tests/toys.py) with node angles ``theta``."""
    from toys import chain_problem

    prob = chain_problem(n=len(theta), periodic=periodic, **kw)
    Phi = prob.medium.group.exp(np.asarray(theta)[:, None])
    return cartan.Problem(prob.medium, prob.grid, cartan.InitialState(Phi=Phi), prob.boundaries, prob.loads)


def _both_jacobians(problem, fd_step=1e-6):
    """(analytic, finite-difference) Jacobians of solve_static's residual at problem.initial, on the unknowns."""
    from cartan.schemes.lattice import Lattice
    from cartan.statics import _analytic_jacobian, _coloured_jacobian, _colouring, _stencil_pairs

    sch = Lattice(problem, track_frames=True)
    state = sch.initial_state()
    state.S[...] = 0.0
    shape, r = sch.grid.shape, sch.group.dim
    nnode = int(np.prod(shape))
    unknown = np.broadcast_to(sch.live, (*shape, r)).copy()
    unknown[sch._clamped] = False
    unknown = unknown.reshape(nnode, r)
    index = -np.ones((nnode, r), dtype=np.int64)
    index[unknown] = np.arange(int(unknown.sum()))
    w = sch.weights[..., None]

    def displaced(direction, eps):
        trial = state.copy()
        sch.drift(trial, eps, direction)
        res = sch.force(trial, np.zeros((*shape, r)), trial.t) * w
        res[~unknown.reshape(*shape, r)] = 0.0
        return res

    periodic = tuple(sch.grid.periodic)
    fd = _coloured_jacobian(displaced, _colouring(shape, periodic), *_stencil_pairs(shape, periodic), unknown, index,
                            shape, fd_step)
    exact = _analytic_jacobian(problem.medium, sch, state, 1.0, np.flatnonzero(unknown.ravel()), nnode * r)
    return exact.toarray(), fd.toarray()


@pytest.mark.parametrize("periodic", [False, True])
def test_analytic_jacobian_matches_finite_differences(periodic):
    """The torsion chain's Laplacian Jacobian (k_e = U''(X_e)/h) against coloured central differences with
    step ε = 1e-6, at a non-uniform configuration (strains far from rest: the diagonal varies ~20× along the
    chain).  Expected difference, relative to max|J|: truncation (ε²/6)·|∂³r/∂δ³| = ε²·(2β/h³) ≈ 13ε²
    (8e4 against max|J| ≈ 6e3; the ε² law is observed: 1.23e-5 at ε = 1e-3, 1.23e-7 at 1e-4) = 1.3e-11,
    plus round-off ε_mach·|r|/(ε·max|J|) ≈ 1e-11; measured 2.2e-11 (open chain, clamped start, end moment,
    body torque) and 4.3e-11 (periodic).  The bound 1e-9 keeps a margin for the round-off's scatter."""
    n, length = 40, 2.0
    u = np.arange(n) * length / n
    rng = np.random.default_rng(7)
    theta = 0.9 * u**2 + 0.02 * rng.standard_normal(n)
    if periodic:
        theta = 0.4 * np.sin(2 * np.pi * u / length) + 0.02 * rng.standard_normal(n)
        prob = _chain_at(theta, periodic=True, length=length, stiffness=2.0, cubic=5.0, rest=0.3)
    else:
        prob = _chain_at(theta, length=length, stiffness=2.0, cubic=5.0, rest=0.3,
                         boundaries={"start": cartan.Clamped(), "end": cartan.Free(load=[1.5])},
                         loads=[cartan.UniformForce([0.7])])
    exact, fd = _both_jacobians(prob)
    assert exact.shape == fd.shape == ((n, n) if periodic else (n - 1, n - 1))
    scale = float(np.max(np.abs(exact)))
    diag = -np.diag(exact)
    assert np.min(diag) > 0 and np.max(diag) / np.min(diag) > 10.0  # the stiffness varies along the chain
    err = float(np.max(np.abs(exact - fd))) / scale
    assert err < 1e-9, err


def test_analytic_and_fd_newton_reach_the_same_equilibrium():
    """A clamped stiffening chain under an end moment M: every edge carries Q = CD + βD³ = M, so the lattice
    equilibrium is the uniform strain X = X0 + D* exactly (D* the real root of the cubic).  Both Jacobians
    converge to it to round-off in the same number of Newton iterations; "auto" picks the analytic one."""
    from toys import chain_problem

    M, C, beta, X0 = 3.0, 2.0, 5.0, 0.3
    roots = np.roots([beta, 0.0, C, -M])
    d_star = float(roots[np.abs(roots.imag) < 1e-12].real[0])

    def solve(jacobian):
        prob = chain_problem(n=41, length=2.0, stiffness=C, cubic=beta, rest=X0,
                             boundaries={"start": cartan.Clamped(), "end": cartan.Free(load=[M])})
        return solve_static(prob, jacobian=jacobian)

    runs = {jac: solve(jac) for jac in ("fd", "analytic", "auto")}
    assert runs["fd"].attrs["newton_jacobian"] == "fd"
    assert runs["analytic"].attrs["newton_jacobian"] == "analytic"
    assert runs["auto"].attrs["newton_jacobian"] == "analytic"
    for ds in runs.values():
        X = ds["X"].isel(time=0).values[:, 0]
        assert np.max(np.abs(X - (X0 + d_star))) < 1e-12, (X[:3], X0 + d_star)
    its = {jac: ds.attrs["newton_iterations"] for jac, ds in runs.items()}
    assert its["fd"] == its["analytic"] == its["auto"] >= 3, its


class _AngleSpring(cartan.problem.Load):
    """A torque −κθ pulling every node back to θ = 0: a configuration-dependent load the chain's
    analytic Jacobian does not cover."""

    needs_structure_field = True

    def __init__(self, kappa):
        self.kappa = kappa

    def bind(self, medium):
        self._group = medium.group

    def force(self, Phi, N, t):
        return -self.kappa * self._group.log(Phi)


def test_analytic_jacobian_unavailable():
    """"auto" falls back to finite differences where the medium has no analytic Jacobian (a Cosserat rod, or
    the chain under a load it does not cover); "analytic" is then a ValueError naming the parameter."""
    from toys import chain_problem

    rod = cartan.medium("cosserat-rod", E=E, G=G, radius=RADIUS, density=5000.0)
    prob = _cantilever(rod, 11, L, [0, 0, -F, 0, 0, 0])
    assert solve_static(prob).attrs["newton_jacobian"] == "fd"
    with pytest.raises(ValueError, match="jacobian='analytic'.*cosserat-rod"):
        solve_static(prob, jacobian="analytic")
    chain = chain_problem(n=21, boundaries={"start": cartan.Clamped(), "end": cartan.Free(load=[1.0])},
                          loads=[_AngleSpring(0.5)])
    assert solve_static(chain).attrs["newton_jacobian"] == "fd"
    with pytest.raises(ValueError, match="jacobian='analytic'.*toy-torsion-chain"):
        solve_static(chain, jacobian="analytic")


def test_analytic_jacobian_of_the_wrong_shape_is_rejected(monkeypatch):
    from toys import TorsionChain, chain_problem

    monkeypatch.setattr(TorsionChain, "static_jacobian", lambda self, scheme, state, lam: np.eye(3))
    prob = chain_problem(n=21, boundaries={"start": cartan.Clamped(), "end": cartan.Free(load=[1.0])})
    with pytest.raises(ValueError, match=r"jacobian: TorsionChain.static_jacobian must return a \(21, 21\)"):
        solve_static(prob, jacobian="auto")


class _Foundation(cartan.problem.Load):
    """An elastic foundation: a force −k(x − x̄) and a moment −k·axial(R) on every node (the
    initial frames are the identity), a support (``scaled`` False)."""

    needs_structure_field = True
    scaled = False

    def __init__(self, group, k: float, x0: np.ndarray):
        self.group, self.k, self.x0 = group, float(k), np.asarray(x0, dtype=float)

    def force(self, Phi, N, t):
        R = Phi[..., 1:, 1:]  # the initial frames are the identity: the rotation vector of R, to first order
        turn = 0.5 * np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                               R[..., 1, 0] - R[..., 0, 1]], -1)
        P = np.concatenate([-self.k * (Phi[..., 1:, 0] - self.x0), -self.k * turn], axis=-1)
        return np.stack([cartan.problem.dead_to_body(self.group, F, p) for F, p in zip(Phi, P, strict=True)])


def _rod_on_foundation(n: int = 11, k: float = 50.0):
    rod = cartan.medium("cosserat-rod", stretch_shear=[1e3] * 3, bend_twist=[1.0] * 3, mass=1.0,
                        rotational_inertia=[1.0] * 3)
    grid = cartan.Grid(n, length=1.0)
    init = rod.initial_state(grid, "straight")
    x0 = init.Phi[:, 1:, 0].copy()
    return cartan.Problem(rod, grid, init, {"end": cartan.Free(load=[0.0, 0.0, -1.0, 0.0, 0.0, 0.0])},
                          loads=[_Foundation(rod.group, k, x0)])


def test_a_support_acts_at_every_load_level():
    """A free rod held only by an elastic foundation (a load with ``scaled`` False): at λ = 0
    the residual of a displaced state holds the foundation's restoring force (the λ-scaled
    part is the end load only), so continuation starts from λ = 0 on a regular Jacobian and
    reaches the solve_static equilibrium at λ = 1."""
    from cartan.statics import _Equilibrium

    problem = _rod_on_foundation()
    eq = _Equilibrium(problem)
    state = eq.state0.copy()
    d = np.zeros(eq.m)
    d[:eq.nunk] = 1e-3
    moved = eq.update(state, np.zeros(eq.nmult), d, 1.0)[0]
    internal, total = eq._parts_full(moved)
    held = problem.loads[0].force(eq.sch.frames(moved), eq.zero, 0.0) * eq.w
    np.testing.assert_allclose(internal - eq.sch.internal_force(moved), held, atol=1e-12)
    assert np.max(np.abs(held)) > 1e-3  # the foundation's force is there at λ = 0
    np.testing.assert_allclose(eq.dlam(moved)[: eq.nunk][: 6], (total - internal)[eq.unknown][: 6], atol=1e-12)
    path = cartan.continuation(problem, 1.0, 0.25, detect=False)
    static = solve_static(problem)
    assert float(path["load_factor"][-1]) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(path["position"].values[-1], static["position"].isel(time=0).values, atol=1e-7)
    with pytest.raises(ValueError, match="scaled = False"):
        solve_static(problem, jacobian="analytic")
