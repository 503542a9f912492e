"""Load continuation of static equilibria: pseudo-arclength, critical points, branch switching.

Follows the equilibrium path of ``r(δ, λ) = F_int + λ·F_ext (+ reactions) = 0`` in the unknowns
(the Lie-algebra increments δ of :func:`cartan.statics.solve_static`, applied on the group as
``Φ_i ← Φ_i exp(δ_i)``) and the load factor λ.

Pseudo-arclength
    From a converged point x₀ = (state₀, λ₀) with unit tangent t, the predictor is x₀ + Δs·t
    and the corrector solves ``r = 0`` together with ``⟨t, x − x₀⟩_W = Δs`` on the bordered
    Jacobian ``[[K, ∂r/∂λ], [W t_δᵀ, W t_λ]]`` (K the medium's analytic Jacobian or the
    coloured finite-difference one of :mod:`cartan.statics`).  The corrector is the damped
    mixed Newton iteration of :func:`~cartan.statics.solve_static` (edge strains carried as
    unknowns, starting from their linearisation along the predictor, ``ε = X₀ + Δs·B t_δ``;
    natural monotonicity test with predicted damping factors).  The increments x − x₀ are the
    sums of the Newton increments.  The weighted norm is ``‖x‖²_W = ‖δ‖²/n + (λ/λ_s)²`` with n
    the number of nodes and λ_s = ``lam_scale`` (reaction forces carry no weight), so ``ds`` is
    dimensionless.  The tangent at each new point solves ``[[K, ∂r/∂λ], [W t_prevᵀ]]·t = (0, 1)``
    (oriented along the previous tangent), which passes folds.  The step grows by 1.5 after an
    easy corrector (≤ 3 iterations), shrinks by 0.7 after a slow one (≥ max_iter − 2) and is
    halved after a failed one.
Critical points
    Between consecutive points a change of the sign of det K (the product of the signs of the
    sparse LU's diagonal and of its row and column permutations) marks a fold or a bifurcation.
    The critical load is located by a safeguarded secant (Illinois) iteration on det K along
    the arclength from the last point before the crossing; the eigenvalue of smallest
    magnitude of the symmetric part of K (``eigsh`` with ``sigma = 0``) is recorded at every
    point.  A critical point whose neighbouring
    tangents have load components of opposite sign is a fold; otherwise a bifurcation.
Branch switching
    At the first bifurcation the path leaves along the null vector φ of K (the eigenvector of
    the eigenvalue nearest zero): predictor ``x_c + Δs·(φ, 0)``, corrector orthogonal to it.
Loads with a global part
    A load with :meth:`~cartan.problem.Load.jacobian_parts` makes K above the whole Jacobian
    ``K_s + U Vᵀ``: the sparse stencil part K_s and a rank-k part (U, V ``(m, k)``), never
    formed.  The corrector and the tangent solve the bordered system by the sparse LU of the
    bordered K_s and the Sherman–Morrison–Woodbury identity
    (:func:`cartan.statics._low_rank_solve`); det K is the matrix determinant lemma on the LU
    of K_s, ``det(K_s + U Vᵀ) = det K_s · det(I_k + Vᵀ K_s⁻¹ U)``; the eigenvalue of smallest
    magnitude of ``sym K = sym K_s + ½(U Vᵀ + V Uᵀ)`` comes from shift-invert Lanczos on a
    LinearOperator whose inverse is Woodbury on the LU of sym K_s (rank 2k).  Without such a
    load the computation is the sparse one above, unchanged.
Pins
    ``pins`` holds spatial position components of chosen nodes (the ends of a rod, any node of a
    lattice) at their initial values (a pinned end: position held, rotation free; a roller: one
    component held) by Lagrange multipliers — spatial reaction forces added at the node as dead
    point loads — without a new boundary kind: give such ends as :class:`cartan.Free` in the
    problem.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from .problem import InitialState, Problem
from .statics import (
    _JACOBIANS,
    ConvergenceError,
    _Equilibrium,
    _factorise,
    _initial_phi,
    _low_rank_slogdet,
    _low_rank_solve,
    _newton,
    _Point,
    _Singular,
)

__all__ = ["continuation"]


def _perm_parity(p: np.ndarray) -> int:
    """+1 for an even permutation, −1 for an odd one."""
    p = np.asarray(p)
    seen = np.zeros(p.size, dtype=bool)
    sign = 1
    for i in range(p.size):
        if seen[i]:
            continue
        j, length = i, 0
        while not seen[j]:
            seen[j] = True
            j = p[j]
            length += 1
        if length % 2 == 0:
            sign = -sign
    return sign


def _log_det(K, low: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[int, float]:
    """(sign, log|det J|) of ``J = K + U Vᵀ`` from the sparse LU of K: the signs of its U
    factor's diagonal and of the row and column permutations (L has a unit diagonal), times
    ``det(I_k + Vᵀ K⁻¹ U)`` by the matrix determinant lemma (:func:`cartan.statics._low_rank_slogdet`)
    when the loads have a rank-k part ``low`` = (U, V) ``(m, k)`` each; (0, −inf) when J (or K)
    is singular."""
    import scipy.sparse.linalg as spla

    try:
        with np.errstate(all="ignore"):
            lu = spla.splu(K.tocsc())
    except RuntimeError:
        return 0, -math.inf
    d = lu.U.diagonal()
    if np.any(d == 0) or not np.all(np.isfinite(d)):
        return 0, -math.inf
    sign = int(np.prod(np.sign(d))) * _perm_parity(lu.perm_r) * _perm_parity(lu.perm_c)
    logabs = float(np.sum(np.log(np.abs(d))))
    if low is None:
        return sign, logabs
    s_low, l_low = _low_rank_slogdet(lu.solve, low)
    return (sign * s_low, logabs + l_low) if s_low else (0, -math.inf)


def _eig_min(K, with_vector: bool = False, low: tuple[np.ndarray, np.ndarray] | None = None):
    """Eigenvalue of smallest magnitude of the symmetric part of ``J = K + U Vᵀ`` (and its
    eigenvector); ``low`` = (U, V) ``(m, k)`` each, the loads' rank-k part, or None (J = K)."""
    import scipy.sparse.linalg as spla

    S = (0.5 * (K + K.T)).tocsc()
    n = S.shape[0]
    sym = None if low is None else _symmetric_low_rank(*low)
    if sym is not None:
        return _eig_min_low_rank(S, sym, with_vector)
    if n <= 12:
        vals, vecs = np.linalg.eigh(S.toarray())
        i = int(np.argmin(np.abs(vals)))
        return (vals[i], vecs[:, i]) if with_vector else vals[i]
    v0 = np.ones(n) / math.sqrt(n)
    try:
        vals, vecs = spla.eigsh(S, k=1, sigma=0.0, which="LM", v0=v0, tol=1e-12)
    except (RuntimeError, spla.ArpackNoConvergence):
        vals, vecs = spla.eigsh(S, k=1, sigma=1e-9 * spla.norm(S, 1), which="LM", v0=v0, tol=1e-12)
    return (float(vals[0]), vecs[:, 0]) if with_vector else float(vals[0])


def _symmetric_low_rank(U: np.ndarray, V: np.ndarray, rtol: float = 1e-13
                        ) -> tuple[np.ndarray, np.ndarray] | None:
    """The symmetric part ``½(U Vᵀ + V Uᵀ)`` of a rank-k matrix as ``B Λ Bᵀ`` with B ``(m, p)``
    orthonormal, p ≤ 2k: (B Λ, B), or None when it vanishes (e.g. a load scaled by λ = 0).
    From the QR factorisation ``[U V] = Q [R_U R_V]`` it is ``Q M Qᵀ``,
    ``M = ½(R_U R_Vᵀ + R_V R_Uᵀ)`` ``(2k, 2k)``, whose eigenvalues below ``rtol`` of the largest
    are dropped: well scaled whatever the sizes of U and V (the plain split
    ``(U, V)/2 · (V, U)ᵀ`` is not when one of them is small)."""
    k = U.shape[1]
    Q, R = np.linalg.qr(np.hstack([U, V]))
    M = 0.5 * (R[:, :k] @ R[:, k:].T + R[:, k:] @ R[:, :k].T)
    lam, P = np.linalg.eigh(M)
    big = float(np.max(np.abs(lam), initial=0.0))
    keep = np.abs(lam) > rtol * big
    if big == 0.0 or not np.all(np.isfinite(lam)) or not keep.any():
        return None
    B = Q @ P[:, keep]
    return B * lam[keep], B


def _eig_min_low_rank(S, sym: tuple[np.ndarray, np.ndarray], with_vector: bool):
    """:func:`_eig_min` of ``S + B Λ Bᵀ`` (``sym`` = (BΛ, B), :func:`_symmetric_low_rank`):
    shift-invert Lanczos (``eigsh``, σ = 0, else a small shift as for the sparse one) on a
    LinearOperator whose inverse is the sparse LU of S − σI and the rank-p part by
    Sherman–Morrison–Woodbury, never forming the matrix (dense only for m ≤ 12)."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    Ut, B = sym
    n = S.shape[0]
    if n <= 12:
        vals, vecs = np.linalg.eigh(S.toarray() + Ut @ B.T)
        i = int(np.argmin(np.abs(vals)))
        return (vals[i], vecs[:, i]) if with_vector else vals[i]
    op = spla.LinearOperator((n, n), matvec=lambda x: S @ np.ravel(x) + Ut @ (B.T @ np.ravel(x)), dtype=float)
    v0 = np.ones(n) / math.sqrt(n)
    error: Exception | None = None
    for sigma in (0.0, 1e-9 * spla.norm(S, 1)):
        try:
            with np.errstate(all="ignore"):
                lu = spla.splu((S - sigma * sp.identity(n, format="csc")).tocsc())
            Z = np.column_stack([lu.solve(Ut[:, j]) for j in range(Ut.shape[1])])
            Cinv = np.linalg.inv(np.eye(Ut.shape[1]) + B.T @ Z)  # (p, p), p ≤ 2k

            def inv(x: np.ndarray, lu=lu, Z=Z, Cinv=Cinv) -> np.ndarray:
                y = lu.solve(np.ravel(x))
                return y - Z @ (Cinv @ (B.T @ y))

            opinv = spla.LinearOperator((n, n), matvec=inv, dtype=float)
            vals, vecs = spla.eigsh(op, k=1, sigma=sigma, which="LM", v0=v0, tol=1e-12, OPinv=opinv)
        except (RuntimeError, np.linalg.LinAlgError, spla.ArpackNoConvergence) as exc:
            error = exc
            continue
        return (float(vals[0]), vecs[:, 0]) if with_vector else float(vals[0])
    raise error


def _bordered_lu(K, f: np.ndarray, row: np.ndarray, corner: float):
    """Sparse LU (``splu``) of the bordered matrix ``[[K, f], [rowᵀ, corner]]`` ``(m + 1, m + 1)``."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    B = sp.bmat([[K, sp.csc_matrix(f[:, None])], [sp.csr_matrix(row[None, :]), np.array([[corner]])]])
    with np.errstate(all="ignore"):
        return spla.splu(B.tocsc())


def _tangent(K, low: tuple[np.ndarray, np.ndarray] | None, f: np.ndarray, wv: np.ndarray, wl: float,
             tu_prev: np.ndarray, tl_prev: float) -> tuple[np.ndarray, float]:
    """Unit tangent (t_δ, t_λ) ``(m,)``, scalar of the path at a point: the solve of the bordered
    system ``[[J, f], [W t_prevᵀ]]·t = (0, 1)`` with ``J = K + U Vᵀ`` (the sparse LU of the
    bordered K and the loads' rank-k part ``low`` by :func:`cartan.statics._low_rank_solve`,
    the same as the corrector; the bordered K's alone when the rank-k part makes the bordered
    matrix singular), normalised in the weighted norm ``‖δ‖²_W + w_λ λ²`` and oriented along the
    previous tangent.  ``f`` = ∂r/∂λ ``(m,)``."""
    m = K.shape[0]
    lu = _bordered_lu(K, f, wv * tu_prev, wl * tl_prev)
    if low is not None:  # the rank-k part, zero in the arclength row
        low = tuple(np.concatenate([x, np.zeros((1, x.shape[1]))]) for x in low)
    rhs = np.zeros(m + 1)
    rhs[-1] = 1.0
    try:
        solve = _low_rank_solve(lu.solve, low)
    except _Singular:  # the capacitance matrix is singular: the stencil part's tangent, a predictor only
        solve = lu.solve
    z = solve(rhs)
    tu, tl = z[:m], z[m]
    nz = math.sqrt(float(np.sum(wv * tu * tu)) + wl * tl * tl)
    tu, tl = tu / nz, tl / nz
    if float(np.sum(wv * tu * tu_prev)) + wl * tl * tl_prev < 0:
        tu, tl = -tu, -tl
    return tu, tl


def continuation(
    problem: Problem,
    lam_max: float,
    ds0: float,
    *,
    monitor: Callable[[Any], float] | None = None,
    stops: Any = None,
    pins: dict | str | None = None,
    lam_scale: float | None = None,
    ds_min: float | None = None,
    ds_max: float | None = None,
    max_points: int = 200,
    tol: float = 1e-9,
    max_iter: int = 10,
    detect: bool = True,
    branch_switch: bool = True,
    switch_direction: float = 1.0,
    locate_tol: float = 1e-9,
    fd_step: float = 1e-6,
    jacobian: str = "auto",
    max_halvings: int = 20,
    mixed: bool = True,
    initial: Any = None,
    t: float = 0.0,
):
    """Follow the equilibrium path of ``problem`` in the load factor λ from 0 to ``lam_max``.

    Parameters
    ----------
    problem : Problem
        As for :func:`cartan.statics.solve_static`; ``problem.initial`` (or ``initial``) must be
        an equilibrium at λ = 0 (e.g. the stress-free rod).  The external loads are scaled by λ.
    lam_max : float
        Stop at the first point with λ ≥ lam_max (it is placed on λ = lam_max exactly).
    ds0 : float
        First arclength step, in the weighted norm ``‖δ‖²/n + (λ/lam_scale)²``.
    monitor : callable(Dataset) -> float, optional
        A scalar of each equilibrium (e.g. a tip displacement), given a one-frame Dataset with
        ``position`` (time, node, row) and ``frame`` (time, node, row, col).  Default: the
        largest displacement of a node from its initial position.
    stops : sequence of float, optional
        Load factors at which path points are placed exactly (λ held fixed in the corrector
        of the step that would pass them), e.g. to read the path at tabulated loads.
    pins : dict, optional
        ``{node: components}`` spatial position components held at their initial values, node
        ``"start"``/``"end"`` (d = 1), a flat node index, or on a lattice of d ≥ 2 one entry per
        axis — ``"start"``, ``"middle"``, ``"end"`` or an index — as a tuple or a text
        (``("end", "middle")``, ``"start,start"``; :func:`cartan.statics.pin_node`); a node held
        by a clamped boundary or a component pinned twice is a ValueError.  ``"rigid"`` holds every
        component of node 0, the rigid-body gauge of a body without clamps (a closed filament;
        :func:`cartan.statics.rigid_gauge_pins`).  E.g. a pinned–pinned
        column along x:
        ``{"start": (0, 1), "end": (1,)}`` (the end slides along x).  Components from m − 1 on
        (m the matrix size: 3, 4, 5 on SE(3)) hold the node's rotation about a spatial axis, e.g.
        the spin of a three-dimensional column about its axis: ``{"start": (0, 1, 2, 3), ...}``.
    lam_scale : float, optional
        Load scale of the arclength norm (default ``lam_max``).
    ds_min, ds_max : float, optional
        Step bounds (default ``ds0/1000`` and ``10·ds0``).
    max_points : int
        Path points allowed (a :class:`ConvergenceError` when exceeded).
    tol : float
        Corrector convergence: ‖r‖_∞ ≤ tol·f with f the largest external nodal force at
        ``lam_scale``; pins within tol·L.
    max_iter : int
        Corrector iterations before the step is halved.
    detect : bool
        Locate folds and bifurcations (sign changes of det K).
    branch_switch : bool
        Leave the path along the null vector at the first bifurcation.
    switch_direction : float
        +1: leave the critical point along the null vector's sign that increases the monitor;
        −1: the one that decreases it.
    locate_tol : float
        Relative tolerance on the critical load.
    fd_step : float
        Finite-difference step of the Jacobian.
    jacobian : str
        ``"auto"`` (default): the medium's analytic Jacobian
        (:meth:`~cartan.medium.Medium.static_jacobian`, with the pins' terms added by
        differences at the pinned nodes) when it returns one for this problem, coloured
        central finite differences otherwise; ``"analytic"``: the medium's (a ``ValueError``
        when it has none); ``"fd"``: finite differences.
    max_halvings : int
        The corrector's damping stops at the step length ``2^−max_halvings`` (then the
        arclength step is halved).
    mixed : bool
        The mixed corrector, edge strains carried as unknowns (default); False: the
        displacement-only one.
    initial : optional
        Starting configuration, as for :func:`cartan.statics.solve_static`.
    t : float
        Time at which time-dependent loads are evaluated.

    Returns
    -------
    xarray.Dataset
        Along ``path``: ``load_factor`` λ, ``monitor``, ``eig_min`` (the eigenvalue of smallest
        magnitude of sym K, K the whole Jacobian, a load's rank-k part included), ``det_sign``,
        ``newton_iterations``, ``step`` (Δs), ``branch``
        (0 before the branch switch, 1 after), ``position`` (path, node, row) for affine
        groups, ``reaction`` (path, pin) when pinned.  Along ``critical``: ``critical_load``,
        ``critical_monitor``, ``critical_eig`` and ``critical_kind`` (``"fold"`` or
        ``"bifurcation"``).  Attributes ``wall_time``, ``newton_iterations`` and ``jacobian``
        (``"analytic"`` or ``"fd"``).

    Raises
    ------
    ValueError
        Bad options, as for :func:`cartan.statics.solve_static`.
    ConvergenceError
        The step fell below ``ds_min`` or ``max_points`` was exceeded.
    """
    import xarray as xr

    start = time.perf_counter()
    if lam_max <= 0 or ds0 <= 0:
        raise ValueError("lam_max and ds0 must be positive")
    init = _initial_phi(problem, initial)
    if init is not problem.initial:
        problem = Problem(problem.medium, problem.grid, InitialState(Phi=init.Phi, holonomy=problem.initial.holonomy,
                                                                     glue=problem.initial.glue),
                          problem.boundaries, problem.loads, problem.name, reference=problem.reference)
    if jacobian not in _JACOBIANS:
        raise ValueError(f"jacobian must be one of {', '.join(map(repr, _JACOBIANS))}, got {jacobian!r}")
    from .statics import rigid_gauge_pins

    pins = rigid_gauge_pins(problem, pins)  # "rigid": node 0 held, the gauge of a free body
    sysm = _Equilibrium(problem, jacobian=jacobian, fd_step=fd_step, t=t, pins=pins, probe_lam=0.0)
    g = sysm.g
    affine = bool(getattr(g, "affine", False))
    lam_scale = float(lam_max if lam_scale is None else lam_scale)
    ds_min = ds0 / 1000.0 if ds_min is None else float(ds_min)
    ds_max = 10.0 * ds0 if ds_max is None else float(ds_max)
    m = sysm.m
    wv = np.concatenate([np.full(sysm.nunk, 1.0 / sysm.nnode), np.zeros(sysm.nmult)])
    wl = 1.0 / lam_scale**2
    ext0 = sysm.dlam(sysm.state0)
    fref = float(np.max(np.abs(ext0[: sysm.nunk]), initial=0.0)) * lam_scale
    atol = tol * (fref if fref > 0 else 1.0)
    ctol = tol * sysm.length
    xtol = 1e-12 * sysm.length
    total_iters = 0
    msize = g.matrix_size
    # scaled norm of a corrector step (δ, μ, λ): the increments as in solve_static, λ in units
    # of lam_scale, the reactions left out
    scale = np.concatenate([sysm.delta_scale, np.zeros(sysm.nmult)])
    scale_l = np.concatenate([scale, [1.0 / lam_scale]])

    npos = sysm.nunk + sysm.npin

    def small(r: np.ndarray) -> bool:
        # forces to atol, pins to tol·L, strain constraints as in solve_static
        return (float(np.max(np.abs(r[: sysm.nunk]), initial=0.0)) <= atol
                and float(np.max(np.abs(r[sysm.nunk: npos]), initial=0.0)) <= ctol
                and sysm.constraints_met(r, tol))

    def bordered(K, f, tu, tl):
        return _bordered_lu(K, f, wv * tu, wl * tl)

    def tangent(state, mu, lam, K, tu_prev, tl_prev):
        return _tangent(K[0], K[1], sysm.dlam(state), wv, wl, tu_prev, tl_prev)

    def correct(state, mu, lam, tu, tl, ds, lam_target=None):
        """Predictor–corrector from (state, μ, λ) along (tu, tl): (state, μ, λ, K, iterations) or None.
        With ``lam_target`` the corrector holds λ = lam_target instead of the arclength.  The
        corrector is the damped mixed Newton iteration of :func:`cartan.statics.solve_static` on
        the bordered system."""
        nonlocal total_iters
        acc0 = ds * tu
        st, mu_ = sysm.update(state, mu, acc0)
        lam0 = lam + ds * tl if lam_target is None else float(lam_target)
        cu, cl = (tu, tl) if lam_target is None else (np.zeros(m), 1.0 / wl)

        def gap(pt: _Point) -> float:
            if lam_target is None:
                return float(np.sum(wv * tu * pt.acc)) + wl * tl * (pt.lam - lam) - ds
            return pt.lam - lam_target

        def residual(pt: _Point) -> np.ndarray:
            return np.concatenate([sysm.residual(pt.state, pt.mu, pt.lam), [gap(pt)]])

        def factorise(pt: _Point, offset):
            K, low = sysm.jacobian(pt.state, pt.mu, pt.lam, offset, low_rank=True)
            try:
                lu = bordered(K, sysm.dlam(pt.state), cu, cl)
            except RuntimeError as exc:
                raise _Singular(str(exc)) from None
            if low is not None:  # the loads' rank-k part, zero in the arclength row
                low = tuple(np.concatenate([x, np.zeros((1, x.shape[1]))]) for x in low)
            return _low_rank_solve(lu.solve, low)

        def move(pt: _Point, alpha: float, d: np.ndarray) -> _Point:
            s, u = sysm.update(pt.state, pt.mu, d[:m], alpha)
            return _Point(s, u, pt.lam + alpha * d[m], pt.acc + alpha * d[:m])

        def converged(pt: _Point, r: np.ndarray) -> bool:
            return small(r[:m]) and abs(r[m]) <= 1e-10 * max(abs(ds), 1e-300)

        # the strains of the predictor: their linearisation at the last point (the mixed iteration)
        eps0 = [x + b for x, b in zip(sysm.strains(state), sysm.strain_rate(state, acc0), strict=True)]
        out = _newton(sysm, _Point(st, mu_, lam0, acc0.copy()), residual=residual, factorise=factorise, move=move,
                      converged=converged, scale=scale_l, max_iter=max_iter, max_halvings=max_halvings, xtol=xtol,
                      min_iter=1, strains=eps0, mixed=mixed)
        total_iters += out.iterations
        if not out.converged:
            return None
        pt = out.point
        return pt.state, pt.mu, pt.lam, sysm.jacobian(pt.state, pt.mu, pt.lam, low_rank=True), out.iterations

    def snapshot(state) -> xr.Dataset:
        Phi = sysm.sch.frames(state).reshape(sysm.nnode, msize, msize)
        return xr.Dataset({
            "position": (("time", "node", "row"), Phi[None, :, 1:, 0]),
            "frame": (("time", "node", "row", "col"), Phi[None, :, 1:, 1:]),
        })

    pos0 = sysm.positions(sysm.state0).copy() if affine else None

    def measure(state) -> float:
        if monitor is not None:
            return float(monitor(snapshot(state)))
        if affine:
            return float(np.max(np.linalg.norm(sysm.positions(state) - pos0, axis=-1)))
        return float(np.max(np.abs(g.log(sysm.sch.frames(state)))))

    # ---------------------------------------------------------------- the first point (λ = 0)
    state, mu, lam = sysm.state0, np.zeros(sysm.nmult), 0.0

    def settle_move(pt: _Point, alpha: float, d: np.ndarray) -> _Point:
        s, u = sysm.update(pt.state, pt.mu, d, alpha)
        return _Point(s, u, 0.0)

    first = _newton(sysm, _Point(state, mu, 0.0),
                    residual=lambda pt: sysm.residual(pt.state, pt.mu, 0.0),
                    factorise=lambda pt, offset: _factorise(sysm, pt.state, pt.mu, 0.0, offset),
                    move=settle_move, converged=lambda pt, r: small(r), scale=scale, max_iter=max_iter,
                    max_halvings=max_halvings, xtol=xtol, mixed=mixed)
    if not first.converged:  # the start (e.g. with residual stresses) must settle at λ = 0
        raise ConvergenceError(f"continuation: no equilibrium at λ = 0: {first.reason}", first.iterations,
                               first.residuals[-1], first.residuals)
    state, mu = first.point.state, first.point.mu
    iters0 = first.iterations
    total_iters += iters0
    K = sysm.jacobian(state, mu, lam, low_rank=True)  # (K, low): the whole Jacobian K + U Vᵀ
    tu, tl = tangent(state, mu, lam, K, np.zeros(m), 1.0)
    points: list[dict[str, Any]] = []
    critical: list[dict[str, Any]] = []

    def record(state, mu, lam, K, iters, ds, branch):
        points.append({
            "load_factor": lam,
            "monitor": measure(state),
            "eig_min": _eig_min(K[0], low=K[1]) if detect else np.nan,
            "det": _log_det(*K) if detect else (0, 0.0),
            "newton_iterations": iters,
            "step": ds,
            "branch": branch,
            "position": sysm.positions(state).copy() if affine else None,
            "reaction": mu[: sysm.npin].copy(),
            "constraint": mu[sysm.npin:].copy(),
            "constraint_residual": (float(np.max(np.abs(sysm.constraint_values(state)), initial=0.0))
                                    if sysm.ncon else 0.0),
        })

    record(state, mu, lam, K, iters0, 0.0, 0)
    targets = sorted(float(x) for x in (stops or ()) if 0 < float(x) < lam_max)
    ds = float(ds0)
    branch = 0
    switched = False
    while lam < lam_max:
        if len(points) >= max_points:
            raise ConvergenceError(f"continuation: max_points = {max_points} reached at λ = {lam:g}",
                                   total_iters, 0.0, [])
        step, target = ds, None
        nxt = next((x for x in targets if x > lam * (1 + 1e-12) + 1e-300), lam_max)
        if tl > 0 and lam + step * tl >= nxt:  # land exactly on the next stop (or lam_max) when
            step, target = (nxt - lam) / tl, nxt  # this step would pass it
        res = correct(state, mu, lam, tu, tl, step, target)
        if res is not None and target is None and tl > 0 and res[2] > nxt:
            # the corrected point passed the stop the predictor fell short of: hold λ on the stop
            step, target = (nxt - lam) / tl, nxt
            res = correct(state, mu, lam, tu, tl, step, target)
        if res is None:
            ds *= 0.5
            if ds < ds_min:
                raise ConvergenceError(f"continuation: step below ds_min = {ds_min:g} at λ = {lam:g}",
                                       total_iters, float("nan"), [])
            continue
        st1, mu1, lam1, K1, it = res
        tu1, tl1 = tangent(st1, mu1, lam1, K1, tu, tl)
        prev = points[-1]
        record(st1, mu1, lam1, K1, it, step, branch)
        cur = points[-1]
        if detect and prev["det"][0] * cur["det"][0] <= 0 and prev["det"][0] != 0:
            crit = _locate(correct, state, mu, lam, tu, tl, step, prev["det"], cur["det"], locate_tol)
            if crit is not None:
                cs, cmu, clam, cK = crit
                kind = "fold" if tl * tl1 < 0 else "bifurcation"
                eig, phi = _eig_min(cK[0], with_vector=True, low=cK[1])
                critical.append({"load": clam, "monitor": measure(cs), "eig": eig, "kind": kind,
                                 "index": len(points) - 1})
                if kind == "bifurcation" and branch_switch and not switched:
                    phi = phi / (math.sqrt(float(np.sum(wv * phi * phi))) or 1.0)
                    probe, _ = sysm.update(cs, cmu, 1e-3 * ds * phi)
                    if (measure(probe) - measure(cs)) * switch_direction < 0:
                        phi = -phi
                    res2 = None
                    dsw = ds
                    while res2 is None and dsw >= ds_min:
                        res2 = correct(cs, cmu, clam, phi, 0.0, dsw)
                        if res2 is None:
                            dsw *= 0.5
                    if res2 is not None:
                        st1, mu1, lam1, K1, it = res2
                        tu1, tl1 = tangent(st1, mu1, lam1, K1, phi, 0.0)
                        branch = 1
                        switched = True
                        points.pop()
                        record(st1, mu1, lam1, K1, it, dsw, branch)
        state, mu, lam, tu, tl = st1, mu1, lam1, tu1, tl1
        ds = min(ds_max, ds * 1.5) if it <= 3 else (ds * 0.7 if it >= max_iter - 2 else ds)
    wall = time.perf_counter() - start

    data: dict[str, Any] = {
        key: ("path", np.array([p[key] for p in points]))
        for key in ("load_factor", "monitor", "eig_min", "newton_iterations", "step", "branch")
    }
    data["det_sign"] = ("path", np.array([p["det"][0] for p in points], dtype=np.int64))
    if affine:
        data["position"] = (("path", "node", "row"), np.array([p["position"] for p in points]))
    if sysm.npin:
        data["reaction"] = (("path", "pin"), np.array([p["reaction"] for p in points]))
    if sysm.ncon:  # strain constraints: the multipliers per edge and component, and the residual
        data["constraint_force"] = (("path", "constrained_edge", "constrained_component"),
                                    np.array([sysm.edge_multipliers(p["constraint"]) for p in points]))
        data["constraint_residual"] = ("path", np.array([p["constraint_residual"] for p in points]))
    data["critical_load"] = ("critical", np.array([c["load"] for c in critical], dtype=float))
    data["critical_monitor"] = ("critical", np.array([c["monitor"] for c in critical], dtype=float))
    data["critical_eig"] = ("critical", np.array([c["eig"] for c in critical], dtype=float))
    data["critical_kind"] = ("critical", np.array([c["kind"] for c in critical], dtype=object).astype(str))
    data["critical_path_index"] = ("critical", np.array([c["index"] for c in critical], dtype=np.int64))
    ds_out = xr.Dataset(data)
    ds_out["load_factor"].attrs.update(long_name="load factor λ (external loads × λ)", units="1")
    ds_out["monitor"].attrs.update(long_name="monitored displacement")
    ds_out["eig_min"].attrs.update(long_name="eigenvalue of smallest magnitude of the symmetric Jacobian part")
    ds_out["det_sign"].attrs.update(long_name="sign of det of the Jacobian (0: singular)")
    ds_out.attrs.update(grid_shape=[int(k) for k in sysm.shape])  # the node axis is the grid's, flattened
    ds_out.attrs.update(wall_time=float(wall), newton_iterations=int(total_iters), jacobian=sysm.kind,
                        title=f"{problem.name or problem.medium.name}: load continuation")
    return ds_out


def _locate(correct, state, mu, lam, tu, tl, s_hi, det_lo, det_hi, rtol):
    """Critical point between arclength 0 and s_hi from (state, λ) along (tu, tl): Illinois
    secant on det K (scaled by |det K| at s = 0, continuous through the crossing)."""
    ref = det_lo[1]

    def q_of(det):
        return det[0] * math.exp(max(min(det[1] - ref, 700.0), -700.0)) if det[0] else 0.0

    a, b, qa, qb = 0.0, float(s_hi), q_of(det_lo), q_of(det_hi)
    best = None
    for _ in range(60):
        s = b - qb * (b - a) / (qb - qa) if qa * qb < 0 else 0.5 * (a + b)
        if not (min(a, b) < s < max(a, b)):
            s = 0.5 * (a + b)
        res = correct(state, mu, lam, tu, tl, s) if s > 0 else None
        if res is None:
            return best
        st, mu_, lam_, K, _ = res
        q = q_of(_log_det(*K))
        best = (st, mu_, lam_, K)
        if q == 0.0:
            return best
        if q * qb < 0:
            a, qa = b, qb
        else:
            qa *= 0.5  # Illinois: halve the stale end
        b, qb = s, q
        width = abs(b - a)
        if width * abs(tl) <= rtol * max(abs(lam_), 1e-300) or width <= 1e-14 * max(s_hi, 1e-300):
            return best
    return best
