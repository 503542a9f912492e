"""The ``cosserat-surface`` medium: a geometrically exact first-order-shear shell on SE(3) (paper §VI.B).

(M, X, G) = (a 2D chart (u, v), E³ × S², SE(3)), d = 2.  The structure field Φ = (r, R) carries
the mid-surface point r and a frame R = (e₁ e₂ e₃) whose third vector is the director
p = R e₃.  The strains X_α = Φ⁻¹∂_αΦ = {θ_α; π_α} (α = u, v) hold, in the frame,

* θ_α = Rᵀ∂_α r — the tangent vectors of the mid-surface,
* π_α — the rotation rates, [π_α]× = Rᵀ∂_α R, so that ∂_α p = R (π_α × e₃) = R d_α with
  d_α = (π_α,2, −π_α,1, 0).

Strain measures (all invariant under a rotation of the frame about p, the drill)
    * metric a_αβ = θ_α·θ_β and membrane strain ε_αβ = ½(a_αβ − a⁰_αβ) (Green–Lagrange),
    * transverse shear γ_α = θ_α·e₃ − θ⁰_α·e₃ = θ_α,3 − θ⁰_α,3,
    * bending κ_αβ = sym(θ_α·d_β) − sym(θ⁰_α·d⁰_β) (the change of a_α·∂_β p, Naghdi's measure).

The superscript 0 marks the rest strain X₀ at the point: the medium's constant
:meth:`~CosseratSurface.rest_strain` (flat, or a cylinder of constant curvature), or the strain
of a stress-free reference configuration given to ``Problem(reference=Φ_ref)`` (any shape).

Energy per unit chart area (St Venant–Kirchhoff, plane stress, thickness h)
    U = √a⁰ [ ½ h 𝒞(ε, ε) + ½ κ_s G h A^αβ γ_α γ_β + ½ (h³/12) 𝒞(κ, κ) ],

with A = (a⁰)⁻¹ the inverse rest metric, 𝒞^{αβγδ} = E/(1−ν²) [ν A^αβ A^γδ +
½(1−ν)(A^αγ A^βδ + A^αδ A^βγ)], G = E/(2(1+ν)) and κ_s the shear correction.  The stress
Q^α = ∂U/∂X_α is, with the resultants n = h𝒞ε, q^α = κ_s G h A^αβ γ_β, m = (h³/12)𝒞κ,

    ∂U/∂θ_α = √a⁰ [ n^αβ θ_β + q^α e₃ + m^αβ (π_β,2, −π_β,1, 0) ],
    ∂U/∂π_β = √a⁰ m^αβ (−θ_α,2, θ_α,1, 0).

Drill (gauge)
    The energy does not depend on the drill components π_α,3 (their stress is identically 0)
    nor on a rotation of the frame about p: the drill rotation Ω₃ is a gauge (paper §VI.B),
    with zero inertia, so the core holds Ω₃ = 0 and the frame is transported without spin
    about the director.  π_α,3 is carried by the lattice but enters neither the energy nor
    any output.

Kinetic energy per unit reference area (paper §VI.B: [K] = energy per unit material area)
    K = ½ ρh |V|² + ½ (ρh³/12)(Ω₁² + Ω₂²), drill inertia 0.  On a chart that is not the
    reference's own measure (the sphere by longitude and colatitude) the medium reports the
    reference area element √a⁰ per unit chart area (:meth:`~CosseratSurface.reference_volume`)
    and the lattice weighs a node's mass and its loads by it; flat plates and cylinders by
    arclength have √a⁰ = 1.

The closed sphere (``"sphere"`` initial kind)
    Longitude u (periodic, N even) × colatitude v, glued across the poles
    (``Grid(..., glued=(None, 0))``, paper §VII.B): the colatitude nodes are staggered,
    v_j = (j + ½)π/n, no node on a pole, and the line of longitude φ continues across a pole
    onto the line φ + π, whose frames seen from it are turned by π about the normal (the
    state's glue Γ).  Frames e₁ = e_φ (east), e₂ = −e_θ (north), e₃ = e_r (outward).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, ClassVar

import numpy as np
from numba import njit

import cartan
from cartan.grid import Grid
from cartan.medium import KernelMedium, MediumKernels, check_finite, check_positive
from cartan.problem import ConstantFieldPotential, InitialState, Load, PotentialLoad, UniformForce, axis_holonomies
from cartan.scatter import scatter_add
from cartan.supports import PenaltySupport, SymmetrySupport  # the core's face supports, d = 2 by default

__all__ = ["CosseratSurface", "NodeSprings", "PenaltySupport", "Pressure", "SurfaceGravity", "SymmetrySupport",
           "VolumePressure", "shell_point",
           "surface_energy", "surface_stress"]


# ====================================================================== point kernels
#: the shell's helpers, inlined into their callers (numba IR inlining): a call of a separately
#: compiled function with array arguments costs the corner stress of the compiled loops more
#: than its arithmetic (≈ 95 ns per corner out of line, ≈ 56 inlined; docs/performance.md, T9)
_inline = njit(inline="always", error_model="numpy")


@_inline
def _constitutive(xuu, xuv, xvv, Auu, Auv, Avv, nu, c):  # pragma: no cover - compiled
    """Contravariant s = c [ν A tr_A(x) + (1 − ν) A x A] of a symmetric covariant tensor x."""
    tr = Auu * xuu + 2.0 * Auv * xuv + Avv * xvv
    suu = nu * Auu * tr + (1.0 - nu) * (Auu * Auu * xuu + 2.0 * Auu * Auv * xuv + Auv * Auv * xvv)
    suv = nu * Auv * tr + (1.0 - nu) * (Auu * Auv * xuu + (Auu * Avv + Auv * Auv) * xuv + Auv * Avv * xvv)
    svv = nu * Avv * tr + (1.0 - nu) * (Auv * Auv * xuu + 2.0 * Auv * Avv * xuv + Avv * Avv * xvv)
    return c * suu, c * suv, c * svv


@_inline
def shell_point(X, X0, p, Q, want, nm, ks):  # pragma: no cover - compiled
    """Energy density of a first-order shell at one point; writes Q = ∂U/∂X when ``want``.

    The membrane strain is half the change of the metric θ_a · θ_b over the first ``nm``
    components of θ (3: the Naghdi shell's whole θ; 2: the tangent components of a
    Kirchhoff–Love surface, whose θ_a,3 is held at zero); the transverse shear energy has the
    factor ``ks`` (κ_s; 0: none).  ``p = (E, ν, h, …)``; X, X₀ ``(2, 6)``; Q ``(2, 6)``, the
    drill components π_a,3 and, with ``nm = 2``, θ_a,3 without constitutive stress (see the
    module docstring).
    """
    E, nu, h = p[0], p[1], p[2]
    cs = E / (1.0 - nu * nu)
    G = 0.5 * E / (1.0 + nu)
    # rest metric, its inverse and the area element
    a0uu, a0uv, a0vv = 0.0, 0.0, 0.0
    auu, auv, avv = 0.0, 0.0, 0.0
    for k in range(nm):
        a0uu += X0[0, k] * X0[0, k]
        a0uv += X0[0, k] * X0[1, k]
        a0vv += X0[1, k] * X0[1, k]
        auu += X[0, k] * X[0, k]
        auv += X[0, k] * X[1, k]
        avv += X[1, k] * X[1, k]
    det0 = a0uu * a0vv - a0uv * a0uv
    J = np.sqrt(det0)
    Auu, Auv, Avv = a0vv / det0, -a0uv / det0, a0uu / det0
    # membrane strain
    euu, euv, evv = 0.5 * (auu - a0uu), 0.5 * (auv - a0uv), 0.5 * (avv - a0vv)
    # bending: b_ab = θ_a · d_b with d_b = (π_b2, −π_b1, 0)
    buu = X[0, 0] * X[0, 4] - X[0, 1] * X[0, 3]
    buv = X[0, 0] * X[1, 4] - X[0, 1] * X[1, 3]
    bvu = X[1, 0] * X[0, 4] - X[1, 1] * X[0, 3]
    bvv = X[1, 0] * X[1, 4] - X[1, 1] * X[1, 3]
    b0uu = X0[0, 0] * X0[0, 4] - X0[0, 1] * X0[0, 3]
    b0uv = X0[0, 0] * X0[1, 4] - X0[0, 1] * X0[1, 3]
    b0vu = X0[1, 0] * X0[0, 4] - X0[1, 1] * X0[0, 3]
    b0vv = X0[1, 0] * X0[1, 4] - X0[1, 1] * X0[1, 3]
    kuu, kuv, kvv = buu - b0uu, 0.5 * (buv + bvu - b0uv - b0vu), bvv - b0vv
    nuu, nuv, nvv = _constitutive(euu, euv, evv, Auu, Auv, Avv, nu, cs * h)
    muu, muv, mvv = _constitutive(kuu, kuv, kvv, Auu, Auv, Avv, nu, cs * h * h * h / 12.0)
    U = 0.5 * J * (nuu * euu + 2.0 * nuv * euv + nvv * evv + muu * kuu + 2.0 * muv * kuv + mvv * kvv)
    qu, qv = 0.0, 0.0
    if ks != 0.0:  # transverse shear
        gu, gv = X[0, 2] - X0[0, 2], X[1, 2] - X0[1, 2]
        kg = ks * G * h
        qu, qv = kg * (Auu * gu + Auv * gv), kg * (Auv * gu + Avv * gv)
        U = 0.5 * J * (nuu * euu + 2.0 * nuv * euv + nvv * evv + qu * gu + qv * gv
                       + muu * kuu + 2.0 * muv * kuv + mvv * kvv)
    if want:
        for i in range(3):
            Q[0, i] = J * (nuu * X[0, i] + nuv * X[1, i]) if i < nm else 0.0
            Q[1, i] = J * (nuv * X[0, i] + nvv * X[1, i]) if i < nm else 0.0
        Q[0, 2] += J * qu
        Q[1, 2] += J * qv
        # ∂/∂θ_a of Σ m^ab b_ab: m^ab (π_b2, −π_b1)
        Q[0, 0] += J * (muu * X[0, 4] + muv * X[1, 4])
        Q[0, 1] -= J * (muu * X[0, 3] + muv * X[1, 3])
        Q[1, 0] += J * (muv * X[0, 4] + mvv * X[1, 4])
        Q[1, 1] -= J * (muv * X[0, 3] + mvv * X[1, 3])
        # ∂/∂π_b of Σ m^ab b_ab: m^ab (−θ_a2, θ_a1)
        Q[0, 3] = -J * (muu * X[0, 1] + muv * X[1, 1])
        Q[0, 4] = J * (muu * X[0, 0] + muv * X[1, 0])
        Q[1, 3] = -J * (muv * X[0, 1] + mvv * X[1, 1])
        Q[1, 4] = J * (muv * X[0, 0] + mvv * X[1, 0])
        Q[0, 5] = 0.0
        Q[1, 5] = 0.0
    return U


@_inline
def _surface(X, X0, p, Q, want):  # pragma: no cover - compiled
    """Energy density of the Naghdi shell at one point; ``p = (E, ν, h, κ_s)`` (:func:`shell_point`)."""
    return shell_point(X, X0, p, Q, want, 3, p[3])


@njit(cache=True)
def surface_energy(X, X0, p):  # pragma: no cover - compiled
    """Energy density U(X; X₀) per unit chart area; ``p = (E, ν, h, κ_s)``; X, X₀ ``(2, 6)``."""
    Q = np.empty((1, 1))
    return _surface(X, X0, p, Q, False)


@njit(cache=True)
def surface_stress(X, X0, p, Q):  # pragma: no cover - compiled
    """Writes Q = ∂U/∂X ``(2, 6)`` (see :func:`surface_energy`)."""
    _surface(X, X0, p, Q, True)


@njit(cache=True)
def _resultants(X, X0, p, out):  # pragma: no cover - compiled
    """(n^uu, n^uv, n^vv, q^u, q^v, m^uu, m^uv, m^vv, K, H) at one point into ``out`` (10,)."""
    E, nu, h, ks = p[0], p[1], p[2], p[3]
    cs = E / (1.0 - nu * nu)
    G = 0.5 * E / (1.0 + nu)
    a0 = np.zeros(3)
    a = np.zeros(3)
    for i in range(3):
        a0[0] += X0[0, i] * X0[0, i]
        a0[1] += X0[0, i] * X0[1, i]
        a0[2] += X0[1, i] * X0[1, i]
        a[0] += X[0, i] * X[0, i]
        a[1] += X[0, i] * X[1, i]
        a[2] += X[1, i] * X[1, i]
    det0 = a0[0] * a0[2] - a0[1] * a0[1]
    Auu, Auv, Avv = a0[2] / det0, -a0[1] / det0, a0[0] / det0
    b = np.empty((2, 2))
    b0 = np.empty((2, 2))
    for i in range(2):
        for j in range(2):
            b[i, j] = X[i, 0] * X[j, 4] - X[i, 1] * X[j, 3]
            b0[i, j] = X0[i, 0] * X0[j, 4] - X0[i, 1] * X0[j, 3]
    n = _constitutive(0.5 * (a[0] - a0[0]), 0.5 * (a[1] - a0[1]), 0.5 * (a[2] - a0[2]), Auu, Auv, Avv, nu, cs * h)
    m = _constitutive(b[0, 0] - b0[0, 0], 0.5 * (b[0, 1] + b[1, 0] - b0[0, 1] - b0[1, 0]), b[1, 1] - b0[1, 1],
                      Auu, Auv, Avv, nu, cs * h ** 3 / 12.0)
    gu, gv = X[0, 2] - X0[0, 2], X[1, 2] - X0[1, 2]
    kg = ks * G * h
    out[0], out[1], out[2] = n
    out[3], out[4] = kg * (Auu * gu + Auv * gv), kg * (Auv * gu + Avv * gv)
    out[5], out[6], out[7] = m
    # curvature of the deformed surface from the director: K = det b / det a, H = ½ tr(a⁻¹ b)
    det = a[0] * a[2] - a[1] * a[1]
    bs = 0.5 * (b[0, 1] + b[1, 0])
    out[8] = (b[0, 0] * b[1, 1] - bs * bs) / det
    out[9] = 0.5 * (a[2] * b[0, 0] - 2.0 * a[1] * bs + a[0] * b[1, 1]) / det


@njit(cache=True)
def _resultants_batch(X, X0, p, out):  # pragma: no cover - compiled
    for i in range(X.shape[0]):
        _resultants(X[i], X0[i], p, out[i])


# ====================================================================== loads
class SurfaceGravity(ConstantFieldPotential):
    """Gravity on the shell: ``U(q) = −ρh g·r`` per unit chart area (paper §IV.B, pulled back by the core).

    Parameters
    ----------
    g : array_like, shape ``(3,)``
        Gravitational acceleration in the spatial frame.
    mass : float
        Mass per unit chart area ρh (> 0).
    """

    def __init__(self, g: Any, mass: float):
        super().__init__(check_finite("g", g, (3,)), float(check_positive("mass", mass)))

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "gravity", "g": self.field.tolist(), "mass": self.density}


def _translation(t: np.ndarray) -> np.ndarray:
    """The SE(3) element ``(4, 4)`` of the translation by ``t`` ``(3,)`` (no rotation)."""
    H = np.eye(4)
    H[1:, 0] = t
    return H


def _half_turn() -> np.ndarray:
    """The half-turn about e₃ in SE(3), ``(4, 4)``: the sphere chart's glue across a pole."""
    G = np.eye(4)
    G[1, 1] = G[2, 2] = -1.0
    return G


def _axis_derivative(x: np.ndarray, axis: int, h: float, periodic: bool, shift: np.ndarray | None) -> np.ndarray:
    """Second-order difference ∂x/∂u_axis of node positions x ``[nu, nv, 3]``.

    Central differences inside; on a periodic axis the neighbour across the seam is the first
    (last) node moved by the axis's holonomy, x(u + L) = R_H x(u) + t_H (``shift`` = the 4 × 4
    matrix H, None for the identity); on an open axis the one-sided second-order differences
    (−3x₀ + 4x₁ − x₂)/(2h) and (3x_{n−1} − 4x_{n−2} + x_{n−3})/(2h) at the ends.
    """
    x = np.moveaxis(x, axis, 0)
    out = np.empty_like(x)
    out[1:-1] = (x[2:] - x[:-2]) / (2.0 * h)
    if periodic:
        first, last = x[0], x[-1]
        if shift is not None:
            Rh, th = shift[1:, 1:], shift[1:, 0]
            after_last = first @ Rh.T + th                  # H·x₀
            before_first = (last - th) @ Rh                  # H⁻¹·x_{n−1}
        else:
            after_last, before_first = first, last
        out[0] = (x[1] - before_first) / (2.0 * h)
        out[-1] = (after_last - x[-2]) / (2.0 * h)
    else:
        out[0] = (-3.0 * x[0] + 4.0 * x[1] - x[2]) / (2.0 * h)
        out[-1] = (3.0 * x[-1] - 4.0 * x[-2] + x[-3]) / (2.0 * h)
    return np.moveaxis(out, 0, axis)


class Pressure(Load):
    """A pressure p normal to the *deformed* mid-surface, p per unit deformed area (a follower load).

    The force per unit chart area is, in the spatial frame,

        f = p (∂_u r × ∂_v r),

    |∂_u r × ∂_v r| being the deformed area per unit chart area (an external force density of the
    balance of linear momentum, paper §IV.B, §VI.B).  Like every load (:class:`cartan.problem.Load`:
    a density per unit *reference* area, which the lattice integrates with its node weights
    w_i J_i, J_i = √a⁰ the reference area per unit chart area, :meth:`CosseratSurface.reference_volume`;
    gravity, ``director-pressure`` and the face loads are weighed so too), :meth:`force` returns
    it per unit reference area, f/J_i, in body components (the generalised force density
    T = (Rᵀf/J_i, 0), no moment): a node then receives w_i J_i · f_i/J_i = w_i f_i, p
    times its deformed area (the chart quadrature of ∮ p n dA) on every chart.  J_i is the one
    the problem's scheme weighs with (:meth:`measure`: its node weights over the grid's); it is 1 on
    plates and on cylinders by arclength, R² sin θ on the sphere by longitude and colatitude, and
    the reference's area element on any ``Problem(reference=...)``.  Without a problem (a
    standalone load built from a grid) J = 1.  The
    tangents are second-order differences of the *current* node positions on the grid
    (:func:`_axis_derivative`: central inside and across periodic seams, one-sided at open
    edges), so the force at a node depends on the positions of its neighbours along each axis.

    Sign convention: positive p pushes along +∂_u r × ∂_v r, which is +e₃ (the director) for
    the built-in shapes (``"flat"``: +z; ``"cylinder"``: outward, so p > 0 inflates a closed
    cylinder) and for ``"surface"`` in the coordinate gauge.

    Not conservative as discretised: the work of the continuum pressure on a closed surface is
    p dV, but the nodal forces of central differences are the gradient of no function of the
    node positions (their derivative ∂f_i/∂r_j is not symmetric in i, j: ∂f_k/∂r_{k+u} =
    −(p/4 h_u h_v)[r_{k+v} − r_{k−v}]× while ∂f_{k+u}/∂r_k = (p/4 h_u h_v)[r_{k+u+v} − r_{k+u−v}]×),
    so a potential −pV would close the energy balance only to O(dx²).  The load is therefore a
    plain :class:`~cartan.problem.Load`: its power Σ w_i f_i·V_i goes to ``external_work``.
    :class:`VolumePressure` is the conservative alternative on a closed surface: the exact gradient
    of the lattice's enclosed volume, with the potential −pV_h.

    Statics: the force at a node depends on its neighbours (``local = False``), so
    ``solve_static`` differences it on the lattice's coloured stencil, the frames displaced
    directly (a load acting at its node alone is differenced node by node): Newton converges
    quadratically (differenced node by node, as a local load, a closed cylinder inflated by
    30 % took 8–10 linearly converging iterations, by 80 % 31–35).

    Parameters
    ----------
    pressure : float
        p (finite; force per unit deformed area).
    grid : Grid, optional
        The d = 2 grid of the problem: spacing, periodic axes, node shape; an open axis needs
        ≥ 3 nodes (one-sided second-order differences).  Default: the grid of the
        :class:`~cartan.problem.Problem` the load is given to (:meth:`attach`; a scene's
        ``[[loads]] kind = "pressure"`` is built so).
    holonomy : dict of int → array ``(4, 4)``, optional
        For a periodic axis whose closing edge is not the identity, the holonomy H of the
        problem's initial state (x(u + L) = H·x(u), e.g. a translation by L along the axis of a
        periodic tube).  Default: with ``grid`` given, the identity; without, the holonomy of
        the problem's initial state.
    """

    needs_structure_field = True
    local = False

    def __init__(self, pressure: float, grid: Grid | None = None, holonomy: Any = None):
        self.pressure = float(check_finite("pressure", pressure, ()))
        self.grid: Grid | None = None
        self.holonomy: dict[int, np.ndarray] = {}
        #: J_i, the reference area per unit chart area ``[*shape]`` (None: 1 at every node), from :meth:`measure`
        self.chart_measure: np.ndarray | None = None
        self._from_problem = grid is None and holonomy is None
        if grid is None:
            if holonomy is not None:
                raise ValueError("holonomy needs the grid it closes; give grid too (or neither, to take both "
                                 "from the problem)")
            return
        self._set_grid(grid, holonomy)

    def _set_grid(self, grid: Any, holonomy: Any) -> None:
        if not isinstance(grid, Grid) or grid.d != 2:
            raise ValueError(f"grid must be a d = 2 Grid, got {grid!r}")
        for axis, (n, p) in enumerate(zip(grid.shape, grid.periodic, strict=True)):
            if not p and n < 3:
                raise ValueError(f"grid: an open axis needs ≥ 3 nodes for the second-order tangents of a pressure, "
                                 f"axis {axis} has {n}")
        self.grid = grid
        self.holonomy = {}
        for axis, H in dict(holonomy or {}).items():
            if axis not in (0, 1) or not grid.periodic[axis]:
                raise ValueError(f"holonomy: axis must be a periodic axis of the grid (0 or 1), got {axis!r}")
            H = check_finite(f"holonomy[{axis}]", H, (4, 4))
            if (np.linalg.norm(H[1:, 1:].T @ H[1:, 1:] - np.eye(3)) > 1e-8 or np.linalg.det(H[1:, 1:]) < 0
                    or np.any(H[0] != (1.0, 0.0, 0.0, 0.0))):
                raise ValueError(f"holonomy[{axis}] must be an SE(3) matrix")
            self.holonomy[int(axis)] = H

    def bind(self, medium: Any) -> None:
        q_r = getattr(getattr(medium, "space", None), "q_r", None)
        if medium.group.name != "SE3" or q_r is None or np.shape(q_r) != (4, 4) or not np.allclose(q_r, np.eye(4)):
            raise ValueError(f"Pressure needs a medium whose points are SE(3) frames (q_r = I), not {medium.name!r}")
        if medium.material_dim != 2:
            raise ValueError(f"Pressure needs a surface (material dimension 2), not {medium.name!r}")

    def attach(self, problem: Any) -> None:
        """Take the grid and the initial state's holonomy from ``problem`` when none was given
        (:meth:`cartan.problem.Load.attach`); a given grid must be the problem's node shape.  The
        chart measure J_i is reset to 1, to be reported by the problem's scheme (:meth:`measure`)."""
        if self._from_problem:
            self._set_grid(problem.grid, axis_holonomies(problem.initial, problem.grid.d))
        elif tuple(self.grid.shape) != tuple(problem.grid.shape):
            raise ValueError(f"pressure: grid has shape {tuple(self.grid.shape)} but the problem's grid has "
                             f"{tuple(problem.grid.shape)}")
        self.chart_measure = None   # 1 until the problem's scheme reports its node volumes (:meth:`measure`)

    def measure(self, volumes: np.ndarray) -> None:
        """J_i = ``volumes``/w_i ``[*shape]``: the node volumes w_i J_i a scheme on a general chart
        weighs the loads with (:meth:`cartan.problem.Load.measure`) over the grid's weights w_i."""
        if self.grid is None:
            raise ValueError("Pressure has no grid: give grid=..., or give the load to a Problem")
        volumes = np.asarray(volumes, dtype=float)
        if volumes.shape != tuple(self.grid.shape):
            raise ValueError(f"volumes must have the grid's shape {tuple(self.grid.shape)}, got {volumes.shape}")
        J = volumes / self.grid.node_weights()
        self.chart_measure = None if np.all(J == 1.0) else J

    def tangents(self, Phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(∂_u r, ∂_v r) ``[*shape, 3]`` each, from the node positions of Φ ``[*shape, 4, 4]``."""
        Phi = np.asarray(Phi, dtype=float)
        if self.grid is None:
            raise ValueError("Pressure has no grid: give grid=..., or give the load to a Problem (which attaches its "
                             "grid and holonomy)")
        if Phi.shape != (*self.grid.shape, 4, 4):
            raise ValueError(f"Phi must have shape {(*self.grid.shape, 4, 4)} (the pressure's grid), got {Phi.shape}")
        x = Phi[..., 1:, 0]
        return tuple(_axis_derivative(x, a, self.grid.spacing[a], self.grid.periodic[a], self.holonomy.get(a))
                     for a in range(2))

    def spatial_force(self, Phi: np.ndarray) -> np.ndarray:
        """f = p (∂_u r × ∂_v r) ``[*shape, 3]`` in the spatial frame, per unit chart area."""
        ru, rv = self.tangents(Phi)
        return self.pressure * np.cross(ru, rv)

    def force(self, Phi, N, t):
        """T = (Rᵀf/J, 0) ``[*shape, 6]``: the pressure's force per unit reference area in body
        components, no moment (J the chart measure, class docstring)."""
        f = self.spatial_force(Phi)
        if self.chart_measure is not None:
            f = f / self.chart_measure[..., None]
        out = np.zeros((*f.shape[:-1], 6))
        out[..., :3] = np.einsum("...ji,...j->...i", np.asarray(Phi)[..., 1:, 1:], f)
        return out

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "pressure", "pressure": self.pressure,
                "holonomy": {int(a): H.tolist() for a, H in self.holonomy.items()}}


class VolumePressure(Load):
    """A pressure p that is exactly the multiplier of the lattice's enclosed volume V_h: the
    nodal forces are p ∂V_h/∂η_i and the potential energy is −pV_h, a conservative follower load
    (paper §IV.B: a configurational potential; §VI.B, §VII.B the closed surface).

    The discrete volume is the corner quadrature of V = ⅓∮ r·n dA with the lattice's corners
    (:meth:`cartan.schemes.lattice.Lattice.corners`: node i, one incident edge per axis, weight
    w_c = w_i/#corners_i, the grid's chart weights):

        V_h = ⅓ Σ_c w_c ρ_i·(θ_u,c × θ_v,c),      ρ_i = R_iᵀ(r_i − r̄),

    θ_α,c the translational part of the corner's edge strain X_α = log(Φ_i⁻¹Φ_j)/h_α (R_iθ_α the
    edge's chord direction, the lattice's tangent), so R_i(θ_u × θ_v) is the area vector per unit
    chart area and V_h is signed by the chart's orientation (positive when ∂_u r × ∂_v r points
    out), r̄ the mean of the node positions.  Measured from r̄, V_h is invariant under every rigid
    motion (the discrete area vectors Σ_c w_c R_i(θ_u × θ_v) need not sum to zero, so measured
    from the origin it would not be under translations): the load has no net force nor moment
    and a free surface under it keeps its momenta.  On a surface adapted to its normal
    (θ_α,3 = 0, the ``kirchhoff-love`` family) it is ⅓ Σ_c w_c ((r_i − r̄)·e₃,i) det T_c, the
    volume of ``cartan_kirchhoff_love.vesicle.surface_measures``.

    Its gradient along a node's motion Φ_i ← Φ_i exp(η_i), η = (v, ω) (translation first) is
    exact: the node's own term gives δρ_i = v + ρ_i × ω, and r̄ moves by R_j v_j/n, so with
    c_i = ⅓ Σ_{c at i} w_c θ_u × θ_v and a = Σ_i R_i c_i

        ∂V_h/∂v_i = c_i − R_iᵀa/n,        ∂V_h/∂ω_i = c_i × ρ_i;

    the corner strains give the "stress" S_c = (⅓w_c θ_v × ρ_i, ⅓w_c ρ_i × θ_u) on (θ_u, θ_v),
    taken from the edges to their end nodes as the lattice takes its internal stress
    (δ(hX_e) = dexp⁻¹(−hX_e)η_j − dexp⁻¹(hX_e)η_i, ghost ends through Ad_{Γ⁻¹}ᵀ on a glued axis).
    :meth:`force` is the density p ∂V_h/∂η_i/(w_i J_i) per unit reference volume, w_i J_i the
    node weights the problem's scheme integrates it with (:meth:`measure`), so that the nodal
    force is p ∂V_h/∂η_i exactly, and :meth:`energy` is −p v_i/(w_i J_i), v_i node i's share of
    V_h: Σ_i w_i J_i e_i = −pV_h and the energy balance closes to the integrator's accuracy.

    Compared with :class:`Pressure` (p per unit deformed area from central-difference tangents,
    equal to it to O(h²) on a smooth surface): a potential load, and the multiplier of V_h in a
    constrained minimisation (``cartan_kirchhoff_love.vesicle.helfrich_flow``).  The force at a
    node reads its neighbours along both axes and across the corners (``local = False``), and the
    mean position couples every node to every other through a: the statics take its exact
    Jacobian from :meth:`jacobian_parts`, the stencil part by coloured differences and the
    mean position's rank-6 part by the Sherman–Morrison–Woodbury identity (Newton quadratic,
    4 iterations on the scene ``sphere-volume-pressure`` as with :class:`Pressure`; without
    the rank-6 part, 6 linearly contracting ones).
    Sign convention as :class:`Pressure`: positive p pushes along +∂_u r × ∂_v r.

    Parameters
    ----------
    pressure : float
        p (finite; force per unit deformed area, the multiplier of V_h).

    Notes
    -----
    The lattice's charts only (the edges and corners are the lattice's); the grid, holonomies and
    glue are those of the :class:`~cartan.problem.Problem` the load is given to (:meth:`attach`).
    """

    needs_structure_field = True
    conservative = True
    local = False

    def __init__(self, pressure: float):
        self.pressure = float(check_finite("pressure", pressure, ()))
        self._lattice: Any = None
        self._holonomies: dict[int, np.ndarray] = {}
        self.volumes: np.ndarray | None = None

    def bind(self, medium: Any) -> None:
        Pressure.bind(self, medium)  # type: ignore[arg-type]

    def attach(self, problem: Any) -> None:
        """Take the grid, the holonomies and the glue of ``problem``'s initial state (a lattice
        of the problem's chart, without its loads); the node weights are the grid's until the
        problem's scheme reports its own (:meth:`measure`)."""
        from cartan.problem import Problem
        from cartan.schemes.lattice import Lattice

        if problem.grid.d != 2:
            raise ValueError(f"grid must be a d = 2 Grid, got d = {problem.grid.d}")
        self._lattice = Lattice(Problem(problem.medium, problem.grid, problem.initial))
        self._holonomies = axis_holonomies(problem.initial, problem.grid.d)
        self.volumes = np.asarray(problem.grid.node_weights(), dtype=float)

    def measure(self, volumes: np.ndarray) -> None:
        """w_i J_i ``[*shape]``: the node weights of the problem's scheme on a general chart
        (:meth:`cartan.problem.Load.measure`)."""
        volumes = np.asarray(volumes, dtype=float)
        if self._lattice is not None and volumes.shape != tuple(self._lattice.grid.shape):
            raise ValueError(f"volumes must have the grid's shape {tuple(self._lattice.grid.shape)}, "
                             f"got {volumes.shape}")
        self.volumes = volumes

    def _edge_logs(self, Phi: np.ndarray) -> list[np.ndarray]:
        """Per axis the flat edge logarithms hX_e = log(Φ_i⁻¹Φ_j) ``[E_α, 6]`` of Φ, as the
        lattice builds its edges (holonomies on periodic axes, ghosts on glued ones)."""
        L = self._lattice
        if L is None:
            raise ValueError("VolumePressure has no problem: give the load to a Problem (which attaches its chart)")
        g = L.group
        Phi = np.asarray(Phi, dtype=float)
        if Phi.shape != (*L.grid.shape, 4, 4):
            raise ValueError(f"Phi must have shape {(*L.grid.shape, 4, 4)} (the problem's grid), got {Phi.shape}")
        out = []
        Phi_inv = g.inverse(Phi)
        for axis in range(2):
            inv_tail, _ = L._ends(Phi_inv, axis, "inverse")
            _, head = L._ends(Phi, axis, "frame")
            if axis in self._holonomies:
                head = np.moveaxis(head.copy(), axis, 0)
                head[-1] = g.compose(self._holonomies[axis], head[-1])
                head = np.moveaxis(head, 0, axis)
            out.append(g.log(g.compose(inv_tail, head)).reshape(-1, g.dim))
        return out

    def _share_gradient(self, xis: list[np.ndarray], rho: np.ndarray,
                        translation: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(v_i ``[n]``, ∂F/∂η_i ``[n, 6]``, c_i ``[n, 3]``) of F = ⅓ Σ_c w_c ρ_i·(θ_u,c × θ_v,c)
        for node vectors ρ_i ``[n, 3]`` (body components) that move with the node as
        δρ_i = v_i + ρ_i × ω_i (``translation``: a point, R_iᵀ(r_i − p)) or δρ_i = ρ_i × ω_i
        (a spatially fixed direction, R_iᵀe), the edge strains ``xis`` (:meth:`_edge_logs`)
        moving as the lattice's (class docstring); v_i node i's share of F, c_i = ⅓ Σ_{c at i}
        w_c θ_u × θ_v."""
        L = self._lattice
        g, c, h = L.group, L.corners(), L.h
        n = rho.shape[0]
        node = c["node"]
        tu, tv = (xis[a][c["edge"][:, a], :3] / h[a] for a in range(2))
        area = np.cross(tu, tv)                                                  # θ_u × θ_v [C, 3]
        w3 = c["weight"] / 3.0
        rc = rho[node]
        v = np.bincount(node, weights=w3 * np.einsum("ci,ci->c", rc, area), minlength=n)
        G = np.zeros((n, 6))
        ci = np.zeros((n, 3))
        scatter_add(ci, node, w3[:, None] * area)
        if translation:
            G[:, :3] += ci
        G[:, 3:] += np.cross(ci, rho)
        S = (w3[:, None] * np.cross(tv, rc), w3[:, None] * np.cross(rc, tu))      # ∂F/∂θ_u, ∂F/∂θ_v
        for a, xi in enumerate(xis):
            Qe = np.zeros_like(xi)
            scatter_add(Qe[:, :3], c["edge"][:, a], S[a] / h[a])
            out = L.from_ghosts(np.einsum("...ji,...j->...i", g.dexp_inv(xi), Qe), c["ghost_tail"][a], a)
            inc = L.from_ghosts(np.einsum("...ji,...j->...i", g.dexp_inv(-xi), Qe), c["ghost_head"][a], a)
            scatter_add(G, c["tail"][a], -out)
            scatter_add(G, c["head"][a], inc)
        return v, G, ci

    def _gradient(self, Phi: np.ndarray, center: np.ndarray | None = None,
                  share: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[np.ndarray]]:
        """(v_i ``[n]``, ∂V_h/∂η_i ``[n, 6]``, a ``(3,)``, edge logs) with the volume measured from
        ``center`` and r̄'s share of the gradient −R_iᵀa/n taken with ``share`` for a (both
        default: r̄ and a of Φ, the exact gradient; given, their values held fixed: the
        gradient's part that reads the stencil only, :meth:`jacobian_parts`)."""
        xis = self._edge_logs(Phi)
        flat = np.asarray(Phi, dtype=float).reshape(-1, 4, 4)
        n = flat.shape[0]
        x = flat[:, 1:, 0]
        R = flat[:, 1:, 1:]
        center = x.mean(axis=0) if center is None else center
        rho = np.einsum("nji,nj->ni", R, x - center)                            # R_iᵀ(r_i − r̄)
        v, G, ci = self._share_gradient(xis, rho, True)
        a = np.einsum("nij,nj->i", R, ci)                                       # Σ_i R_i c_i: r̄'s share
        G[:, :3] -= np.einsum("nji,j->ni", R, a if share is None else share) / n
        return v, G, a, xis

    def volume_and_gradient(self, Phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(v_i ``[*shape]``, ∂V_h/∂η_i ``[*shape, 6]``): each node's share of V_h (Σ v_i = V_h)
        and the exact gradient of V_h along Φ_i ← Φ_i exp(η_i) (class docstring)."""
        v, G, _, _ = self._gradient(Phi)
        shape = tuple(self._lattice.grid.shape)
        return v.reshape(shape), G.reshape(*shape, 6)

    def jacobian_parts(self, Phi: np.ndarray, t: float) -> tuple[Callable, np.ndarray, np.ndarray]:
        """The statics' Jacobian of :meth:`force` (:meth:`cartan.problem.Load.jacobian_parts`):
        the Hessian of −pV_h along the drifts, ∂(p ∂V_h/∂η_i)/∂η_j, exactly.

        V_h = V(r̄) with V(q) = ⅓ Σ_c w_c R_iᵀ(r_i − q)·(θ_u × θ_v) = V(0) − q·a, a = Σ_i R_i c_i,
        and ∂V_h/∂η_i = ∂V(q)/∂η_i|_{q = r̄} − (R_iᵀa/n, 0).  Differentiating along η_j:

        * with q = r̄ and a held at their values at Φ (``frozen``), the gradient reads node i's
          corners and edges only: the lattice's coloured stencil differences it (the change of
          the cells' area vectors θ_u × θ_v and of R_iᵀ, as the internal force);
        * q = r̄ moves by R_j v_j/n and ∂²V(q)/∂q∂η_i = −B_iᵀ, B_j = ∂a/∂η_j ``(3, 6)``; a moves
          by B_j η_j in −R_iᵀa/n: together the rank-6 remainder, every node with every other,

              −(1/n) [P_vᵀ R_iᵀ B_j + B_iᵀ R_j P_v],      P_v η = v,

          returned as U_i = −(p/(n w_iJ_i)) [P_vᵀR_iᵀ | B_iᵀ], V_j = [B_jᵀ | P_vᵀR_jᵀ] ``(6, 6)``.

        B_j row k is the gradient of a_k = ⅓ Σ_c w_c (R_iᵀe_k)·(θ_u × θ_v), whose node vectors
        turn with the frame and do not translate (:meth:`_share_gradient`).  On a closed surface
        a = O(h²) and B = O(h²) per node, so the remainder is small, but without it Newton
        contracts linearly.

        Returns
        -------
        frozen : callable
            Φ' ``[*shape, 4, 4]`` → the force density ``[*shape, 6]`` with r̄ and a held.
        U, V : arrays ``[*shape, 6, 6]``
        """
        shape = tuple(self._lattice.grid.shape)
        flat = np.asarray(Phi, dtype=float).reshape(-1, 4, 4)
        n = flat.shape[0]
        R = flat[:, 1:, 1:]
        center = flat[:, 1:, 0].mean(axis=0)
        _, _, a, xis = self._gradient(Phi)
        vol = self.volumes.reshape(n)
        p = self.pressure

        def frozen(moved: np.ndarray) -> np.ndarray:
            _, G, _, _ = self._gradient(moved, center, a)
            return (p * G / vol[:, None]).reshape(*shape, 6)

        B = np.stack([self._share_gradient(xis, R[:, k, :], False)[1] for k in range(3)], axis=1)  # [n, 3, 6]
        Rt = np.zeros((n, 6, 3))
        Rt[:, :3, :] = np.swapaxes(R, -1, -2)                                    # P_vᵀR_iᵀ [n, 6, 3]
        Bt = np.swapaxes(B, -1, -2)                                              # B_iᵀ [n, 6, 3]
        U = -(p / (n * vol))[:, None, None] * np.concatenate([Rt, Bt], axis=-1)
        V = np.concatenate([Bt, Rt], axis=-1)
        return frozen, U.reshape(*shape, 6, 6), V.reshape(*shape, 6, 6)

    def volume(self, Phi: np.ndarray) -> float:
        """V_h of the configuration Φ ``[*shape, 4, 4]``."""
        return float(np.sum(self.volume_and_gradient(Phi)[0]))

    def force(self, Phi, N, t):
        """p ∂V_h/∂η_i/(w_i J_i) ``[*shape, 6]`` (body components, a moment included)."""
        _, G = self.volume_and_gradient(Phi)
        return self.pressure * G / self.volumes[..., None]

    def energy(self, Phi):
        """−p v_i/(w_i J_i) ``[*shape]``: the potential −pV_h per unit reference volume."""
        v, _ = self.volume_and_gradient(Phi)
        return -self.pressure * v / self.volumes

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "volume-pressure", "pressure": self.pressure}


class NodeSprings(PotentialLoad):
    """Springs on chosen spatial position components of chosen nodes: ``U = ½k(x_c − x̄_c)²`` per
    unit chart area at each listed (node, component), zero elsewhere, x̄ the held positions.
    A support: not multiplied by the load parameter λ (:attr:`cartan.problem.Load.scaled` False).

    Parameters
    ----------
    Phi : array, shape ``(*shape, 4, 4)``, or None
        The configuration whose positions are held; None: the initial state of the first
        :class:`~cartan.problem.Problem` the load is given to (:meth:`attach`; a scene's
        ``[[loads]] kind = "node-springs"`` is built so).
    springs : sequence of (tuple of int, int)
        (node index, spatial component 0, 1 or 2); at least one.
    stiffness : float
        k > 0 per unit chart area.
    """

    scaled = False

    def __init__(self, Phi: np.ndarray | None, springs: Any, stiffness: float):
        self.stiffness = float(check_positive("stiffness", stiffness, shape=()))
        try:
            self.springs = [(tuple(int(i) for i in node), int(comp)) for node, comp in springs]
        except (TypeError, ValueError):
            raise ValueError(f"springs must be a list of (node index, component) pairs, got {springs!r}") from None
        if not self.springs:
            raise ValueError("springs must list at least one (node index, component) pair")
        for _, comp in self.springs:
            if comp not in (0, 1, 2):
                raise ValueError(f"springs: component must be 0, 1 or 2, got {comp!r}")
        self.K: np.ndarray | None = None
        self.held: np.ndarray | None = None
        self._from_problem = Phi is None
        if Phi is not None:
            self._hold(np.asarray(Phi, dtype=float))

    def _hold(self, Phi: np.ndarray) -> None:
        shape = Phi.shape[:-2]
        K = np.zeros((*shape, 3))
        for node, comp in self.springs:
            if len(node) != len(shape) or any(not 0 <= i < n for i, n in zip(node, shape, strict=True)):
                raise ValueError(f"springs: node {list(node)} is not a node of the grid of shape {list(shape)}")
            K[node][comp] = self.stiffness
        self.K, self.held = K, Phi[..., 1:, 0].copy()

    def attach(self, problem: Any) -> None:
        """Hold the positions of the first problem's initial state when no ``Phi`` was given (a
        later problem with the same loads, e.g. ``solve_static`` from another start, keeps them)."""
        if self._from_problem and self.K is None:
            self._hold(np.asarray(problem.initial.Phi, dtype=float))
        elif self.K.shape[:-1] != tuple(problem.grid.shape):
            raise ValueError(f"node-springs: Phi has the node shape {list(self.K.shape[:-1])}, the problem's grid "
                             f"{list(problem.grid.shape)}")

    def potential_energy(self, q: np.ndarray) -> np.ndarray:
        return 0.5 * np.sum(self.K * (q[..., 1:, 0] - self.held) ** 2, axis=-1)

    def potential_gradient(self, q: np.ndarray) -> np.ndarray:
        grad = np.zeros(np.shape(q))
        grad[..., 1:, 0] = self.K * (q[..., 1:, 0] - self.held)
        return grad

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "node-springs", "springs": [[*node, comp] for node, comp in self.springs],
                "stiffness": self.stiffness}


# ====================================================================== medium
def _frames_from_tangents(ru: np.ndarray, rv: np.ndarray) -> np.ndarray:
    """Frames ``[..., 3, 3]`` (columns e₁, e₂, e₃): e₁ ∥ r_u, e₃ ∥ r_u × r_v (the coordinate gauge)."""
    n = np.cross(ru, rv)
    nn = np.linalg.norm(n, axis=-1, keepdims=True)
    nu = np.linalg.norm(ru, axis=-1, keepdims=True)
    if np.any(nn <= 1e-12 * np.maximum(nu, 1.0) ** 2) or np.any(nu == 0):
        raise ValueError("the surface is singular (r_u × r_v = 0) at some node; use a regular chart")
    e3 = n / nn
    e1 = ru / nu
    e2 = np.cross(e3, e1)
    return np.stack([e1, e2, e3], axis=-1)


class CosseratSurface(KernelMedium):
    """Geometrically exact Cosserat shell (Naghdi / Reissner–Mindlin) on SE(3), d = 2 (paper §VI.B).

    Parameters
    ----------
    E : float
        Young's modulus (> 0).
    poisson : float
        Poisson ratio ν, in (−1, 0.5).
    thickness : float
        Shell thickness h (> 0).
    density : float
        Mass density ρ (> 0); the inertia per unit chart area is ρh (translation) and ρh³/12
        (rotation about e₁, e₂), 0 about the director (the drill gauge).
    shear_correction : float
        κ_s (> 0), default 5/6.
    rest_curvature : sequence of 2 floats
        Constant rest curvatures (k_u, k_v) of the chart axes (a cylinder of radius 1/k): at most
        one may be non-zero, since a constant rest strain on a flat chart is integrable only
        then.  Other stress-free shapes are given as ``Problem(reference=Φ_ref)``.

    Notes
    -----
    Strains, energy and stress: see the module docstring.  Components of X_α: (θ_α; π_α) in
    the SE(3) basis, translations first.
    """

    name: ClassVar[str] = "cosserat-surface"
    material_dim: ClassVar[int] = 2
    initial_kinds: ClassVar[tuple[str, ...]] = ("flat", "cylinder", "sphere", "surface")
    #: :meth:`outputs` measures the resultants from the problem's reference (its nodal rest strains)
    outputs_read_reference: ClassVar[bool] = True
    load_kinds: ClassVar[tuple[str, ...]] = ("gravity", "dead-load", "director-pressure", "pressure", "volume-pressure",
                                             "node-springs", "simple-support", "symmetry")
    output_fields: ClassVar[dict[str, tuple[str, str]]] = {
        "director_x": ("director p = R e3, x component", "1"),
        "director_y": ("director p = R e3, y component", "1"),
        "director_z": ("director p = R e3, z component", "1"),
        "membrane_force_uu": ("membrane force N^uu (thickness-integrated, physical component)", "N m-1"),
        "membrane_force_uv": ("membrane force N^uv (thickness-integrated, physical component)", "N m-1"),
        "membrane_force_vv": ("membrane force N^vv (thickness-integrated, physical component)", "N m-1"),
        "shear_force_u": ("transverse shear force Q^u (thickness-integrated, physical component)", "N m-1"),
        "shear_force_v": ("transverse shear force Q^v (thickness-integrated, physical component)", "N m-1"),
        "bending_moment_uu": ("bending moment M^uu (thickness-integrated, physical component)", "N"),
        "bending_moment_uv": ("bending moment M^uv (thickness-integrated, physical component)", "N"),
        "bending_moment_vv": ("bending moment M^vv (thickness-integrated, physical component)", "N"),
        "gauss_curvature": ("Gauss curvature of the director field, det b / det a", "m-2"),
        "mean_curvature": ("mean curvature of the director field, tr(a^-1 b)/2", "m-1"),
    }

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        # a subclass with outputs of its own reads the reference only when it declares so
        if "outputs" in vars(cls) and "outputs_read_reference" not in vars(cls):
            cls.outputs_read_reference = False

    def __init__(self, E: float = 1.0, poisson: float = 0.3, thickness: float = 0.1, density: float = 1.0,
                 shear_correction: float = 5.0 / 6.0, rest_curvature: Any = (0.0, 0.0)):
        self.group = cartan.group("SE3")
        self.space = cartan.space("frame-E3")
        self.E = float(check_positive("E", E, shape=()))
        nu = float(check_finite("poisson", poisson, ()))
        if not -1.0 < nu < 0.5:
            raise ValueError(f"poisson must be in (-1, 0.5), got {poisson!r}")
        self.nu = nu
        self.h = float(check_positive("thickness", thickness, shape=()))
        self.rho = float(check_positive("density", density, shape=()))
        self.ks = float(check_positive("shear_correction", shear_correction, shape=()))
        k = check_finite("rest_curvature", rest_curvature, (2,))
        if k[0] != 0.0 and k[1] != 0.0:
            raise ValueError("rest_curvature: at most one of (k_u, k_v) may be non-zero (a constant rest strain "
                             f"on a flat chart is a cylinder); got {k.tolist()}; use Problem(reference=...)")
        self.k0 = k

    # ------------------------------------------------------------------ contract
    def parameters(self) -> dict[str, Any]:
        return {"E": self.E, "poisson": self.nu, "thickness": self.h, "density": self.rho,
                "shear_correction": self.ks, "rest_curvature": self.k0.tolist()}

    @property
    def bending_stiffness(self) -> float:
        """D = Eh³/(12(1 − ν²))."""
        return self.E * self.h ** 3 / (12.0 * (1.0 - self.nu ** 2))

    @property
    def shear_modulus(self) -> float:
        """G = E/(2(1 + ν))."""
        return 0.5 * self.E / (1.0 + self.nu)

    @property
    def area_density(self) -> float:
        """Mass per unit area ρh."""
        return self.rho * self.h

    def inertia(self) -> np.ndarray:
        m, j = self.rho * self.h, self.rho * self.h ** 3 / 12.0
        return np.array([m, m, m, j, j, 0.0])

    def rest_strain(self) -> np.ndarray:
        X0 = np.zeros((2, 6))
        X0[0, 0] = X0[1, 1] = 1.0
        X0[0, 4] = self.k0[0]     # ∂_u R = R[(0, k_u, 0)]×: bends e₁ towards −e₃ about e₂
        X0[1, 3] = -self.k0[1]    # ∂_v R = R[(−k_v, 0, 0)]×
        return X0

    def reference_volume(self, X0: np.ndarray) -> np.ndarray | None:
        """The reference area element √det a⁰ per unit chart area at the nodal rest strains
        ``X0 [..., 2, 6]`` → ``[...]`` (a⁰_αβ = θ⁰_α·θ⁰_β), or None when it is 1 to round-off
        (flat plates, cylinders by arclength keep the chart's weights to the bit)."""
        t = np.asarray(X0, dtype=float)[..., :3]
        a = np.einsum("...ai,...bi->...ab", t, t)
        J = np.sqrt(np.maximum(a[..., 0, 0] * a[..., 1, 1] - a[..., 0, 1] ** 2, 0.0))
        return None if np.all(np.abs(J - 1.0) <= 1e-12) else J

    def point_kernels(self) -> MediumKernels:
        return MediumKernels(surface_energy, surface_stress, np.array([self.E, self.nu, self.h, self.ks]))

    # ------------------------------------------------------------------ loads
    def make_load(self, kind: str, **params: Any):
        """``"gravity"`` (``g``, 3 components; mass ρh), ``"director-pressure"`` (``pressure``:
        a force ``pressure`` per unit reference area along the director, a follower load),
        ``"pressure"`` (:class:`Pressure`: ``pressure``, optional ``grid`` and ``holonomy``,
        by default the problem's: p per unit deformed area normal to the deformed surface,
        positive along e₃), ``"volume-pressure"`` (:class:`VolumePressure`: ``pressure``, the
        conservative multiplier of the lattice's enclosed volume), ``"node-springs"``
        (:class:`NodeSprings` on the initial positions:
        ``springs`` a list of ``[i, j, component]``, ``stiffness``),
        ``"dead-load"`` (``force``: a spatially fixed force (3,) per unit reference area) or
        ``"simple-support"`` (:class:`PenaltySupport`: ``edges``, ``position_stiffness``,
        ``director_stiffness``) or ``"symmetry"`` (:class:`SymmetrySupport`: ``edges``, ``normal``,
        ``position_stiffness``, ``director_stiffness``).

        Every density is per unit *reference* area: the lattice weighs node i by w_iJ_i, J_i = √a⁰
        the reference area per unit chart area (1 on plates and cylinders of the default chart)."""
        if kind == "gravity":
            if set(params) != {"g"}:
                raise ValueError(f"load 'gravity' takes exactly the parameter 'g', got {sorted(params)}")
            return SurfaceGravity(params["g"], self.area_density)
        if kind == "dead-load":
            if set(params) != {"force"}:
                raise ValueError(f"load 'dead-load' takes exactly the parameter 'force', got {sorted(params)}")
            return ConstantFieldPotential(check_finite("force", params["force"], (3,)), 1.0)
        if kind == "simple-support":
            return PenaltySupport(**params)
        if kind == "symmetry":
            return SymmetrySupport(**params)
        if kind == "pressure":
            if not {"pressure"} <= set(params) <= {"pressure", "grid", "holonomy"}:
                raise ValueError("load 'pressure' takes the parameter 'pressure' and optionally 'grid' and 'holonomy' "
                                 f"(default: the problem's), got {sorted(params)}")
            return Pressure(**params)
        if kind == "volume-pressure":
            if set(params) != {"pressure"}:
                raise ValueError(f"load 'volume-pressure' takes exactly the parameter 'pressure', got {sorted(params)}")
            return VolumePressure(params["pressure"])
        if kind == "node-springs":
            if set(params) != {"springs", "stiffness"}:
                raise ValueError("load 'node-springs' takes exactly the parameters 'springs' (a list of [i, j, "
                                 f"component]) and 'stiffness', got {sorted(params)}")
            springs = params["springs"]
            if not isinstance(springs, list | tuple) or not all(
                    isinstance(s, list | tuple) and len(s) == 3 and all(isinstance(x, int | np.integer)
                                                                         and not isinstance(x, bool) for x in s)
                    for s in springs):
                raise ValueError(f"springs must be a list of [i, j, component] integer triples, got {springs!r}")
            return NodeSprings(None, [((s[0], s[1]), s[2]) for s in springs], params["stiffness"])
        if kind == "director-pressure":
            if set(params) != {"pressure"}:
                raise ValueError(
                    f"load 'director-pressure' takes exactly the parameter 'pressure', got {sorted(params)}")
            p = float(check_finite("pressure", params["pressure"], ()))
            return UniformForce(np.array([0.0, 0.0, p, 0.0, 0.0, 0.0]), frame="body")
        return super().make_load(kind, **params)

    # ------------------------------------------------------------------ initial states
    def initial_state(self, grid, kind: str, **params: Any) -> InitialState:
        """Initial structure field on a d = 2 grid from a named shape.

        Parameters
        ----------
        grid : cartan.grid.Grid
            d = 2, axes (u, v).
        kind : str
            ``"flat"``: r = origin + rotation·(u, v, 0), frames = rotation (default identity).
            On a periodic axis α the plate is a periodic strip (a sheet when both are): it
            repeats after L_α along the axis's direction in space, the state's holonomy on
            that axis the translation by L_α·rotation·e_α (the closing edge carries the strain of
            every other edge, no seam force), as a periodic v axis of the ``"cylinder"``.
            ``"cylinder"``: r = (R sin(u/R), v, R cos(u/R) − R), axis along y, e₁ along the
            circumference, e₃ the outward normal; ``radius`` R (default: L_u/(2π) on a periodic u).
            On a periodic v axis the tube repeats after L_v: the state's holonomy is the
            translation by L_v along y (a long tube's plane strain).
            ``"sphere"``: the closed sphere of ``radius`` R (default 1) charted by longitude
            φ = 2πu/L_u and colatitude θ = πv/L_v on a grid with a periodic u axis (an even number
            of nodes) and a v axis glued across the poles, ``Grid((N, n), (L_u, L_v),
            periodic=(True, False), glued=(None, 0))``; the poles on the axis ``rotation``·e_z
            through ``center`` (anywhere: the chart is turned, not the physics).  Stress-free:
            the state's reference is itself, its glue Γ the half-turn about e₃.  The optional
            ``radial_velocity`` V starts the shell with the outward velocity V everywhere (a
            breathing mode).
            ``"surface"``: r = ``position(u, v)`` (a callable on node arrays returning ``[..., 3]``),
            frames from ``frames(u, v)`` (``[..., 3, 3]``, columns e₁ e₂ e₃) or, if not given, the
            coordinate gauge e₁ ∥ r_u, e₃ ∥ r_u × r_v (tangents by central differences).
        **params
            The shape's parameters, plus ``twist`` (6,): a spatial twist (v, ω) whose rigid-body
            velocity the shell starts with (its drill components dropped, the gauge).

        Returns
        -------
        InitialState
        """
        if grid.d != 2:
            raise ValueError(f"cosserat-surface needs a d = 2 grid, got d = {grid.d}")
        twist = params.pop("twist", None)
        builders: dict[str, Callable] = {"flat": self._flat, "cylinder": self._cylinder, "sphere": self._sphere,
                                         "surface": self._surface}
        if kind not in builders:
            return super().initial_state(grid, kind)
        from cartan.medium import check_keywords

        radial = params.pop("radial_velocity", None) if kind == "sphere" else None
        check_keywords(kind, builders[kind], params, extra=("twist", "radial_velocity") if kind == "sphere"
                       else ("twist",))
        pos, frames = builders[kind](grid, **params)
        Phi = self._assemble(pos, frames)
        N = None
        if twist is not None:
            xi = check_finite("twist", twist, (6,))
            N = np.einsum("...ij,j->...i", self.group.Ad(self.group.inverse(Phi)), xi)
            N[..., 5] = 0.0
        if radial is not None:
            N = np.zeros((*grid.shape, 6)) if N is None else N
            N[..., 2] += float(check_finite("radial_velocity", radial, ()))
        if kind == "sphere":
            glue = _half_turn()
            return InitialState(Phi=Phi, N=N, glue=glue, reference=InitialState(Phi=Phi.copy(), glue=glue))
        holonomy = None
        if kind == "cylinder" and grid.periodic[1]:
            # a periodic axial direction: the tube repeats after L_v along its axis, Φ(v + L) = HΦ(v)
            holonomy = {1: _translation(np.array([0.0, grid.length[1], 0.0]))}
        elif kind == "flat" and any(grid.periodic):
            # a periodic strip (or sheet): it repeats after L_α along the axis's direction in
            # space, Φ(u_α + L_α) = H_α Φ(u_α) with H_α the translation by L_α·rotation·e_α
            Rm = np.eye(3) if params.get("rotation") is None else np.asarray(params["rotation"], dtype=float)
            holonomy = {a: _translation(grid.length[a] * Rm[:, a]) for a in range(2) if grid.periodic[a]}
        return InitialState(Phi=Phi, N=N, holonomy=holonomy)

    def _mesh(self, grid) -> tuple[np.ndarray, np.ndarray]:
        return np.meshgrid(grid.coordinates(0), grid.coordinates(1), indexing="ij")

    def _flat(self, grid, origin=None, rotation=None):
        u, v = self._mesh(grid)
        o = np.zeros(3) if origin is None else check_finite("origin", origin, (3,))
        Rm = np.eye(3) if rotation is None else check_finite("rotation", rotation, (3, 3))
        if np.linalg.norm(Rm.T @ Rm - np.eye(3)) > 1e-10 or np.linalg.det(Rm) < 0:
            raise ValueError("rotation must be a proper rotation matrix")
        local = np.stack([u, v, np.zeros_like(u)], axis=-1)
        return o + local @ Rm.T, np.broadcast_to(Rm, (*u.shape, 3, 3)).copy()

    def _cylinder(self, grid, radius=None):
        if radius is None:
            if not grid.periodic[0]:
                raise ValueError("cylinder: give radius (or a periodic u axis of length 2πR)")
            radius = grid.length[0] / (2.0 * np.pi)
        R = float(check_positive("radius", radius, shape=()))
        if grid.periodic[0] and abs(grid.length[0] - 2.0 * np.pi * R) > 1e-9 * R:
            raise ValueError(f"radius: a periodic u axis closes only for length 2πR = {2 * np.pi * R}, "
                             f"got length {grid.length[0]}")
        u, v = self._mesh(grid)
        phi = u / R
        pos = np.stack([R * np.sin(phi), v, R * np.cos(phi) - R], axis=-1)
        c, s, z = np.cos(phi), np.sin(phi), np.zeros_like(phi)
        e1 = np.stack([c, z, -s], axis=-1)
        e2 = np.stack([z, z + 1.0, z], axis=-1)
        e3 = np.stack([s, z, c], axis=-1)
        return pos, np.stack([e1, e2, e3], axis=-1)

    def _sphere(self, grid, radius=1.0, center=None, rotation=None):
        if not (grid.periodic[0] and grid.glued is not None and grid.glued[1] == 0):
            raise ValueError("sphere: the grid must have a periodic u axis with an even number of nodes and a v axis "
                             "glued across the poles, Grid((N, n), (L_u, L_v), periodic=(True, False), "
                             f"glued=(None, 0)); got periodic={list(grid.periodic)}, glued={grid.glued}")
        R = float(check_positive("radius", radius, shape=()))
        o = np.zeros(3) if center is None else check_finite("center", center, (3,))
        Rm = np.eye(3) if rotation is None else check_finite("rotation", rotation, (3, 3))
        if np.linalg.norm(Rm.T @ Rm - np.eye(3)) > 1e-10 or np.linalg.det(Rm) < 0:
            raise ValueError("rotation must be a proper rotation matrix")
        u, v = self._mesh(grid)
        phi, theta = 2.0 * np.pi * u / grid.length[0], np.pi * v / grid.length[1]
        cp, sp, ct, st = np.cos(phi), np.sin(phi), np.cos(theta), np.sin(theta)
        e_r = np.stack([st * cp, st * sp, ct], axis=-1)
        e_theta = np.stack([ct * cp, ct * sp, -st], axis=-1)
        e_phi = np.stack([-sp, cp, np.zeros_like(sp)], axis=-1)
        frames = np.einsum("ij,...jk->...ik", Rm, np.stack([e_phi, -e_theta, e_r], axis=-1))
        return o + R * e_r @ Rm.T, frames

    def _surface(self, grid, position=None, frames=None):
        if not callable(position):
            raise ValueError("surface: position must be a callable r(u, v) -> [..., 3]")
        u, v = self._mesh(grid)
        pos = check_finite("position", position(u, v), (*u.shape, 3))
        if frames is not None:
            if not callable(frames):
                raise ValueError("surface: frames must be a callable (u, v) -> [..., 3, 3]")
            E = check_finite("frames", frames(u, v), (*u.shape, 3, 3))
            defect = np.linalg.norm(np.swapaxes(E, -1, -2) @ E - np.eye(3), axis=(-2, -1))
            if np.any(defect > 1e-8) or np.any(np.linalg.det(E) < 0):
                raise ValueError("frames must be proper rotations (columns e1, e2, e3)")
            return pos, E
        eps = 1e-6 * max(grid.length)
        ru = (np.asarray(position(u + eps, v)) - np.asarray(position(u - eps, v))) / (2 * eps)
        rv = (np.asarray(position(u, v + eps)) - np.asarray(position(u, v - eps))) / (2 * eps)
        return pos, _frames_from_tangents(ru, rv)

    def _assemble(self, pos: np.ndarray, frames: np.ndarray) -> np.ndarray:
        Phi = np.zeros((*pos.shape[:-1], 4, 4))
        Phi[..., 0, 0] = 1.0
        Phi[..., 1:, 0] = pos
        Phi[..., 1:, 1:] = frames
        return Phi

    # ------------------------------------------------------------------ outputs
    def resultants(self, X: np.ndarray, X0: np.ndarray | None = None) -> np.ndarray:
        """Resultants and curvatures at strains X ``[..., 2, 6]`` (rest strain X0, default the
        medium's): ``[..., 10]`` = (n^uu, n^uv, n^vv, q^u, q^v, m^uu, m^uv, m^vv, K, H)."""
        X = np.asarray(X, dtype=float)
        X0 = self.rest_strain() if X0 is None else np.asarray(X0, dtype=float)
        lead = X.shape[:-2]
        Xf = np.ascontiguousarray(X.reshape(-1, 2, 6))
        X0f = np.ascontiguousarray(np.broadcast_to(X0, X.shape).reshape(-1, 2, 6))
        out = np.empty((Xf.shape[0], 10))
        _resultants_batch(Xf, X0f, np.array([self.E, self.nu, self.h, self.ks]), out)
        return out.reshape(*lead, 10)

    def held_strain_twins(self) -> tuple:
        """The Kirchhoff–Love (Koiter) surface, ``kirchhoff-love`` with the same E, ν, h, ρ and
        rest curvature: the transverse shear θ_α·e₃ = 0 held on both axes (paper §VII.B); none
        for a medium that holds strains of its own (see
        :meth:`cartan.medium.Medium.held_strain_twins`)."""
        from cartan.medium import HeldStrainTwin

        if self.constrained_strains() is not None:
            return ()

        def parameters(p: dict[str, Any]) -> dict[str, Any]:
            return {key: p[key] for key in ("E", "poisson", "thickness", "density", "rest_curvature")}

        return (HeldStrainTwin("kirchhoff-love", (2,), (0.0,), parameters, "transverse shear"),)

    def outputs(self, q: np.ndarray, X: np.ndarray, N: np.ndarray, grid: Any,
                reference: dict[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
        """Director, resultants and curvatures at the nodes ``[*shape]`` each.

        The strains are measured from the problem's stress-free reference (``reference["X0"]``
        ``[*shape, 2, 6]``, the nodal rest strains, :attr:`outputs_read_reference`), else from the
        medium's constant :meth:`rest_strain`, as the energy measures them.  The resultants are
        reported in physical components on the reference chart's unit tangents
        t_α = θ⁰_α/|θ⁰_α|: N^αβ = n^αβ|θ⁰_α||θ⁰_β|, Q^α = q^α|θ⁰_α|, M^αβ = m^αβ|θ⁰_α||θ⁰_β|
        (force and moment per unit reference length; the contravariant chart components
        themselves on plates and cylinders by arclength, |θ⁰_α| = 1).  On the sphere by longitude
        and colatitude, |θ⁰_u| = R sin θ: the contravariant n^uu ~ N/(R² sin² θ) would grow
        without bound towards the poles."""
        X0 = self.rest_strain() if reference is None else np.asarray(reference["X0"], dtype=float)
        res = self.resultants(X, X0)
        X0 = np.broadcast_to(X0, np.shape(X))
        s = np.linalg.norm(X0[..., :3], axis=-1)              # |θ⁰_α| [*shape, 2]
        scale = np.stack([s[..., 0] ** 2, s[..., 0] * s[..., 1], s[..., 1] ** 2, s[..., 0], s[..., 1],
                          s[..., 0] ** 2, s[..., 0] * s[..., 1], s[..., 1] ** 2], axis=-1)
        res[..., :8] *= scale
        names = ["membrane_force_uu", "membrane_force_uv", "membrane_force_vv", "shear_force_u", "shear_force_v",
                 "bending_moment_uu", "bending_moment_uv", "bending_moment_vv", "gauss_curvature", "mean_curvature"]
        out = {name: res[..., i] for i, name in enumerate(names)}
        out["director_x"], out["director_y"], out["director_z"] = q[..., 1, 3], q[..., 2, 3], q[..., 3, 3]
        return out
