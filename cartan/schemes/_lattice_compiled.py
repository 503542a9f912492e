"""Compiled step loops of the ``lattice`` scheme for d = 1 (ARCHITECTURE.md §7).

Whole multi-step loops between saves run here, in numba, instead of a Python loop of numpy
calls.  :meth:`cartan.schemes.lattice.Lattice.compiled_advance` is the entry point;
``docs/performance.md`` describes what qualifies and what it gains.

Design
------
* **Groups by integer switch.**  numba does not cache functions that receive other jitted
  functions as arguments, so the group is a static integer ``gid`` and the ``g_*`` functions
  below dispatch to the per-point kernels of :mod:`cartan.groups` (SO(2), SE(2), SO(3),
  SE(3)).  Every kernel is ``@njit(cache=True)``: a second process loads the machine code
  from numba's cache instead of compiling it.
* **Media and loads as data.**  A qualifying medium has a quadratic potential
  ``U = ½(X − X₀)ᵀC(X − X₀)`` (``Medium.quadratic_energy``); loads are reduced to damping
  coefficients, a uniform body-frame force, a constant spatial field acting on positions
  (``ConstantFieldPotential``: ``T = (Rᵀ ρf, 0)``), end loads (follower or dead) and clamps.
  They travel as the tuple ``P`` built by :func:`build_plan` (indices ``I_*``).
* **Same formulas as the reference path.**  Every step performs the operations of
  ``Integrator.step`` with ``Lattice.force``/``drift``/``velocity``/``constrain``/``powers``,
  including the trapezoidal booking of dissipated power and external work, in the same
  order, so that the compiled and the Python paths agree to round-off (≈1e-13 in the tests).
  What differs changes round-off only: products by ``1/w``, ``1/h`` and ``τ/m`` instead of
  quotients; the Taylor series of the SO(3)/SE(3) coefficients (the library's own, valid for
  θ < 0.1, with four terms below θ² = 10⁻⁴) and of atan(x)/x in the logarithm; on SE(3),
  scalar code read straight from the state arrays, ``dexp⁻¹(ξ)ᵀQ`` applied without forming
  6 × 6 matrices (Barfoot–Furgale's block by seven cross products), the head term of an edge
  from ``dexp⁻¹(−ξ)ᵀ = Ad_Gᵀ dexp⁻¹(ξ)ᵀ`` for the integrators that keep G on the group (all
  but ``forward-euler``); and ``lie-verlet``'s palindromic free-flow pieces composed per node
  into one element ``D_i = D₁⋯D_k`` before the edges are conjugated once,
  ``G_e ← D_i⁻¹ G_e D_j``.
* **Vectorised SE(3) lie-verlet.**  For SE(3) with closed-form pieces (the three
  translations, then single body axes: every rod with positive inertias) the loop works on
  structure-of-arrays copies of the state, made once per call; its passes over nodes and
  edges are short, branch-free loops that LLVM vectorises.  Elements outside the series'
  range (an edge turning by 0.1 rad or more, a node turning by 0.1 rad or more in one
  piece) are flagged and recomputed with the closed forms.  Kernels use IEEE division
  (``error_model="numpy"``: inf/nan like the reference path, no zero-divisor test, which
  also blocks vectorisation) and helpers inlined in numba's IR (``inline="always"``).
* **No per-step allocation.**  Work arrays are allocated once per call; the state arrays
  (``S [n, r]``, ``G [ne, m, m]``, ``Phi [n, m, m]`` or the root frame as ``[1, m, m]``) are
  updated in place.
* **Per-step blow-up test.**  After every step a loop tests what the run's guard tests
  (``cartan.simulate``): finite momentum and ``½Σ w S²/m ≤ kinetic_limit`` (or, for
  integrators without momentum, a finite configuration), and stops after the first failing
  step so that the caller can name it.

The loops are serial; there is no ``prange`` variant (``CARTAN_THREADS`` is not read): one
step of a rod is about ten short passes over the nodes, each of which would need its own
parallel region, and a vectorised pass over 10³ nodes takes a few microseconds — about the
cost of starting a parallel region.
"""

from __future__ import annotations

import time

import numpy as np
from numba import njit

from ..groups.se2 import (
    se2_Ad_point,
    se2_ad_point,
    se2_compose_point,
    se2_dexp_inv_point,
    se2_E_point,
    se2_exp_point,
    se2_hat_point,
    se2_inverse_point,
    se2_log_point,
)
from ..groups.se3 import (
    TAYLOR_D,
    TAYLOR_E,
    _dexp_coeffs_direct,
    _exp_coeffs3_direct,
    _V_apply,
    se3_Ad_point,
    se3_ad_point,
    se3_compose_point,
    se3_dexp_inv_point,
    se3_E_point,
    se3_exp_point,
    se3_hat_point,
    se3_inverse_point,
    se3_log_point,
)
from ..groups.so2 import (
    so2_Ad_point,
    so2_ad_point,
    so2_compose_point,
    so2_dexp_inv_point,
    so2_E_point,
    so2_exp_point,
    so2_hat_point,
    so2_inverse_point,
    so2_log_point,
)
from ..groups.so3 import (
    SMALL_THETA2,
    TAYLOR_A,
    TAYLOR_B,
    TAYLOR_C,
    TAYLOR_CINV,
    _cinv_direct,
    _exp_coeffs_direct,
    _log_factor_direct,
    _poly_entries,
    _quat_from_matrix,
    cross3,
    horner,
    so3_Ad_point,
    so3_ad_point,
    so3_compose_point,
    so3_dexp_inv_point,
    so3_E_point,
    so3_exp_point,
    so3_hat_point,
    so3_inverse_point,
    so3_log_point,
)

__all__ = [
    "GROUP_IDS",
    "advance",
    "build_plan",
    "forward_euler_loop",
    "lie_euler_loop",
    "lie_verlet_loop",
    "lie_verlet_se3_loop",
    "overdamped_loop",
    "overdamped_velocity",
    "rkmk_loop",
]

GID_SO2 = 0
GID_SE2 = 1
GID_SO3 = 2
GID_SE3 = 3
#: registered group names with compiled kernels → static group id
GROUP_IDS = {"SO2": GID_SO2, "SE2": GID_SE2, "SO3": GID_SO3, "SE3": GID_SE3}

#: kinds of lie-verlet free-flow pieces: generic (exp and Ad kernels), SE(3) translations
#: {0, 1, 2}, SE(3) rotation about one body axis
KIND_GENERIC = 0
KIND_SE3_TRANSLATION = 1
KIND_SE3_ROTATION = 2

#: blow-up tests after each step: none, momentum (finite, kinetic energy), configuration
CHECK_NONE = 0
CHECK_MOMENTUM = 1
CHECK_CONFIGURATION = 2

#: every kernel: cached, and IEEE division (inf/nan like numpy, no zero-divisor test, which
#: would also keep LLVM from vectorising the loops); helpers are inlined in numba's IR, so
#: that large ones do not leave calls inside loops that LLVM would otherwise vectorise
_jit = njit(cache=True, error_model="numpy")
_inline = njit(inline="always", error_model="numpy")

#: layout of the plan tuple P (see :func:`build_plan`)
(I_GID, I_TRACK, I_AFFINE, I_H, I_X0, I_C, I_DIAG, I_W, I_MASS, I_LIVE, I_CLAMPED, I_CONSTRAINED,
 I_DAMP, I_HAS_DAMP, I_UBODY, I_HAS_UBODY, I_FIELD, I_HAS_FIELD, I_END_IDX, I_END_LOAD, I_END_FOLLOW,
 I_HAS_POWER) = range(22)

#: below this θ², four Taylor terms of the SO(3)/SE(3) coefficients are exact to < 1e-21
SERIES4_THETA2 = 1e-4
_A4, _B4, _C4, _D4, _E4, _CINV4 = (c[-4:] for c in (TAYLOR_A, TAYLOR_B, TAYLOR_C, TAYLOR_D, TAYLOR_E, TAYLOR_CINV))
#: atan(x)/x = Σ (−1)ᵏ x²ᵏ/(2k+1), highest power first: below x² = 1/400 nine terms reach 1e-19
ATAN_SERIES = (1.0 / 17.0, -1.0 / 15.0, 1.0 / 13.0, -1.0 / 11.0, 1.0 / 9.0, -1.0 / 7.0, 1.0 / 5.0, -1.0 / 3.0, 1.0)
ATAN_SERIES_X2 = 1.0 / 400.0
#: below x² = 1e-5 the first five terms suffice (truncation < 1e-21)
ATAN_SERIES5 = ATAN_SERIES[-5:]
ATAN_SERIES5_X2 = 1e-5


# ---------------------------------------------------------------------------- group dispatch
@_jit
def g_exp(gid, xi, out):
    if gid == GID_SE3:
        se3_exp_point(xi, out)
    elif gid == GID_SE2:
        se2_exp_point(xi, out)
    elif gid == GID_SO3:
        so3_exp_point(xi, out)
    else:
        so2_exp_point(xi, out)


@_jit
def g_log(gid, g, out):
    if gid == GID_SE3:
        se3_log_point(g, out)
    elif gid == GID_SE2:
        se2_log_point(g, out)
    elif gid == GID_SO3:
        so3_log_point(g, out)
    else:
        so2_log_point(g, out)


@_jit
def g_inverse(gid, g, out):
    if gid == GID_SE3:
        se3_inverse_point(g, out)
    elif gid == GID_SE2:
        se2_inverse_point(g, out)
    elif gid == GID_SO3:
        so3_inverse_point(g, out)
    else:
        so2_inverse_point(g, out)


@_jit
def g_compose(gid, g, h, out):
    if gid == GID_SE3:
        se3_compose_point(g, h, out)
    elif gid == GID_SE2:
        se2_compose_point(g, h, out)
    elif gid == GID_SO3:
        so3_compose_point(g, h, out)
    else:
        so2_compose_point(g, h, out)


@_jit
def g_Ad(gid, g, out):
    if gid == GID_SE3:
        se3_Ad_point(g, out)
    elif gid == GID_SE2:
        se2_Ad_point(g, out)
    elif gid == GID_SO3:
        so3_Ad_point(g, out)
    else:
        so2_Ad_point(g, out)


@_jit
def g_ad(gid, xi, out):
    if gid == GID_SE3:
        se3_ad_point(xi, out)
    elif gid == GID_SE2:
        se2_ad_point(xi, out)
    elif gid == GID_SO3:
        so3_ad_point(xi, out)
    else:
        so2_ad_point(xi, out)


@_jit
def g_hat(gid, xi, out):
    if gid == GID_SE3:
        se3_hat_point(xi, out)
    elif gid == GID_SE2:
        se2_hat_point(xi, out)
    elif gid == GID_SO3:
        so3_hat_point(xi, out)
    else:
        so2_hat_point(xi, out)


@_jit
def g_dexp_inv(gid, xi, out):
    if gid == GID_SE3:
        se3_dexp_inv_point(xi, out)
    elif gid == GID_SE2:
        se2_dexp_inv_point(xi, out)
    elif gid == GID_SO3:
        so3_dexp_inv_point(xi, out)
    else:
        so2_dexp_inv_point(xi, out)


@_jit
def g_E(gid, dt, xi, out):
    if gid == GID_SE3:
        se3_E_point(dt, xi, out)
    elif gid == GID_SE2:
        se2_E_point(dt, xi, out)
    elif gid == GID_SO3:
        so3_E_point(dt, xi, out)
    else:
        so2_E_point(dt, xi, out)


# ---------------------------------------------------------------------------- small helpers
@_jit
def _scratch(r, m, ne):
    """Per-call work arrays: three r-vectors, two r×r and three m×m matrices, and the edge
    logarithms ``[ne, 7]`` of the SE(3) force."""
    return (np.empty(r), np.empty(r), np.empty(r), np.empty((r, r)), np.empty((r, r)),
            np.empty((m, m)), np.empty((m, m)), np.empty((m, m)), np.empty((ne, 7)))


@_jit
def _copy_matrix(src, dst):
    m = src.shape[0]
    for a in range(m):
        for b in range(m):
            dst[a, b] = src[a, b]


@_inline
def _edge_nodes(e, n):
    """Tail and head node of edge ``e`` (the last edge of a ring closes onto node 0)."""
    j = e + 1
    if j == n:
        j = 0
    return e, j


@_jit
def _velocity(P, S, N):
    """``N = ∂K*/∂S``: ``S/m`` on live components, zero on gauge components and clamped nodes."""
    mass = P[I_MASS]
    live = P[I_LIVE]
    clamped = P[I_CLAMPED]
    n, r = S.shape
    for i in range(n):
        if clamped[i]:
            for k in range(r):
                N[i, k] = 0.0
            continue
        for k in range(r):
            N[i, k] = S[i, k] / mass[k] if live[k] else 0.0


@_jit
def _constrain(P, S):
    """Zero the momentum of gauge components and clamped nodes."""
    if not P[I_CONSTRAINED]:
        return
    live = P[I_LIVE]
    clamped = P[I_CLAMPED]
    n, r = S.shape
    for i in range(n):
        for k in range(r):
            if clamped[i] or not live[k]:
                S[i, k] = 0.0


@_jit
def _kick(S, W, half):
    n, r = S.shape
    for i in range(n):
        for k in range(r):
            S[i, k] = S[i, k] + half * W[i, k]


# ---------------------------------------------------------------------------- SE(3) scalar code
@_inline
def _cinv(t2):
    """``so3_dexp_inv_coeff``: ``c = (1 − (θ/2)cot(θ/2))/θ²``."""
    if t2 < SERIES4_THETA2:
        return horner(t2, _CINV4)
    if t2 < SMALL_THETA2:
        return horner(t2, TAYLOR_CINV)
    return _cinv_direct(t2)


@_inline
def _rot_coeffs(t2):
    """``so3_exp_coeffs``: ``(A, B) = (sin θ/θ, (1 − cos θ)/θ²)``."""
    if t2 < SERIES4_THETA2:
        return horner(t2, _A4), horner(t2, _B4)
    if t2 < SMALL_THETA2:
        return horner(t2, TAYLOR_A), horner(t2, TAYLOR_B)
    return _exp_coeffs_direct(t2)


@_inline
def _exp3_coeffs(t2):
    """``se3_exp_coeffs``: ``(A, B, C)``, ``C = (θ − sin θ)/θ³``."""
    if t2 < SERIES4_THETA2:
        return horner(t2, _A4), horner(t2, _B4), horner(t2, _C4)
    if t2 < SMALL_THETA2:
        return horner(t2, TAYLOR_A), horner(t2, TAYLOR_B), horner(t2, TAYLOR_C)
    return _exp_coeffs3_direct(t2)


@_inline
def _q_coeffs(t2):
    """The coefficients ``(C, D, E)`` of Barfoot–Furgale's block (``se3_dexp_coeffs`` without B)."""
    if t2 < SERIES4_THETA2:
        return horner(t2, _C4), horner(t2, _D4), horner(t2, _E4)
    if t2 < SMALL_THETA2:
        return horner(t2, TAYLOR_C), horner(t2, TAYLOR_D), horner(t2, TAYLOR_E)
    _, c, d, e = _dexp_coeffs_direct(t2)
    return c, d, e


@_inline
def _q_block(r0, r1, r2, p0, p1, p2, c, d, e, v0, v1, v2):
    """``Q v`` for Barfoot–Furgale's block ``Q = ½P + C(KP + PK + KPK) + D(K²P + PK² − 3KPK)
    + E(KPK² + K²PK)`` (``P = r̂``, ``K = p̂``), grouped as
    ``½u₁ + Cu₂ + Du₃ + K(y + Kz)`` with ``u_k = P Kᵏ⁻¹v``, ``y = Cu₁ + (C − 3D)u₂ + Eu₃``,
    ``z = Du₁ + Eu₂``: seven cross products."""
    b0, b1, b2 = cross3(p0, p1, p2, v0, v1, v2)
    k0, k1, k2 = cross3(p0, p1, p2, b0, b1, b2)
    u0, u1, u2 = cross3(r0, r1, r2, v0, v1, v2)
    w0, w1, w2 = cross3(r0, r1, r2, b0, b1, b2)
    x0, x1, x2 = cross3(r0, r1, r2, k0, k1, k2)
    c3 = c - 3.0 * d
    z = cross3(p0, p1, p2, d * u0 + e * w0, d * u1 + e * w1, d * u2 + e * w2)
    y0 = c * u0 + c3 * w0 + e * x0 + z[0]
    y1 = c * u1 + c3 * w1 + e * x1 + z[1]
    y2 = c * u2 + c3 * w2 + e * x2 + z[2]
    t = cross3(p0, p1, p2, y0, y1, y2)
    return (0.5 * u0 + c * w0 + d * x0 + t[0], 0.5 * u1 + c * w1 + d * x1 + t[1],
            0.5 * u2 + c * w2 + d * x2 + t[2])


@_inline
def _jinv_T(p0, p1, p2, cinv, v0, v1, v2):
    """``J⁻¹(p)ᵀ v = v + ½ p × v + c p × (p × v)``."""
    u = cross3(p0, p1, p2, v0, v1, v2)
    z = cross3(p0, p1, p2, u[0], u[1], u[2])
    return v0 + 0.5 * u[0] + cinv * z[0], v1 + 0.5 * u[1] + cinv * z[1], v2 + 0.5 * u[2] + cinv * z[2]


@_inline
def _se3_dexp_inv_T(r0, r1, r2, p0, p1, p2, cinv, c, d, e, F0, F1, F2, M0, M1, M2):
    """``dexp⁻¹(ξ)ᵀ (F; M)`` for ``ξ = (r; p)``: with ``dexp⁻¹ = [[J⁻¹, −J⁻¹QJ⁻¹], [0, J⁻¹]]``
    and ``Q(ξ)ᵀ = Q(−ξ)``, it is ``(J⁻ᵀF; J⁻ᵀ(M − Q(−ξ) J⁻ᵀF))``."""
    o0, o1, o2 = _jinv_T(p0, p1, p2, cinv, F0, F1, F2)
    q = _q_block(-r0, -r1, -r2, -p0, -p1, -p2, c, d, e, o0, o1, o2)
    o3, o4, o5 = _jinv_T(p0, p1, p2, cinv, M0 - q[0], M1 - q[1], M2 - q[2])
    return o0, o1, o2, o3, o4, o5


@_inline
def _se3_log12(b0, b1, b2, r00, r01, r02, r10, r11, r12, r20, r21, r22):
    """``log (b; R)`` as 6 scalars ``(a1; a2)`` and the coefficient ``c`` of ``J⁻¹(a2)``:
    :func:`cartan.groups.se3.se3_log_point` on scalars, with the quaternion factor
    ``θ/|q_v| = (2/q_w) atan(x)/x`` from its series for ``x = |q_v|/q_w < 1/20``."""
    case = 0
    best = r00 + r11 + r22
    if r00 > best:
        case = 1
        best = r00
    if r11 > best:
        case = 2
        best = r11
    if r22 > best:
        case = 3
    qw, qx, qy, qz = _quat_from_matrix(r00, r01, r02, r10, r11, r12, r20, r21, r22, case)
    if qw < 0.0:
        qw, qx, qy, qz = -qw, -qx, -qy, -qz
    v2 = qx * qx + qy * qy + qz * qz
    w2 = qw * qw
    if v2 < ATAN_SERIES5_X2 * w2:
        f = (2.0 / qw) * horner(v2 / w2, ATAN_SERIES5)
    elif v2 < ATAN_SERIES_X2 * w2:
        f = (2.0 / qw) * horner(v2 / w2, ATAN_SERIES)
    else:
        f = _log_factor_direct(np.sqrt(v2), qw)
    w0, w1, w2 = f * qx, f * qy, f * qz
    c = _cinv(w0 * w0 + w1 * w1 + w2 * w2)
    t = _V_apply(w0, w1, w2, -0.5, c, b0, b1, b2)
    return t[0], t[1], t[2], w0, w1, w2, c


@_inline
def _se3_log_at(G, e):
    """:func:`_se3_log12` of the edge element ``G[e]`` (read straight from the batch)."""
    return _se3_log12(G[e, 1, 0], G[e, 2, 0], G[e, 3, 0], G[e, 1, 1], G[e, 1, 2], G[e, 1, 3],
                      G[e, 2, 1], G[e, 2, 2], G[e, 2, 3], G[e, 3, 1], G[e, 3, 2], G[e, 3, 3])


@_jit
def _se3_internal_force(P, G, F, XI, on_group):
    """``F`` ← internal forces of every SE(3) edge (not divided by the node weights): tail
    ``+dexp⁻¹(ξ)ᵀQ``, head ``−dexp⁻¹(−ξ)ᵀQ`` with ``ξ = log G_e``, ``Q = C(ξ/h − X₀)``; the
    head term is ``Ad_Gᵀ`` of the tail term when ``on_group``, else evaluated directly.  Two
    passes (the logarithms into ``XI``, then the Jacobians): short loop bodies overlap better."""
    X0 = P[I_X0]
    C = P[I_C]
    diag = P[I_DIAG]
    h = P[I_H]
    n = F.shape[0]
    ne = G.shape[0]
    for e in range(ne):
        XI[e, 0], XI[e, 1], XI[e, 2], XI[e, 3], XI[e, 4], XI[e, 5], XI[e, 6] = _se3_log_at(G, e)
    for i in range(n):
        for k in range(6):
            F[i, k] = 0.0
    for e in range(ne):
        i, j = _edge_nodes(e, n)
        r0, r1, r2, p0, p1, p2, cinv = XI[e, 0], XI[e, 1], XI[e, 2], XI[e, 3], XI[e, 4], XI[e, 5], XI[e, 6]
        d0, d1, d2 = r0 / h - X0[0], r1 / h - X0[1], r2 / h - X0[2]
        d3, d4, d5 = p0 / h - X0[3], p1 / h - X0[4], p2 / h - X0[5]
        if diag:
            q0, q1, q2 = C[0, 0] * d0, C[1, 1] * d1, C[2, 2] * d2
            q3, q4, q5 = C[3, 3] * d3, C[4, 4] * d4, C[5, 5] * d5
        else:
            q0 = C[0, 0] * d0 + C[0, 1] * d1 + C[0, 2] * d2 + C[0, 3] * d3 + C[0, 4] * d4 + C[0, 5] * d5
            q1 = C[1, 0] * d0 + C[1, 1] * d1 + C[1, 2] * d2 + C[1, 3] * d3 + C[1, 4] * d4 + C[1, 5] * d5
            q2 = C[2, 0] * d0 + C[2, 1] * d1 + C[2, 2] * d2 + C[2, 3] * d3 + C[2, 4] * d4 + C[2, 5] * d5
            q3 = C[3, 0] * d0 + C[3, 1] * d1 + C[3, 2] * d2 + C[3, 3] * d3 + C[3, 4] * d4 + C[3, 5] * d5
            q4 = C[4, 0] * d0 + C[4, 1] * d1 + C[4, 2] * d2 + C[4, 3] * d3 + C[4, 4] * d4 + C[4, 5] * d5
            q5 = C[5, 0] * d0 + C[5, 1] * d1 + C[5, 2] * d2 + C[5, 3] * d3 + C[5, 4] * d4 + C[5, 5] * d5
        c, dd, ee = _q_coeffs(p0 * p0 + p1 * p1 + p2 * p2)
        o0, o1, o2, o3, o4, o5 = _se3_dexp_inv_T(r0, r1, r2, p0, p1, p2, cinv, c, dd, ee, q0, q1, q2, q3, q4, q5)
        F[i, 0] += o0
        F[i, 1] += o1
        F[i, 2] += o2
        F[i, 3] += o3
        F[i, 4] += o4
        F[i, 5] += o5
        if on_group:
            # Ad_Gᵀ (o_t; o_r) = (Rᵀo_t; Rᵀ(o_r − a × o_t)) for G = (a; R)
            w = cross3(G[e, 1, 0], G[e, 2, 0], G[e, 3, 0], o0, o1, o2)
            v0, v1, v2 = o3 - w[0], o4 - w[1], o5 - w[2]
            for k in range(3):
                F[j, k] += -(G[e, 1, k + 1] * o0 + G[e, 2, k + 1] * o1 + G[e, 3, k + 1] * o2)
                F[j, k + 3] += -(G[e, 1, k + 1] * v0 + G[e, 2, k + 1] * v1 + G[e, 3, k + 1] * v2)
        else:
            o0, o1, o2, o3, o4, o5 = _se3_dexp_inv_T(-r0, -r1, -r2, -p0, -p1, -p2, cinv, c, dd, ee,
                                                     q0, q1, q2, q3, q4, q5)
            F[j, 0] += -o0
            F[j, 1] += -o1
            F[j, 2] += -o2
            F[j, 3] += -o3
            F[j, 4] += -o4
            F[j, 5] += -o5


@_jit
def _se3_exp_nodes(N, tau, D):
    """``D_i = exp(τN_i)`` on SE(3) (``se3_exp_point`` written into the batch)."""
    for i in range(N.shape[0]):
        x0, x1, x2 = tau * N[i, 0], tau * N[i, 1], tau * N[i, 2]
        w0, w1, w2 = tau * N[i, 3], tau * N[i, 4], tau * N[i, 5]
        a, b, c = _exp3_coeffs(w0 * w0 + w1 * w1 + w2 * w2)
        R = _poly_entries(w0, w1, w2, a, b, 1.0)
        t = _V_apply(w0, w1, w2, b, c, x0, x1, x2)
        D[i, 0, 0], D[i, 0, 1], D[i, 0, 2], D[i, 0, 3] = 1.0, 0.0, 0.0, 0.0
        D[i, 1, 0], D[i, 1, 1], D[i, 1, 2], D[i, 1, 3] = t[0], R[0], R[1], R[2]
        D[i, 2, 0], D[i, 2, 1], D[i, 2, 2], D[i, 2, 3] = t[1], R[3], R[4], R[5]
        D[i, 3, 0], D[i, 3, 1], D[i, 3, 2], D[i, 3, 3] = t[2], R[6], R[7], R[8]


@_jit
def _se3_conjugate(G, Phi, track, D):
    """SE(3) drift by per-node elements ``D = (t; R)``: ``G_e ← D_i⁻¹ G_e D_j`` as
    ``(R_iᵀ(B t_j + b − t_i); R_iᵀ B R_j)`` for ``G_e = (b; B)``; ``Φ_i ← Φ_i D_i``."""
    n = D.shape[0]
    for e in range(G.shape[0]):
        i, j = _edge_nodes(e, n)
        u0 = G[e, 1, 1] * D[j, 1, 0] + G[e, 1, 2] * D[j, 2, 0] + G[e, 1, 3] * D[j, 3, 0] + G[e, 1, 0] - D[i, 1, 0]
        u1 = G[e, 2, 1] * D[j, 1, 0] + G[e, 2, 2] * D[j, 2, 0] + G[e, 2, 3] * D[j, 3, 0] + G[e, 2, 0] - D[i, 2, 0]
        u2 = G[e, 3, 1] * D[j, 1, 0] + G[e, 3, 2] * D[j, 2, 0] + G[e, 3, 3] * D[j, 3, 0] + G[e, 3, 0] - D[i, 3, 0]
        for a in range(1, 4):
            b0 = G[e, a, 1] * D[j, 1, 1] + G[e, a, 2] * D[j, 2, 1] + G[e, a, 3] * D[j, 3, 1]
            b1 = G[e, a, 1] * D[j, 1, 2] + G[e, a, 2] * D[j, 2, 2] + G[e, a, 3] * D[j, 3, 2]
            b2 = G[e, a, 1] * D[j, 1, 3] + G[e, a, 2] * D[j, 2, 3] + G[e, a, 3] * D[j, 3, 3]
            G[e, a, 1] = b0
            G[e, a, 2] = b1
            G[e, a, 3] = b2
        for b in range(1, 4):
            m0, m1, m2 = G[e, 1, b], G[e, 2, b], G[e, 3, b]
            G[e, 1, b] = D[i, 1, 1] * m0 + D[i, 2, 1] * m1 + D[i, 3, 1] * m2
            G[e, 2, b] = D[i, 1, 2] * m0 + D[i, 2, 2] * m1 + D[i, 3, 2] * m2
            G[e, 3, b] = D[i, 1, 3] * m0 + D[i, 2, 3] * m1 + D[i, 3, 3] * m2
        G[e, 1, 0] = D[i, 1, 1] * u0 + D[i, 2, 1] * u1 + D[i, 3, 1] * u2
        G[e, 2, 0] = D[i, 1, 2] * u0 + D[i, 2, 2] * u1 + D[i, 3, 2] * u2
        G[e, 3, 0] = D[i, 1, 3] * u0 + D[i, 2, 3] * u1 + D[i, 3, 3] * u2
    nf = n if track else 1
    for i in range(nf):
        for a in range(1, 4):
            x0, x1, x2, x3 = Phi[i, a, 0], Phi[i, a, 1], Phi[i, a, 2], Phi[i, a, 3]
            Phi[i, a, 0] = x1 * D[i, 1, 0] + x2 * D[i, 2, 0] + x3 * D[i, 3, 0] + x0
            Phi[i, a, 1] = x1 * D[i, 1, 1] + x2 * D[i, 2, 1] + x3 * D[i, 3, 1]
            Phi[i, a, 2] = x1 * D[i, 1, 2] + x2 * D[i, 2, 2] + x3 * D[i, 3, 2]
            Phi[i, a, 3] = x1 * D[i, 1, 3] + x2 * D[i, 2, 3] + x3 * D[i, 3, 3]


@_inline
def _turn(cs, sn, x, y):
    """Components of ``Rᵀ(x, y)`` for a plane rotation R by (cos, sin) = (cs, sn)."""
    return cs * x + sn * y, -sn * x + cs * y


# ---------------------------------------------------------------------------- forces
@_jit
def _end_load(gid, affine, Phi, idx, load, follower, out, M, A):
    """Body components of an end load: ``load`` (follower) or ``Ad_Rᵀ load`` (dead), R the
    rotational part of the end frame."""
    r = load.shape[0]
    if follower:
        for a in range(r):
            out[a] = load[a]
        return
    _copy_matrix(Phi[idx], A)
    if affine:
        for a in range(1, A.shape[0]):
            A[a, 0] = 0.0
    g_Ad(gid, A, M)
    for a in range(r):
        acc = 0.0
        for b in range(r):
            acc += M[b, a] * load[b]
        out[a] = acc


@_jit
def _force(P, G, Phi, N, W, F, scr, on_group):
    """``W = Lattice.force(state, N, t)`` for the problem of the plan ``P``."""
    gid = P[I_GID]
    live = P[I_LIVE]
    clamped = P[I_CLAMPED]
    xi, Q, tr, M, M2, A1, A2, A3, XI = scr
    n, r = W.shape
    w = P[I_W]
    if gid == GID_SE3:
        _se3_internal_force(P, G, F, XI, on_group)
    else:
        X0 = P[I_X0]
        C = P[I_C]
        h = P[I_H]
        for i in range(n):
            for k in range(r):
                F[i, k] = 0.0
        for e in range(G.shape[0]):
            i, j = _edge_nodes(e, n)
            g_log(gid, G[e], xi)
            for k in range(r):
                tr[k] = xi[k] / h - X0[k]
            for k in range(r):
                acc = 0.0
                for b in range(r):
                    acc += C[k, b] * tr[b]
                Q[k] = acc
            g_dexp_inv(gid, xi, M)
            for k in range(r):
                tr[k] = -xi[k]
            g_dexp_inv(gid, tr, M2)
            for a in range(r):
                out = 0.0
                inc = 0.0
                for b in range(r):
                    out += M[b, a] * Q[b]
                    inc += M2[b, a] * Q[b]
                F[i, a] += out
                F[j, a] += -inc
    for i in range(n):
        for k in range(r):
            W[i, k] = F[i, k] / w[i]
    if P[I_HAS_DAMP]:
        damp = P[I_DAMP]
        for i in range(n):
            for k in range(r):
                W[i, k] += -N[i, k] * damp[k]
    if P[I_HAS_UBODY]:
        ubody = P[I_UBODY]
        for i in range(n):
            for k in range(r):
                W[i, k] += ubody[k]
    if P[I_HAS_FIELD]:
        field = P[I_FIELD]
        ks = field.shape[0]
        for i in range(n):
            for k in range(ks):
                acc = 0.0
                for b in range(ks):
                    acc += Phi[i, b + 1, k + 1] * field[b]
                W[i, k] += acc
    end_idx = P[I_END_IDX]
    for q in range(end_idx.shape[0]):
        idx = end_idx[q]
        _end_load(gid, P[I_AFFINE], Phi, idx, P[I_END_LOAD][q], P[I_END_FOLLOW][q], tr, M, A1)
        for a in range(r):
            W[idx, a] += tr[a] / w[idx]
    if P[I_CONSTRAINED]:
        for i in range(n):
            for k in range(r):
                if clamped[i] or not live[k]:
                    W[i, k] = 0.0


@_jit
def _powers(P, N, Phi, scr):
    """(dissipated, external) power of the loads at velocity N (``Scheme.powers``)."""
    if not P[I_HAS_POWER]:
        return 0.0, 0.0
    xi, Q, tr, M, M2, A1, A2, A3, XI = scr
    w = P[I_W]
    n, r = N.shape
    dissipated = 0.0
    external = 0.0
    if P[I_HAS_DAMP]:
        damp = P[I_DAMP]
        p = 0.0
        for i in range(n):
            s = 0.0
            for k in range(r):
                s += (-N[i, k] * damp[k]) * N[i, k]
            p += w[i] * s
        dissipated -= p
    if P[I_HAS_UBODY]:
        ubody = P[I_UBODY]
        p = 0.0
        for i in range(n):
            s = 0.0
            for k in range(r):
                s += ubody[k] * N[i, k]
            p += w[i] * s
        external += p
    end_idx = P[I_END_IDX]
    p = 0.0
    for q in range(end_idx.shape[0]):
        idx = end_idx[q]
        _end_load(P[I_GID], P[I_AFFINE], Phi, idx, P[I_END_LOAD][q], P[I_END_FOLLOW][q], tr, M, A1)
        for a in range(r):
            p += tr[a] * N[idx, a]
    external += p
    return dissipated, external


# ---------------------------------------------------------------------------- drifts
@_jit
def _conjugate(P, G, Phi, D, A1, A2):
    """Drift by per-node elements D: ``G_e ← D_i⁻¹ G_e D_j``; ``Φ_i ← Φ_i D_i`` (or the root)."""
    gid = P[I_GID]
    track = P[I_TRACK]
    if gid == GID_SE3:
        _se3_conjugate(G, Phi, track, D)
        return
    n = D.shape[0]
    for e in range(G.shape[0]):
        i, j = _edge_nodes(e, n)
        g_inverse(gid, D[i], A1)
        g_compose(gid, A1, G[e], A2)
        g_compose(gid, A2, D[j], G[e])
    nf = n if track else 1
    for i in range(nf):
        g_compose(gid, Phi[i], D[i], A1)
        _copy_matrix(A1, Phi[i])


@_jit
def _exp_drift(P, G, Phi, N, tau, D, scr):
    """Exact drift ``Φ ← Φ exp(τN)`` (``Lattice.drift(exact=True)``)."""
    gid = P[I_GID]
    xi = scr[0]
    if gid == GID_SE3:
        _se3_exp_nodes(N, tau, D)
    else:
        n, r = N.shape
        for i in range(n):
            for k in range(r):
                xi[k] = tau * N[i, k]
            g_exp(gid, xi, D[i])
    _conjugate(P, G, Phi, D, scr[5], scr[6])


@_jit
def _free_flow(P, S, D, dt, seq_mask, seq_frac, scr):
    """Palindromic exact free flow of every node, composed into one element ``D_i`` per node:
    for each piece p, ``S_i ← Ad*_{exp(τN_p)} S_i`` and ``D_i ← D_i exp(τN_p)``."""
    gid = P[I_GID]
    mass = P[I_MASS]
    clamped = P[I_CLAMPED]
    xi, Q, tr, M, M2, A1, A2, A3, XI = scr
    n, r = S.shape
    m = D.shape[1]
    for i in range(n):
        for a in range(m):
            for b in range(m):
                D[i, a, b] = 1.0 if a == b else 0.0
        if clamped[i]:
            continue  # N = 0: every piece is the identity
        for p in range(seq_frac.shape[0]):
            tau = seq_frac[p] * dt
            for k in range(r):
                xi[k] = tau * (S[i, k] / mass[k]) if seq_mask[p, k] else 0.0
            g_exp(gid, xi, A1)
            g_Ad(gid, A1, M)
            for a in range(r):
                acc = 0.0
                for b in range(r):
                    acc += M[b, a] * S[i, b]
                tr[a] = acc
            for a in range(r):
                S[i, a] = tr[a]
            g_compose(gid, D[i], A1, A2)
            _copy_matrix(A2, D[i])


# ---------------------------------------------------------------------------- blow-up test
@_jit
def _unstable(check, kinetic_limit, S, G, Phi, w, inv):
    """True when the state fails the run's per-step blow-up test."""
    if check == CHECK_MOMENTUM:
        n, r = S.shape
        tot = 0.0
        for i in range(n):
            for k in range(r):
                tot += S[i, k]
        if not np.isfinite(tot):
            return True
        if kinetic_limit < np.inf:
            K = 0.0
            for i in range(n):
                for k in range(r):
                    K += w[i] * S[i, k] * S[i, k] * inv[k]
            if not 0.5 * K <= kinetic_limit:
                return True
        return False
    if check == CHECK_CONFIGURATION:
        for x in S.ravel():
            if not np.isfinite(x):
                return True
        for x in G.ravel():
            if not np.isfinite(x):
                return True
        for x in Phi.ravel():
            if not np.isfinite(x):
                return True
    return False


# ---------------------------------------------------------------------------- lie-verlet
@_jit
def lie_verlet_loop(P, S, G, Phi, W, have_force, velocity_free, seq_mask, seq_frac,
                    t, dt, nsteps, dissipated, external, check, kinetic_limit, inv):
    """``nsteps`` steps of ``LieVerlet`` (half kick, exact split free flow, half kick).

    ``W`` holds the force at the current state when ``have_force`` (first-same-as-last) and
    the force at the final state on return.  ``seq_mask``, ``seq_frac``: the palindromic
    pieces (components, fraction of Δt).  Returns
    ``(steps done, force evaluations, t, dissipated, external)``.
    """
    n, r = S.shape
    m = G.shape[1]
    N = np.zeros((n, r))
    F = np.empty((n, r))
    D = np.empty((n, m, m))
    scr = _scratch(r, m, G.shape[0])
    w = P[I_W]
    # N enters the force only through damping, and the bookkeeping only through the powers
    need_N = P[I_HAS_DAMP] or P[I_HAS_POWER]
    nforce = 0
    half = 0.5 * dt
    if need_N:
        _velocity(P, S, N)
    p0d, p0e = _powers(P, N, Phi, scr)
    done = 0
    for _ in range(nsteps):
        if not (have_force and velocity_free):
            _force(P, G, Phi, N, W, F, scr, True)
            nforce += 1
        _kick(S, W, half)
        _constrain(P, S)
        _free_flow(P, S, D, dt, seq_mask, seq_frac, scr)
        _conjugate(P, G, Phi, D, scr[5], scr[6])
        _constrain(P, S)
        if need_N:
            _velocity(P, S, N)
        _force(P, G, Phi, N, W, F, scr, True)
        nforce += 1
        have_force = True
        _kick(S, W, half)
        _constrain(P, S)
        t = t + dt
        if need_N:
            _velocity(P, S, N)
        p1d, p1e = _powers(P, N, Phi, scr)
        dissipated = dissipated + 0.5 * dt * (p0d + p1d)
        external = external + 0.5 * dt * (p0e + p1e)
        p0d, p0e = p1d, p1e
        done += 1
        if _unstable(check, kinetic_limit, S, G, Phi, w, inv):
            break
    return done, nforce, t, dissipated, external


# ---------------------------------------------------------------------------- SE(3) lie-verlet, vectorised
# For SE(3) with every free-flow piece in closed form (translations, single body axes), the
# loop works on structure-of-arrays copies of the state — one row per component, one column
# per node or edge, made once per call — so that LLVM vectorises the passes over nodes and
# edges.  Their bodies have no branches: the SO(3)/SE(3) coefficients come from their Taylor
# series (the library's own, valid for θ < 0.1) and the edge logarithm from the trace
# quaternion; each pass flags the elements outside that range (large angles) and recomputes
# them with the closed forms of the scalar code.
@_inline
def _ad_T(b0, b1, b2, m00, m01, m02, m10, m11, m12, m20, m21, m22, o0, o1, o2, o3, o4, o5):
    """``Ad_Gᵀ (o_t; o_r) = (Mᵀo_t; Mᵀ(o_r − b × o_t))`` for ``G = (b; M)``."""
    x0, x1, x2 = cross3(b0, b1, b2, o0, o1, o2)
    v0, v1, v2 = o3 - x0, o4 - x1, o5 - x2
    return (m00 * o0 + m10 * o1 + m20 * o2, m01 * o0 + m11 * o1 + m21 * o2, m02 * o0 + m12 * o1 + m22 * o2,
            m00 * v0 + m10 * v1 + m20 * v2, m01 * v0 + m11 * v1 + m21 * v2, m02 * v0 + m12 * v1 + m22 * v2)


@_inline
def _edge_terms(r0, r1, r2, p0, p1, p2, cinv, c, d, e, q0, q1, q2, q3, q4, q5,
                b0, b1, b2, m00, m01, m02, m10, m11, m12, m20, m21, m22):
    """Tail term ``dexp⁻¹(ξ)ᵀQ`` and head term ``Ad_Gᵀ`` of it for ``G = (b; M)``: 12 scalars."""
    o0, o1, o2, o3, o4, o5 = _se3_dexp_inv_T(r0, r1, r2, p0, p1, p2, cinv, c, d, e, q0, q1, q2, q3, q4, q5)
    h = _ad_T(b0, b1, b2, m00, m01, m02, m10, m11, m12, m20, m21, m22, o0, o1, o2, o3, o4, o5)
    return o0, o1, o2, o3, o4, o5, h[0], h[1], h[2], h[3], h[4], h[5]


@_inline
def _stress(P, r0, r1, r2, p0, p1, p2, h):
    """``Q = C(ξ/h − X₀)`` as 6 scalars."""
    X0 = P[I_X0]
    C = P[I_C]
    d0, d1, d2 = r0 / h - X0[0], r1 / h - X0[1], r2 / h - X0[2]
    d3, d4, d5 = p0 / h - X0[3], p1 / h - X0[4], p2 / h - X0[5]
    if P[I_DIAG]:
        return C[0, 0] * d0, C[1, 1] * d1, C[2, 2] * d2, C[3, 3] * d3, C[4, 4] * d4, C[5, 5] * d5
    return (C[0, 0] * d0 + C[0, 1] * d1 + C[0, 2] * d2 + C[0, 3] * d3 + C[0, 4] * d4 + C[0, 5] * d5,
            C[1, 0] * d0 + C[1, 1] * d1 + C[1, 2] * d2 + C[1, 3] * d3 + C[1, 4] * d4 + C[1, 5] * d5,
            C[2, 0] * d0 + C[2, 1] * d1 + C[2, 2] * d2 + C[2, 3] * d3 + C[2, 4] * d4 + C[2, 5] * d5,
            C[3, 0] * d0 + C[3, 1] * d1 + C[3, 2] * d2 + C[3, 3] * d3 + C[3, 4] * d4 + C[3, 5] * d5,
            C[4, 0] * d0 + C[4, 1] * d1 + C[4, 2] * d2 + C[4, 3] * d3 + C[4, 4] * d4 + C[4, 5] * d5,
            C[5, 0] * d0 + C[5, 1] * d1 + C[5, 2] * d2 + C[5, 3] * d3 + C[5, 4] * d4 + C[5, 5] * d5)


@_jit
def _soa_logs(g, XI, bad):
    """``XI[:, e]`` = log of every edge ``g[:, e] = (b; M)`` with its ``J⁻¹`` coefficient, by
    the series (trace quaternion); ``bad[e] = 1`` where those do not apply.  Returns the count."""
    nbad = 0
    for e in range(g.shape[1]):
        m00, m01, m02 = g[3, e], g[4, e], g[5, e]
        m10, m11, m12 = g[6, e], g[7, e], g[8, e]
        m20, m21, m22 = g[9, e], g[10, e], g[11, e]
        tr = m00 + m11 + m22
        qw = 1.0 + tr
        qx, qy, qz = m21 - m12, m02 - m20, m10 - m01
        x2 = (qx * qx + qy * qy + qz * qz) / (qw * qw)
        f = (2.0 / qw) * horner(x2, ATAN_SERIES)
        w0, w1, w2 = f * qx, f * qy, f * qz
        t2 = w0 * w0 + w1 * w1 + w2 * w2
        cinv = horner(t2, TAYLOR_CINV)
        t = _V_apply(w0, w1, w2, -0.5, cinv, g[0, e], g[1, e], g[2, e])
        XI[0, e] = t[0]
        XI[1, e] = t[1]
        XI[2, e] = t[2]
        XI[3, e] = w0
        XI[4, e] = w1
        XI[5, e] = w2
        XI[6, e] = cinv
        flag = (x2 >= ATAN_SERIES_X2) | (t2 >= SMALL_THETA2) | (m00 > tr) | (m11 > tr) | (m22 > tr)
        bad[e] = flag
        nbad += flag
    return nbad


@_jit
def _soa_stress(P, XI, QS, h):
    """``QS[:, e] = C(ξ_e/h − X₀)`` (diagonal or full C, each a branch-free loop)."""
    X0 = P[I_X0]
    C = P[I_C]
    ne = XI.shape[1]
    if P[I_DIAG]:
        for k in range(6):
            ck = C[k, k]
            x0 = X0[k]
            for e in range(ne):
                QS[k, e] = ck * (XI[k, e] / h - x0)
        return
    for e in range(ne):
        q = _stress(P, XI[0, e], XI[1, e], XI[2, e], XI[3, e], XI[4, e], XI[5, e], h)
        for k in range(6):
            QS[k, e] = q[k]


@_jit
def _soa_force(P, g, phi, Nv, w, XI, QS, OUT, INC, bad):
    """``w`` ← ``Lattice.force`` on the structure-of-arrays state (SE(3))."""
    live = P[I_LIVE]
    clamped = P[I_CLAMPED]
    wts = P[I_W]
    h = P[I_H]
    n = w.shape[1]
    ne = g.shape[1]
    nbad = _soa_logs(g, XI, bad)
    if nbad:
        for e in range(ne):
            if bad[e]:
                r = _se3_log12(g[0, e], g[1, e], g[2, e], g[3, e], g[4, e], g[5, e], g[6, e], g[7, e], g[8, e],
                               g[9, e], g[10, e], g[11, e])
                for k in range(7):
                    XI[k, e] = r[k]
    _soa_stress(P, XI, QS, h)
    # tail terms, then head terms: two short loops vectorise where one long one does not
    for e in range(ne):
        r0, r1, r2, p0, p1, p2, cinv = XI[0, e], XI[1, e], XI[2, e], XI[3, e], XI[4, e], XI[5, e], XI[6, e]
        t2 = p0 * p0 + p1 * p1 + p2 * p2
        o = _se3_dexp_inv_T(r0, r1, r2, p0, p1, p2, cinv, horner(t2, TAYLOR_C), horner(t2, TAYLOR_D),
                            horner(t2, TAYLOR_E), QS[0, e], QS[1, e], QS[2, e], QS[3, e], QS[4, e], QS[5, e])
        OUT[0, e] = o[0]
        OUT[1, e] = o[1]
        OUT[2, e] = o[2]
        OUT[3, e] = o[3]
        OUT[4, e] = o[4]
        OUT[5, e] = o[5]
    for e in range(ne):
        hd = _ad_T(g[0, e], g[1, e], g[2, e], g[3, e], g[4, e], g[5, e], g[6, e], g[7, e], g[8, e], g[9, e],
                   g[10, e], g[11, e], OUT[0, e], OUT[1, e], OUT[2, e], OUT[3, e], OUT[4, e], OUT[5, e])
        INC[0, e] = hd[0]
        INC[1, e] = hd[1]
        INC[2, e] = hd[2]
        INC[3, e] = hd[3]
        INC[4, e] = hd[4]
        INC[5, e] = hd[5]
    if nbad:
        for e in range(ne):
            if bad[e]:
                r0, r1, r2, p0, p1, p2, cinv = XI[0, e], XI[1, e], XI[2, e], XI[3, e], XI[4, e], XI[5, e], XI[6, e]
                q0, q1, q2, q3, q4, q5 = _stress(P, r0, r1, r2, p0, p1, p2, h)
                c, dd, ee = _q_coeffs(p0 * p0 + p1 * p1 + p2 * p2)
                o = _edge_terms(r0, r1, r2, p0, p1, p2, cinv, c, dd, ee, q0, q1, q2, q3, q4, q5,
                                g[0, e], g[1, e], g[2, e], g[3, e], g[4, e], g[5, e],
                                g[6, e], g[7, e], g[8, e], g[9, e], g[10, e], g[11, e])
                for k in range(6):
                    OUT[k, e] = o[k]
                    INC[k, e] = o[k + 6]
    # node i: tail of edge i, head of edge i − 1 (F_i = out_i − inc_{i−1}), divided by w_i
    for k in range(6):
        for i in range(1, n - 1):
            w[k, i] = (OUT[k, i] - INC[k, i - 1]) / wts[i]
        if ne == n:  # ring: node 0 heads the closing edge
            w[k, 0] = (OUT[k, 0] - INC[k, ne - 1]) / wts[0]
            w[k, n - 1] = (OUT[k, n - 1] - INC[k, n - 2]) / wts[n - 1]
        else:
            w[k, 0] = OUT[k, 0] / wts[0]
            w[k, n - 1] = -INC[k, n - 2] / wts[n - 1]
    if P[I_HAS_DAMP]:
        damp = P[I_DAMP]
        for k in range(6):
            for i in range(n):
                w[k, i] += -Nv[k, i] * damp[k]
    if P[I_HAS_UBODY]:
        ubody = P[I_UBODY]
        for k in range(6):
            for i in range(n):
                w[k, i] += ubody[k]
    if P[I_HAS_FIELD]:
        f0, f1, f2 = P[I_FIELD][0], P[I_FIELD][1], P[I_FIELD][2]
        for k in range(3):
            for i in range(n):
                w[k, i] += phi[3 + k, i] * f0 + phi[6 + k, i] * f1 + phi[9 + k, i] * f2
    end_idx = P[I_END_IDX]
    for q in range(end_idx.shape[0]):
        i = end_idx[q]
        b = _soa_end_load(P, phi, q)
        for k in range(6):
            w[k, i] += b[k] / wts[i]
    if P[I_CONSTRAINED]:
        for k in range(6):
            for i in range(n):
                if clamped[i] or not live[k]:
                    w[k, i] = 0.0


@_inline
def _soa_end_load(P, phi, q):
    """Body components of end load ``q``: the load (follower) or ``(Rᵀf; Rᵀm)`` (dead), R the
    rotation of the end frame."""
    load = P[I_END_LOAD][q]
    if P[I_END_FOLLOW][q]:
        return load[0], load[1], load[2], load[3], load[4], load[5]
    i = P[I_END_IDX][q]
    R = (phi[3, i], phi[4, i], phi[5, i], phi[6, i], phi[7, i], phi[8, i], phi[9, i], phi[10, i], phi[11, i])
    return (R[0] * load[0] + R[3] * load[1] + R[6] * load[2], R[1] * load[0] + R[4] * load[1] + R[7] * load[2],
            R[2] * load[0] + R[5] * load[1] + R[8] * load[2], R[0] * load[3] + R[3] * load[4] + R[6] * load[5],
            R[1] * load[3] + R[4] * load[4] + R[7] * load[5], R[2] * load[3] + R[5] * load[4] + R[8] * load[5])


@_jit
def _soa_powers(P, Nv, phi):
    """(dissipated, external) power at velocity ``Nv`` (``Scheme.powers``)."""
    if not P[I_HAS_POWER]:
        return 0.0, 0.0
    w = P[I_W]
    n = Nv.shape[1]
    dissipated = 0.0
    external = 0.0
    if P[I_HAS_DAMP]:
        damp = P[I_DAMP]
        p = 0.0
        for i in range(n):
            s = 0.0
            for k in range(6):
                s += (-Nv[k, i] * damp[k]) * Nv[k, i]
            p += w[i] * s
        dissipated -= p
    if P[I_HAS_UBODY]:
        ubody = P[I_UBODY]
        p = 0.0
        for i in range(n):
            s = 0.0
            for k in range(6):
                s += ubody[k] * Nv[k, i]
            p += w[i] * s
        external += p
    p = 0.0
    end_idx = P[I_END_IDX]
    for q in range(end_idx.shape[0]):
        i = end_idx[q]
        b = _soa_end_load(P, phi, q)
        for k in range(6):
            p += b[k] * Nv[k, i]
    external += p
    return dissipated, external


@_jit
def _soa_velocity(P, s, Nv):
    mass = P[I_MASS]
    live = P[I_LIVE]
    clamped = P[I_CLAMPED]
    n = s.shape[1]
    for k in range(6):
        if not live[k]:
            for i in range(n):
                Nv[k, i] = 0.0
            continue
        m = mass[k]
        for i in range(n):
            Nv[k, i] = s[k, i] / m
    if P[I_CONSTRAINED]:
        for i in range(n):
            if clamped[i]:
                for k in range(6):
                    Nv[k, i] = 0.0


@_jit
def _soa_constrain(P, s):
    if not P[I_CONSTRAINED]:
        return
    live = P[I_LIVE]
    clamped = P[I_CLAMPED]
    for k in range(6):
        for i in range(s.shape[1]):
            if clamped[i] or not live[k]:
                s[k, i] = 0.0


@_jit
def _soa_kick(s, w, half):
    for k in range(6):
        for i in range(s.shape[1]):
            s[k, i] = s[k, i] + half * w[k, i]


@_jit
def _soa_free_flow(s, D, fac, kinds, axes):
    """The palindromic free flow of every node composed into ``D[:, i] = (t; R)``, piece by
    piece (see :func:`_free_flow`): translations ``(a; I)`` with ``L ← L − a × P``, rotations
    about ``e_k`` of cosine ``1 − Bθ²`` and sine ``Aθ``; ``fac[p, k] = τ_p/m_k``.  Clamped nodes
    have zero momentum, so every piece is exactly the identity there."""
    n = s.shape[1]
    for i in range(n):
        for a in range(12):
            D[a, i] = 0.0
        D[3, i] = 1.0
        D[7, i] = 1.0
        D[11, i] = 1.0
    for p in range(kinds.shape[0]):
        if kinds[p] == KIND_SE3_TRANSLATION:
            f0, f1, f2 = fac[p, 0], fac[p, 1], fac[p, 2]
            for i in range(n):
                P0, P1, P2 = s[0, i], s[1, i], s[2, i]
                a0, a1, a2 = f0 * P0, f1 * P1, f2 * P2
                c0, c1, c2 = cross3(a0, a1, a2, P0, P1, P2)
                s[3, i] -= c0
                s[4, i] -= c1
                s[5, i] -= c2
                D[0, i] += D[3, i] * a0 + D[4, i] * a1 + D[5, i] * a2
                D[1, i] += D[6, i] * a0 + D[7, i] * a1 + D[8, i] * a2
                D[2, i] += D[9, i] * a0 + D[10, i] * a1 + D[11, i] * a2
            continue
        k = axes[p]
        pp = k + 1 if k < 2 else 0  # the plane (e_pp, e_qq) turned about e_k
        qq = k + 2 if k < 1 else k - 1
        f = fac[p, 3 + k]
        big = 0
        for i in range(n):
            th = f * s[3 + k, i]
            big += th * th >= SMALL_THETA2
        if big:  # some angle beyond the series: closed forms for this piece
            for i in range(n):
                th = f * s[3 + k, i]
                q2 = th * th
                a, b = _rot_coeffs(q2)
                _soa_turn_node(s, D, i, pp, qq, 1.0 - b * q2, a * th)
        else:
            for i in range(n):
                th = f * s[3 + k, i]
                q2 = th * th
                _soa_turn_node(s, D, i, pp, qq, 1.0 - horner(q2, TAYLOR_B) * q2, horner(q2, TAYLOR_A) * th)


@_inline
def _soa_turn_node(s, D, i, pp, qq, cs, sn):
    """Rotate node i about e_k by (cos, sin): ``S ← Ad*S`` on the plane (pp, qq), ``R ← R Rot``."""
    s[pp, i], s[qq, i] = _turn(cs, sn, s[pp, i], s[qq, i])
    s[3 + pp, i], s[3 + qq, i] = _turn(cs, sn, s[3 + pp, i], s[3 + qq, i])
    D[3 + pp, i], D[3 + qq, i] = _turn(cs, sn, D[3 + pp, i], D[3 + qq, i])
    D[6 + pp, i], D[6 + qq, i] = _turn(cs, sn, D[6 + pp, i], D[6 + qq, i])
    D[9 + pp, i], D[9 + qq, i] = _turn(cs, sn, D[9 + pp, i], D[9 + qq, i])


@_inline
def _soa_conjugate_translation(g, D, e, i, j):
    """Translation of ``D_i⁻¹ G_e D_j``: ``R_iᵀ(M t_j + b − t_i)`` for ``G_e = (b; M)``."""
    m00, m01, m02 = g[3, e], g[4, e], g[5, e]
    m10, m11, m12 = g[6, e], g[7, e], g[8, e]
    m20, m21, m22 = g[9, e], g[10, e], g[11, e]
    tj0, tj1, tj2 = D[0, j], D[1, j], D[2, j]
    u0 = m00 * tj0 + m01 * tj1 + m02 * tj2 + g[0, e] - D[0, i]
    u1 = m10 * tj0 + m11 * tj1 + m12 * tj2 + g[1, e] - D[1, i]
    u2 = m20 * tj0 + m21 * tj1 + m22 * tj2 + g[2, e] - D[2, i]
    g[0, e] = D[3, i] * u0 + D[6, i] * u1 + D[9, i] * u2
    g[1, e] = D[4, i] * u0 + D[7, i] * u1 + D[10, i] * u2
    g[2, e] = D[5, i] * u0 + D[8, i] * u1 + D[11, i] * u2


@_inline
def _soa_conjugate_rotation(g, D, e, i, j):
    """Rotation of ``D_i⁻¹ G_e D_j``: ``R_iᵀ M R_j``."""
    m00, m01, m02 = g[3, e], g[4, e], g[5, e]
    m10, m11, m12 = g[6, e], g[7, e], g[8, e]
    m20, m21, m22 = g[9, e], g[10, e], g[11, e]
    n00 = m00 * D[3, j] + m01 * D[6, j] + m02 * D[9, j]
    n01 = m00 * D[4, j] + m01 * D[7, j] + m02 * D[10, j]
    n02 = m00 * D[5, j] + m01 * D[8, j] + m02 * D[11, j]
    n10 = m10 * D[3, j] + m11 * D[6, j] + m12 * D[9, j]
    n11 = m10 * D[4, j] + m11 * D[7, j] + m12 * D[10, j]
    n12 = m10 * D[5, j] + m11 * D[8, j] + m12 * D[11, j]
    n20 = m20 * D[3, j] + m21 * D[6, j] + m22 * D[9, j]
    n21 = m20 * D[4, j] + m21 * D[7, j] + m22 * D[10, j]
    n22 = m20 * D[5, j] + m21 * D[8, j] + m22 * D[11, j]
    r00, r01, r02 = D[3, i], D[4, i], D[5, i]
    r10, r11, r12 = D[6, i], D[7, i], D[8, i]
    r20, r21, r22 = D[9, i], D[10, i], D[11, i]
    g[3, e] = r00 * n00 + r10 * n10 + r20 * n20
    g[4, e] = r00 * n01 + r10 * n11 + r20 * n21
    g[5, e] = r00 * n02 + r10 * n12 + r20 * n22
    g[6, e] = r01 * n00 + r11 * n10 + r21 * n20
    g[7, e] = r01 * n01 + r11 * n11 + r21 * n21
    g[8, e] = r01 * n02 + r11 * n12 + r21 * n22
    g[9, e] = r02 * n00 + r12 * n10 + r22 * n20
    g[10, e] = r02 * n01 + r12 * n11 + r22 * n21
    g[11, e] = r02 * n02 + r12 * n12 + r22 * n22


@_jit
def _soa_conjugate(g, phi, D):
    """Drift by ``D``: every edge ``G_e ← D_i⁻¹ G_e D_j`` (translations first: they read the
    old rotation), frames ``Φ_i ← Φ_i D_i``."""
    ne = g.shape[1]
    n = D.shape[1]
    m = min(ne, n - 1)
    for e in range(m):
        _soa_conjugate_translation(g, D, e, e, e + 1)
    if ne == n:
        _soa_conjugate_translation(g, D, n - 1, n - 1, 0)
    for e in range(m):
        _soa_conjugate_rotation(g, D, e, e, e + 1)
    if ne == n:
        _soa_conjugate_rotation(g, D, n - 1, n - 1, 0)
    for i in range(phi.shape[1]):
        for a in range(3):
            f0, f1, f2 = phi[3 + 3 * a, i], phi[4 + 3 * a, i], phi[5 + 3 * a, i]
            phi[a, i] = f0 * D[0, i] + f1 * D[1, i] + f2 * D[2, i] + phi[a, i]
            phi[3 + 3 * a, i] = f0 * D[3, i] + f1 * D[6, i] + f2 * D[9, i]
            phi[4 + 3 * a, i] = f0 * D[4, i] + f1 * D[7, i] + f2 * D[10, i]
            phi[5 + 3 * a, i] = f0 * D[5, i] + f1 * D[8, i] + f2 * D[11, i]


@_jit
def _soa_unstable(check, kinetic_limit, s, w, inv):
    if check != CHECK_MOMENTUM:
        return False
    n = s.shape[1]
    tot = 0.0
    for k in range(6):
        for i in range(n):
            tot += s[k, i]
    if not np.isfinite(tot):
        return True
    if kinetic_limit < np.inf:
        K = 0.0
        for k in range(6):
            for i in range(n):
                K += w[i] * s[k, i] * s[k, i] * inv[k]
        if not 0.5 * K <= kinetic_limit:
            return True
    return False


@_jit
def _se3_to_soa(A, a):
    """``a[:, i]`` ← rows 1–3 of ``A[i]`` = (translation; rotation row-major)."""
    for i in range(A.shape[0]):
        for r in range(3):
            a[r, i] = A[i, r + 1, 0]
            for c in range(3):
                a[3 + 3 * r + c, i] = A[i, r + 1, c + 1]


@_jit
def _se3_from_soa(a, A):
    for i in range(A.shape[0]):
        for r in range(3):
            A[i, r + 1, 0] = a[r, i]
            for c in range(3):
                A[i, r + 1, c + 1] = a[3 + 3 * r + c, i]


@_jit
def lie_verlet_se3_loop(P, S, G, Phi, W, have_force, velocity_free, fac, kinds, axes,
                        t, dt, nsteps, dissipated, external, check, kinetic_limit, inv):
    """:func:`lie_verlet_loop` for SE(3) with closed-form free-flow pieces, on
    structure-of-arrays copies of ``S``, ``G``, ``Phi`` and ``W`` (copied back on return)."""
    n = S.shape[0]
    ne = G.shape[0]
    s = np.empty((6, n))
    w = np.empty((6, n))
    g = np.empty((12, ne))
    phi = np.empty((12, Phi.shape[0]))
    D = np.empty((12, n))
    Nv = np.zeros((6, n))
    XI = np.empty((7, ne))
    QS = np.empty((6, ne))
    OUT = np.empty((6, ne))
    INC = np.empty((6, ne))
    bad = np.zeros(ne, dtype=np.int64)
    for i in range(n):
        for k in range(6):
            s[k, i] = S[i, k]
            w[k, i] = W[i, k]
    _se3_to_soa(G, g)
    _se3_to_soa(Phi, phi)
    wts = P[I_W]
    need_N = P[I_HAS_DAMP] or P[I_HAS_POWER]
    nforce = 0
    half = 0.5 * dt
    if need_N:
        _soa_velocity(P, s, Nv)
    p0d, p0e = _soa_powers(P, Nv, phi)
    done = 0
    for _ in range(nsteps):
        if not (have_force and velocity_free):
            _soa_force(P, g, phi, Nv, w, XI, QS, OUT, INC, bad)
            nforce += 1
        _soa_kick(s, w, half)
        _soa_constrain(P, s)
        _soa_free_flow(s, D, fac, kinds, axes)
        _soa_conjugate(g, phi, D)
        _soa_constrain(P, s)
        if need_N:
            _soa_velocity(P, s, Nv)
        _soa_force(P, g, phi, Nv, w, XI, QS, OUT, INC, bad)
        nforce += 1
        have_force = True
        _soa_kick(s, w, half)
        _soa_constrain(P, s)
        t = t + dt
        if need_N:
            _soa_velocity(P, s, Nv)
        p1d, p1e = _soa_powers(P, Nv, phi)
        dissipated = dissipated + 0.5 * dt * (p0d + p1d)
        external = external + 0.5 * dt * (p0e + p1e)
        p0d, p0e = p1d, p1e
        done += 1
        if _soa_unstable(check, kinetic_limit, s, wts, inv):
            break
    for i in range(n):
        for k in range(6):
            S[i, k] = s[k, i]
            W[i, k] = w[k, i]
    _se3_from_soa(g, G)
    _se3_from_soa(phi, Phi)
    return done, nforce, t, dissipated, external


# ---------------------------------------------------------------------------- lie-euler
@_jit
def lie_euler_loop(P, S, G, Phi, t, dt, nsteps, dissipated, external, check, kinetic_limit, inv):
    """``nsteps`` steps of ``LieEuler``: ``S⁺ = Ad*_{exp ΔtN}S + 𝓔(Δt,N)ᵀW``, ``Φ⁺ = Φ exp(ΔtN)``.
    Returns ``(steps done, t, dissipated, external)``."""
    gid = P[I_GID]
    n, r = S.shape
    m = G.shape[1]
    N = np.empty((n, r))
    F = np.empty((n, r))
    W = np.empty((n, r))
    D = np.empty((n, m, m))
    scr = _scratch(r, m, G.shape[0])
    xi, Q, tr, M, M2, A1, A2, A3, XI = scr
    w = P[I_W]
    _velocity(P, S, N)
    p0d, p0e = _powers(P, N, Phi, scr)
    done = 0
    for _ in range(nsteps):
        _force(P, G, Phi, N, W, F, scr, True)
        if gid == GID_SE3:
            _se3_exp_nodes(N, dt, D)
        for i in range(n):
            if gid != GID_SE3:
                for k in range(r):
                    xi[k] = dt * N[i, k]
                g_exp(gid, xi, D[i])
            g_Ad(gid, D[i], M)
            g_E(gid, dt, N[i], M2)
            for a in range(r):
                u = 0.0
                v = 0.0
                for b in range(r):
                    u += M[b, a] * S[i, b]
                    v += M2[b, a] * W[i, b]
                tr[a] = u + v
            for a in range(r):
                S[i, a] = tr[a]
        _conjugate(P, G, Phi, D, A1, A2)
        _constrain(P, S)
        t = t + dt
        _velocity(P, S, N)
        p1d, p1e = _powers(P, N, Phi, scr)
        dissipated = dissipated + 0.5 * dt * (p0d + p1d)
        external = external + 0.5 * dt * (p0e + p1e)
        p0d, p0e = p1d, p1e
        done += 1
        if _unstable(check, kinetic_limit, S, G, Phi, w, inv):
            break
    return done, t, dissipated, external


# ---------------------------------------------------------------------------- forward-euler
@_jit
def forward_euler_loop(P, S, G, Phi, t, dt, nsteps, dissipated, external, check, kinetic_limit, inv):
    """``nsteps`` steps of ``ForwardEuler``: ``Φ += ΔtΦN̂`` (edges ``G += Δt(−N̂_iG + GN̂_j)``),
    ``S += Δt(ad_NᵀS + W)``.  Returns ``(steps done, t, dissipated, external)``."""
    gid = P[I_GID]
    track = P[I_TRACK]
    n, r = S.shape
    m = G.shape[1]
    N = np.empty((n, r))
    F = np.empty((n, r))
    W = np.empty((n, r))
    Sd = np.empty((n, r))
    D = np.empty((n, m, m))
    scr = _scratch(r, m, G.shape[0])
    xi, Q, tr, M, M2, A1, A2, A3, XI = scr
    w = P[I_W]
    _velocity(P, S, N)
    p0d, p0e = _powers(P, N, Phi, scr)
    done = 0
    for _ in range(nsteps):
        _force(P, G, Phi, N, W, F, scr, False)
        for i in range(n):
            g_ad(gid, N[i], M)
            for a in range(r):
                acc = 0.0
                for b in range(r):
                    acc += M[b, a] * S[i, b]
                Sd[i, a] = acc + W[i, a]
            for k in range(r):
                xi[k] = dt * N[i, k]
            g_hat(gid, xi, D[i])
        for e in range(G.shape[0]):
            i, j = _edge_nodes(e, n)
            for a in range(m):
                for b in range(m):
                    left = 0.0
                    right = 0.0
                    for c in range(m):
                        left += D[i, a, c] * G[e, c, b]
                        right += G[e, a, c] * D[j, c, b]
                    A1[a, b] = G[e, a, b] - left + right
            _copy_matrix(A1, G[e])
        nf = n if track else 1
        for i in range(nf):
            for a in range(m):
                for b in range(m):
                    acc = 0.0
                    for c in range(m):
                        acc += Phi[i, a, c] * D[i, c, b]
                    A1[a, b] = Phi[i, a, b] + acc
            _copy_matrix(A1, Phi[i])
        for i in range(n):
            for k in range(r):
                S[i, k] = S[i, k] + dt * Sd[i, k]
        _constrain(P, S)
        t = t + dt
        _velocity(P, S, N)
        p1d, p1e = _powers(P, N, Phi, scr)
        dissipated = dissipated + 0.5 * dt * (p0d + p1d)
        external = external + 0.5 * dt * (p0e + p1e)
        p0d, p0e = p1d, p1e
        done += 1
        if _unstable(check, kinetic_limit, S, G, Phi, w, inv):
            break
    return done, t, dissipated, external


# ---------------------------------------------------------------------------- overdamped, RKMK
@_jit
def _drift_velocity(P, G, Phi, Z, W, F, N, gam, scr):
    """Overdamped velocity ``N = Γ⁻¹ W(N = 0)`` (live components; zero at clamped nodes)."""
    live = P[I_LIVE]
    clamped = P[I_CLAMPED]
    _force(P, G, Phi, Z, W, F, scr, True)
    n, r = N.shape
    for i in range(n):
        for k in range(r):
            N[i, k] = W[i, k] / gam[k] if live[k] else 0.0
        if clamped[i]:
            for k in range(r):
                N[i, k] = 0.0


@_jit
def overdamped_velocity(P, G, Phi, N, gam):
    """``N = Γ⁻¹W(N = 0)`` at the current state (the overdamped integrator's velocity)."""
    n, r = N.shape
    Z = np.zeros((n, r))
    F = np.empty((n, r))
    W = np.empty((n, r))
    _drift_velocity(P, G, Phi, Z, W, F, N, gam, _scratch(r, G.shape[1], G.shape[0]))


@_jit
def overdamped_loop(P, S, G, Phi, N, gam, t, dt, nsteps, dissipated, external, check, kinetic_limit, inv):
    """``nsteps`` steps of ``Overdamped(order=1)``: ``Φ ← Φ exp(ΔtN)``, ``N = Γ⁻¹W(N = 0)``.

    ``N`` holds the velocity of the current state on entry and of the final state on return.
    Returns ``(steps done, t, dissipated, external)``.
    """
    n, r = S.shape
    m = G.shape[1]
    Z = np.zeros((n, r))
    F = np.empty((n, r))
    W = np.empty((n, r))
    D = np.empty((n, m, m))
    scr = _scratch(r, m, G.shape[0])
    w = P[I_W]
    p0d, p0e = _powers(P, N, Phi, scr)
    done = 0
    for _ in range(nsteps):
        _exp_drift(P, G, Phi, N, dt, D, scr)
        for i in range(n):
            for k in range(r):
                S[i, k] = 0.0
        t = t + dt
        _drift_velocity(P, G, Phi, Z, W, F, N, gam, scr)
        p1d, p1e = _powers(P, N, Phi, scr)
        dissipated = dissipated + 0.5 * dt * (p0d + p1d)
        external = external + 0.5 * dt * (p0e + p1e)
        p0d, p0e = p1d, p1e
        done += 1
        if _unstable(check, kinetic_limit, S, G, Phi, w, inv):
            break
    return done, t, dissipated, external


@_jit
def rkmk_loop(P, S, G, Phi, N, gam, dynamics, A, b, t, dt, nsteps, dissipated, external, check,
              kinetic_limit, inv):
    """``nsteps`` explicit Runge–Kutta–Munthe-Kaas steps with tableau ``(A, b)``.

    ``dynamics``: ``rkmk4`` (S by the same tableau on ``Ṡ = ad_NᵀS + W``, N = velocity(S));
    otherwise the overdamped flow of order 2 (N = Γ⁻¹W(N = 0), S = 0), with ``N`` the drift
    velocity of the current state on entry and of the final state on return.
    Returns ``(steps done, t, dissipated, external)``.
    """
    gid = P[I_GID]
    n, r = S.shape
    m = G.shape[1]
    s = b.shape[0]
    ksig = np.empty((s, n, r))
    kS = np.empty((s, n, r))
    sigma = np.empty((n, r))
    Sst = np.empty((n, r))
    Nst = np.empty((n, r))
    Z = np.zeros((n, r))
    F = np.empty((n, r))
    W = np.empty((n, r))
    D = np.empty((n, m, m))
    Gst = np.empty_like(G)
    Phist = np.empty_like(Phi)
    scr = _scratch(r, m, G.shape[0])
    xi, Q, tr, M, M2, A1, A2, A3, XI = scr
    w = P[I_W]
    if dynamics:
        _velocity(P, S, N)
    p0d, p0e = _powers(P, N, Phi, scr)
    done = 0
    for _ in range(nsteps):
        for st in range(s):
            moved = False
            for i in range(n):
                for k in range(r):
                    acc = 0.0
                    for j in range(st):
                        if A[st, j] != 0.0:
                            acc = acc + dt * A[st, j] * ksig[j, i, k]
                    sigma[i, k] = acc
                    if acc != 0.0:
                        moved = True
            if dynamics:
                for i in range(n):
                    for k in range(r):
                        acc = 0.0
                        for j in range(st):
                            if A[st, j] != 0.0:
                                acc = acc + dt * A[st, j] * kS[j, i, k]
                        Sst[i, k] = S[i, k] + acc
            Gst[:] = G
            Phist[:] = Phi
            if moved:
                _exp_drift(P, Gst, Phist, sigma, 1.0, D, scr)
            if dynamics:
                _velocity(P, Sst, Nst)
            elif st == 0:
                Nst[:] = N
            else:
                _drift_velocity(P, Gst, Phist, Z, W, F, Nst, gam, scr)
            for i in range(n):
                for k in range(r):
                    tr[k] = -sigma[i, k]
                g_dexp_inv(gid, tr, M)
                for a in range(r):
                    acc = 0.0
                    for c in range(r):
                        acc += M[a, c] * Nst[i, c]
                    ksig[st, i, a] = acc
            if dynamics:
                _force(P, Gst, Phist, Nst, W, F, scr, True)
                for i in range(n):
                    g_ad(gid, Nst[i], M)
                    for a in range(r):
                        acc = 0.0
                        for c in range(r):
                            acc += M[c, a] * Sst[i, c]
                        kS[st, i, a] = acc + W[i, a]
        for i in range(n):
            for k in range(r):
                acc = 0.0
                for j in range(s):
                    acc = acc + dt * b[j] * ksig[j, i, k]
                sigma[i, k] = acc
        _exp_drift(P, G, Phi, sigma, 1.0, D, scr)
        if dynamics:
            for i in range(n):
                for k in range(r):
                    acc = 0.0
                    for j in range(s):
                        acc = acc + dt * b[j] * kS[j, i, k]
                    S[i, k] = S[i, k] + acc
            _constrain(P, S)
        else:
            for i in range(n):
                for k in range(r):
                    S[i, k] = 0.0
        t = t + dt
        if dynamics:
            _velocity(P, S, N)
        else:
            _drift_velocity(P, G, Phi, Z, W, F, N, gam, scr)
        p1d, p1e = _powers(P, N, Phi, scr)
        dissipated = dissipated + 0.5 * dt * (p0d + p1d)
        external = external + 0.5 * dt * (p0e + p1e)
        p0d, p0e = p1d, p1e
        done += 1
        if _unstable(check, kinetic_limit, S, G, Phi, w, inv):
            break
    return done, t, dissipated, external


@_jit
def force_once(P, G, Phi, N, W, on_group):
    """One force evaluation ``W`` at ``(G, Phi, N)`` (compared with ``Lattice.force`` by the tests)."""
    n, r = W.shape
    F = np.empty((n, r))
    _force(P, G, Phi, N, W, F, _scratch(r, G.shape[1], G.shape[0]), on_group)


# ---------------------------------------------------------------------------- Python glue
def _writable(a: np.ndarray) -> np.ndarray:
    """``a`` itself when it is a writable C-contiguous float64 array, else such a copy."""
    if isinstance(a, np.ndarray) and a.dtype == np.float64 and a.flags.c_contiguous and a.flags.writeable:
        return a
    return np.array(a, dtype=np.float64, order="C")


def _group_id(group) -> int | None:
    from ..groups.se2 import SE2
    from ..groups.se3 import SE3
    from ..groups.so2 import SO2
    from ..groups.so3 import SO3

    return {SO2: GID_SO2, SE2: GID_SE2, SO3: GID_SO3, SE3: GID_SE3}.get(type(group))


def _same_methods(obj, base, names) -> bool:
    return all(getattr(type(obj), name, None) is getattr(base, name) for name in names)


def build_plan(scheme) -> tuple | None:
    """The problem of a lattice scheme as compiled-loop data ``P`` (layout ``I_*``), or None
    when it does not qualify: d = 1; SO(2), SE(2), SO(3), SE(3); a medium with
    :meth:`~cartan.medium.Medium.quadratic_energy` and the base kinetic energy and body force;
    ``Damping``, body-frame ``UniformForce`` and ``ConstantFieldPotential`` loads; free
    (loaded or not) and clamped ends; frames stepped when a load needs them.

    Raises
    ------
    ValueError
        When the medium's ``quadratic_energy`` is malformed or disagrees with its ``stress``.
    """
    from ..medium import Medium
    from ..problem import Clamped, ConstantFieldPotential, Damping, Free, PotentialLoad, UniformForce
    from .base import Scheme
    from .lattice import Lattice

    problem, medium, group, grid = scheme.problem, scheme.medium, scheme.group, scheme.grid
    gid = _group_id(group)
    if grid.d != 1 or gid is None:
        return None
    if not _same_methods(scheme, Lattice, ("force", "internal_force", "drift", "frames", "_boundary_power",
                                           "_axis_stress", "initial_state")):
        return None
    if not _same_methods(scheme, Scheme, ("velocity", "constrain", "powers", "has_external_power", "drag")):
        return None
    if not _same_methods(medium, Medium, ("velocity", "body_force")):
        return None
    if getattr(medium, "velocity_dependent_forces", False):
        return None
    quad = medium.quadratic_energy()
    if quad is None:
        return None
    r = group.dim
    X0 = np.array(quad[0], dtype=float).reshape(-1)
    C = np.array(quad[1], dtype=float)
    if X0.shape != (r,) or C.shape != (r, r) or not (np.all(np.isfinite(X0)) and np.all(np.isfinite(C))):
        raise ValueError(
            f"medium {medium.name!r}: quadratic_energy() must return finite X0 of shape ({r},) and C of "
            f"shape ({r}, {r}); got shapes {X0.shape} and {C.shape}"
        )
    delta = 1e-2 * np.sin(np.arange(1.0, r + 1.0))
    Q = np.asarray(medium.stress((X0 + delta)[None, None, :]), dtype=float).reshape(-1)
    if not np.allclose(Q, C @ delta, rtol=1e-9, atol=1e-12 * max(1.0, float(np.abs(C).max()))):
        raise ValueError(f"medium {medium.name!r}: quadratic_energy() disagrees with stress(): Q ≠ C (X − X0)")
    k = group.space_dim if getattr(group, "affine", False) else 1
    damp, ubody, field = np.zeros(r), np.zeros(r), np.zeros(k)
    has_damp = has_ubody = has_field = False
    for load in problem.loads:
        if type(load) is Damping:
            damp = damp + np.asarray(load.coefficients, dtype=float)
            has_damp = True
        elif type(load) is UniformForce and load.frame == "body":
            ubody = ubody + np.asarray(load.components, dtype=float)
            has_ubody = True
        elif (
            isinstance(load, ConstantFieldPotential)
            and type(load).force is PotentialLoad.force
            and _same_methods(load, ConstantFieldPotential, ("potential_gradient", "position", "_matrix"))
        ):
            field = field + load.density * np.asarray(load.field, dtype=float)
            has_field = True
        else:
            return None
    if any(type(b) not in (Free, Clamped) for b in problem.boundaries.values()):
        return None
    n = grid.shape[0]
    ends = [(0 if sl[0] == 0 else n - 1, b) for sl, b in scheme._end_loads]
    if (has_field or any(not b.follower for _, b in ends)) and not scheme.track:
        return None
    weights = np.ascontiguousarray(scheme.weights, dtype=float)
    live = np.ascontiguousarray(scheme.live, dtype=np.bool_)
    clamped = np.ascontiguousarray(scheme._clamped, dtype=np.bool_)
    return (
        int(gid),
        bool(scheme.track),
        bool(getattr(group, "affine", False)),
        float(scheme.h[0]),
        X0,
        np.ascontiguousarray(C),
        bool(np.count_nonzero(C - np.diag(np.diag(C))) == 0),
        weights,
        np.ascontiguousarray(scheme.mass, dtype=float),
        live,
        clamped,
        bool(clamped.any() or not live.all()),
        damp,
        has_damp,
        ubody,
        has_ubody,
        field,
        has_field,
        np.array([i for i, _ in ends], dtype=np.int64),
        np.array([np.asarray(b.load, dtype=float) for _, b in ends], dtype=float).reshape(len(ends), r),
        np.array([bool(b.follower) for _, b in ends], dtype=np.bool_),
        bool(scheme.has_external_power()),
    )


def _lie_verlet_sequence(integrator, scheme, gid: int, dt: float, cache: dict):
    """``LieVerlet._sequence`` as arrays, cached per Δt in ``cache`` (the sequence depends on
    the scheme's group and live components only): component masks, fractions of Δt, ``τ/m``
    per component, and (kind, SE(3) rotation axis) per piece."""
    key = ("lie-verlet", dt)
    if key in cache:
        return cache[key]
    seq = integrator._sequence(scheme)
    r = scheme.group.dim
    mask = np.zeros((len(seq), r), dtype=np.bool_)
    frac = np.empty(len(seq))
    kind = np.zeros((len(seq), 2), dtype=np.int64)
    for p, (piece, f) in enumerate(seq):
        idx = sorted(int(i) for i in piece)
        mask[p, idx] = True
        frac[p] = f
        if gid == GID_SE3 and idx == [0, 1, 2]:
            kind[p] = (KIND_SE3_TRANSLATION, 0)
        elif gid == GID_SE3 and len(idx) == 1 and idx[0] >= 3:
            kind[p] = (KIND_SE3_ROTATION, idx[0] - 3)
    fac = np.where(mask, (frac * dt)[:, None] / np.where(scheme.live, scheme.mass, 1.0), 0.0)
    if len(cache) > 16:
        cache.clear()
    cache[key] = (mask, frac, np.ascontiguousarray(fac), kind)
    return cache[key]


def advance(scheme, plan: tuple, integrator, state, dt: float, nsteps: int, kinetic_limit: float) -> bool:
    """Run up to ``nsteps`` steps of ``integrator`` on ``state`` in compiled code (see
    :meth:`cartan.schemes.lattice.Lattice.compiled_advance`); False, touching nothing, when
    the integrator is not supported."""
    from ..integrators.explicit import _TABLEAUX, RKMK4, ForwardEuler, LieEuler, LieVerlet, Overdamped

    kind = type(integrator)
    if kind not in (LieVerlet, LieEuler, ForwardEuler, Overdamped, RKMK4):
        return False
    gam = None
    if kind is Overdamped:
        gam = np.asarray(scheme.drag(), dtype=float)
        if np.any(scheme.live & ~(gam > 0)) or integrator.order not in (1, 2):
            return False  # the reference path raises the error
    key = scheme._key(0)
    frame_key = "Phi" if scheme.track else "Phi_root"
    if set(state.arrays) != {key, frame_key}:
        return False
    nsteps = int(nsteps)
    if nsteps <= 0:
        return True
    t_start = time.perf_counter()
    dt = float(dt)
    S = state.S = _writable(state.S)
    G = state.arrays[key] = _writable(state.arrays[key])
    Phi = state.arrays[frame_key] = _writable(state.arrays[frame_key])
    Phi3 = Phi if scheme.track else Phi.reshape(1, *Phi.shape)
    nstep0 = state.scalars.get("nstep", 0)
    stamp = (id(state), state.t, nstep0)
    t0 = float(state.t)
    diss = float(state.scalars.get("dissipated_energy", 0.0))
    ext = float(state.scalars.get("external_work", 0.0))
    check = CHECK_MOMENTUM if integrator.uses_momentum else CHECK_CONFIGURATION
    limit = float(kinetic_limit)
    cache = scheme.__dict__.setdefault("_compiled_cache", {})
    inv = cache.get("inv")
    if inv is None:
        inv = cache["inv"] = np.where(scheme.live, 1.0 / np.where(scheme.live, scheme.mass, 1.0), 0.0)
    W = None
    if kind is LieVerlet:
        velocity_free = not any(ld.velocity_dependent for ld in scheme.problem.loads) and not getattr(
            scheme.medium, "velocity_dependent_forces", False)
        fsal = integrator._fsal
        have = bool(velocity_free and fsal is not None and fsal[0] == stamp)
        W = np.array(fsal[1], dtype=float, order="C") if have else np.zeros_like(S)
        mask, frac, fac, kinds = _lie_verlet_sequence(integrator, scheme, plan[I_GID], dt, cache)
        if plan[I_GID] == GID_SE3 and np.all(kinds[:, 0] != KIND_GENERIC):
            done, nforce, t, diss, ext = lie_verlet_se3_loop(
                plan, S, G, Phi3, W, have, bool(velocity_free), fac, np.ascontiguousarray(kinds[:, 0]),
                np.ascontiguousarray(kinds[:, 1]), t0, dt, nsteps, diss, ext, check, limit, inv)
        else:
            done, nforce, t, diss, ext = lie_verlet_loop(
                plan, S, G, Phi3, W, have, bool(velocity_free), mask, frac, t0, dt, nsteps, diss, ext, check,
                limit, inv)
    elif kind is LieEuler or kind is ForwardEuler:
        loop = lie_euler_loop if kind is LieEuler else forward_euler_loop
        done, t, diss, ext = loop(plan, S, G, Phi3, t0, dt, nsteps, diss, ext, check, limit, inv)
        nforce = done
    else:
        dynamics = kind is RKMK4
        order = 4 if dynamics else integrator.order
        hit = False
        if dynamics:
            N = np.zeros_like(S)
        else:
            cache = integrator._cache
            hit = cache is not None and cache[0] == stamp
            N = np.array(cache[1], dtype=float, order="C") if hit else np.empty_like(S)
            if not hit:
                overdamped_velocity(plan, G, Phi3, N, gam)
        if order == 1:
            done, t, diss, ext = overdamped_loop(plan, S, G, Phi3, N, gam, t0, dt, nsteps, diss, ext, check, limit, inv)
        else:
            A, b, _ = _TABLEAUX[order]
            done, t, diss, ext = rkmk_loop(
                plan, S, G, Phi3, N, np.ones(S.shape[1]) if gam is None else gam, dynamics,
                np.ascontiguousarray(A, dtype=float), np.ascontiguousarray(b, dtype=float),
                t0, dt, nsteps, diss, ext, check, limit, inv)
        # force evaluations as the reference path counts them: rkmk4 evaluates 4 per step;
        # overdamped evaluates its velocity before and after every step (plus the 2 stages of
        # order 2), the very first one taken from the integrator's cache when it matches
        nforce = (4 if (dynamics or order == 2) else 2) * done - (1 if hit else 0)
        if not dynamics:
            integrator._cache = ((id(state), t, nstep0 + done - 1), N.copy())
    state.t = t
    state.scalars["dissipated_energy"] = diss
    state.scalars["external_work"] = ext
    state.scalars["nstep"] = nstep0 + done
    if W is not None:
        integrator._fsal = ((id(state), t, nstep0 + done), W)
    integrator.nstep += done
    integrator.nforce += nforce
    integrator.wall_time += time.perf_counter() - t_start
    return True
