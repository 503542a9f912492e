"""The pole cell of a glued chart, ``Lattice(problem, pole="cap")`` (cartan.schemes._pole_cell;
docs/media/cosserat-surface.md, "The closed sphere"): the caps replace the corners through the
poles, every edge takes the chord-length strain X″ = (θ|p|/|v|, π)."""

from __future__ import annotations

import json
import pathlib

import numpy as np
import pytest

import cartan
from cartan.problem import InitialState, Problem
from cartan.schemes._pole_cell import pole_strain, pole_strain_vjp
from cartan.schemes.lattice import Lattice

SE3 = cartan.group("SE3")
SO3 = cartan.group("SO3")
TILT = SO3.exp(np.array([0.3, -1.1, 0.7]))  # poles anywhere


def _sphere(N: int = 8, rotation=None, center=None, medium: str = "cosserat-surface"):
    med = cartan.medium(medium, E=1.0, poisson=0.3, thickness=0.05, density=1.0)
    grid = cartan.Grid((N, N // 2), (2 * np.pi, np.pi), periodic=(True, False), glued=(None, 0))
    return med, grid, med.initial_state(grid, "sphere", rotation=rotation, center=center)


# ---------------------------------------------------------------------------- the option
def test_pole_option_is_validated_and_recorded():
    med, grid, init = _sphere(8)
    prob = Problem(med, grid, init)
    with pytest.raises(ValueError, match="pole must be one of 'corners', 'cap'"):
        Lattice(prob, pole="disc")
    flat = cartan.Grid((8, 4), (1.0, 1.0))
    plate = Problem(med, flat, med.initial_state(flat, "flat"))
    with pytest.raises(ValueError, match="pole = 'cap' needs a d = 2 chart with a glued axis"):
        Lattice(plate, pole="cap")
    with pytest.raises(ValueError, match="pole = 'cap' needs a reference"):
        Lattice(Problem(med, grid, InitialState(Phi=init.Phi, glue=init.glue)), pole="cap")
    assert Lattice(prob).options() == {"track_frames": Lattice(prob).track}  # the default is not recorded
    assert Lattice(prob, pole="cap").options()["pole"] == "cap"


def test_scene_takes_the_pole_from_the_scheme_options():
    from cartan.scene import SceneError, load_scene, read_scene_file

    scenes = pathlib.Path(__file__).resolve().parents[1] / "plugins" / "cartan_cosserat_surface" / "scenes"
    data = read_scene_file(scenes / "sphere-breathing.toml")
    data["run"]["scheme_options"] = {"pole": "cap"}
    assert load_scene(data).scheme_options == {"pole": "cap"}
    data["run"]["scheme_options"] = {"pole": "disc"}
    with pytest.raises(SceneError, match="run.scheme_options: lattice: pole must be one of"):
        load_scene(data)


def test_statics_paths_take_the_cap():
    """The strain constraints hold the logarithmic edge strains under the cap too (the same rows as
    with the corners), and the Jacobian's stencil joins each pole row (tests/test_pole_cell_statics.py)."""
    from cartan.constraints import StrainConstraints
    from cartan.statics import _lattice_stencil

    med, grid, init = _sphere(8, medium="kirchhoff-love")
    sch = Lattice(Problem(med, grid, init, reference=init), pole="cap")
    corners = Lattice(Problem(med, grid, init, reference=init))
    unknown = np.ones((*grid.shape, 6), dtype=bool)
    con = StrainConstraints(sch, unknown, sch.initial_state())
    ref = StrainConstraints(corners, unknown, corners.initial_state())
    assert con.ncon == ref.ncon > 0
    assert np.array_equal(con.values(sch.initial_state()), ref.values(corners.initial_state()))
    _, src, dst = _lattice_stencil(sch)
    row = np.arange(int(np.prod(grid.shape))).reshape(grid.shape)[:, 0]
    assert np.isin(row, dst[src == row[0]]).all()


def test_pole_strain_has_the_fitted_invariants_and_its_exact_gradient():
    rng = np.random.default_rng(3)
    C = np.array([[1.2, 0.1], [0.1, 0.9]])
    K = np.array([[0.3, -0.2], [-0.2, 0.5]])
    g = np.array([0.1, -0.2])
    X = pole_strain(C, K, g)
    # θ_α·θ_β = C, θ_α3 = g, θ_α·(π_β2, −π_β1, 0) = K, to round-off
    np.testing.assert_allclose(X[:, :3] @ X[:, :3].T, C, atol=1e-15)
    np.testing.assert_allclose(X[:, 2], g, atol=0)
    np.testing.assert_allclose(X[:, None, 0] * X[None, :, 4] - X[:, None, 1] * X[None, :, 3], K, atol=1e-15)
    Q = rng.normal(size=(2, 6))
    cb, kb, gb = pole_strain_vjp(C, K, g, Q)
    E = [np.array([[1.0, 0.0], [0.0, 0.0]]), np.array([[0.0, 1.0], [1.0, 0.0]]), np.array([[0.0, 0.0], [0.0, 1.0]])]
    eps = 1e-6  # central differences: O(eps²) ≈ 1e-12, round-off ≈ 1e-16/eps = 1e-10

    def f(C, K, g):
        return float(np.sum(Q * pole_strain(C, K, g)))

    for i, Ei in enumerate(E):
        assert (f(C + eps * Ei, K, g) - f(C - eps * Ei, K, g)) / (2 * eps) == pytest.approx(cb[i], abs=1e-8)
        assert (f(C, K + eps * Ei, g) - f(C, K - eps * Ei, g)) / (2 * eps) == pytest.approx(kb[i], abs=1e-8)
    for i in range(2):
        e = eps * np.eye(2)[i]
        assert (f(C, K, g + e) - f(C, K, g - e)) / (2 * eps) == pytest.approx(gb[i], abs=1e-8)


# ---------------------------------------------------------------------------- statics of the cell
def test_rigidly_moved_sphere_is_strain_and_force_free_with_the_cap():
    med, grid, init = _sphere(8, rotation=TILT, center=[0.1, 0.2, 0.3])
    M = SE3.exp(np.array([0.2, -0.4, 0.5, 1.0, 0.3, -0.6]))
    prob = Problem(med, grid, InitialState(Phi=M @ init.Phi, glue=init.glue), reference=init.reference)
    sch = Lattice(prob, track_frames=True, pole="cap")
    st = sch.initial_state()
    for a, X in enumerate(sch.edge_strains(st)):  # the chord-length strains are the reference's
        np.testing.assert_allclose(X, sch.edge_rest_strains(a)[..., a, :], atol=1e-13)
    assert np.max(np.abs(sch.internal_force(st))) < 1e-13 * med.E * med.h  # round-off of the membrane force
    assert abs(sch.potential_energy(st)) < 1e-26
    c = sch.corners()  # the corners through a pole are replaced by the caps
    glued = c["ghost_tail"][1] | c["ghost_head"][1]
    assert np.all(c["weight"][glued[c["edge"][:, 1]]] == 0.0) and np.sum(glued[c["edge"][:, 1]]) == 4 * 8


def test_forces_are_the_exact_gradient_of_the_energy_with_the_cap():
    from test_sphere_chart import perturbed_sphere

    _, _, F, d, V = perturbed_sphere(pole="cap")

    def D(eps):
        return (V(eps) - V(-eps)) / (2 * eps)

    # Richardson-extrapolated central differences: O(eps⁴) ≈ 1e-20 plus round-off ≈ 1e-11 relative
    # (measured 4e-11); a corner or a cap term missing from the force would be O(1)
    dV = (4 * D(5e-6) - D(1e-5)) / 3
    assert dV == pytest.approx(-np.sum(F * d), rel=1e-9)


def _expansion_forces(N: int, eps: float = 1e-6) -> np.ndarray:
    """Row means of the force per node weight ``[N/2, r]`` under r → (1 + ε)r, over the equator's
    radial force (as tests/test_sphere_chart.py, with the cap)."""
    med, grid, init = _sphere(N)
    Phi = init.Phi.copy()
    Phi[..., 1:, 0] *= 1.0 + eps
    ref = Problem(med, grid, init).reference
    sch = Lattice(Problem(med, grid, InitialState(Phi=Phi, glue=init.glue), reference=ref), track_frames=True,
                  pole="cap")
    F = (sch.internal_force(sch.initial_state()) / sch.weights[..., None]).mean(axis=0)
    return F / F[N // 4, 2]


def test_uniform_expansion_with_the_cap_balances_the_pole_rows():
    F16, F32 = _expansion_forces(16), _expansion_forces(32)
    for F in (F16, F32):
        np.testing.assert_allclose(F[1:-1, 2], 1.0, atol=1e-6)  # the other rows: the equator's (round-off of eps)
        # the moment on the pole rows: the chord length does not depend on the edge's rotation
        # (measured 1.9e-5, 9.4e-6; the logarithmic strains give 1.5e-2, 9.6e-3)
        assert np.max(np.abs(F[:, 3])) < 1e-4
    # the pole rows' meridional force over the radial one falls as h, O(h) like the next rows'
    # (measured 0.106 → 0.053, the corners' grows as 1/h)
    assert abs(F32[0, 1]) < abs(F16[0, 1]) / 1.9
    # their radial excess is O(h²) (measured 1.64e-3 → 4.04e-4, 4.07×; the corners' stays at 25 %)
    assert 0.0 < F32[0, 2] - 1.0 < (F16[0, 2] - 1.0) / 3.5
    assert F16[-1, 2] == pytest.approx(F16[0, 2], rel=1e-6)


# ---------------------------------------------------------------------------- breathing
def _pole_spread(N: int, pole: str) -> float:
    from cartan_cosserat_surface.cases_sphere import radial_displacement, sphere_problem

    prob, dt = sphere_problem(N)
    ds = cartan.simulate(prob, dt=dt, t_end=1.0, save_every=5, progress=False, scheme_options={"pole": pole})
    assert json.loads(ds.attrs["cartan_config"])["run"]["scheme_options"].get("pole", "corners") == pole
    rows = radial_displacement(ds)[-1].mean(axis=0)
    return float(np.ptp(rows) / np.max(np.abs(rows)))


def test_breathing_with_the_cap_is_more_uniform_than_with_the_corners():
    corners, cap = _pole_spread(16, "corners"), _pole_spread(16, "cap")
    # measured 4.8 % with the corners, 0.94 % with the cap (5.1×) at N = 16
    assert cap < corners / 3, (corners, cap)


@pytest.mark.slow
def test_breathing_frequency_with_the_cap_converges_at_order_two():
    from cartan_cosserat_surface.cases_sphere import SphereBreathing

    case = SphereBreathing()
    errors = []
    for level in (0, 1, 2):
        prob, settings = case.problem(level)
        errors.append(case.error(cartan.simulate(prob, progress=False, scheme_options={"pole": "cap"}, **settings),
                                 prob))
    # measured 5.1e-2, 1.42e-2, 3.75e-3 at N = 8, 16, 32 (orders 1.84, 1.92)
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(orders - case.space_order) < 0.3), (errors, orders)
