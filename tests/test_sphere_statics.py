"""Statics on the closed sphere: ``solve_static`` and ``continuation`` on a glued chart.

A glued colatitude (``Grid(glued=(None, 0))``) has, on each line, an edge across each pole
joining node (i, end) to node (i + N/2, end) through the constant glue Γ.  The Jacobian's
stencil and colouring are then built from the lattice's own edges and corners
(``cartan.statics._lattice_stencil``), the Jacobian is the coloured central difference of the
whole force (glued ends included), and the mixed iteration's linearised strains move a ghost end
by ``Ad_{Γ⁻¹}δ``.  Checked here: the stencil holds the pairs across the poles and the colouring
separates every stencil (fast); the linearised strains of the glued edges (fast); the coloured
Jacobian equals a dense finite-difference Jacobian on N = 8, with and without a stress offset
(slow); a pressurised sphere converges to the thin-shell value at order 2 (slow).  The loads on
this chart: the surface ``Pressure`` is a density per unit reference area, so its total force and
virial are those of ∮ p n dA (fast); ``VolumePressure`` is the exact gradient of the lattice's
enclosed volume across the poles (fast) and a potential in a run (slow); the scenes
``sphere-pressure`` and ``sphere-volume-pressure`` load (fast).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from cartan_cosserat_surface.surface import Pressure
from toys import assert_volume_gradient

import cartan
from cartan.problem import Problem
from cartan.schemes.lattice import Lattice
from cartan.statics import _Equilibrium, _lattice_stencil

E, NU, H = 1.0, 0.3, 0.05


def _sphere(N: int):
    med = cartan.medium("cosserat-surface", E=E, poisson=NU, thickness=H, density=1.0)
    grid = cartan.Grid((N, N // 2), (2 * np.pi, np.pi), periodic=(True, False), glued=(None, 0))
    return med, grid, med.initial_state(grid, "sphere")


def _perturbed(eq: _Equilibrium, seed: int = 1):
    rng = np.random.default_rng(seed)
    st = eq.state0.copy()
    eq.sch.drift(st, 1.0, 0.05 * rng.standard_normal((*eq.shape, eq.r_dim)))
    return st, rng


# ---------------------------------------------------------------------------- stencil
def test_stencil_holds_the_pairs_across_the_poles_and_colours_separate_them():
    med, grid, init = _sphere(8)
    sch = Lattice(Problem(med, grid, init))
    colour, src, dst = _lattice_stencil(sch)
    pairs = set(zip(src.tolist(), dst.tolist(), strict=True))
    idx = np.arange(grid.size).reshape(grid.shape)
    n, m = grid.shape
    for i in range(n):
        for end in (0, m - 1):  # the glued edge across each pole
            assert (idx[i, end], idx[(i + n // 2) % n, end]) in pairs
        # a corner through the pole couples the node to the neighbours of its opposite node
        assert (idx[i, 0], idx[(i + n // 2 + 1) % n, 0]) in pairs
    # nodes of one colour have disjoint stencils: every target is reached once per colour
    counts = np.zeros((colour.max() + 1, grid.size), dtype=int)
    np.add.at(counts, (colour[src], dst), 1)
    assert counts.max() == 1
    assert (src == dst).sum() == grid.size


def test_strain_rate_moves_the_ghost_ends_by_Ad():
    """B δ of the mixed iteration equals the change of the edge strains to O(|δ|²), the glued
    edges (whose ghost end moves by Ad_{Γ⁻¹}δ) included."""
    med, grid, init = _sphere(8)
    eq = _Equilibrium(Problem(med, grid, init), jacobian="fd")
    st, rng = _perturbed(eq)
    mu = np.zeros(eq.nmult)
    for size in (1e-5, 1e-6):
        d = size * rng.standard_normal(eq.nunk)
        moved, _ = eq.update(st, mu, np.concatenate([d, np.zeros(eq.nmult)]))
        B = eq.strain_rate(st, d)
        for x0, x1, b in zip(eq.strains(st), eq.strains(moved), B, strict=True):
            # a second-order remainder, |ΔX − Bδ| = O(|δ|²): 0.7·size relative measured (a ghost
            # end moved by δ instead of Ad_{Γ⁻¹}δ leaves an O(1) relative error on the glued edges)
            assert np.abs((x1 - x0) - b).max() <= 10.0 * size * np.abs(b).max()


# ---------------------------------------------------------------------------- the pressure's total force
def _pressure_sums(N: int, p: float, stretch=(1.0, 1.0, 1.0)):
    """Σ_i w_i J_i f_i and Σ_i w_i J_i f_i·x_i of the surface ``Pressure`` p on the unit sphere's
    chart with its positions stretched by ``stretch`` along x, y, z (an ellipsoid; the frames,
    which the spatial force does not read, kept): f_i the load's density per unit reference area
    in the spatial frame, w_i J_i the lattice's node weights."""
    med, grid, init = _sphere(N)
    load = Pressure(p)
    weights = Lattice(Problem(med, grid, init, loads=[load])).weights   # the scheme reports J_i to the load
    Phi = init.Phi.copy()
    Phi[..., 1:, 0] *= np.asarray(stretch)
    f = np.einsum("...ij,...j->...i", Phi[..., 1:, 1:], load.force(Phi, None, 0.0)[..., :3])
    return np.einsum("ij,ijk->k", weights, f), float(np.sum(weights * np.sum(f * Phi[..., 1:, 0], axis=-1)))


def test_pressure_on_the_sphere_has_no_net_force_and_the_virial_3pV():
    """A uniform pressure on a closed surface: ∮ p n dA = 0 and ∮ p n·x dA = 3pV (n along
    ∂_u r × ∂_v r, inward on this chart, so V is −4π abc/3).  The chart measure J = sin θ is in the
    lattice's weights once: Σ w_i J_i (f_i/J_i) is the chart quadrature of p n dA.  Measured
    relative virial error on the sphere −9.7e-2, −3.9e-2, −1.08e-2, −2.8e-3 at N = 8, 16, 32, 64
    (order 2: the tangents' central differences; the chart measure counted twice leaves an O(1)
    error), the net force at round-off (the chart's symmetry)."""
    p = 0.7
    for stretch in ((1.0, 1.0, 1.0), (1.0, 0.8, 1.3)):
        V = -4.0 * math.pi / 3.0 * float(np.prod(stretch))
        errs = []
        for N in (16, 32):
            F, virial = _pressure_sums(N, p, stretch)
            assert np.abs(F).max() <= 1e-13 * abs(p)
            errs.append(abs(virial / (3.0 * p * V) - 1.0))
        assert errs[0] <= 0.05                              # 3.9e-2 on the sphere
        assert 1.7 <= math.log2(errs[0] / errs[1]) <= 2.3   # order 2 (1.84 on the sphere at N = 16 → 32)



def test_volume_pressure_gradient_across_the_poles():
    """``VolumePressure`` on the glued chart: V_h → −4π/3 at order 2 (2.6e-2, 6.5e-3, 1.6e-3 at
    N = 8, 16, 32 measured; signed by the chart's inward ∂_φ r × ∂_θ r), and its nodal forces
    w_i J_i T_i are p ∂V_h/∂η_i, the gradient through the ghost ends across the poles included:
    against central differences of V_h at the pole rows and the equator of a perturbed sphere
    (ε = 1e-6: 9e-10 of the largest component measured)."""
    from cartan_cosserat_surface.surface import VolumePressure

    errs = []
    for N in (8, 16):
        med, grid, init = _sphere(N)
        load = VolumePressure(1.0)
        Problem(med, grid, init, loads=[load])
        errs.append(abs(load.volume(init.Phi) / (-4.0 * math.pi / 3.0) - 1.0))
    assert errs[0] <= 0.03 and 1.8 <= math.log2(errs[0] / errs[1]) <= 2.2
    med, grid, init = _sphere(8)
    p = -0.3
    load = VolumePressure(p)
    weights = Lattice(Problem(med, grid, init, loads=[load])).weights
    g = med.group
    rng = np.random.default_rng(4)
    Phi = init.Phi @ g.exp(0.05 * rng.standard_normal((*grid.shape, 6)))
    _, G = load.volume_and_gradient(Phi)
    np.testing.assert_allclose(weights[..., None] * load.force(Phi, None, 0.0), p * G, atol=1e-14 * np.abs(G).max())
    assert_volume_gradient(load, g, Phi, ((0, 0), (3, 3), (5, 0), (2, 2)), 1e-8)


# ---------------------------------------------------------------------------- Jacobian
@pytest.mark.slow
@pytest.mark.parametrize("offset", [False, True])
def test_coloured_jacobian_matches_a_dense_difference_on_the_sphere(offset):
    """The coloured Jacobian (internal force, pressure read from the neighbours, a stress
    offset's geometric stiffness) against central differences column by column, N = 8 (the
    difference of both: their truncation and round-off, 1e-10 relative measured)."""
    med, grid, init = _sphere(8)
    prob = Problem(med, grid, init, loads=[Pressure(-0.01)])
    eq = _Equilibrium(prob, jacobian="fd")
    st, rng = _perturbed(eq)
    mu = np.zeros(eq.nmult)
    off = [0.1 * rng.standard_normal(x.shape) for x in eq.strains(st)] if offset else None
    K = eq.jacobian(st, mu, 1.0, off).toarray()

    def res(s):
        r = eq.residual(s, mu, 1.0)
        return r if off is None else r + eq.assemble(s, off)

    D = np.zeros_like(K)
    h = 1e-6
    for j in range(eq.nunk):
        d = np.zeros(eq.m)
        d[j] = h
        D[:, j] = (res(eq.update(st, mu, d)[0]) - res(eq.update(st, mu, -d)[0])) / (2 * h)
    assert np.abs(K - D).max() <= 1e-8 * np.abs(D).max()


# ---------------------------------------------------------------------------- pressurised sphere
def _pressurised(N: int, p: float = -1e-4):
    """The sphere (R = 1) under a uniform internal pressure |p| (p < 0 pushes outward on this
    chart, ∂_φ r × ∂_θ r being the inward normal), held against rigid motion by pins that the
    uniform expansion does not load: node A = (0, N/4) in translation and in rotation about the
    spatial x, y axes (its director lies in the x–z plane), node B half way round in y.  Returns
    the radial displacement about the mean position ``[N, N/2]`` and the pins' reactions."""
    med, grid, init = _sphere(N)
    prob = Problem(med, grid, init, loads=[Pressure(p)])
    m = N // 2
    ds = cartan.solve_static(prob, pins={N // 4: [0, 1, 2, 3, 4], (N // 2) * m + N // 4: [1]})
    x = ds["position"].values[-1]
    return np.linalg.norm(x - x.reshape(-1, 3).mean(axis=0), axis=-1) - 1.0, ds["reaction"].values


@pytest.mark.slow
def test_pressurised_sphere_converges_to_the_thin_shell_value():
    """Reference: a uniform radial displacement w stretches every direction by w/R, the membrane
    force N = Eh(w/R)/(1 − ν) pulls inward by 2N/R and the change of curvature w/R² in both
    directions adds the factor 1 + h²/(12R²) (as for the breathing mode,
    cases_sphere.py), so ``w = |p|R²(1 − ν)/(2Eh(1 + h²/12R²))`` (linear: |p| = 1e-4 gives
    w/R = 7e-4: the follower load's (1 + w/R)² and the Green–Lagrange strain change w by
    O(w/R) ≈ 1e-3 relative, below the N = 32 error of 8e-3).
    Measured (N = 8, 16, 32): mean error 0.385, 0.064, 0.0081 (orders 2.6, 3.0); equator rows
    −0.536, −0.0997, −0.0222 (2.4, 2.2); pole rows +1.33, +0.45, +0.11 (1.6, 2.0): the rows next
    to the poles bulge out, 13 % of w more than the equator at N = 32."""
    p = -1e-4
    w_ref = -p * (1 - NU) / (2 * E * H * (1 + H * H / 12))
    errs, reactions = {}, {}
    for N in (8, 16, 32):
        w, reaction = _pressurised(N, p)
        # the pins carry next to nothing: the discrete pressure is balanced in force by symmetry,
        # in moment to the discretisation (largest reaction 2.3e-6, 5.8e-9, 1.5e-10 at N = 8, 16, 32)
        reactions[N] = np.abs(reaction).max()
        assert reactions[N] <= 5e-3 * 4 * math.pi * abs(p) * (8 / N) ** 2
        # axisymmetric: every line of longitude alike (round-off and the pins' gauge)
        assert np.ptp(w, axis=0).max() <= 0.3 * w_ref * (8 / N) ** 2
        rel = w / w_ref - 1.0
        errs[N] = (abs(rel.mean()), abs(rel[:, N // 4].mean()), abs(rel[:, 0].mean()), rel)
    for k in range(3):
        e = [errs[N][k] for N in (8, 16, 32)]
        order = math.log2(e[1] / e[2])
        assert order >= 1.8, (k, e)  # second order: the pressure's central tangents, the lattice
    assert errs[32][0] <= 0.01  # 8.1e-3 measured
    rel = errs[32][3]
    spread = rel[:, 0].mean() - rel[:, 8].mean()  # pole row against the equator row
    assert 0.0 < spread <= 0.15  # 0.132 measured: the pole rows bulge, O(h²)


@pytest.mark.slow
def test_continuation_follows_the_linear_path_of_the_sphere():
    """``continuation`` on the glued chart: at this small pressure the path is linear, the mean
    radius grows as λ w (w the solve_static value at λ = 1, the O(w/R) = 1e-3 nonlinearity of
    the follower load and strains bounding the departure)."""
    N = 8
    med, grid, init = _sphere(N)
    prob = Problem(med, grid, init, loads=[Pressure(-1e-4)])
    m = N // 2

    def radius(ds):
        x = ds["position"].values[-1].reshape(-1, 3)
        return float(np.linalg.norm(x - x.mean(axis=0), axis=-1).mean() - 1.0)

    ds = cartan.continuation(prob, lam_max=1.0, ds0=0.4, monitor=radius,
                             pins={N // 4: [0, 1, 2, 3, 4], (N // 2) * m + N // 4: [1]})
    lam, mon = ds["load_factor"].values, ds["monitor"].values
    assert lam.size >= 3 and lam.max() >= 1.0 - 1e-9
    w1, _ = _pressurised(N)
    slope = float(w1.mean())
    assert np.abs(mon - lam * slope).max() <= 5e-3 * abs(slope)


# ---------------------------------------------------------------------------- implicit midpoint
@pytest.mark.slow
def test_implicit_midpoint_runs_on_the_sphere():
    """``implicit-midpoint`` shares the stencil and colouring: on the breathing sphere (N = 8,
    10 steps) it follows lie-verlet node by node to their O(Δt²) difference (both second order,
    ωΔt ≈ 0.02 here: 1e-4 of the displacement measured after 40 steps)."""
    from cartan_cosserat_surface.cases_sphere import radial_displacement, sphere_problem

    prob, dt = sphere_problem(8, radial_velocity=1e-3)
    w = [radial_displacement(cartan.simulate(prob, integrator=name, dt=dt, t_end=10 * dt, progress=False))[-1]
         for name in ("lie-verlet", "implicit-midpoint")]
    assert np.abs(w[1] - w[0]).max() <= 1e-3 * np.abs(w[0]).max()
    assert w[0].mean() > 0.0


@pytest.mark.slow
def test_volume_pressure_is_conservative_in_a_run():
    """``VolumePressure`` is a potential load: on the breathing sphere (N = 8, started at 0.01
    outward, internal pressure 0.02) ``lie-verlet`` keeps K + V (V with −pV_h) to the integrator's
    O(Δt²) — max drift over 2 time units 8.75e-5, 2.23e-5 of K's swing at Δt = 0.01, 0.005
    measured (order 1.97) — with no external work; the central-difference ``Pressure`` at the
    same pressure balances only K + V − W, 10 × less closely (8.8e-4, 2.1e-4)."""
    from cartan_cosserat_surface.cases_sphere import sphere_problem
    from cartan_cosserat_surface.surface import VolumePressure

    drift = []
    for fac in (1, 2):
        prob, dt = sphere_problem(8, radial_velocity=1e-2)
        pb = Problem(prob.medium, prob.grid, prob.initial, loads=[VolumePressure(-0.02)])
        ds = cartan.simulate(pb, integrator="lie-verlet", dt=dt / fac, t_end=2.0, progress=False)
        K, V, W = (ds[k].values for k in ("kinetic_energy", "potential_energy", "external_work"))
        assert np.all(W == 0.0)
        drift.append(np.ptp(K + V) / np.ptp(K))
    assert drift[0] <= 2e-4
    assert 1.7 <= math.log2(drift[0] / drift[1]) <= 2.3


def test_pressure_scenes_load_with_the_chart_measure():
    """The scenes ``sphere-pressure`` and ``sphere-volume-pressure`` build their loads from the
    problem; the lattice reports its node weights w_i J_i, J_i = sin θ_i on the unit sphere's chart."""
    from cartan_cosserat_surface.surface import VolumePressure

    from cartan.scene import scene

    sc = scene("sphere-pressure")
    (load,) = sc.problem.loads
    assert isinstance(load, Pressure) and load.chart_measure is None        # 1 until a scheme reports
    weights = Lattice(sc.problem).weights
    theta = sc.problem.grid.coordinates(1)
    np.testing.assert_allclose(load.chart_measure, np.broadcast_to(np.sin(theta), weights.shape), rtol=1e-2)
    np.testing.assert_allclose(weights / load.chart_measure, sc.problem.grid.node_weights(), rtol=1e-14)
    (vload,) = scene("sphere-volume-pressure").problem.loads
    assert isinstance(vload, VolumePressure) and vload.pressure == -0.002
