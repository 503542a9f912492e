"""``rattle`` on the ``collocation`` scheme: the supports' reactions and ``Held`` ends.

``Rattle.support_reaction`` on the collocation's nodal rows (:class:`cartan.constraints.
NodalStrainConstraints`): ``R = −w(W + ad_NᵀS) − B_cᵀλ`` on the held components, W the scheme's
raw force (``Collocation.force(raw=True)``: not zeroed at the supports, with the clamped end's
natural-condition term, so that ``−wW`` is the weak-form force ``Lᵀ(wQ)`` minus the loads) and
``B_cᵀλ`` the rows' force (the filament's tension and shear, all multiplier).  Checked on exact
equilibria (a filament hanging from its clamp or pin; an arc under its end moment) to round-off,
and (slow) on the cantilever under its weight relaxed to rest: the clamp balances the weight and
its moment at the scheme's second order in h, and agrees with the lattice's reaction at that
order.  ``Held`` ends and ``Symmetry`` faces: the rows at round-off, the held components held,
the energy error of second order in Δt, and (slow) the lattice's motion at second order in h.
"""

from __future__ import annotations

import numpy as np
import pytest
from toys import PLANAR_PIN, frames_of, pinned_arc

import cartan
from cartan.integrators import Rattle
from cartan.schemes import Lattice
from cartan.schemes.collocation import Collocation


def filament():
    return cartan.medium("filament", bending=1.0, twist=0.8, mass=1.0, rotational_inertia=0.01)


def spatial_wrench(scheme, state, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The spatial force and moment about the origin of the body wrenches R ``[n, 6]`` (force
    first, the filament's (v, ω) order), summed over the nodes."""
    Phi = scheme.frames(state)
    f = np.einsum("nij,nj->ni", Phi[:, 1:, 1:], R[:, :3])
    m = np.einsum("nij,nj->ni", Phi[:, 1:, 1:], R[:, 3:]) + np.cross(Phi[:, 1:, 0], f)
    return f.sum(axis=0), m.sum(axis=0)


def hanging(support, n: int = 11, g: float = 3.0) -> cartan.Problem:
    """A straight filament (L = 1, ρA = 1) hanging along +x from its support at s = 0 under
    gravity g e_x: an exact equilibrium of both schemes, its tension ρg(L − s) all multiplier."""
    fil = filament()
    grid = cartan.Grid(n, length=1.0)
    return cartan.Problem(fil, grid, fil.initial_state(grid, "straight"), {"start": support, "end": cartan.Free()},
                          loads=[fil.make_load("gravity", g=[g, 0.0, 0.0])])


@pytest.mark.parametrize("support", [cartan.Clamped(), cartan.Held((0, 1, 2))], ids=["clamped", "pinned"])
@pytest.mark.parametrize("cls", [Collocation, Lattice])
def test_the_support_carries_the_weight_of_the_hanging_filament(cls, support):
    """The clamp (whole node) or pin (translations held: ``Rattle.support_reaction``'s
    held-components path, ``force(raw=True)``) of the hanging filament carries its weight,
    −ρgL e_x, and no moment, to round-off (bound 1e-12 on a weight of 3; the rows' tension is
    the reaction's all but the end node's share w₀ρg: the scheme's reaction alone is that share),
    at the start and after 10 steps (it stays at rest: an exact equilibrium)."""
    scheme, integ = cls(hanging(support)), Rattle()
    state = scheme.initial_state()
    for k in range(2):
        R = integ.support_reaction(scheme, state)
        assert np.all(R[1:] == 0.0)
        f, m = spatial_wrench(scheme, state, R)
        np.testing.assert_allclose(f, [-3.0, 0.0, 0.0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(m, 0.0, atol=1e-12)
        if k == 0:
            for _ in range(10):
                integ.step(scheme, state, 4e-3)
    assert np.max(np.abs(scheme.velocity(state))) < 1e-12
    if cls is Collocation and isinstance(support, cartan.Clamped):
        f_node, _ = spatial_wrench(scheme, state, scheme.support_reaction(state))
        np.testing.assert_allclose(f_node, [-3.0 * scheme.weights[0], 0.0, 0.0], atol=1e-12)


@pytest.mark.parametrize("cls", [Collocation, Lattice])
def test_the_clamp_holds_the_end_moment_of_an_arc(cls):
    """An arc of curvature κ = 1.3 (B = 1) under the end moment Bκ e₃ is an exact equilibrium
    (constant strains, constant stress, no tension): the clamp's reaction is the moment −Bκ e₃
    and no force, to round-off (bound 1e-12).  On the collocation scheme it is the clamped end's
    stress ``Q₀`` (the natural-condition term of ``force(raw=True)``): the strong-form force
    density at the node, times its weight h/2, would miss it."""
    kappa = 1.3
    fil = filament()
    grid = cartan.Grid(11, length=1.0)
    problem = cartan.Problem(fil, grid, fil.initial_state(grid, "arc", curvature=kappa),
                             {"start": cartan.Clamped(), "end": cartan.Free(load=[0, 0, 0, 0, 0, kappa])})
    scheme, integ = cls(problem), Rattle()
    state = scheme.initial_state()
    R = integ.support_reaction(scheme, state)
    np.testing.assert_allclose(R[0], [0, 0, 0, 0, 0, -kappa], atol=1e-12)
    assert np.all(R[1:] == 0.0)
    if cls is Collocation:
        np.testing.assert_allclose(scheme.support_reaction(state)[0], R[0], atol=1e-12)
        strong = -scheme.weights[0] * (scheme.force(state, scheme.velocity(state), 0.0, raw=True)[0]
                                       - scheme._clamped_traction(state)[0])
        assert abs(strong[5]) < 1e-12  # the strong form alone holds nothing


@pytest.mark.parametrize("cls", [Collocation, Lattice])
def test_the_scheme_reaction_of_an_unconstrained_rod(cls):
    """The same equilibrium for a ``cosserat-rod`` (no rows: the scheme's ``support_reaction``
    alone, the lattice's and the collocation's override): the clamp's moment −Bκ and no force
    to 1e-12, on the collocation the end's stress carried by the raw force's natural-condition
    term."""
    kappa = 1.3
    rod = cartan.medium("cosserat-rod", stretch_shear=[1e3, 1e3, 1e3], bend_twist=[1.0, 1.0, 1.0], mass=1.0,
                        rotational_inertia=[0.02, 0.01, 0.01])
    grid = cartan.Grid(11, length=1.0)
    problem = cartan.Problem(rod, grid, rod.initial_state(grid, "arc", curvature=kappa),
                             {"start": cartan.Clamped(), "end": cartan.Free(load=[0, 0, 0, 0, 0, kappa])})
    scheme = cls(problem)
    R = scheme.support_reaction(scheme.initial_state())
    np.testing.assert_allclose(R[0], [0, 0, 0, 0, 0, -kappa], atol=1e-12)
    assert np.all(R[1:] == 0.0)


def test_the_rows_keep_the_length_between_supports():
    """The dependent combinations are those of the operator (found with every node component
    free): the stretch's odd–even mode (½, −1, 1, …, ½) only, whatever the ends.  Between two
    supports that hold the translations (pins, clamps) the straight reference has a second one,
    the weighted sum Σ w(X₁ − 1) (the length between them), a real constraint on a slack shape:
    it stays held (3n − 1 rows of 3n, as clamped–free)."""
    n = 11
    ripple = (-1.0) ** np.arange(n)
    ripple[[0, -1]] *= 0.5
    for ends in ({"start": cartan.Held(PLANAR_PIN), "end": cartan.Held(PLANAR_PIN)},
                 {"start": cartan.Clamped(), "end": cartan.Clamped()},
                 {"start": cartan.Held(PLANAR_PIN), "end": cartan.Free()}):
        problem = pinned_arc(n=n)
        problem = cartan.Problem(problem.medium, problem.grid, problem.initial, ends, loads=problem.loads)
        scheme = Collocation(problem)
        con = Rattle()._constraints(scheme, scheme.initial_state())[0]
        assert con.nrow == 3 * n and con.ncon == 3 * n - 1, ends
        mode = np.linalg.svd(con.T.toarray(), full_matrices=True)[0][:, -1].reshape(n, 3)  # the one left out
        assert np.max(np.abs(mode[:, 1:])) < 1e-12
        assert abs(abs(mode[:, 0] @ ripple) / np.linalg.norm(ripple) - 1.0) < 1e-12


def test_symmetry_face_on_collocation():
    """The half s ≤ L/2 of the arc pinned by ball joints, with a ``Symmetry`` face at s = L/2 (the
    node slides in the plane x = 0 and turns about x only), on the collocation scheme (n = 6): the
    rows at round-off, the face node on its plane exactly, the held components zero; it moves
    as the whole arc's first half to the scheme's accuracy (max position difference over t ≤ 0.3
    measured 2.1e-2, 6.1e-3, 2.1e-3 at n = 11, 21, 41 for the whole, almost all of it the
    collocated grid's odd–even mode, first order between two supports: docs/schemes.md,
    "Between two supports: the odd–even error"; asserted < 0.05 at n = 11, where the middle
    moves by 0.028)."""
    full = pinned_arc(end=None)
    full = cartan.Problem(full.medium, full.grid, full.initial,
                          {"start": cartan.Held((0, 1, 2)), "end": cartan.Held((0, 1, 2))}, loads=full.loads)
    half = cartan.Problem(full.medium, cartan.Grid(6, length=0.5), cartan.InitialState(Phi=full.initial.Phi[:6].copy()),
                          {"start": cartan.Held((0, 1, 2)), "end": cartan.Symmetry()}, loads=full.loads)
    run = {"scheme": "collocation", "integrator": "rattle", "dt": 2e-3, "t_end": 0.3, "save_every": 25,
           "progress": False, "compiled": False}
    a, b = cartan.simulate(full, **run), cartan.simulate(half, **run)
    assert float(np.max(b.constraint_residual.values)) < 1e-12
    assert np.max(np.abs(b.position.values[:, -1, 0])) == 0.0
    assert np.all(b.N.values[:, -1, [0, 4, 5]] == 0.0)
    assert float(np.ptp(a.position.values[:, 5, 1])) > 1e-2
    assert np.max(np.abs(a.position.values[:, :6] - b.position.values)) < 0.05


# ---------------------------------------------------------------------------- slow: convergence in h
G = 2.0  # the cantilever's gravity −G e_z (ρA = 1: a weight G)


def cantilever(n: int, initial=None, damping=None) -> cartan.Problem:
    fil = filament()
    grid = cartan.Grid(n, length=1.0)
    loads = [fil.make_load("gravity", g=[0.0, 0.0, -G])] + ([] if damping is None else [cartan.Damping(damping)])
    return cartan.Problem(fil, grid, fil.initial_state(grid, "straight") if initial is None else initial,
                          {"start": cartan.Clamped(), "end": cartan.Free()}, loads=loads)


@pytest.mark.slow  # ≈ 4000 Python steps (≈ 25 s)
def test_cantilever_clamp_balances_the_weight_at_second_order():
    """The horizontal cantilever under its weight (ρAgL³/B = 2), started on the lattice's static
    solution and relaxed to rest on the collocation scheme (damping 6 on the translations, until
    max|N| < 1e-8): the clamp's force balances the weight ρgL and its moment the weight's
    moment about the clamp, Σ w_i (x_i − x_0) × ρg, up to the scheme's O(h²) (the discrete D has
    no product rule: the internal forces cancel to O(h²) only).  Measured at n = 11, 21, 41: the
    force's error 9.36e-3, 2.48e-3, 6.36e-4 (ratios 3.8, 3.9), the moment's 3.8e-4, 1.0e-4,
    2.6e-5, the differences with the lattice's reaction (exact balance) 9.3e-3, 2.5e-3, 6.3e-4
    (force) and 1.09e-3, 2.9e-4, 7.5e-5 (moment); asserted: a ratio > 2^1.5 from n = 11 to 21,
    and at n = 11 errors below 1e-2 of the weight (force) and 1e-3 (moment, of ≈ 0.98)."""
    err_f, err_m, lat_f, lat_m = [], [], [], []
    for n in (11, 21):
        static = cartan.solve_static(cantilever(n), tol=1e-12)
        lattice = Lattice(cantilever(n, cartan.InitialState(Phi=frames_of(static))))
        st = lattice.initial_state()
        fL, mL = spatial_wrench(lattice, st, Rattle().support_reaction(lattice, st))
        scheme = Collocation(cantilever(n, cartan.InitialState(Phi=frames_of(static)), damping=[6.0] * 3 + [0.05] * 3))
        state, integ = scheme.initial_state(), Rattle()
        dt = 4e-3 * 11 / n
        for _ in range(6000):
            integ.step(scheme, state, dt)
            if np.max(np.abs(scheme.velocity(state))) < 1e-8:
                break
        assert np.max(np.abs(scheme.velocity(state))) < 1e-8
        f, m = spatial_wrench(scheme, state, integ.support_reaction(scheme, state))
        x = scheme.frames(state)[:, 1:, 0]
        m_weight = np.sum(scheme.weights[:, None] * np.cross(x - x[0], [0.0, 0.0, -G]), axis=0)
        err_f.append(float(np.linalg.norm(f - [0.0, 0.0, G])))
        err_m.append(float(np.linalg.norm(m + m_weight)))
        lat_f.append(float(np.linalg.norm(f - fL)))
        lat_m.append(float(np.linalg.norm(m - mL)))
    assert err_f[0] < 1e-2 * G and err_m[0] < 1e-3, (err_f, err_m)
    for errs in (err_f, err_m, lat_f, lat_m):
        assert errs[0] / errs[1] > 2**1.5, (err_f, err_m, lat_f, lat_m)


@pytest.mark.slow  # ≈ 1800 Python steps (≈ 10 s)
def test_pinned_filament_agrees_with_the_lattice_as_n_grows():
    """The arc pinned at s = 0 (``Held``, planar pin) and free at s = L swinging down under
    gravity, t = 0.3 with Δt = 1e-3, on both schemes at the same n: the tips' difference falls at
    second order in h (measured 6.3e-3, 1.8e-3, 4.1e-4 at n = 11, 21, 41: ratios 3.5, 4.4;
    asserted > 2^1.5; the tip moves by ≈ 0.3), the rows at round-off."""
    errs = []
    for n in (11, 21, 41):
        tips = []
        for cls in (Collocation, Lattice):
            scheme, integ = cls(pinned_arc(n=n, end=cartan.Free())), Rattle()
            state = scheme.initial_state()
            for _ in range(300):
                integ.step(scheme, state, 1e-3)
            assert integ.constraint_residual(scheme, state) < 1e-12
            tips.append(scheme.frames(state)[-1, 1:, 0])
        errs.append(float(np.linalg.norm(tips[0] - tips[1])))
    assert errs[0] / errs[1] > 2**1.5 and errs[1] / errs[2] > 2**1.5, errs
