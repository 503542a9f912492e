"""``Held`` ends and ``Symmetry`` faces on the ``collocation`` scheme (numpy path).

The held body components of the end node get zero velocity, momentum and force, as a clamp does
for all of them (the clamp mask ``(*shape, r)`` of :meth:`cartan.schemes.base.Scheme._clamp_mask`,
shared with the lattice); the free components obey the natural condition n_α Q^α = 0, the
simultaneous-approximation term of an unloaded free end (paper §IV.D; docs/schemes.md,
"Boundaries").

A Cosserat rod (SE(3)) clamped at both ends and set moving by a smooth velocity profile that is
symmetric about mid-span, V(u) = sin²(πu/L) V₀, is compared with its half [0, L/2] whose cut is a
``Symmetry`` end (v₁ and ω₂, ω₃ held; v₂, v₃ and the twist ω₁ free, traction-free).  The half and
the whole share the interior stencils, so their difference is the closure at the cut (the SBP
row and its penalty against the whole's central stencil): it vanishes faster than the scheme's
own O(h²) error.  The lattice's half problem equals its whole problem to round-off
(tests/test_symmetry_faces.py), so the collocation's half against the lattice's half is the
difference of two second-order schemes.  A pinned end (``Held((0, 1, 2))``) and an octant of a
Cosserat block (d = 3, three symmetry faces) close the energy balance at lie-verlet's order.
Numpy backend, no compilation; Δt ∝ h.
"""

from __future__ import annotations

import numpy as np
import pytest

import cartan
from cartan._backend import use_backend
from cartan.schemes.collocation import Collocation

V0 = np.array([0.0, 0.3, 0.6])  # the mid-span velocity (m/s), transverse
T_END = 0.04
C_AXIAL = np.sqrt(1e6 / 1000.0)  # the fastest wave speed √(E/ρ) (m/s)


@pytest.fixture(autouse=True)
def _numpy_backend():
    with use_backend("numpy"):
        yield


def _rod():
    return cartan.medium("cosserat-rod", E=1e6, G=4e5, radius=0.05, density=1000.0)


def _problem(n: int, length: float, boundaries: dict) -> cartan.Problem:
    rod = _rod()
    grid = cartan.Grid(n, length=length)
    u = grid.coordinates(0)
    N = np.zeros((n, 6))
    N[:, :3] = np.sin(np.pi * u)[:, None] ** 2 * V0  # symmetric about u = 1/2, zero at u = 0 and 1
    return cartan.Problem(rod, grid, cartan.InitialState(Phi=rod.initial_state(grid, "straight").Phi, N=N),
                          boundaries=boundaries)


def _half(m: int) -> cartan.Problem:
    return _problem(m, 0.5, {"start": cartan.Clamped(), "end": cartan.Symmetry()})


def _run(problem: cartan.Problem, scheme: str, dt: float, t_end: float = T_END, **options):
    steps = int(round(t_end / dt))
    return cartan.simulate(problem, scheme=scheme, integrator="lie-verlet", dt=t_end / steps, t_end=t_end,
                           save_every=max(1, steps // 4), progress=False, scheme_options=options or None)


def _dt(m: int) -> float:
    """Half the axial CFL step on the half's spacing h = 0.5/(m − 1)."""
    return 0.5 * (0.5 / (m - 1)) / C_AXIAL


def test_symmetry_end_holds_its_components_and_the_mask():
    """The clamp mask is ``(n, 6)`` with the mirror conditions at the cut (v₁, ω₂, ω₃), all six at
    the clamp; the compiled operators take it (tests/test_collocation_held_compiled.py); the held
    components stay zero to the bit and the stepped frames (``track_frames``) keep the cut in its
    plane, u·n = 0, to round-off (the frames rebuilt from the strains, the default, keep it to the
    integrability residual only)."""
    scheme = Collocation(_half(9))
    assert scheme._clamped.shape == (9, 6)
    assert scheme._clamped[-1].tolist() == [True, False, False, False, True, True]
    assert scheme._clamped[0].all() and not scheme._clamped[1:-1].any()
    assert scheme.held_nodes().tolist() == [True] + [False] * 8
    ops = scheme.compiled_operators()
    assert ops.ok and ops.data.any_held, ops.reason
    out = _run(_half(9), "collocation", _dt(9), track_frames=True)
    N, S = out.N.values, out.S.values
    assert np.all(N[:, -1, [0, 4, 5]] == 0.0) and np.all(S[:, -1, [0, 4, 5]] == 0.0)
    assert np.all(N[:, 0] == 0.0)
    assert np.max(np.abs(N[1:, -1, 1:3])) > 0.1 * np.max(np.abs(V0))  # the free components move
    x = out.position.values
    assert np.max(np.abs(x[:, -1, 0] - x[0, -1, 0])) < 1e-14  # the cut stays in its plane (u·n = 0)
    d1 = out.frame.values[:, -1, :, 0]  # and its tangent along n (φ ∥ n)
    assert np.max(np.abs(d1 - [1.0, 0.0, 0.0])) < 1e-14


def test_half_with_a_symmetry_end_converges_to_the_whole():
    """The half (m nodes, ``Symmetry`` at the cut) against the whole (2m − 1 nodes, both ends
    clamped), positions at t = 0.04 on the half's nodes, m = 9, 17, 33.  Measured: 1.7e-5, 1.9e-6,
    2.5e-7 (orders 3.1, 2.9, above the scheme's order 2: the interior error is shared and only the
    cut's closure differs; 3.5–3.9 at Δt/2 and m up to 81); asserted: an observed order > 2.5 at
    each refinement (above the scheme's order 2, below the measured 2.9), and the motion is not
    small (≈ 2 cm)."""
    errors = []
    for m in (9, 17, 33):
        dt = _dt(m)
        half = _run(_half(m), "collocation", dt).position.values
        whole = _run(_problem(2 * m - 1, 1.0, {"start": cartan.Clamped(), "end": cartan.Clamped()}),
                     "collocation", dt).position.values[:, :m]
        assert np.max(np.abs(half[-1] - half[0])) > 0.01
        errors.append(float(np.max(np.abs(half[-1] - whole[-1]))))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(orders > 2.5), (errors, orders)


def test_half_agrees_with_the_lattice_half_as_n_grows():
    """The collocation's half against the lattice's half (both with the ``Symmetry`` end, the
    same Δt), m = 9, 17, 33: the difference of two second-order schemes.  Measured: 8.8e-4,
    2.4e-4, 7.9e-5 (orders 1.9, 1.6; the same gap as between the two schemes' whole problems,
    whose order falls near 1 at m = 81 at Δt/2: not the cut's); asserted: a factor > 2 per halving
    of h (order > 1, below the measured 1.6)."""
    gaps = []
    for m in (9, 17, 33):
        dt = _dt(m)
        col = _run(_half(m), "collocation", dt).position.values[-1]
        lat = _run(_half(m), "lattice", dt).position.values[-1]
        gaps.append(float(np.max(np.abs(col - lat))))
    ratios = np.array(gaps[:-1]) / np.array(gaps[1:])
    assert np.all(ratios > 2.0), (gaps, ratios)


def test_held_end_energy_balance_closes_at_second_order():
    """A rod clamped at u = 0 and pinned at u = L (``Held((0, 1, 2))``: the position held, the frame
    free): the end's velocity and momentum are zero on (0, 1, 2) to the bit, its rotation moves,
    and lie-verlet's energy error max |E − E₀| falls by ≈ 4 when Δt is halved (measured 6.1e-4 and
    1.5e-4 of E₀ = 0.66 over t = 0.08, order 1.98; asserted: an observed order between 1.8 and
    2.2, the integrator's order 2 ± 0.2)."""
    problem = _problem(17, 1.0, {"start": cartan.Clamped(), "end": cartan.Held((0, 1, 2))})
    errors = []
    for dt in (_dt(9), 0.5 * _dt(9)):
        out = _run(problem, "collocation", dt, t_end=0.08)
        N, S = out.N.values, out.S.values
        assert np.all(N[:, -1, :3] == 0.0) and np.all(S[:, -1, :3] == 0.0)
        assert np.max(np.abs(N[1:, -1, 3:])) > 0.0  # the pinned end turns
        E = (out.kinetic_energy.values + out.potential_energy.values + out.dissipated_energy.values
             - out.external_work.values)
        assert out.external_work.values[-1] == 0.0  # a support does no work
        errors.append(float(np.max(np.abs(E - E[0]))))
    order = np.log2(errors[0] / errors[1])
    assert 1.8 < order < 2.2, (errors, order)


def test_octant_faces_hold_and_the_energy_balance_closes():
    """d = 3: an octant of a Cosserat block (4³ nodes) with three ``Symmetry`` faces and a
    traction suddenly applied on its far u-face.  With stepped frames each face stays in its plane
    (x on the u-face, y on the v-face, z on the w-face) to the bit, and the energy balance
    E = K + U − W_ext closes at lie-verlet's order: measured max |E| 1.04e-6, 2.6e-7, 6.5e-8 of a
    work 1.2e-4 at Δt = 0.02, 0.01, 0.005 (orders 2.00, 2.00); asserted at the first two: an
    observed order between 1.8 and 2.2 (the integrator's 2 ± 0.2)."""
    solid = cartan.medium("cosserat-solid")
    grid = cartan.Grid((4, 4, 4), length=(0.5, 0.5, 0.5))
    problem = cartan.Problem(solid, grid, solid.initial_state(grid, "undeformed"),
                             {"u-start": cartan.Symmetry(), "v-start": cartan.Symmetry(normal="y"),
                              "w-start": cartan.Symmetry(normal="z"),
                              "u-end": cartan.Free(load=[-0.05, 0.0, 0.0, 0.0, 0.0, 0.0])})
    errors = []
    for dt in (0.02, 0.01):
        out = _run(problem, "collocation", dt, t_end=0.4, track_frames=True)
        x = out.position.values
        assert np.max(np.abs(x - x[0])) > 5e-3  # it moved
        assert np.array_equal(x[:, 0, :, :, 0], np.broadcast_to(x[0, 0, :, :, 0], x[:, 0, :, :, 0].shape))
        assert np.array_equal(x[:, :, 0, :, 1], np.broadcast_to(x[0, :, 0, :, 1], x[:, :, 0, :, 1].shape))
        assert np.array_equal(x[:, :, :, 0, 2], np.broadcast_to(x[0, :, :, 0, 2], x[:, :, :, 0, 2].shape))
        E = (out.kinetic_energy.values + out.potential_energy.values + out.dissipated_energy.values
             - out.external_work.values)
        errors.append(float(np.max(np.abs(E - E[0]))))
    order = np.log2(errors[0] / errors[1])
    assert 1.8 < order < 2.2, (errors, order)


def test_nambu_goto_string_between_fixed_ends_converges_at_order_two():
    """The relativistic-rod plugin's Nambu–Goto string between two ``Held`` ends fixed in space
    (``fixed_end()``: the spatial velocity and the frame held, r⁰ free; docs/media/relativistic-rod.md,
    "Fixed ends"), its exact standing wave (θ₀ = 0.8) to t = L/c, on the collocation scheme with
    stepped frames: the ends stay put to round-off, and the lab positions' error against the exact
    wave falls as h²: measured 3.2e-3, 7.8e-4 at 17, 33 nodes (order 2.04; 4.2e-3, 1.05e-3,
    2.7e-4 at 17, 33, 65 with frames rebuilt from the strains, orders 1.99, 1.96); asserted: an
    observed order within 2 ± 0.15 (the scheme's order 2)."""
    fixed = pytest.importorskip("cartan_relativistic.fixed")
    rod = cartan.medium("relativistic-rod")
    errors = []
    for n in (17, 33):
        grid = cartan.Grid(n, length=1.0)
        problem = cartan.Problem(rod, grid, rod.initial_state(grid, "standing", angle=0.8),
                                 boundaries={"start": fixed.fixed_end(), "end": fixed.fixed_end()})
        out = _run(problem, "collocation", 0.5 * grid.spacing[0], t_end=1.0, track_frames=True)
        lab = np.stack([out.lab_x.values, out.lab_y.values, out.lab_z.values], axis=-1)
        assert np.max(np.abs(lab[:, 0])) <= 1e-15
        assert np.max(np.abs(lab[:, -1] - [fixed.span(0.8, 1.0), 0.0, 0.0])) <= 1e-14
        sigma = grid.coordinates(0)
        errors.append(max(float(np.max(np.linalg.norm(lab[k] - fixed.fixed_standing_wave(sigma, float(t), 0.8, 1.0)[0],
                                                      axis=-1))) for k, t in enumerate(out.time.values)))
    order = np.log2(errors[0] / errors[1])
    assert abs(order - 2.0) <= 0.15, (errors, order)


def test_bad_input():
    """A Held end leaving free a set that is not a subalgebra is refused (``rattle`` takes held
    components on the collocation: tests/test_collocation_rattle_reactions.py; a Driven end moves
    there: tests/test_collocation_driven.py)."""
    with pytest.raises(ValueError, match="subalgebra"):  # ω₁, ω₂ free: [e₄, e₅] has a component along e₃
        Collocation(_problem(9, 0.5, {"start": cartan.Clamped(), "end": cartan.Held((0, 1, 2, 3))}))
