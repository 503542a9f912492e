"""Compiled stage residual of ``implicit-midpoint`` (``cartan.integrators.implicit``).

One evaluation of the stage residual (paper §V; the discrete Lagrangian of the module
docstring of :mod:`cartan.integrators.implicit`)::

    R(ξ) = dexp⁻¹_ξᵀ μ − Δt B(ξ)ᵀ W_{k+½} − S_k,   μ = m ξ/Δt,   B(ξ) = (I + Ad_{exp(ξ/2)})⁻¹,
    W_{k+½} = W(Φ_k exp(ξ/2), ξ/Δt)

is one numba call: the drift of a copy of the step's configuration to the midpoint
``Φ_k exp(ξ/2)``, the scheme's force there, and the ``r × r`` algebra of every node.  The
drift and the force are the kernels of the compiled step loops of the scheme
(:mod:`cartan.schemes._lattice_compiled` for the lattice, d = 1, 2, 3;
:mod:`cartan.schemes._collocation_compiled` for collocation, d = 1) with the plan those loops
use (:meth:`~cartan.schemes.base.Scheme.compiled_plan`), so the problems that qualify are the ones the compiled
loops run (``docs/performance.md``): SO(2), SE(2), SO(3), SE(3); a quadratic potential;
damping, body-frame uniform forces, constant fields, end loads and clamps.  The loads of such
plans do not depend on time, so the midpoint time ``t_k + Δt/2`` is not needed.

The formulas are those of ``ImplicitMidpoint._residual`` (the numpy reference, which uses
``Scheme.drift``, ``Scheme.force`` and the batched group operations); the two differ by
round-off: the compiled drift and force differ from the numpy ones as the compiled loops do,
``B(ξ)ᵀW`` is solved in closed form on SO(3) and SE(3) (:func:`_nodes`) and by Gaussian
elimination with partial pivoting on SO(2) and SE(2) instead of LAPACK, and the sums run in
another order.  :class:`StageResidual` holds the work arrays (allocated once per scheme and
grid) and the step's configuration, so that no state is copied per evaluation.

Newton's iteration around the residual uses two more compiled pieces: :class:`LUSolve`, the
substitutions of a SuperLU factorisation, and :func:`weighted_norm`, the kinetic-energy norms.

:func:`newton_steps` runs whole blocks of steps — ``ImplicitMidpoint._step`` and the
bookkeeping of ``ImplicitMidpoint.step`` — with these pieces, in the Python driver's order, so
that both give the same results bit for bit; it returns to Python when it needs a fresh
Jacobian (:data:`NEED_JACOBIAN`: the caller factorises it at the loop's current iterate and
calls again to continue the same step) and when a step fails (a ``FAIL_*`` status).
:class:`NewtonBlocks` keeps its work arrays and makes the call.  The residual of the scheme
at hand is chosen when the loop is compiled (:func:`_evaluate`, an ``overload`` on which of
the lattice or collocation contexts is given), since numba does not cache functions that
receive jitted functions as arguments.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit
from numba.extending import overload

from .._backend import get_backend
from ..groups.so3 import cross3
from ..schemes._collocation_compiled import drift_once as _collocation_drift
from ..schemes._collocation_compiled import force_once as _collocation_force
from ..schemes._lattice_compiled import (
    CHUNK,
    I_D,
    I_ECH,
    I_GID,
    I_MASS,
    _chunk_scratch,
    _cinv,
    _constrain,
    _exp_drift_nd,
    _force_once,
    _jinv_T,
    _q_coeffs,
    _rot_coeffs,
    _se3_dexp_inv_T,
    _unstable,
    load_powers,
)
from ..schemes._lattice_compiled_kernels import GID_SE2, GID_SE3, GID_SO2, GID_SO3, g_Ad, g_dexp_inv, g_exp
from ..schemes._lattice_compiled_plan import (
    CHECK_MOMENTUM,
    I_END_FACE,
    I_END_IDX,
    I_HAS_POWER,
    I_W,
)

__all__ = ["LUSolve", "NewtonBlocks", "StageResidual", "newton_steps", "stage_residual", "weighted_norm"]

_jit = njit(cache=True, error_model="numpy")
_inline = njit(inline="always", error_model="numpy")


# ---------------------------------------------------------------------------- per-node algebra
@_jit
def _in_domain(gid: int, xi: np.ndarray, radius: float) -> bool:
    """Whether every node's ξ ``[n, r]`` is inside the injectivity radius of exp (the groups'
    ``log_domain_norm``: the rotation angle, ``|ω|`` of SE(3) and SO(3), ``|θ|`` of SE(2), SO(2))."""
    n = xi.shape[0]
    for i in range(n):
        if gid == GID_SE3:
            a = np.sqrt(xi[i, 3] * xi[i, 3] + xi[i, 4] * xi[i, 4] + xi[i, 5] * xi[i, 5])
        elif gid == GID_SE2:
            a = abs(xi[i, 2])
        elif gid == GID_SO2:
            a = abs(xi[i, 0])
        else:
            a = np.sqrt(xi[i, 0] * xi[i, 0] + xi[i, 1] * xi[i, 1] + xi[i, 2] * xi[i, 2])
        if not a < radius:  # also NaN
            return False
    return True


@_jit
def _solve_transposed(A: np.ndarray, w: np.ndarray, out: np.ndarray, M: np.ndarray) -> None:
    """``out = (I + A)⁻ᵀ w`` for one ``r × r`` matrix ``A`` by Gaussian elimination with partial
    pivoting (``M`` ``[r, r + 1]`` work: the augmented matrix)."""
    r = w.shape[0]
    for a in range(r):
        for b in range(r):
            M[a, b] = A[b, a]
        M[a, a] += 1.0
        M[a, r] = w[a]
    for k in range(r):
        p = k
        big = abs(M[k, k])
        for a in range(k + 1, r):
            v = abs(M[a, k])
            if v > big:
                big = v
                p = a
        if p != k:
            for b in range(k, r + 1):
                tmp = M[k, b]
                M[k, b] = M[p, b]
                M[p, b] = tmp
        piv = M[k, k]
        for a in range(k + 1, r):
            f = M[a, k] / piv
            if f != 0.0:
                for b in range(k + 1, r + 1):
                    M[a, b] -= f * M[k, b]
    for a in range(r - 1, -1, -1):
        acc = M[a, r]
        for b in range(a + 1, r):
            acc -= M[a, b] * out[b]
        out[a] = acc / M[a, a]


@_inline
def _half_cayley(p0: float, p1: float, p2: float, w0: float, w1: float, w2: float) -> tuple:
    """``(I + Rᵀ)⁻¹ w = ½(w + κ p × w)`` for ``R = exp(p̂)``, ``κ = tan(θ/2)/θ = B/A`` (θ = |p|,
    ``A = sin θ/θ``, ``B = (1 − cos θ)/θ²``): ``Rᵀ = exp(−p̂)`` is the Cayley transform of
    ``−κp̂``, so ``I + Rᵀ = 2(I + κp̂)⁻¹``.  Here θ = |ω|/2 < π/2 (ξ inside the injectivity
    radius), so A > 0."""
    a, b = _rot_coeffs(p0 * p0 + p1 * p1 + p2 * p2)
    k = b / a
    c = cross3(p0, p1, p2, w0, w1, w2)
    return 0.5 * (w0 + k * c[0]), 0.5 * (w1 + k * c[1]), 0.5 * (w2 + k * c[2])


@_jit
def _nodes(gid: int, mass: np.ndarray, xi: np.ndarray, N: np.ndarray, D: np.ndarray, W: np.ndarray,
           S: np.ndarray, dt: float, mu: np.ndarray, BW: np.ndarray, Dmu: np.ndarray, R: np.ndarray,
           A: np.ndarray, M: np.ndarray) -> None:
    """Per node: ``μ = m N``, ``BW = (I + Ad_D)⁻ᵀ W`` (``D = exp(ξ/2)``), ``Dmu = dexp⁻¹_ξᵀ μ``
    and ``R = Dmu − Δt BW − S``; all ``[n, r]`` but ``D`` ``[n, m, m]``; ``A`` ``[r, r]`` and
    ``M`` ``[r, r + 1]`` work.

    SE(3) and SO(3) in scalar code: with ``D = (t; Q)`` and ``Ad_D = [[Q, t̂Q], [0, Q]]``,
    ``(I + Ad_D)ᵀ`` is block lower triangular, ``BW = (y₁; (I + Qᵀ)⁻¹(W₂ + Qᵀ(t × y₁)))`` with
    ``y₁ = (I + Qᵀ)⁻¹W₁`` (:func:`_half_cayley`, ``Q = exp(ω̂/2)``), and ``dexp⁻¹_ξᵀ`` is
    ``_se3_dexp_inv_T`` / ``_jinv_T`` of the compiled loops.  SE(2), SO(2): the matrix kernels
    and :func:`_solve_transposed`.
    """
    n, r = xi.shape
    for i in range(n):
        for k in range(r):
            mu[i, k] = N[i, k] * mass[k]
    if gid == GID_SE3:
        for i in range(n):
            r0, r1, r2, p0, p1, p2 = xi[i, 0], xi[i, 1], xi[i, 2], xi[i, 3], xi[i, 4], xi[i, 5]
            h0, h1, h2 = 0.5 * p0, 0.5 * p1, 0.5 * p2
            y0, y1, y2 = _half_cayley(h0, h1, h2, W[i, 0], W[i, 1], W[i, 2])
            c = cross3(D[i, 1, 0], D[i, 2, 0], D[i, 3, 0], y0, y1, y2)
            u0 = W[i, 3] + D[i, 1, 1] * c[0] + D[i, 2, 1] * c[1] + D[i, 3, 1] * c[2]
            u1 = W[i, 4] + D[i, 1, 2] * c[0] + D[i, 2, 2] * c[1] + D[i, 3, 2] * c[2]
            u2 = W[i, 5] + D[i, 1, 3] * c[0] + D[i, 2, 3] * c[1] + D[i, 3, 3] * c[2]
            y3, y4, y5 = _half_cayley(h0, h1, h2, u0, u1, u2)
            BW[i, 0], BW[i, 1], BW[i, 2], BW[i, 3], BW[i, 4], BW[i, 5] = y0, y1, y2, y3, y4, y5
            t2 = p0 * p0 + p1 * p1 + p2 * p2
            cq, dq, eq = _q_coeffs(t2)
            o = _se3_dexp_inv_T(r0, r1, r2, p0, p1, p2, _cinv(t2), cq, dq, eq,
                                mu[i, 0], mu[i, 1], mu[i, 2], mu[i, 3], mu[i, 4], mu[i, 5])
            for k in range(6):
                Dmu[i, k] = o[k]
                R[i, k] = o[k] - dt * BW[i, k] - S[i, k]
        return
    if gid == GID_SO3:
        for i in range(n):
            p0, p1, p2 = xi[i, 0], xi[i, 1], xi[i, 2]
            y = _half_cayley(0.5 * p0, 0.5 * p1, 0.5 * p2, W[i, 0], W[i, 1], W[i, 2])
            o = _jinv_T(p0, p1, p2, _cinv(p0 * p0 + p1 * p1 + p2 * p2), mu[i, 0], mu[i, 1], mu[i, 2])
            for k in range(3):
                BW[i, k] = y[k]
                Dmu[i, k] = o[k]
                R[i, k] = o[k] - dt * y[k] - S[i, k]
        return
    for i in range(n):
        g_Ad(gid, D[i], A)
        _solve_transposed(A, W[i], BW[i], M)
        g_dexp_inv(gid, xi[i], A)
        for k in range(r):
            acc = 0.0
            for j in range(r):
                acc += A[j, k] * mu[i, j]
            Dmu[i, k] = acc
            R[i, k] = acc - dt * BW[i, k] - S[i, k]


@_jit
def momentum_update(gid: int, xi: np.ndarray, mu: np.ndarray, W: np.ndarray, BW: np.ndarray, dt: float,
                    out: np.ndarray) -> None:
    """The end-of-step momentum ``S_{k+1} = dexp⁻¹_{−ξ}ᵀ μ + Δt (W − BW)`` per node into ``out``
    (all ``[n, r]``)."""
    n, r = xi.shape
    A = np.empty((r, r))
    v = np.empty(r)
    for i in range(n):
        if gid == GID_SE3:
            p0, p1, p2 = xi[i, 3], xi[i, 4], xi[i, 5]
            t2 = p0 * p0 + p1 * p1 + p2 * p2
            cq, dq, eq = _q_coeffs(t2)
            o = _se3_dexp_inv_T(-xi[i, 0], -xi[i, 1], -xi[i, 2], -p0, -p1, -p2, _cinv(t2), cq, dq, eq,
                                mu[i, 0], mu[i, 1], mu[i, 2], mu[i, 3], mu[i, 4], mu[i, 5])
            for k in range(6):
                out[i, k] = o[k] + dt * (W[i, k] - BW[i, k])
            continue
        if gid == GID_SO3:
            p0, p1, p2 = xi[i, 0], xi[i, 1], xi[i, 2]
            o3 = _jinv_T(-p0, -p1, -p2, _cinv(p0 * p0 + p1 * p1 + p2 * p2), mu[i, 0], mu[i, 1], mu[i, 2])
            for k in range(3):
                out[i, k] = o3[k] + dt * (W[i, k] - BW[i, k])
            continue
        for k in range(r):
            v[k] = -xi[i, k]
        g_dexp_inv(gid, v, A)
        for k in range(r):
            acc = 0.0
            for j in range(r):
                acc += A[j, k] * mu[i, j]
            out[i, k] = acc + dt * (W[i, k] - BW[i, k])


# ---------------------------------------------------------------------------- lattice
@_jit
def lattice_residual(P: tuple, G0s: tuple, Phi0: np.ndarray, Gs: tuple, Phi: np.ndarray, S: np.ndarray,
                     xi: np.ndarray, dt: float, radius: float, N: np.ndarray, W: np.ndarray, mu: np.ndarray,
                     BW: np.ndarray, Dmu: np.ndarray, R: np.ndarray, D: np.ndarray, scr: tuple, A: np.ndarray,
                     M: np.ndarray) -> bool:
    """The stage residual on the lattice; False (nothing computed) when ξ is outside the
    domain of dexp⁻¹.

    ``G0s``/``Phi0``: the step's edges (one ``[ne_α, m, m]`` per axis) and frames ``[n or 1,
    m, m]``, read only; ``Gs``/``Phi``: work copies, left at the midpoint; ``S``, ``xi``
    ``[n, r]``; outputs ``N = ξ/Δt``, ``W``, ``mu``, ``BW``, ``Dmu``, ``R`` ``[n, r]`` and
    ``D = exp(ξ/2)`` ``[n, m, m]``; ``scr`` the drift's chunk scratch (as
    ``cartan.schemes._lattice_compiled._exp_drift`` makes it), ``A``, ``M`` as :func:`_nodes`.
    """
    gid = P[I_GID]
    if not _in_domain(gid, xi, radius):
        return False
    for a in range(len(Gs)):
        Gs[a][...] = G0s[a]
    Phi[...] = Phi0
    n, r = xi.shape
    empty = np.empty((0, r))
    _exp_drift_nd(P, Gs, Phi, xi, 0.5, D, empty, empty, scr)  # Φ ← Φ exp(ξ/2), D = exp(ξ/2)
    for i in range(n):
        for k in range(r):
            N[i, k] = xi[i, k] / dt
    _force_once(P, Gs, Phi, N, W, True)
    _nodes(gid, P[I_MASS], xi, N, D, W, S, dt, mu, BW, Dmu, R, A, M)
    return True


@_jit
def lattice_drift(P: tuple, Gs: tuple, Phi: np.ndarray, xi: np.ndarray, tau: float, D: np.ndarray,
                  scr: tuple) -> None:
    """The drift ``Φ ← Φ exp(τξ)`` of the edges ``Gs`` and frames ``Phi`` in place (``D`` work)."""
    empty = np.empty((0, xi.shape[1]))
    _exp_drift_nd(P, Gs, Phi, xi, tau, D, empty, empty, scr)


# ---------------------------------------------------------------------------- collocation
@_jit
def collocation_residual(P: tuple, Dc: tuple, X0: np.ndarray, Phi0: np.ndarray, X: np.ndarray, Phi: np.ndarray,
                         S: np.ndarray, xi: np.ndarray, dt: float, radius: float, N: np.ndarray, W: np.ndarray,
                         mu: np.ndarray, BW: np.ndarray, Dmu: np.ndarray, R: np.ndarray, D: np.ndarray,
                         A: np.ndarray, M: np.ndarray) -> bool:
    """The stage residual of the collocation scheme (as :func:`lattice_residual`): ``X0`` ``[n, r]``
    and ``Phi0`` the step's strains and frames (read only), ``X``, ``Phi`` work copies left at
    the midpoint."""
    gid = P[I_GID]
    if not _in_domain(gid, xi, radius):
        return False
    X[...] = X0
    Phi[...] = Phi0
    _collocation_drift(P, Dc, X, Phi, xi, 0.5, True)  # X, Φ at Φ exp(ξ/2)
    n, r = xi.shape
    v = np.empty(r)
    for i in range(n):
        for k in range(r):
            N[i, k] = xi[i, k] / dt
            v[k] = 0.5 * xi[i, k]
        g_exp(gid, v, D[i])
    _collocation_force(P, Dc, X, Phi, N, W)
    _nodes(gid, P[I_MASS], xi, N, D, W, S, dt, mu, BW, Dmu, R, A, M)
    return True


# ---------------------------------------------------------------------------- Newton's linear solve, norms
@_jit
def _lu_solve(Lp: np.ndarray, Li: np.ndarray, Lx: np.ndarray, Ld: np.ndarray, Up: np.ndarray, Ui: np.ndarray,
              Ux: np.ndarray, Ud: np.ndarray, perm_r: np.ndarray, perm_c: np.ndarray, b: np.ndarray, x: np.ndarray,
              y: np.ndarray) -> None:
    """``x = A⁻¹b`` from SuperLU's factors ``Pr A Pc = L U``: the strictly lower and upper parts
    of L and U as CSC arrays with their diagonals ``Ld``, ``Ud``; ``Pr b`` placed at ``perm_r``,
    ``x = Pc z`` read at ``perm_c``.  One forward and one back substitution by columns, ``y``
    ``(n,)`` work."""
    n = b.shape[0]
    for i in range(n):
        y[perm_r[i]] = b[i]
    for j in range(n):
        yj = y[j] / Ld[j]
        y[j] = yj
        for p in range(Lp[j], Lp[j + 1]):
            y[Li[p]] -= Lx[p] * yj
    for j in range(n - 1, -1, -1):
        yj = y[j] / Ud[j]
        y[j] = yj
        for p in range(Up[j], Up[j + 1]):
            y[Ui[p]] -= Ux[p] * yj
    for i in range(n):
        x[i] = y[perm_c[i]]


class LUSolve:
    """The solve of a ``scipy.sparse.linalg.splu`` factorisation in compiled code (the same
    factors; the substitutions in another order than SuperLU's, so round-off apart the same
    solution).  ``solve(b)`` for ``b`` ``(n,)`` returns a new array, as ``SuperLU.solve``."""

    def __init__(self, lu: Any):
        import scipy.sparse as sp

        def parts(T: Any, k: int) -> tuple:
            T = sp.csc_matrix(T)
            off = sp.csc_matrix(sp.tril(T, -1) if k < 0 else sp.triu(T, 1))
            return (off.indptr.astype(np.int64), off.indices.astype(np.int64),
                    np.ascontiguousarray(off.data, dtype=np.float64),
                    np.ascontiguousarray(T.diagonal(), dtype=np.float64))

        self.shape = lu.shape
        self._args = (*parts(lu.L, -1), *parts(lu.U, 1), np.ascontiguousarray(lu.perm_r, np.int64),
                      np.ascontiguousarray(lu.perm_c, np.int64))
        self._work = np.empty(lu.shape[0])

    def solve(self, b: np.ndarray) -> np.ndarray:
        x = np.empty(self.shape[0])
        _lu_solve(*self._args, np.ascontiguousarray(b, dtype=np.float64), x, self._work)
        return x


@_jit
def weighted_norm(w: np.ndarray, idx: np.ndarray, y: np.ndarray) -> float:
    """``sqrt(Σ_k w_k y[idx_k]²)`` for ``y`` flattened (the kinetic-energy norms of the Newton
    iteration over the unknowns ``idx``)."""
    acc = 0.0
    for k in range(idx.shape[0]):
        v = y[idx[k]]
        acc += w[k] * (v * v)
    return np.sqrt(acc)


# ---------------------------------------------------------------------------- Newton's iteration
#: what :func:`newton_steps` returns with: the steps are done (or the run's blow-up test failed
#: after the last of them); a fresh Jacobian is needed at the current iterate of the step in
#: progress; or that step failed (the reasons of ``ImplicitMidpoint._step``)
DONE, NEED_JACOBIAN, FAIL_NOT_FINITE, FAIL_MAX_ITER, FAIL_SINGULAR, FAIL_NO_DECREASE = range(6)
#: rows of a slot of the residual buffers ``BUF [2, 6, n·r]``
_N, _W, _MU, _BW, _DMU, _R = range(6)
#: ``64 ε``: the round-off floor of ``‖R‖_*`` is this times the size of its terms
_FLOOR = 64 * np.finfo(float).eps


def _evaluate(P, lat, col, xi, dt, radius, N, W, mu, BW, Dmu, R, D, A, M):  # pragma: no cover - compiled only
    """The stage residual of the scheme whose context is not empty (``lat`` for the lattice,
    ``col`` for collocation): :func:`lattice_residual` or :func:`collocation_residual`, chosen
    when :func:`newton_steps` is compiled (numba does not cache functions that receive jitted
    functions as arguments)."""
    raise NotImplementedError("compiled code only")


@overload(_evaluate, jit_options={"error_model": "numpy"})
def _evaluate_impl(P, lat, col, xi, dt, radius, N, W, mu, BW, Dmu, R, D, A, M):
    if len(lat) > 0:
        def lattice(P, lat, col, xi, dt, radius, N, W, mu, BW, Dmu, R, D, A, M):
            G0s, Phi0, Gs, Phi, S, scr = lat
            return lattice_residual(P, G0s, Phi0, Gs, Phi, S, xi, dt, radius, N, W, mu, BW, Dmu, R, D, scr, A, M)
        return lattice

    def collocation(P, lat, col, xi, dt, radius, N, W, mu, BW, Dmu, R, D, A, M):
        Dc, X0, Phi0, X, Phi, S = col
        return collocation_residual(P, Dc, X0, Phi0, X, Phi, S, xi, dt, radius, N, W, mu, BW, Dmu, R, D, A, M)
    return collocation


def _drift(P, lat, col, xi, tau, D, work):  # pragma: no cover - compiled only
    """The exact drift ``Φ ← Φ exp(τξ)`` of the step's configuration in place (``work`` False)
    or of its work copy, taken afresh (``work`` True); returns the frames drifted."""
    raise NotImplementedError("compiled code only")


@overload(_drift, jit_options={"error_model": "numpy"})
def _drift_impl(P, lat, col, xi, tau, D, work):
    if len(lat) > 0:
        def lattice(P, lat, col, xi, tau, D, work):
            G0s, Phi0, Gs, Phi, S, scr = lat
            if work:
                for a in range(len(Gs)):
                    Gs[a][...] = G0s[a]
                Phi[...] = Phi0
                lattice_drift(P, Gs, Phi, xi, tau, D, scr)
                return Phi
            lattice_drift(P, G0s, Phi0, xi, tau, D, scr)
            return Phi0
        return lattice

    def collocation(P, lat, col, xi, tau, D, work):
        Dc, X0, Phi0, X, Phi, S = col
        if work:
            X[...] = X0
            Phi[...] = Phi0
            _collocation_drift(P, Dc, X, Phi, xi, tau, True)
            return Phi
        _collocation_drift(P, Dc, X0, Phi0, xi, tau, True)
        return Phi0
    return collocation


@_jit
def midpoint_powers(P: tuple, face: np.ndarray, N: np.ndarray, Phi: np.ndarray, tr: np.ndarray, Mr: np.ndarray,
                    Am: np.ndarray) -> tuple:
    """``(dissipated, external)`` power of the loads of the plan ``P`` at the velocity ``N``
    ``[n, r]`` and frames ``Phi`` (``Scheme.powers`` with ``_boundary_power``): damping,
    body-frame uniform force, end loads weighted by their ``face`` ``(n_end,)`` (the lattice's
    ``weights/(h/2)`` on a face, 1 at the end of a rod); ``tr`` ``(r,)``, ``Mr`` ``[r, r]``,
    ``Am`` ``[m, m]`` work (:func:`cartan.schemes._lattice_compiled.load_powers`)."""
    return load_powers(P, N, Phi, face, True, tr, Mr, Am)


@_jit
def _convergence_norms(w_over_m: np.ndarray, w_times_m: np.ndarray, unk: np.ndarray, S: np.ndarray,
                       Dmu: np.ndarray, BW: np.ndarray, xi: np.ndarray) -> tuple:
    """``(‖S‖_*, ‖Dmu‖_*, ‖BW‖_*, ‖ξ‖_M)`` in one pass over the unknowns, each summed in the
    order of :func:`weighted_norm` (so the same values); all arrays flattened."""
    s = d = b = x = 0.0
    for k in range(unk.shape[0]):
        j = unk[k]
        v = S[j]
        s += w_over_m[k] * (v * v)
        v = Dmu[j]
        d += w_over_m[k] * (v * v)
        v = BW[j]
        b += w_over_m[k] * (v * v)
        v = xi[j]
        x += w_times_m[k] * (v * v)
    return np.sqrt(s), np.sqrt(d), np.sqrt(b), np.sqrt(x)


@_jit
def _slot_residual(P: tuple, lat: tuple, col: tuple, XI: np.ndarray, BUF: np.ndarray, slot: int, dt: float,
                   radius: float, D: np.ndarray, A: np.ndarray, M: np.ndarray) -> bool:
    """The stage residual at the iterate ``XI[slot]`` into the buffers ``BUF[slot]``."""
    n, r = D.shape[0], A.shape[0]
    B = BUF[slot]
    return _evaluate(P, lat, col, XI[slot].reshape((n, r)), dt, radius, B[_N].reshape((n, r)),
                     B[_W].reshape((n, r)), B[_MU].reshape((n, r)), B[_BW].reshape((n, r)),
                     B[_DMU].reshape((n, r)), B[_R].reshape((n, r)), D, A, M)


@_jit
def newton_steps(P: tuple, lat: tuple, col: tuple, face: np.ndarray, unk: np.ndarray, w_over_m: np.ndarray,
                 w_times_m: np.ndarray, inv: np.ndarray, lu: tuple, have_lu: bool, resume: bool, S: np.ndarray,
                 XI: np.ndarray, BUF: np.ndarray, prev: np.ndarray, hist: np.ndarray, ist: np.ndarray,
                 fst: np.ndarray, work: tuple, t: float, dt: float, nsteps: int, dissipated: float,
                 external: float, kinetic_limit: float, radius: float, tol: float, contraction: float,
                 xtol: float, max_iter: int, max_halvings: int, predictor: bool, reuse: bool) -> tuple:
    """Up to ``nsteps`` steps of ``implicit-midpoint`` (``ImplicitMidpoint._step`` and the
    bookkeeping of ``ImplicitMidpoint.step``), Newton's iteration included, on the state whose
    arrays the contexts hold.

    The operations are those of the Python driver, in its order, on the same compiled pieces
    (:func:`_evaluate`, :func:`weighted_norm`, :func:`_lu_solve`, :func:`momentum_update`, the
    scheme's drift), so that the steps agree with it bit for bit; only the powers of the loads
    (:func:`midpoint_powers`) are summed in another order than ``Scheme.powers``.

    Parameters
    ----------
    P : tuple
        The compiled plan of the scheme (``_lattice_compiled_plan`` layout).
    lat, col : tuple
        The lattice context ``(G0s, Phi0, Gs, Phi, S, scr)`` — the state's edges (one
        ``[ne_α, m, m]`` per axis) and frames ``[nf, m, m]``, their work copies, the momentum
        ``[n, r]`` and the drift's chunk scratch — and ``()``, or ``()`` and the collocation
        context ``(Dc, X0, Phi0, X, Phi, S)``.  The state's arrays are updated in place.
    face : ndarray, shape (n_end,)
        Weights of the end loads' power (:func:`midpoint_powers`).
    unk : ndarray of int64, shape (nunk,)
        The unknowns: indices into ``S.ravel()``.
    w_over_m, w_times_m : ndarray, shape (nunk,)
        The weights of ``‖R‖_*²`` and ``‖N‖_M²`` at the unknowns.
    inv : ndarray, shape (r,)
        ``1/m`` on live components, 0 on gauge ones (the blow-up test).
    lu : tuple of ndarray
        The factors of the Jacobian (``LUSolve``'s arrays), read when ``have_lu``.
    have_lu : bool
        Whether ``lu`` holds the kept factorisation.
    resume : bool
        Continue the step in progress (state in ``XI``, ``BUF``, ``hist``, ``ist``, ``fst``)
        with the fresh factorisation ``lu`` at its current iterate.
    S : ndarray, shape (n, r)
        The state's momentum (the array of the contexts), updated in place.
    XI : ndarray, shape (2, n·r)
        Two iterates ξ (slots); ``ist[0]`` is the current one.
    BUF : ndarray, shape (2, 6, n·r)
        The residual's pieces ``N, W, μ, BW, Dmu, R`` of each slot.
    prev : ndarray, shape (n·r,)
        ξ of the previous step (the predictor), valid when ``ist[3]``.
    hist : ndarray, shape (max_iter + 1,)
        ``‖R‖_*`` of the accepted iterates of the step in progress (``ist[2]`` of them).
    ist : ndarray of int64, shape (4,)
        ``(current slot, iterations of the step, len(history), previous ξ valid)``, kept
        between calls.
    fst : ndarray, shape (2,)
        ``(‖R‖_* of the current iterate, Δt of the previous step)``, kept between calls.
    work : tuple
        ``(D [n, m, m], A [r, r], M [r, r + 1], b, delta, y [nunk], tr [r], Mr [r, r],
        Am [m, m])``.
    t, dt, nsteps, dissipated, external
        Time, step, steps to take, energy accumulators.
    kinetic_limit : float
        The run's per-step blow-up bound on ``½Σ w S²/m`` (inf: off).
    radius, tol, contraction, xtol, max_iter, max_halvings, predictor, reuse
        The injectivity radius of exp and the options of ``ImplicitMidpoint``
        (``xtol = XTOL·max(1, L)``).

    Returns
    -------
    tuple
        ``(status, steps done, residual evaluations, Newton iterations of the steps done, t,
        dissipated, external, have_lu)``; ``status`` is :data:`DONE`, :data:`NEED_JACOBIAN`
        (the iterate is ``XI[ist[0]]``) or a ``FAIL_*`` reason (the state is that of the
        last step done; ``ist``, ``fst`` and ``hist`` describe the failed step).
    """
    D, A, M, b, delta, y, tr, Mr, Am = work
    n, r = S.shape
    nunk = unk.shape[0]
    mass = P[I_MASS]
    w = P[I_W]
    Sf = S.reshape(n * r)
    cur, it, nhist, have_prev = ist[0], ist[1], ist[2], ist[3] != 0
    rn, dt_prev = fst[0], fst[1]
    done = 0
    nforce = 0
    iters = 0
    status = DONE
    fresh = resume
    in_step = resume
    while done < nsteps:
        if not in_step:
            # ---- start of a step: the initial iterate (ImplicitMidpoint._step)
            if not reuse:
                have_lu = False
            got = False
            a = 1 - cur
            if have_prev and predictor:
                q = dt / dt_prev
                xa = XI[a]
                xa[:] = 0.0
                for k in range(nunk):
                    xa[unk[k]] = q * prev[unk[k]]
                if _slot_residual(P, lat, col, XI, BUF, a, dt, radius, D, A, M):
                    nforce += 1
                    cur = a
                    got = True
            if not got:
                xa = XI[a]
                xa[:] = 0.0
                nonzero = False
                for k in range(nunk):
                    j = unk[k]
                    v = dt * (Sf[j] / mass[j % r])
                    xa[j] = v
                    if v != 0.0:
                        nonzero = True
                ok = _slot_residual(P, lat, col, XI, BUF, a, dt, radius, D, A, M)
                if ok:
                    nforce += 1
                cur = a
                if nonzero:
                    z = 1 - a
                    XI[z][:] = 0.0
                    _slot_residual(P, lat, col, XI, BUF, z, dt, radius, D, A, M)
                    nforce += 1
                    if not ok or (weighted_norm(w_over_m, unk, BUF[z, _R])
                                  < weighted_norm(w_over_m, unk, BUF[a, _R])):
                        cur = z
            rn = weighted_norm(w_over_m, unk, BUF[cur, _R])
            hist[0] = rn
            nhist = 1
            it = 0
            fresh = False
            in_step = True
        # ---- Newton's iteration
        converged = False
        while True:
            if resume:
                resume = False  # the tests below ran before the Jacobian was requested
            else:
                if not np.isfinite(rn):
                    status = FAIL_NOT_FINITE
                    break
                s_norm, dmu_norm, bw_norm, xi_norm = _convergence_norms(w_over_m, w_times_m, unk, Sf, BUF[cur, _DMU],
                                                                         BUF[cur, _BW], XI[cur])
                floor = _FLOOR * (s_norm + dmu_norm + abs(dt) * bw_norm)
                bound = tol * xi_norm / abs(dt)
                if floor > bound:  # Python's max(bound, floor)
                    bound = floor
                if nunk == 0 or rn <= bound:
                    converged = True
                    break
                if it >= max_iter:
                    status = FAIL_MAX_ITER
                    break
                if not have_lu:
                    status = NEED_JACOBIAN
                    break
            xc = XI[cur]
            Rc = BUF[cur, _R]
            for k in range(nunk):
                b[k] = -Rc[unk[k]]
            _lu_solve(lu[0], lu[1], lu[2], lu[3], lu[4], lu[5], lu[6], lu[7], lu[8], lu[9], b, delta, y)
            big = 0.0
            finite = True
            for k in range(nunk):
                if not np.isfinite(delta[k]):
                    finite = False
                big = max(big, abs(delta[k]))
            if not finite:
                status = FAIL_SINGULAR
                break
            negligible = big <= xtol
            a = 1 - cur
            xt = XI[a]
            alpha = 1.0
            accepted = False
            final = False
            rn_t = np.inf
            for _ in range(max_halvings + 1 if fresh else 1):
                xt[:] = xc
                for k in range(nunk):
                    j = unk[k]
                    xt[j] = xc[j] + alpha * delta[k]
                ok = _slot_residual(P, lat, col, XI, BUF, a, dt, radius, D, A, M)
                rn_t = np.inf
                if ok:
                    nforce += 1
                    rn_t = weighted_norm(w_over_m, unk, BUF[a, _R])
                it += 1
                if negligible and ok:
                    # a Newton step at the round-off level of ξ: what is left of R is round-off noise
                    accepted = True
                    final = True
                    break
                if rn_t < rn:
                    accepted = True
                    break
                if not fresh or it >= max_iter:
                    break
                alpha *= 0.5
            if accepted:
                slow = rn_t > contraction * rn
                cur = a
                rn = rn_t
                hist[nhist] = rn
                nhist += 1
                fresh = False
                if final:
                    converged = True
                    break
                if slow:
                    have_lu = False  # convergence slows: a Jacobian at the new iterate
            elif not fresh:
                have_lu = False  # a kept Jacobian that no longer contracts: a fresh one here
            elif it >= max_iter:
                status = FAIL_MAX_ITER
                break
            else:
                status = FAIL_NO_DECREASE
                break
        if not converged:
            break
        # ---- end of the step: powers at the midpoint, Φ ← Φ exp(ξ), S ← dexp⁻¹_{−ξ}ᵀ μ + Δt (W − BW)
        iters += it
        xi = XI[cur].reshape((n, r))
        B = BUF[cur]
        pd = 0.0
        pe = 0.0
        if P[I_HAS_POWER]:
            Phi_mid = _drift(P, lat, col, xi, 0.5, D, True)
            pd, pe = midpoint_powers(P, face, B[_N].reshape((n, r)), Phi_mid, tr, Mr, Am)
        momentum_update(P[I_GID], xi, B[_MU].reshape((n, r)), B[_W].reshape((n, r)), B[_BW].reshape((n, r)), dt,
                        S)
        _drift(P, lat, col, xi, 1.0, D, False)
        _constrain(P, S)
        t = t + dt
        dissipated = dissipated + dt * pd
        external = external + dt * pe
        prev[:] = XI[cur]
        have_prev = True
        dt_prev = dt
        in_step = False
        done += 1
        if _unstable(CHECK_MOMENTUM, kinetic_limit, S, D, D, w, inv):
            break
    ist[0], ist[1], ist[2], ist[3] = cur, it, nhist, 1 if have_prev else 0
    fst[0], fst[1] = rn, dt_prev
    return status, done, nforce, iters, t, dissipated, external, have_lu


# ---------------------------------------------------------------------------- Python glue
def _contiguous(a: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """``a`` reshaped to ``shape``, without a copy when it is a C-contiguous float64 array."""
    return np.ascontiguousarray(a, dtype=np.float64).reshape(shape)


class StageResidual:
    """The compiled stage residual of one scheme (work arrays allocated once).

    Use :func:`stage_residual` to get one (or None when the scheme has no compiled plan).
    :meth:`bind` takes the step's state; :meth:`__call__` evaluates ``R(ξ)`` and its pieces;
    :meth:`midpoint` gives the midpoint state (for the powers) and :meth:`advance` performs
    the end of the step.
    """

    def __init__(self, scheme: Any, kind: str, plan: Any):
        self.scheme = scheme
        self.kind = kind
        self.plan = plan
        group = scheme.group
        self.gid = int(plan[I_GID] if kind == "lattice" else plan[0][I_GID])
        self.radius = float(group.injectivity_radius)
        self.shape = (*scheme.grid.shape, group.dim)
        n, r, m = scheme.grid.size, group.dim, group.matrix_size
        self.n, self.r, self.m = n, r, m
        self.frame_key = "Phi" if scheme.track else "Phi_root"
        nf = n if scheme.track else 1
        self.Phi = np.empty((nf, m, m))
        self.D = np.empty((n, m, m))
        self.A = np.empty((r, r))
        self.M = np.empty((r, r + 1))
        if kind == "lattice":
            self.keys = tuple(scheme._key(a) for a in range(scheme.grid.d))
            nch = max((n + CHUNK - 1) // CHUNK, int(plan[I_ECH][plan[I_D]]))
            self.scr = _chunk_scratch(nch, r, m, 0)
            self.Gs: tuple | None = None  # allocated at the first bind (edge shapes)
        else:
            self.keys = ("X",)
            self.X = np.empty((n, r))
        self._base: tuple | None = None

    def accepts(self, state: Any) -> bool:
        """Whether ``state`` has the layout the kernels read (the scheme's configuration arrays)."""
        if set(state.arrays) != {*self.keys, self.frame_key} or np.shape(state.S) != self.shape:
            return False
        return self.kind == "lattice" or np.shape(state.arrays["X"]) == (self.n, 1, self.r)

    def bind(self, state: Any) -> None:
        """Take the step's configuration and momentum (read, never modified; not copied when
        they are C-contiguous float64 arrays)."""
        n, r, m = self.n, self.r, self.m
        Phi0 = _contiguous(state.arrays[self.frame_key], self.Phi.shape)
        S = _contiguous(state.S, (n, r))
        if self.kind == "lattice":
            G0s = tuple(_contiguous(state.arrays[k], (-1, m, m)) for k in self.keys)
            if self.Gs is None or any(g.shape != h.shape for g, h in zip(self.Gs, G0s, strict=True)):
                self.Gs = tuple(np.empty_like(g) for g in G0s)
            self._base = (G0s, Phi0, S)
        else:
            self._base = (_contiguous(state.arrays["X"], (n, r)), Phi0, S)

    def __call__(self, xi: np.ndarray, dt: float) -> dict[str, np.ndarray] | None:
        """``{"R", "W", "BW", "mu", "Dmu"}`` (new ``[*shape, r]`` arrays) at ξ ``[*shape, r]``
        for the bound state, or None when ξ is outside the domain of dexp⁻¹."""
        if self._base is None:
            raise RuntimeError("StageResidual.bind(state) must be called before evaluating")
        n, r = self.n, self.r
        x = _contiguous(xi, (n, r))
        out = {k: np.empty((n, r)) for k in ("N", "W", "mu", "BW", "Dmu", "R")}
        if self.kind == "lattice":
            G0s, Phi0, S = self._base
            ok = lattice_residual(self.plan, G0s, Phi0, self.Gs, self.Phi, S, x, float(dt), self.radius, out["N"],
                                  out["W"], out["mu"], out["BW"], out["Dmu"], out["R"], self.D, self.scr, self.A,
                                  self.M)
        else:
            X0, Phi0, S = self._base
            P, Dc = self.plan
            ok = collocation_residual(P, Dc, X0, Phi0, self.X, self.Phi, S, x, float(dt), self.radius, out["N"],
                                      out["W"], out["mu"], out["BW"], out["Dmu"], out["R"], self.D, self.A, self.M)
        if not ok:
            return None
        del out["N"]
        return {k: v.reshape(self.shape) for k, v in out.items()}

    def drifted(self, state: Any, xi: np.ndarray, tau: float) -> dict[str, np.ndarray]:
        """The configuration arrays of ``state`` drifted by ``Φ ← Φ exp(τξ)`` (the scheme's exact
        drift), as new arrays; ``state`` is not modified."""
        n, r, m = self.n, self.r, self.m
        x = _contiguous(xi, (n, r))
        Phi = np.array(state.arrays[self.frame_key], dtype=np.float64, order="C")
        Phi3 = Phi.reshape(self.Phi.shape)
        out = {self.frame_key: Phi}
        if self.kind == "lattice":
            Gs = tuple(np.array(state.arrays[k], dtype=np.float64, order="C") for k in self.keys)
            lattice_drift(self.plan, tuple(g.reshape(-1, m, m) for g in Gs), Phi3, x, float(tau), self.D, self.scr)
            out.update(zip(self.keys, Gs, strict=True))
        else:
            X = np.array(state.arrays["X"], dtype=np.float64, order="C")
            P, Dc = self.plan
            _collocation_drift(P, Dc, X.reshape(n, r), Phi3, x, float(tau), True)
            out["X"] = X
        return out

    def midpoint(self, state: Any, xi: np.ndarray) -> Any:
        """A copy of ``state`` at the midpoint configuration ``Φ exp(ξ/2)`` (for the powers)."""
        mid = state.copy()
        mid.arrays.update(self.drifted(state, xi, 0.5))
        return mid

    def advance(self, state: Any, xi: np.ndarray, res: dict[str, np.ndarray], dt: float) -> None:
        """End of the step: ``S ← dexp⁻¹_{−ξ}ᵀ μ + Δt (W − BW)`` from the pieces ``res`` of the
        converged residual, and ``Φ ← Φ exp(ξ)`` into new arrays."""
        n, r = self.n, self.r
        S_new = np.empty((n, r))
        momentum_update(self.gid, _contiguous(xi, (n, r)), _contiguous(res["mu"], (n, r)),
                        _contiguous(res["W"], (n, r)), _contiguous(res["BW"], (n, r)), float(dt), S_new)
        state.arrays.update(self.drifted(state, xi, 1.0))
        state.S = S_new.reshape(self.shape)


class NewtonBlocks:
    """The work arrays of :func:`newton_steps` for one compiled stage residual and one set of
    unknowns, and its call (``ImplicitMidpoint.compiled_advance`` drives it: it builds the Jacobians
    the loop asks for and turns its failures into errors).

    Parameters
    ----------
    kernel : StageResidual
        The compiled residual, bound to the state before every :meth:`run`.
    unk : ndarray of int64, shape (nunk,)
        The unknowns, as indices into ``S.ravel()``.
    w_over_m, w_times_m : ndarray, shape (nunk,)
        The weights of the norms ``‖R‖_*`` and ``‖N‖_M`` at the unknowns.
    inv : ndarray, shape (r,)
        ``1/m`` on live components, 0 on gauge ones.
    """

    def __init__(self, kernel: StageResidual, unk: np.ndarray, w_over_m: np.ndarray, w_times_m: np.ndarray,
                 inv: np.ndarray):
        n, r, m = kernel.n, kernel.r, kernel.m
        nunk = len(unk)
        self.kernel = kernel
        self.shape = kernel.shape
        self.unk = np.ascontiguousarray(unk, dtype=np.int64)
        self.w_over_m = np.ascontiguousarray(w_over_m, dtype=np.float64)
        self.w_times_m = np.ascontiguousarray(w_times_m, dtype=np.float64)
        self.inv = np.ascontiguousarray(inv, dtype=np.float64)
        self.XI = np.zeros((2, n * r))
        self.BUF = np.zeros((2, 6, n * r))
        self.prev = np.zeros(n * r)
        self.hist = np.zeros(1)
        self.ist = np.zeros(4, dtype=np.int64)
        self.fst = np.zeros(2)
        self.work = (kernel.D, kernel.A, kernel.M, np.empty(nunk), np.empty(nunk), np.empty(nunk), np.empty(r),
                     np.empty((r, r)), np.empty((m, m)))
        i0, f0 = np.zeros(0, dtype=np.int64), np.zeros(0)
        self.no_lu = (np.zeros(1, dtype=np.int64), i0, f0, f0, np.zeros(1, dtype=np.int64), i0, f0, f0, i0, i0)

    def start(self, prev: np.ndarray | None, dt_prev: float, max_iter: int) -> None:
        """Begin a block: ``prev`` ``[*shape, r]`` the previous step's ξ (None: no previous step)
        and its ``dt_prev``; room for the residual history of ``max_iter`` iterations."""
        self.ist[:] = (0, 0, 0, prev is not None)
        self.fst[:] = (0.0, dt_prev)
        if prev is not None:
            self.prev[:] = np.ravel(prev)
        if self.hist.shape[0] < max_iter + 1:
            self.hist = np.zeros(max_iter + 1)

    def run(self, lu: Any, resume: bool, t: float, dt: float, nsteps: int, dissipated: float, external: float,
            kinetic_limit: float, radius: float, options: tuple) -> tuple:
        """One call of :func:`newton_steps` on the bound state with the factorisation ``lu``
        (a :class:`LUSolve`, or None); ``options`` = ``(tol, contraction, xtol, max_iter,
        max_halvings, predictor, reuse)``.  Returns what :func:`newton_steps` returns."""
        k = self.kernel
        if k.kind == "lattice":
            G0s, Phi0, S = k._base
            P, lat, col, face = k.plan, (G0s, Phi0, k.Gs, k.Phi, S, k.scr), (), k.plan[I_END_FACE]
        else:
            X0, Phi0, S = k._base
            P, Dc = k.plan
            lat, col, face = (), (Dc, X0, Phi0, k.X, k.Phi, S), np.ones(len(P[I_END_IDX]))
        tol, contraction, xtol, max_iter, max_halvings, predictor, reuse = options
        return newton_steps(P, lat, col, face, self.unk, self.w_over_m, self.w_times_m, self.inv,
                            self.no_lu if lu is None else lu._args, lu is not None, bool(resume), S, self.XI,
                            self.BUF, self.prev, self.hist, self.ist, self.fst, self.work, float(t), float(dt),
                            int(nsteps), float(dissipated), float(external), float(kinetic_limit), float(radius),
                            float(tol), float(contraction), float(xtol), int(max_iter), int(max_halvings),
                            bool(predictor), bool(reuse))

    def iterate(self) -> np.ndarray:
        """The current iterate ξ ``[*shape, r]`` of the step in progress (a copy)."""
        return self.XI[self.ist[0]].reshape(self.shape).copy()

    def previous(self) -> np.ndarray:
        """ξ ``[*shape, r]`` of the last step done (a copy)."""
        return self.prev.reshape(self.shape).copy()

    def progress(self) -> tuple[int, float, list[float]]:
        """``(iterations, ‖R‖_*, history)`` of the step in progress."""
        return int(self.ist[1]), float(self.fst[0]), [float(x) for x in self.hist[: self.ist[2]]]


def stage_residual(scheme: Any) -> StageResidual | None:
    """The compiled stage residual of ``scheme``, or None: the numpy backend, a scheme other
    than ``lattice`` and ``collocation``, a problem without a compiled plan (the plan of the
    compiled step loops, :meth:`~cartan.schemes.base.Scheme.compiled_plan`), or a medium
    whose momentum is not the base ``m N``."""
    from ..medium import Medium
    from ..schemes.collocation import Collocation
    from ..schemes.lattice import Lattice

    if get_backend() != "numba":
        return None
    if type(scheme.medium).momentum is not Medium.momentum:
        return None
    if isinstance(scheme, Lattice):
        kind, module = "lattice", "_lattice_compiled"
    elif isinstance(scheme, Collocation) and scheme.grid.d == 1:
        kind, module = "collocation", "_collocation_compiled"
    else:
        return None
    plan = scheme.compiled_plan(module)
    if plan is None:
        return None
    return StageResidual(scheme, kind, plan)
