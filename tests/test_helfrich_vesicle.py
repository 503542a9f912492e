"""Closed surfaces of the Kirchhoff–Love family (paper §VII.B): the ``torus`` initial state, the
lattice's Willmore energy, area and volume of the torus of revolution, Gauss–Bonnet in its
plaquette and curvature forms, and (slow) the Willmore flow to the Clifford torus and the
Helfrich flow with held area and volume (:mod:`cartan_kirchhoff_love.vesicle`)."""

from __future__ import annotations

import math
import pathlib
import sys

import numpy as np
import pytest
from toys import assert_volume_gradient

import cartan

try:
    import cartan_kirchhoff_love.plugin as kl_plugin
except ModuleNotFoundError:  # not installed yet: the package beside the others
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "plugins"))
    import cartan_kirchhoff_love.plugin as kl_plugin

from cartan_kirchhoff_love import vesicle  # noqa: E402

from cartan.schemes.lattice import Lattice  # noqa: E402

R, r = 2.0, 1.0
#: Willmore flow of the R/r = 2 torus on a 6 × 12 lattice (exact along the parallels; the flow stays
#: axisymmetric, 24 × 12 gives the same numbers): steps, and the bounds on W/2π² − 1 and (R/r)/√2 − 1.
#: Measured after 8 steps: 5.1e-4 and 5.6e-3; but run on, the discrete W undershoots 2π² by 1–2 %
#: (−1.14e-2 at nv = 12, −1.88e-2 at nv = 16 with mesh="initial"; docs/media/kirchhoff-love.md): the
#: flow grades the meridian mesh through the tangential mode and the lattice's W on a graded mesh is
#: below 2π² by O(h²) times the grading (test_clifford_energy_on_a_graded_mesh_converges_from_below);
#: the mesh the flow picks grades more as h falls, so the W bound is that measured offset, not a
#: resolution-derived one; the shape's bound is the distance measured at nv = 12
FLOW_STEPS = 8
CLIFFORD_TOL = 2e-2
ASPECT_TOL = 1e-2


@pytest.fixture(scope="module", autouse=True)
def registered():
    """The media registered (through the entry point when installed, else in-process)."""
    from cartan.plugins import reset_registry

    if "helfrich-membrane" not in cartan.registry("media"):
        reset_registry([("kirchhoff_love", kl_plugin)])
    yield


def _torus(nu: int, nv: int, medium: str = "helfrich-membrane", **params):
    grid = cartan.Grid((nu, nv), length=(2 * np.pi * R, 2 * np.pi * r), periodic=(True, True))
    m = cartan.medium(medium, **params)
    return cartan.Problem(m, grid, m.initial_state(grid, "torus"))


# ---------------------------------------------------------------------------- the torus initial state
def test_torus_initial_state_is_closed_and_adapted():
    pb = _torus(8, 6, "kirchhoff-love")
    Phi = pb.initial.Phi
    E = Phi[..., 1:, 1:]
    np.testing.assert_allclose(np.swapaxes(E, -1, -2) @ E, np.broadcast_to(np.eye(3), E.shape), atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(E), 1.0, atol=1e-14)
    x = Phi[..., 1:, 0]
    rho = np.hypot(x[..., 0], x[..., 1])
    np.testing.assert_allclose((rho - R) ** 2 + x[..., 2] ** 2, r * r, atol=1e-14)   # on the torus
    np.testing.assert_allclose(np.sum(E[..., :, 2] * np.stack([x[..., 0] / rho * (rho - R) / r,
                                                               x[..., 1] / rho * (rho - R) / r, x[..., 2] / r], -1),
                                      axis=-1), 1.0, atol=1e-14)                 # e₃ the outward normal
    scheme = Lattice(pb)
    Xu, Xv = scheme.edge_strains(scheme.initial_state())
    assert max(np.max(np.abs(Xu[..., 2])), np.max(np.abs(Xv[..., 2]))) < 1e-14    # θ_α,3 = 0, closing edges included
    # every parallel and meridian is an orbit of a one-parameter subgroup: constant strains along it
    np.testing.assert_allclose(Xu, np.broadcast_to(Xu[:1], Xu.shape), atol=1e-13)
    np.testing.assert_allclose(Xv, np.broadcast_to(Xv[:, :1], Xv.shape), atol=1e-13)


def test_torus_principal_gauge_puts_e1_on_the_meridian():
    grid = cartan.Grid((8, 6), length=(2 * np.pi * R, 2 * np.pi * r), periodic=(True, True))
    coord = cartan.medium("kirchhoff-love").initial_state(grid, "torus").Phi
    princ = cartan.medium("kirchhoff-love", gauge="principal").initial_state(grid, "torus").Phi
    # e₁' = ±e₂, the meridian (κ₁ = 1/r; φ = ±π/2, a direction's sign is free)
    np.testing.assert_allclose(np.abs(np.sum(princ[..., 1:, 1] * coord[..., 1:, 2], axis=-1)), 1.0, atol=1e-12)
    np.testing.assert_allclose(princ[..., 1:, 3], coord[..., 1:, 3], atol=1e-14)


@pytest.mark.parametrize("kwargs, grid_kw, match", [
    ({"minor_radius": 1.5}, {}, "minor_radius"),                         # period 2π·1.5 ≠ L_v
    ({}, {"periodic": (True, False)}, "periodic"),
    ({"major_radius": -1.0}, {}, "major_radius"),
    ({}, {"length": (2 * np.pi, 2 * np.pi * 2.0)}, "minor_radius must be <"),
    ({"tube": 1.0}, {}, "tube"),
])
def test_torus_rejects_bad_input(kwargs, grid_kw, match):
    gk = {"length": (2 * np.pi * R, 2 * np.pi * r), "periodic": (True, True), **grid_kw}
    grid = cartan.Grid((8, 6), **gk)
    with pytest.raises(ValueError, match=match):
        cartan.medium("kirchhoff-love").initial_state(grid, "torus", **kwargs)


# ---------------------------------------------------------------------------- energy and measures at rest
def test_torus_willmore_energy_is_spectral_in_v_and_exact_in_u():
    """E = 2κ_b W, W = π² a²/√(a² − 1): the parallels' strains are exact (any nu), the meridian's
    trapezoid rule converges like ρ^(−nv), ρ = a + √(a² − 1) = 3.73 (2.7e-7 at nv = 12)."""
    W = vesicle.torus_willmore_energy(R / r)
    errs = {}
    for nu, nv in ((4, 8), (9, 8), (4, 12), (4, 16)):
        pb = _torus(nu, nv)
        errs[nu, nv] = abs(vesicle.bending_energy(pb, pb.initial.Phi) / (2 * W) - 1.0)
    assert errs[4, 8] == pytest.approx(errs[9, 8], rel=1e-9, abs=1e-15)
    rho = R / r + math.sqrt((R / r) ** 2 - 1)
    for nv in (8, 12, 16):   # the trapezoid rule of ∫dψ/(a + cos ψ): 2ρ^(−n)/(1 − ρ^(−n)) relative
        assert errs[4, nv] == pytest.approx(2.0 * rho ** (-nv) / (1.0 - rho ** (-nv)), rel=0.1)
    assert vesicle.clifford_energy() == pytest.approx(vesicle.torus_willmore_energy(math.sqrt(2.0)), rel=1e-15)


def test_torus_area_and_volume():
    pb = _torus(5, 8)
    meas = vesicle.surface_measures(pb)
    assert meas["area"] == pytest.approx(4 * math.pi ** 2 * R * r, rel=1e-13)
    assert meas["volume"] == pytest.approx(2 * math.pi ** 2 * R * r * r, rel=1e-13)


def test_tether_gradient_and_tension_multiplier():
    rng = np.random.default_rng(3)
    x0 = rng.normal(size=(3, 2, 3))
    t = vesicle.Tether(x0, 2.5)
    q = np.zeros((3, 2, 4, 4))
    q[..., 0, 0] = 1.0
    q[..., 1:, 0] = x0 + rng.normal(size=x0.shape)
    g = t.potential_gradient(q)
    e = 1e-6
    for k in range(3):
        qp, qm = q.copy(), q.copy()
        qp[1, 0, 1 + k, 0] += e
        qm[1, 0, 1 + k, 0] -= e
        fd = (t.potential_energy(qp)[1, 0] - t.potential_energy(qm)[1, 0]) / (2 * e)
        assert fd == pytest.approx(g[1, 0, 1 + k, 0], rel=1e-8)
    with pytest.raises(ValueError, match="stiffness"):
        vesicle.Tether(x0, 0.0)
    m = cartan.medium("helfrich-membrane")
    assert m.with_tension(-0.3).sigma == -0.3 and m.sigma == 0.0
    with pytest.raises(ValueError, match="tension"):
        cartan.medium("helfrich-membrane", tension=-0.3)



def test_volume_pressure_is_the_exact_gradient_of_the_held_volume():
    """``VolumePressure``: V_h is ``surface_measures``' volume (2π²Rr² on the torus of revolution,
    round-off), its nodal forces are p ∂V_h/∂η_i — against central differences of V_h along
    Φ_i exp(±εe_k) on a torus whose frames are perturbed off the adaptation (ε = 1e-6: truncation
    ε² and round-off 1e-16 V/ε ≈ 4e-9 of the largest component; 2.3e-9 measured) — and the lattice's
    potential energy gains −pV_h with the node weights w_i J_i of a general chart (the reference
    torus: J from 0.5 to 1.5)."""
    from cartan_cosserat_surface.surface import VolumePressure

    pb = _torus(6, 12)
    p = 0.7
    load = VolumePressure(p)
    ref = cartan.Problem(pb.medium, pb.grid, pb.initial, reference=pb.initial, loads=[load])
    scheme = Lattice(ref)                                   # reports its weights w_i J_i to the load
    assert np.ptp(scheme.weights / scheme.chart_weights) > 0.9
    Phi0 = pb.initial.Phi
    assert load.volume(Phi0) == pytest.approx(vesicle.surface_measures(pb)["volume"], rel=1e-14)
    assert load.volume(Phi0) == pytest.approx(2 * math.pi ** 2 * R * r * r, rel=1e-13)
    g = pb.medium.group
    rng = np.random.default_rng(1)
    Phi = Phi0 @ g.exp(0.05 * rng.standard_normal((*pb.grid.shape, 6)))
    assert load.volume(Phi) == pytest.approx(vesicle.surface_measures(pb, Phi)["volume"], rel=1e-13)
    _, G = load.volume_and_gradient(Phi)
    T = load.force(Phi, None, 0.0)
    np.testing.assert_allclose(scheme.weights[..., None] * T, p * G, rtol=1e-13, atol=1e-13 * np.abs(G).max())
    nodes = [tuple(int(rng.integers(0, n)) for n in pb.grid.shape) for _ in range(4)]
    assert_volume_gradient(load, g, Phi, nodes, 2e-8)
    # V_h is measured from the mean node position: invariant under rigid motions, so the load has
    # no net force nor moment about the origin (round-off; the origin's V would leave O(h²) ones)
    R_ = Phi[..., 1:, 1:]
    f = np.einsum("...ij,...j->...i", R_, G[..., :3])
    moment = np.cross(Phi[..., 1:, 0], f) + np.einsum("...ij,...j->...i", R_, G[..., 3:])
    assert np.abs(f.sum(axis=(0, 1))).max() <= 1e-12 * np.abs(G).max()
    assert np.abs(moment.sum(axis=(0, 1))).max() <= 1e-12 * np.abs(G).max()
    shifted = Phi.copy()
    shifted[..., 1:, 0] += (0.3, -0.2, 0.5)
    assert load.volume(shifted) == pytest.approx(load.volume(Phi), rel=1e-13)
    state = scheme.initial_state()
    bare = Lattice(cartan.Problem(pb.medium, pb.grid, pb.initial, reference=pb.initial))
    assert scheme.potential_energy(state) - bare.potential_energy(bare.initial_state()) == pytest.approx(
        -p * load.volume(Phi0), rel=1e-12)



def _clifford_on_a_graded_meridian(nv: int, eps: float, nu: int = 4) -> float:
    """W/2π² − 1 of the lattice on the exact Clifford torus (R/r = √2, adapted frames in the
    coordinate gauge) whose meridian nodes sit at ψ_j = s_j + ε sin s_j, s_j = 2πj/nv."""
    pb = vesicle.graded_torus(nv, eps, nu=nu)
    Phi = np.asarray(pb.initial.Phi)
    return vesicle.bending_energy(pb, Phi) / 2.0 / vesicle.clifford_energy() - 1.0


def test_clifford_energy_on_a_graded_mesh_converges_from_below():
    """The lattice's W is consistent on a non-uniform mesh: on the exact Clifford torus with the
    meridian nodes graded (ε = 0.6, spacing ratio 4) it undershoots 2π² by −1.18e-2, −2.98e-3,
    −7.47e-4 at nv = 12, 24, 48 (measured; order 2.0) — the corner quadrature on the meridian,
    Σ_j f(ψ_j)(ψ_{j+1} − ψ_{j−1})/2 of f = H²√a, the meridian's edges being exact circles.  This is
    the offset the Willmore flow's end state shows (docs/media/kirchhoff-love.md): the flow grades
    its own mesh through the tangential mode, and on a mesh map held fixed the offset falls as h²."""
    errs = [_clifford_on_a_graded_meridian(nv, 0.6) for nv in (12, 24, 48)]
    assert all(e < 0.0 for e in errs)
    assert 5e-3 < -errs[0] < 2e-2
    for coarse, fine in zip(errs, errs[1:], strict=False):
        assert 1.8 < math.log2(coarse / fine) < 2.2
    assert abs(_clifford_on_a_graded_meridian(24, 0.0)) < 1e-8       # uniform: spectral (1.3e-9)


# ---------------------------------------------------------------------------- Gauss–Bonnet
def test_gauss_bonnet_at_rest_and_on_a_moving_wavy_torus():
    """Torus of revolution: both forms vanish to round-off.  Wavy torus (a snapshot of a motion
    at each amplitude): the plaquette form to round-off at every amplitude, the curvature form at
    O(h²) (4.6e-3, 1.4e-3 of ∫|K|dA at nv = 8, 16)."""
    gb = vesicle.gauss_bonnet(_torus(6, 12))
    assert abs(gb["plaquette"]) < 1e-14 * gb["absolute"] and abs(gb["curvature"]) < 1e-14 * gb["absolute"]
    for a in (0.1, 0.3, 0.5):
        gb = vesicle.gauss_bonnet(vesicle.wavy_torus_problem(8, amplitude=a))
        assert abs(gb["plaquette"]) < 1e-14 * gb["absolute"]
        assert 1e-6 < abs(gb["curvature"]) / gb["absolute"] < 2e-2
    e8, e16 = (abs(g["curvature"]) / g["absolute"] for g in
               (vesicle.gauss_bonnet(vesicle.wavy_torus_problem(n)) for n in (8, 16)))
    assert 1.5 < math.log2(e8 / e16) < 2.5                                # order 2 (1.74 measured here)


def test_plaquette_curvature_is_k_da_to_second_order():
    """Ω_p against K J h_u h_v at the plaquette centres of the torus of revolution: the relative
    difference falls as h² (1.14e-2, 6.41e-3 at nv = 12, 16; ratio (16/12)²)."""
    diffs = []
    for nv in (12, 16):
        pb = _torus(4, nv)
        hu, hv = pb.grid.spacing
        Om = vesicle.plaquette_curvature(pb)
        psi = (pb.grid.coordinates(1) + hv / 2) / r
        KJ = np.cos(psi) / (r * (R + r * np.cos(psi))) * (R + r * np.cos(psi)) / R * hu * hv
        diffs.append(np.max(np.abs(Om - KJ[None, :])) / np.max(np.abs(KJ)))
    assert diffs[0] < 2e-2
    assert diffs[0] / diffs[1] == pytest.approx((16 / 12) ** 2, rel=0.05)


def test_gauss_bonnet_case_quick_level():
    case = vesicle.GaussBonnetTorus()
    pb, settings = case.problem(1)
    ds = case.run(pb, settings)
    parts = case.parts(ds, pb)
    assert parts["plaquette"] < 1e-15 and parts["curvature"] < case.tolerance


def test_flow_rejects_bad_input():
    pb = _torus(4, 8)
    for kw, match in (({"hold": ("mass",)}, "hold"), ({"steps": 0}, "steps"), ({"tau": -1.0}, "tau"),
                      ({"growth": 0.5}, "growth"), ({"hold_tol": 0.0}, "hold_tol"),
                      ({"mesh": "final"}, "mesh")):
        with pytest.raises(ValueError, match=match):
            vesicle.helfrich_flow(pb, **kw)
    with pytest.raises(ValueError, match="helfrich-membrane"):
        vesicle.helfrich_flow(_torus(4, 8, "kirchhoff-love"))
    grid = cartan.Grid((4, 8), length=(1.0, 1.0), periodic=(True, False))
    m = cartan.medium("helfrich-membrane")
    with pytest.raises(ValueError, match="periodic"):
        vesicle.helfrich_flow(cartan.Problem(m, grid, m.initial_state(grid, "flat")))


# ---------------------------------------------------------------------------- flows (slow)
@pytest.mark.slow
def test_willmore_flow_relaxes_a_torus_to_the_clifford_torus():
    """R/r = 2 → √2 at held area: E_H monotone, A held to 1e-8, W near 2π² within the measured
    offset, the plaquette Gauss–Bonnet at round-off at every step of the motion.  Run longer, the
    lattice's tangential mesh mode along the meridian lowers the discrete W below 2π² (−0.4 % after
    14 steps; docs/media/kirchhoff-love.md), so the check stops at 8 steps."""
    pb = _torus(6, 12, area_modulus=1.0, shear_modulus=0.1)
    ds = vesicle.helfrich_flow(pb, steps=FLOW_STEPS, tau=0.2, growth=1.5, tau_max=5.0, hold=("area",))
    E = ds["bending_energy"].values
    assert np.all(np.diff(E) < 0.0)
    A = ds["area"].values
    assert np.max(np.abs(A / A[0] - 1.0)) < 1e-8
    W = E[-1] / 2.0                                  # E_H = ½κ_b(2H)² = 2κ_b H² per unit area
    assert abs(W / vesicle.clifford_energy() - 1.0) < CLIFFORD_TOL
    Rf, rf = vesicle.torus_radii(vesicle._frames_of(ds))
    assert abs(Rf / rf / math.sqrt(2.0) - 1.0) < ASPECT_TOL
    gb_abs = ds["gauss_bonnet_absolute"].values
    assert np.max(np.abs(ds["gauss_bonnet_plaquette"].values) / gb_abs) < 1e-14
    assert np.max(np.abs(ds["gauss_bonnet_curvature"].values) / gb_abs) < 2e-2    # O(h²) at h = π/6


@pytest.mark.slow
def test_helfrich_flow_holds_area_and_volume_and_lowers_the_energy():
    """Both global constraints held by the outer iteration to 1e-8 relative, and E_H decreasing at
    every step: the volume's multiplier load (``VolumePressure``) is the exact gradient of the held
    V_h, as the tension's σ-term is of A, so each step minimises E_H + D − σ(A − A₀) − p(V − V₀)
    over admissible shapes and E_H(Φ_{n+1}) + D ≤ E_H(Φ_n).  Measured on 6 × 12 from R/r = 2:
    E_H 45.586 → 45.451 → 45.330 → 45.262 (σ ≈ −1.0, p ≈ −1.4)."""
    pb = _torus(6, 12, area_modulus=1.0, shear_modulus=0.1)
    ds = vesicle.helfrich_flow(pb, steps=3, tau=0.05, growth=1.5, tau_max=5.0)
    A, V = (ds[k].values for k in ("area", "volume"))
    assert np.max(np.abs(A / A[0] - 1.0)) < 1e-8 and np.max(np.abs(V / V[0] - 1.0)) < 1e-8
    assert np.all(ds["pressure_multiplier"].values[1:] != 0.0)
    E = ds["bending_energy"].values
    assert np.all(np.diff(E) < 0.0), E
