"""Load continuation of static equilibria: pseudo-arclength, critical points, branch switching.

Follows the equilibrium path of ``r(δ, λ) = F_int + λ·F_ext (+ reactions) = 0`` in the unknowns
(the Lie-algebra increments δ of :func:`cartan.statics.solve_static`, applied on the group as
``Φ_i ← Φ_i exp(δ_i)``) and the load factor λ.

Pseudo-arclength
    From a converged point x₀ = (state₀, λ₀) with unit tangent t, the predictor is x₀ + Δs·t
    and the corrector solves ``r = 0`` together with ``⟨t, x − x₀⟩_W = Δs`` by Newton's method
    on the bordered Jacobian ``[[K, ∂r/∂λ], [W t_δᵀ, W t_λ]]`` (K the coloured finite-difference
    Jacobian of :mod:`cartan.statics`).  The increments x − x₀ are the sums of the Newton
    increments.  The weighted norm is ``‖x‖²_W = ‖δ‖²/n + (λ/λ_s)²`` with n the number of nodes
    and λ_s = ``lam_scale`` (reaction forces carry no weight), so ``ds`` is dimensionless.
    The tangent at each new point solves ``[[K, ∂r/∂λ], [W t_prevᵀ]]·t = (0, 1)`` (oriented
    along the previous tangent), which passes folds.  The step grows by 1.5 after an easy
    corrector (≤ 3 iterations) and is halved after a failed one.
Critical points
    Between consecutive points a change of the sign of det K (the product of the signs of the
    sparse LU's diagonal and of its row and column permutations) marks a fold or a bifurcation.
    The critical load is located by a safeguarded secant (Illinois) iteration on the eigenvalue
    of smallest magnitude of the symmetric part of K (``eigsh`` with ``sigma = 0``), along the
    arclength from the last point before the crossing.  A critical point whose neighbouring
    tangents have load components of opposite sign is a fold; otherwise a bifurcation.
Branch switching
    At the first bifurcation the path leaves along the null vector φ of K (the eigenvector of
    the eigenvalue nearest zero): predictor ``x_c + Δs·(φ, 0)``, corrector orthogonal to it.
Pins
    ``pins`` holds spatial position components of chosen end nodes at their initial values (a
    pinned end: position held, rotation free; a roller: one component held) by Lagrange
    multipliers — spatial reaction forces added at the node as dead point loads — without a new
    boundary kind: give such ends as :class:`cartan.Free` in the problem.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from .problem import InitialState, Problem, dead_to_body
from .statics import ConvergenceError, _colouring, _initial_phi, _stencil_pairs

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


class _System:
    """Residual, Jacobian and bookkeeping of one problem (lattice scheme, affine groups for pins)."""

    def __init__(self, problem: Problem, pins: dict | None, fd_step: float, t: float):
        from .schemes.lattice import Lattice

        self.sch = sch = Lattice(problem, track_frames=True)
        self.g = g = sch.group
        self.shape = shape = sch.grid.shape
        self.r_dim = r_dim = g.dim
        self.nnode = nnode = int(np.prod(shape))
        self.fd_step = fd_step
        self.t = float(t)
        unknown = np.broadcast_to(sch.live, (*shape, r_dim)).copy()
        unknown[sch._clamped] = False
        self.unknown = unknown
        self.unknown_flat = unknown.reshape(nnode, r_dim)
        self.index = -np.ones((nnode, r_dim), dtype=np.int64)
        self.nunk = int(unknown.sum())
        self.index[self.unknown_flat] = np.arange(self.nunk)
        self.w = sch.weights[..., None]
        self.zero = np.zeros((*shape, r_dim))
        self.colour = _colouring(shape, tuple(sch.grid.periodic))
        self.src, self.dst = _stencil_pairs(shape, tuple(sch.grid.periodic))
        self.length = max(1.0, float(np.max(sch.grid.length)))
        # pins: (flat node, spatial component)
        self.pins: list[tuple[int, int]] = []
        for where, comps in (pins or {}).items():
            node = self._node(where)
            for k in np.atleast_1d(comps):
                self.pins.append((node, int(k)))
        if self.pins and not getattr(g, "affine", False):
            raise ValueError("pins need a medium on an affine group (positions)")
        self.npin = len(self.pins)
        self.m = self.nunk + self.npin
        state = sch.initial_state()
        state.S[...] = 0.0
        state.t = self.t
        self.state0 = state
        self.x0 = np.array([self.positions(state)[n, k] for n, k in self.pins])

    def _node(self, where: Any) -> int:
        if isinstance(where, str):
            if self.sch.grid.d != 1 or where not in ("start", "end"):
                raise ValueError(f"pins: unknown end {where!r} (use 'start', 'end' or a node index)")
            return 0 if where == "start" else self.nnode - 1
        idx = np.ravel_multi_index(np.atleast_1d(where), self.shape) if np.ndim(where) else int(where) % self.nnode
        return int(idx)

    def positions(self, state) -> np.ndarray:
        m = self.g.matrix_size
        return self.sch.frames(state).reshape(self.nnode, m, m)[:, 1:, 0]

    def _reaction_basis(self, state) -> list[np.ndarray]:
        """Body components (per pin) of a unit spatial force at the pinned node."""
        Phi = self.sch.frames(state).reshape(self.nnode, self.g.matrix_size, self.g.matrix_size)
        out = []
        for n, k in self.pins:
            P = np.zeros(self.r_dim)
            P[k] = 1.0
            out.append(dead_to_body(self.g, Phi[n], P))
        return out

    def parts(self, state) -> tuple[np.ndarray, np.ndarray]:
        """(internal, external) nodal forces on the unknowns (flat)."""
        total = self.sch.force(state, self.zero, state.t) * self.w
        internal = self.sch.internal_force(state)
        return internal[self.unknown], (total - internal)[self.unknown]

    def residual(self, state, mu: np.ndarray, lam: float) -> np.ndarray:
        internal, ext = self.parts(state)
        r = internal + lam * ext
        if self.npin:
            full = np.zeros((self.nnode, self.r_dim))
            for (n, _), b, m_ in zip(self.pins, self._reaction_basis(state), mu, strict=True):
                full[n] += m_ * b
            r = r + full[self.unknown_flat]
            c = np.array([self.positions(state)[n, k] for n, k in self.pins]) - self.x0
            r = np.concatenate([r, c])
        return r

    def dlam(self, state) -> np.ndarray:
        return np.concatenate([self.parts(state)[1], np.zeros(self.npin)])

    def jacobian(self, state, mu: np.ndarray, lam: float):
        import scipy.sparse as sp

        nnode, r_dim, h = self.nnode, self.r_dim, self.fd_step
        rows, cols, vals = [], [], []
        pin_nodes = np.array([n for n, _ in self.pins], dtype=np.int64)
        for c in range(int(self.colour.max()) + 1):
            nodes = self.colour == c
            sel = nodes[self.src]
            s_c, d_c = self.src[sel], self.dst[sel]
            for a in range(r_dim):
                pert = np.zeros((nnode, r_dim))
                pert[nodes & self.unknown_flat[:, a], a] = 1.0
                if not pert.any():
                    continue
                pert = pert.reshape(*self.shape, r_dim)
                plus, minus = state.copy(), state.copy()
                self.sch.drift(plus, h, pert)
                self.sch.drift(minus, -h, pert)
                diff = (self.residual(plus, mu, lam) - self.residual(minus, mu, lam)) / (2 * h)
                full = np.zeros((nnode, r_dim))
                full[self.unknown_flat] = diff[: self.nunk]
                col = self.index[s_c, a]
                ok = col >= 0
                rr = self.index[d_c[ok]]
                vv = full[d_c[ok]]
                cc = np.broadcast_to(col[ok, None], rr.shape)
                m = rr >= 0
                rows.append(rr[m])
                cols.append(cc[m])
                vals.append(vv[m])
                if self.npin:  # constraint rows: a pin depends on its own node only
                    hit = nodes[pin_nodes] & (self.index[pin_nodes, a] >= 0)
                    j = np.nonzero(hit)[0]
                    rows.append(self.nunk + j)
                    cols.append(self.index[pin_nodes[j], a])
                    vals.append(diff[self.nunk + j])
        for j, b in enumerate(self._reaction_basis(state) if self.npin else []):
            n = self.pins[j][0]
            idx = self.index[n]
            ok = idx >= 0
            rows.append(idx[ok])
            cols.append(np.full(int(ok.sum()), self.nunk + j))
            vals.append(b[ok])
        return sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                             shape=(self.m, self.m))

    def update(self, state, mu: np.ndarray, d: np.ndarray):
        """A new (state, μ) after the increment ``d`` (unknowns then multipliers)."""
        full = np.zeros((*self.shape, self.r_dim))
        full[self.unknown] = d[: self.nunk]
        new = state.copy()
        self.sch.drift(new, 1.0, full)
        return new, mu + d[self.nunk:]


def _log_det(K) -> tuple[int, float]:
    """(sign, log|det K|) from the sparse LU: the signs of U's diagonal and of the row and
    column permutations (L has a unit diagonal); (0, −inf) when K is singular."""
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
    return sign, float(np.sum(np.log(np.abs(d))))


def _eig_min(K, with_vector: bool = False):
    """Eigenvalue of smallest magnitude of the symmetric part of K (and its eigenvector)."""
    import scipy.sparse.linalg as spla

    S = (0.5 * (K + K.T)).tocsc()
    n = S.shape[0]
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


def continuation(
    problem: Problem,
    lam_max: float,
    ds0: float,
    *,
    monitor: Callable[[Any], float] | None = None,
    stops: Any = None,
    pins: dict | None = None,
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
        ``{end: components}`` spatial position components held at their initial values, end
        ``"start"``/``"end"`` (d = 1) or a node index; e.g. a pinned–pinned column along x:
        ``{"start": (0, 1), "end": (1,)}`` (the end slides along x).
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
    initial : optional
        Starting configuration, as for :func:`cartan.statics.solve_static`.
    t : float
        Time at which time-dependent loads are evaluated.

    Returns
    -------
    xarray.Dataset
        Along ``path``: ``load_factor`` λ, ``monitor``, ``eig_min`` (the eigenvalue of smallest
        magnitude of sym K), ``det_sign``, ``newton_iterations``, ``step`` (Δs), ``branch``
        (0 before the branch switch, 1 after), ``position`` (path, node, row) for affine
        groups, ``reaction`` (path, pin) when pinned.  Along ``critical``: ``critical_load``,
        ``critical_monitor``, ``critical_eig`` and ``critical_kind`` (``"fold"`` or
        ``"bifurcation"``).  Attributes ``wall_time`` and ``newton_iterations``.

    Raises
    ------
    ConvergenceError
        The step fell below ``ds_min`` or ``max_points`` was exceeded.
    """
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla
    import xarray as xr

    start = time.perf_counter()
    if lam_max <= 0 or ds0 <= 0:
        raise ValueError("lam_max and ds0 must be positive")
    init = _initial_phi(problem, initial)
    if init is not problem.initial:
        problem = Problem(problem.medium, problem.grid, InitialState(Phi=init.Phi, holonomy=problem.initial.holonomy),
                          problem.boundaries, problem.loads, problem.name)
    sysm = _System(problem, pins, fd_step, t)
    g = sysm.g
    affine = bool(getattr(g, "affine", False))
    lam_scale = float(lam_max if lam_scale is None else lam_scale)
    ds_min = ds0 / 1000.0 if ds_min is None else float(ds_min)
    ds_max = 10.0 * ds0 if ds_max is None else float(ds_max)
    m = sysm.m
    wv = np.concatenate([np.full(sysm.nunk, 1.0 / sysm.nnode), np.zeros(sysm.npin)])
    wl = 1.0 / lam_scale**2
    ext0 = sysm.dlam(sysm.state0)
    fref = float(np.max(np.abs(ext0[: sysm.nunk]), initial=0.0)) * lam_scale
    atol = tol * (fref if fref > 0 else 1.0)
    ctol = tol * sysm.length
    total_iters = 0
    msize = g.matrix_size

    def wnorm(u: np.ndarray, lam: float) -> float:
        return math.sqrt(float(np.sum(wv * u * u)) + wl * lam * lam)

    def small(r: np.ndarray) -> bool:
        return (float(np.max(np.abs(r[: sysm.nunk]), initial=0.0)) <= atol
                and float(np.max(np.abs(r[sysm.nunk:]), initial=0.0)) <= ctol)

    def bordered(K, f, tu, tl):
        B = sp.bmat([[K, sp.csc_matrix(f[:, None])], [sp.csr_matrix((wv * tu)[None, :]), np.array([[wl * tl]])]])
        with np.errstate(all="ignore"):
            return spla.splu(B.tocsc())

    def tangent(state, mu, lam, K, tu_prev, tl_prev):
        f = sysm.dlam(state)
        lu = bordered(K, f, tu_prev, tl_prev)
        rhs = np.zeros(m + 1)
        rhs[-1] = 1.0
        z = lu.solve(rhs)
        tu, tl = z[:m], z[m]
        nz = wnorm(tu, tl)
        tu, tl = tu / nz, tl / nz
        if float(np.sum(wv * tu * tu_prev)) + wl * tl * tl_prev < 0:
            tu, tl = -tu, -tl
        return tu, tl

    def correct(state, mu, lam, tu, tl, ds, lam_target=None):
        """Predictor–corrector from (state, μ, λ) along (tu, tl): (state, μ, λ, K, iterations) or None.
        With ``lam_target`` the corrector holds λ = lam_target instead of the arclength."""
        nonlocal total_iters
        acc = ds * tu.copy()
        st, mu_ = sysm.update(state, mu, acc)
        lam_ = lam + ds * tl if lam_target is None else float(lam_target)
        cu, cl = (tu, tl) if lam_target is None else (np.zeros(m), 1.0 / wl)
        for k in range(max_iter + 1):
            r = sysm.residual(st, mu_, lam_)
            if lam_target is None:
                gap = float(np.sum(wv * tu * acc)) + wl * tl * (lam_ - lam) - ds
            else:
                gap = lam_ - lam_target
            if not np.all(np.isfinite(r)):
                return None
            if k > 0 and small(r) and abs(gap) <= 1e-10 * max(abs(ds), 1e-300):
                K = sysm.jacobian(st, mu_, lam_)
                return st, mu_, lam_, K, k
            if k == max_iter:
                return None
            K = sysm.jacobian(st, mu_, lam_)
            try:
                lu = bordered(K, sysm.dlam(st), cu, cl)
                d = lu.solve(-np.concatenate([r, [gap]]))
            except RuntimeError:
                return None
            if not np.all(np.isfinite(d)):
                return None
            total_iters += 1
            st, mu_ = sysm.update(st, mu_, d[:m])
            acc = acc + d[:m]
            lam_ = lam_ + d[m]
        return None

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
    state, mu, lam = sysm.state0, np.zeros(sysm.npin), 0.0
    r = sysm.residual(state, mu, lam)
    K = sysm.jacobian(state, mu, lam)
    iters0 = 0
    while not small(r):  # settle the start (e.g. residual stresses) at λ = 0
        if iters0 >= max_iter:
            raise ConvergenceError("continuation: no equilibrium at λ = 0", iters0, float(np.linalg.norm(r)), [])
        with np.errstate(all="ignore"):
            d = spla.splu(K).solve(-r)
        state, mu = sysm.update(state, mu, d)
        r = sysm.residual(state, mu, lam)
        K = sysm.jacobian(state, mu, lam)
        iters0 += 1
    tu, tl = tangent(state, mu, lam, K, np.zeros(m), 1.0)
    points: list[dict[str, Any]] = []
    critical: list[dict[str, Any]] = []

    def record(state, mu, lam, K, iters, ds, branch):
        points.append({
            "load_factor": lam,
            "monitor": measure(state),
            "eig_min": _eig_min(K) if detect else np.nan,
            "det": _log_det(K) if detect else (0, 0.0),
            "newton_iterations": iters,
            "step": ds,
            "branch": branch,
            "position": sysm.positions(state).copy() if affine else None,
            "reaction": mu.copy(),
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
        if tl > 0:  # land exactly on the next stop (or lam_max) when this step would pass it
            nxt = next((x for x in targets if x > lam * (1 + 1e-12) + 1e-300), lam_max)
            if lam + step * tl >= nxt:
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
                eig, phi = _eig_min(cK, with_vector=True)
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
    ds_out.attrs.update(wall_time=float(wall), newton_iterations=int(total_iters),
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
        q = q_of(_log_det(K))
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
