"""The closed sphere: a chart glued across its poles (``Grid(glued=...)``) on the lattice.

The ``cosserat-surface`` ``"sphere"`` initial kind charts the sphere by longitude (periodic)
and staggered colatitude glued across the poles (a line of longitude continues over a pole onto
the line half way round, seen in a frame turned by π about the normal).  Checked here: the
grid and glue declarations and their errors; a rigidly moved sphere, poles anywhere, is
strain- and force-free to round-off; the forces are the exact gradient of the energy across
the glued edges; the drift keeps the two stored copies of every glued edge and every plaquette
(those across a pole too) consistent; the compiled paths decline glued problems; the breathing
mode conserves energy and does not see where the poles are; its frequency converges to the
membrane value at order 2, and the rows next to the poles approach the equator's (slow); a
uniform expansion pulls every row alike but the pole rows (their meridional balance: strict xfail).
"""

from __future__ import annotations

import numpy as np
import pytest

import cartan
from cartan.problem import InitialState, Problem
from cartan.schemes.lattice import Lattice

SE3 = cartan.group("SE3")
SO3 = cartan.group("SO3")
TILT = SO3.exp(np.array([0.3, -1.1, 0.7]))  # poles anywhere


def _sphere(N: int = 8, rotation=None, center=None, thickness: float = 0.05, **kw):
    med = cartan.medium("cosserat-surface", E=1.0, poisson=0.3, thickness=thickness, density=1.0)
    grid = cartan.Grid((N, N // 2), (2 * np.pi, np.pi), periodic=(True, False), glued=(None, 0))
    return med, grid, med.initial_state(grid, "sphere", rotation=rotation, center=center, **kw)


# ---------------------------------------------------------------------------- declarations
def test_glued_grid_is_staggered_and_has_n_plus_1_edges():
    grid = cartan.Grid((8, 4), (2 * np.pi, np.pi), periodic=(True, False), glued=(None, 0))
    h = np.pi / 4
    assert grid.spacing[1] == pytest.approx(h)
    np.testing.assert_allclose(grid.coordinates(1), (np.arange(4) + 0.5) * h)
    assert grid.edge_shape(1) == (8, 5) and grid.edge_shape(0) == (8, 4)
    np.testing.assert_allclose(grid.node_weights(), np.full((8, 4), h * 2 * np.pi / 8))
    assert grid.to_dict()["glued"] == [-1, 0]
    assert cartan.Grid((8, 4), periodic=(True, False), glued=[-1, 0]) == grid.__class__((8, 4), periodic=(True, False),
                                                                                        glued=(None, 0))


@pytest.mark.parametrize("kwargs, match", [
    ({"shape": (7, 4), "periodic": (True, False), "glued": (None, 0)}, "even number"),
    ({"shape": (8, 4), "periodic": (False, False), "glued": (None, 0)}, "must be periodic"),
    ({"shape": (8, 4), "periodic": (True, True), "glued": (None, 0)}, r"periodic\[1\] must be False"),
    ({"shape": (8, 4), "periodic": (True, False), "glued": (None, 1)}, "another axis"),
    ({"shape": (8, 4), "periodic": (True, False), "glued": (None,)}, "2 entries"),
])
def test_glued_grid_rejects_bad_declarations(kwargs, match):
    with pytest.raises(ValueError, match=match):
        cartan.Grid(**kwargs)


def test_glue_must_be_an_involution_and_only_on_glued_grids():
    med, grid, init = _sphere()
    bad = SE3.exp(np.array([0, 0, 0, 0, 0, 0.4]))
    with pytest.raises(ValueError, match="involution"):
        Problem(med, grid, InitialState(Phi=init.Phi, glue=bad))
    flat = cartan.Grid((8, 4), periodic=(True, False))
    with pytest.raises(ValueError, match="glued axis"):
        Problem(med, flat, InitialState(Phi=init.Phi, glue=init.glue))
    assert "v-start" not in Problem(med, grid, init).boundary_names()
    with pytest.raises(ValueError, match="sphere: the grid must"):
        med.initial_state(flat, "sphere")


# ---------------------------------------------------------------------------- rigid motions, gradient
def test_rigidly_moved_sphere_is_strain_and_force_free_with_the_poles_anywhere():
    med, grid, init = _sphere(8, rotation=TILT, center=[0.1, 0.2, 0.3])
    M = SE3.exp(np.array([0.2, -0.4, 0.5, 1.0, 0.3, -0.6]))  # a rigid motion of the whole sphere
    for track in (True, False):
        prob = Problem(med, grid, InitialState(Phi=M @ init.Phi, glue=init.glue), reference=init.reference)
        sch = Lattice(prob, track_frames=track)
        st = sch.initial_state()
        scale = med.E * med.h  # membrane force per unit length
        assert np.max(np.abs(sch.internal_force(st))) < 1e-13 * scale
        assert abs(sch.potential_energy(st)) < 1e-26
        assert sch.plaquette_residual(st) < 1e-13
        np.testing.assert_allclose(sch.frames(st), M @ init.Phi, atol=1e-13)
    # the stored copies of a glued edge agree: G' = Γ G⁻¹ Γ
    G = st.arrays["G_v"]
    Gam = init.glue
    np.testing.assert_allclose(G[4:, 0], Gam @ np.linalg.inv(G[:4, 0]) @ Gam, atol=1e-13)


def perturbed_sphere(**options):
    """A lattice on a perturbed 8 × 4 sphere, poles tilted (``options`` to :class:`Lattice`),
    with its initial internal force F, a drift direction d (no drill) and V(τ), the potential
    energy after a drift τd: the force is the exact gradient when dV/dτ(0) = −Σ F·d."""
    med, grid, init = _sphere(8, rotation=TILT)
    rng = np.random.default_rng(1)
    eta = 1e-2 * rng.normal(size=(8, 4, 6))
    prob = Problem(med, grid, InitialState(Phi=init.Phi @ SE3.exp(eta), glue=init.glue), reference=init.reference)
    sch = Lattice(prob, track_frames=True, **options)
    F = sch.internal_force(sch.initial_state())
    d = rng.normal(size=(8, 4, 6))
    d[..., 5] = 0.0

    def V(tau):
        st = sch.initial_state()
        sch.drift(st, tau, d)
        return sch.potential_energy(st)

    return sch, init, F, d, V


def test_forces_are_the_gradient_of_the_energy_across_the_poles():
    sch, init, F, d, V = perturbed_sphere()
    eps = 1e-5
    dV = (V(eps) - V(-eps)) / (2 * eps)  # central difference: error O(eps²) ≈ 1e-10 relative
    assert dV == pytest.approx(-np.sum(F * d), rel=1e-7)
    st = sch.initial_state()
    sch.drift(st, 0.5, d)
    assert sch.plaquette_residual(st) < 1e-13  # plaquettes across the poles stay closed
    assert sch.integrability_residual(st) < 1e-12
    G = st.arrays["G_v"]
    np.testing.assert_allclose(G[4:, 0], init.glue @ np.linalg.inv(G[:4, 0]) @ init.glue, atol=1e-12)
    np.testing.assert_allclose(G[4:, -1], init.glue @ np.linalg.inv(G[:4, -1]) @ init.glue, atol=1e-12)


def _expansion_forces(N: int, eps: float = 1e-6) -> np.ndarray:
    """Row means of the force per node weight ``[N/2, r]`` (body components) under the uniform
    expansion r → (1 + ε)r of the sphere, over the equator row's radial force."""
    med, grid, init = _sphere(N)
    Phi = init.Phi.copy()
    Phi[..., 1:, 0] *= 1.0 + eps  # the positions (SE(3) as 4×4, translation in column 0)
    ref = Problem(med, grid, init).reference
    sch = Lattice(Problem(med, grid, InitialState(Phi=Phi, glue=init.glue), reference=ref), track_frames=True)
    F = (sch.internal_force(sch.initial_state()) / sch.weights[..., None]).mean(axis=0)
    return F / F[N // 4, 2]


def test_uniform_expansion_pulls_every_row_off_the_poles_alike():
    for N in (16, 32):
        F = _expansion_forces(N)
        # radial (e₃) pull of the rows not next to a pole: the equator's, to round-off of the
        # eps = 1e-6 difference (the chart's longitude and the staggered rows are exact)
        np.testing.assert_allclose(F[1:-1, 2], 1.0, atol=1e-6)
        # the meridional (e₂) force of those rows is O(h) of the radial one (the corner quadrature)
        assert np.max(np.abs(F[1:-1, 1])) < 0.2 * np.pi / (N // 2)
        # the pole rows pull harder: ≈ 1 + ¼ (the glued edge's meridional stress, weighed like any edge's)
        assert 1.2 < F[0, 2] < 1.3 and F[-1, 2] == pytest.approx(F[0, 2], rel=1e-6)


@pytest.mark.xfail(strict=True, reason="the pole rows keep a meridional force ∝ 1/h under a uniform expansion "
                                        "(docs/media/cosserat-surface.md, 'The closed sphere')")
def test_uniform_expansion_leaves_the_pole_rows_in_meridional_balance():
    ratios = [abs(_expansion_forces(N)[0, 1]) for N in (16, 32)]
    # a consistent quadrature: the meridional force over the radial one falls at least as h
    assert ratios[1] < ratios[0] / 2, ratios


def test_compiled_paths_decline_glued_problems():
    med, grid, init = _sphere(8)
    sch = Lattice(Problem(med, grid, init))
    ops = sch.compiled_operators()
    assert not ops.ok and "glued" in ops.reason
    st = sch.initial_state()
    assert sch.compiled_advance(None, st, 0.01, 3) is False  # declined before the integrator is read


def test_solvers_without_glued_edges_refuse_the_sphere():
    """Collocation refuses a glued chart by name (statics and implicit-midpoint on the sphere:
    test_sphere_statics.py)."""
    from cartan.schemes.collocation import Collocation

    med, grid, init = _sphere(8)
    prob = Problem(med, grid, init)
    with pytest.raises(ValueError, match="collocation scheme does not support a glued axis"):
        Collocation(prob)


# ---------------------------------------------------------------------------- breathing
def _breathe(N: int, rotation=None, t_end: float = 0.15):
    from cartan_cosserat_surface.cases_sphere import radial_displacement, sphere_problem

    prob, dt = sphere_problem(N, rotation=rotation)
    ds = cartan.simulate(prob, dt=dt, t_end=t_end, save_every=5, progress=False)
    return ds, radial_displacement(ds)


@pytest.mark.slow
def test_breathing_conserves_energy_and_does_not_see_the_poles():
    ds, w = _breathe(8)
    _, w_tilt = _breathe(8, rotation=TILT)
    E = ds["kinetic_energy"].values + ds["potential_energy"].values
    # lie-verlet: the energy error oscillates at O((ωΔt)²) ≈ 3e-4 of the energy, never drifts
    assert np.ptp(E) < 1e-3 * E[0]
    # the poles placed elsewhere: the same motion (the chart is turned, not the physics)
    np.testing.assert_allclose(w_tilt, w, atol=1e-9 * np.max(np.abs(w)))
    # every node of a ring of colatitude moves alike (the chart's longitude is a symmetry)
    assert np.max(np.ptp(w, axis=1)) < 1e-8 * np.max(np.abs(w))


@pytest.mark.slow
def test_breathing_frequency_converges_at_order_two():
    from cartan_cosserat_surface.cases_sphere import SphereBreathing

    case = SphereBreathing()
    errors = []
    for level in (0, 1, 2):
        prob, settings = case.problem(level)
        errors.append(case.error(case.run(prob, settings, "lie-verlet"), prob))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(orders - case.space_order) < 0.3), (errors, orders)
    # the finest level against the order-2 prediction from the one before (case tolerance at level 3)
    assert errors[-1] < 1.5 * errors[-2] / 4


@pytest.mark.slow
def test_breathing_pole_rows_move_like_the_equator():
    spreads, poles = [], []
    for N in (32, 64):
        _, w = _breathe(N, t_end=1.0)
        rows = w[-1].mean(axis=0)
        spreads.append(float(np.ptp(rows) / np.max(np.abs(rows))))
        poles.append(float(rows[0] / rows[N // 4] - 1.0))  # the pole row over the equator row
    # the pole artefact is O(h²) (4× per halving, measured 3.9× from N = 64 to 128) but still
    # pre-asymptotic here: measured 3.1× (spread 3.0 % → 0.97 %) and 2.8× (pole row +2.2 % →
    # +0.79 %); the bound asks for order > 1.3 (2.5×)
    assert spreads[1] < spreads[0] / 2.5, spreads
    assert 0.0 < poles[1] < poles[0] / 2.5, poles
