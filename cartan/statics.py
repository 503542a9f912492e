"""Static equilibria: Newton's method on the group (``cartan.solve_static``).

An equilibrium solves ``D*Q + T = 0`` with the boundary conditions, i.e. the scheme's force
density ``W`` vanishes at ``N = 0``.  The unknowns are one Lie-algebra increment δ_i ∈ 𝔤 per
node (clamped nodes and gauge components excluded), applied on the group,

    Φ_i ← Φ_i exp(δ_i)        (the scheme's exact drift with τ = 1, N = δ),

so the iterates stay in G and the lattice edges stay exact (``G_e ← exp(−δ_i) G_e exp(δ_j)``).

Residual
    ``r = w·W`` (the generalised nodal forces, w the node weights) on the unknowns.
Jacobian
    Analytic when the medium provides one (:meth:`cartan.medium.Medium.static_jacobian`,
    ``∂r/∂δ`` over all node components, restricted here to the unknowns); otherwise coloured
    central finite differences of r along drift directions: the lattice force at a node
    depends only on the node and its neighbours along each axis, so perturbing every third
    node (per axis) in one component at once gives 3^d·r force-difference pairs per
    Jacobian, assembled as a sparse banded matrix.  Either is factorised by sparse LU.
Globalisation
    A backtracking line search halves the step until the residual norm decreases; the load
    can be applied in ``load_steps`` equal increments, each solved from the previous
    equilibrium (``r(λ) = F_int + λ·F_ext``).
Failure
    :class:`ConvergenceError` (a ``RuntimeError``) names the iteration count and the residual
    when the iteration limit is reached, the Jacobian is singular, or the line search finds
    no decrease (a singular or ill-posed problem, e.g. a free body under an unbalanced load).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from .problem import InitialState, Problem

__all__ = ["ConvergenceError", "solve_static"]


class ConvergenceError(RuntimeError):
    """Newton's method did not reach an equilibrium.

    Attributes
    ----------
    iterations : int
        Newton iterations done (over all load steps).
    residual : float
        The last residual norm ‖r‖₂.
    history : list of float
        The residual norm at every iteration.
    """

    def __init__(self, message: str, iterations: int, residual: float, history: list[float]):
        super().__init__(message)
        self.iterations = iterations
        self.residual = residual
        self.history = list(history)


class _Static:
    """Stands in for an integrator in :func:`cartan.io.frame_record` (N = 0, S = 0)."""

    uses_momentum = True
    name = "newton"


def _colouring(shape: tuple[int, ...], periodic: tuple[bool, ...]) -> np.ndarray:
    """Colour per node (flat) such that nodes of one colour have disjoint stencils
    (the node and its ±1 neighbours along every axis)."""
    per_axis = []
    for n, p in zip(shape, periodic, strict=True):
        c = np.arange(n) % 3
        if p and n % 3:
            # the last n mod 3 nodes would sit next to colour 0 across the seam: own colours
            c[n - n % 3:] = 3 + np.arange(n % 3)
        per_axis.append(c)
    ncol = [int(c.max()) + 1 for c in per_axis]
    grids = np.meshgrid(*per_axis, indexing="ij")
    colour = np.zeros(shape, dtype=np.int64)
    for c, m in zip(grids, ncol, strict=True):
        colour = colour * m + c
    return colour.ravel()


def _stencil_pairs(shape: tuple[int, ...], periodic: tuple[bool, ...]) -> tuple[np.ndarray, np.ndarray]:
    """(source, target) flat node pairs: target in the stencil of source (self included)."""
    idx = np.arange(int(np.prod(shape))).reshape(shape)
    src, dst = [idx.ravel()], [idx.ravel()]
    for axis, (n, p) in enumerate(zip(shape, periodic, strict=True)):
        for step in (-1, 1):
            if p:
                nb = np.roll(idx, -step, axis=axis)
                src.append(idx.ravel())
                dst.append(nb.ravel())
            else:
                sl_src = [slice(None)] * len(shape)
                sl_dst = [slice(None)] * len(shape)
                sl_src[axis] = slice(max(0, -step), n - max(0, step))
                sl_dst[axis] = slice(max(0, step), n - max(0, -step))
                src.append(idx[tuple(sl_src)].ravel())
                dst.append(idx[tuple(sl_dst)].ravel())
    pairs = np.unique(np.stack([np.concatenate(src), np.concatenate(dst)], axis=1), axis=0)
    return pairs[:, 0], pairs[:, 1]


def _coloured_jacobian(displaced, colour: np.ndarray, src: np.ndarray, dst: np.ndarray, unknown: np.ndarray,
                       index: np.ndarray, shape: tuple[int, ...], step: float):
    """Sparse Jacobian of a nodal residual by coloured central finite differences.

    Parameters
    ----------
    displaced : callable ``(direction, eps) -> residual``
        The residual ``[*shape, r]`` at the point displaced by ``eps`` along ``direction``
        ``[*shape, r]`` (e.g. the scheme's drift by ``eps·direction``, or ``x + eps·direction``).
    colour : array ``(nnode,)``
        :func:`_colouring` (nodes of one colour have disjoint stencils).
    src, dst : arrays ``(npairs,)``
        :func:`_stencil_pairs`: node ``dst`` is in the stencil of node ``src``.
    unknown : bool array ``(nnode, r)``
        The unknowns (other residual entries and directions are left out).
    index : int array ``(nnode, r)``
        Position of each unknown in the unknown vector (−1 elsewhere).
    shape : tuple of int
        Node shape of the grid.
    step : float
        Finite-difference step ``eps``.

    Returns
    -------
    scipy.sparse.csc_matrix, shape ``(nunk, nunk)``
        ``J[i, j] = ∂r_i/∂x_j``: 2 residual evaluations per colour and component.
    """
    import scipy.sparse as sp

    nnode, r_dim = unknown.shape
    nunk = int(unknown.sum())
    rows, cols, vals = [], [], []
    for c in range(int(colour.max()) + 1):
        nodes = colour == c
        sel = nodes[src]
        s_c, d_c = src[sel], dst[sel]
        for a in range(r_dim):
            pert = np.zeros((nnode, r_dim))
            pert[nodes & unknown[:, a], a] = 1.0
            if not pert.any():
                continue
            pert = pert.reshape(*shape, r_dim)
            diff = ((displaced(pert, step) - displaced(pert, -step)) / (2 * step)).reshape(nnode, r_dim)
            col = index[s_c, a]
            ok = col >= 0
            rr = index[d_c[ok]]  # [pairs, r]
            vv = diff[d_c[ok]]
            cc = np.broadcast_to(col[ok, None], rr.shape)
            m = rr >= 0
            rows.append(rr[m])
            cols.append(cc[m])
            vals.append(vv[m])
    if not rows:
        return sp.csc_matrix((nunk, nunk))
    return sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(nunk, nunk))


_JACOBIANS = ("auto", "analytic", "fd")


def _analytic_jacobian(medium, scheme, state, lam: float, cols: np.ndarray, size: int):
    """The medium's :meth:`~cartan.medium.Medium.static_jacobian` restricted to the unknowns.

    Parameters
    ----------
    cols : int array ``(nunk,)``
        Flat positions ``node·r + k`` of the unknowns, in the order of the unknown vector.
    size : int
        ``nnode·r``, the side of the medium's matrix.

    Returns
    -------
    scipy.sparse.csc_matrix, shape ``(nunk, nunk)``, or None when the medium has none.
    """
    import scipy.sparse as sp

    J = medium.static_jacobian(scheme, state, float(lam))
    if J is None:
        return None
    J = sp.csr_matrix(J)
    if J.shape != (size, size):
        raise ValueError(f"jacobian: {type(medium).__name__}.static_jacobian must return a ({size}, {size}) matrix "
                         f"(nnode·r), got shape {J.shape}")
    return J[cols][:, cols].tocsc()


def _initial_phi(problem: Problem, initial: Any) -> InitialState:
    g = problem.medium.group
    if initial is None:
        return problem.initial
    if isinstance(initial, InitialState):
        return initial
    if hasattr(initial, "data_vars"):  # a Dataset from solve_static or simulate: its last frame
        if not getattr(g, "affine", False) or "position" not in initial or "frame" not in initial:
            raise ValueError("initial: a Dataset can seed only media on affine groups (position and frame)")
        pos = np.asarray(initial["position"].isel(time=-1))
        frame = np.asarray(initial["frame"].isel(time=-1))
        m = g.matrix_size
        Phi = np.zeros((*pos.shape[:-1], m, m))
        Phi[..., 0, 0] = 1.0
        Phi[..., 1:, 0] = pos
        Phi[..., 1:, 1:] = frame
        return InitialState(Phi=Phi)
    return InitialState(Phi=np.asarray(initial, dtype=float))


def solve_static(
    problem: Problem,
    scheme: str = "lattice",
    tol: float = 1e-10,
    max_iter: int = 50,
    initial: Any = None,
    jacobian: str = "auto",
    *,
    xtol: float = 1e-12,
    load_steps: int = 1,
    fd_step: float = 1e-6,
    max_halvings: int = 20,
    t: float = 0.0,
):
    """An equilibrium of ``problem`` by Newton's method on the group.

    Parameters
    ----------
    problem : Problem
        Medium, grid, boundaries and loads; ``problem.initial.Phi`` is the starting guess
        (velocities are ignored).
    scheme : str
        ``"lattice"`` (the only scheme supported).
    tol : float
        Converged when ``‖r‖_∞ ≤ tol·f``, f the largest external nodal force at the start of
        the load step (or of the first residual when there is none).
    max_iter : int
        Newton iterations allowed per load step.
    initial : None, InitialState, array ``[*shape, m, m]`` or Dataset
        Starting configuration instead of ``problem.initial`` (a Dataset: its last frame,
        for media on affine groups — e.g. a previous :func:`solve_static` result).
    jacobian : str
        ``"auto"`` (default): the medium's analytic Jacobian
        (:meth:`~cartan.medium.Medium.static_jacobian`) when it returns one for this
        problem, coloured central finite differences otherwise; ``"analytic"``: the
        medium's, a ``ValueError`` when it has none; ``"fd"``: finite differences.
    xtol : float
        Also converged when the Newton increment satisfies ``‖δ‖_∞ ≤ xtol·max(1, L)``
        (L the largest grid length), i.e. at the round-off floor of the residual.
    load_steps : int
        Apply the external loads in this many equal increments, each solved from the
        previous equilibrium.
    fd_step : float
        Finite-difference step along the drift directions.
    max_halvings : int
        Line-search halvings before declaring stagnation.
    t : float
        Time at which time-dependent loads are evaluated.

    Returns
    -------
    xarray.Dataset
        One frame (``time`` of length 1) with the usual run variables (position, frame, X,
        energies, residuals) plus ``newton_residual`` and ``load_factor`` along ``iteration``;
        attributes ``newton_iterations``, ``newton_wall_time`` and ``newton_jacobian``
        (``"analytic"`` or ``"fd"``, the Jacobian used).

    Raises
    ------
    ValueError
        Bad options; ``jacobian="analytic"`` for a medium without an analytic Jacobian of
        this problem; a :meth:`~cartan.medium.Medium.static_jacobian` of the wrong shape.
    ConvergenceError
        No equilibrium was found (see the module docstring).
    """
    import scipy.sparse.linalg as spla

    from . import io
    from .schemes.lattice import Lattice

    if scheme != "lattice":
        raise ValueError(f"solve_static supports scheme='lattice' only, got {scheme!r}")
    if jacobian not in _JACOBIANS:
        raise ValueError(f"jacobian must be one of {', '.join(map(repr, _JACOBIANS))}, got {jacobian!r}")
    if int(load_steps) < 1:
        raise ValueError(f"load_steps must be ≥ 1, got {load_steps!r}")
    start = time.perf_counter()
    init = _initial_phi(problem, initial)
    if init is not problem.initial:
        problem = Problem(problem.medium, problem.grid, InitialState(Phi=init.Phi, holonomy=problem.initial.holonomy),
                          problem.boundaries, problem.loads, problem.name)
    sch = Lattice(problem, track_frames=True)
    state = sch.initial_state()
    state.S[...] = 0.0
    state.t = float(t)
    g = sch.group
    shape = sch.grid.shape
    r_dim = g.dim
    nnode = int(np.prod(shape))
    zero = np.zeros((*shape, r_dim))
    unknown = np.broadcast_to(sch.live, (*shape, r_dim)).copy()
    unknown[sch._clamped] = False
    unknown_flat = unknown.reshape(nnode, r_dim)
    index = -np.ones((nnode, r_dim), dtype=np.int64)
    nunk = int(unknown.sum())
    index[unknown_flat] = np.arange(nunk)
    w = sch.weights[..., None]
    length = max(1.0, float(np.max(sch.grid.length)))
    colour = _colouring(shape, tuple(sch.grid.periodic))
    src, dst = _stencil_pairs(shape, tuple(sch.grid.periodic))

    def parts(st) -> tuple[np.ndarray, np.ndarray]:
        """(internal, total) nodal forces, zero off the unknowns."""
        total = sch.force(st, zero, st.t) * w
        internal = sch.internal_force(st)
        internal[~unknown] = 0.0
        total[~unknown] = 0.0
        return internal, total

    def residual(st, lam: float) -> np.ndarray:
        internal, total = parts(st)
        return total if lam == 1.0 else internal + lam * (total - internal)

    unknown_cols = np.flatnonzero(unknown_flat.ravel())  # flat node·r + k of each unknown, in index order
    medium = problem.medium
    # the analytic Jacobian is probed once, at the starting configuration and first load factor;
    # the probe's matrix serves as the first Newton Jacobian
    probe = None
    if jacobian != "fd":
        probe = _analytic_jacobian(medium, sch, state, 1.0 / int(load_steps), unknown_cols, nnode * r_dim)
        if probe is None and jacobian == "analytic":
            raise ValueError(
                f"jacobian='analytic': medium {medium.name!r} provides no analytic Jacobian for this problem "
                "(Medium.static_jacobian returned None); use jacobian='auto' or 'fd'"
            )
    used = "analytic" if probe is not None else "fd"
    first = [(state, 1.0 / int(load_steps), probe)] if probe is not None else []

    def assemble(st, lam: float):
        if used == "analytic":
            if first and first[0][0] is st and first[0][1] == lam:
                return first.pop()[2]
            first.clear()
            J = _analytic_jacobian(medium, sch, st, lam, unknown_cols, nnode * r_dim)
            if J is None:
                raise ValueError(f"jacobian: medium {medium.name!r} returned an analytic Jacobian at the start "
                                 "but None later; Medium.static_jacobian must depend on the problem only")
            return J

        def displaced(direction: np.ndarray, eps: float) -> np.ndarray:
            trial = st.copy()
            sch.drift(trial, eps, direction)
            return residual(trial, lam)

        return _coloured_jacobian(displaced, colour, src, dst, unknown_flat, index, shape, fd_step)

    history: list[float] = []
    factors: list[float] = []
    alphas: list[float] = []
    iters = 0

    def fail(reason: str, rnorm: float) -> ConvergenceError:
        tail = ", ".join(f"{x:.3e}" for x in history[-6:])
        return ConvergenceError(
            f"solve_static: no equilibrium after {iters} Newton iteration(s), residual ‖r‖ = {rnorm:.3e}: "
            f"{reason} (last residuals: {tail})",
            iters,
            rnorm,
            history,
        )

    nsteps = int(load_steps)
    for step in range(1, nsteps + 1):
        lam = step / nsteps
        internal, total = parts(state)
        ext = float(np.max(np.abs(total - internal))) if nunk else 0.0
        r = internal + lam * (total - internal)
        scale = ext * lam if ext > 0 else float(np.max(np.abs(r), initial=0.0))
        atol = tol * scale if scale > 0 else tol
        k_step = 0
        while True:
            rnorm = float(np.linalg.norm(r[unknown]))
            history.append(rnorm)
            factors.append(lam)
            if not np.isfinite(rnorm):
                raise fail("the residual is not finite", rnorm)
            if nunk == 0 or float(np.max(np.abs(r[unknown]))) <= atol:
                break
            if k_step >= max_iter:
                raise fail(f"the iteration limit max_iter = {max_iter} was reached at load factor {lam:g}", rnorm)
            J = assemble(state, lam)
            try:
                with np.errstate(all="ignore"):
                    lu = spla.splu(J)
                    delta = lu.solve(-r[unknown])
            except RuntimeError as exc:
                raise fail(f"the Jacobian is singular ({exc}); the problem may be ill-posed, e.g. a free body "
                           "under an unbalanced load or without supports", rnorm) from None
            if not np.all(np.isfinite(delta)):
                raise fail("the Jacobian is singular (non-finite Newton step); the problem may be ill-posed, "
                           "e.g. a free body under an unbalanced load", rnorm)
            full = np.zeros((*shape, r_dim))
            full[unknown] = delta
            step_norm = float(np.max(np.abs(delta)))
            alpha = 1.0
            accepted = False
            for _ in range(max_halvings + 1):
                trial = state.copy()
                sch.drift(trial, alpha, full)
                r_trial = residual(trial, lam)
                n_trial = float(np.linalg.norm(r_trial[unknown]))
                if np.isfinite(n_trial) and n_trial < rnorm:
                    accepted = True
                    break
                if np.isfinite(n_trial):
                    # affine-invariant (natural) monotonicity: the simplified Newton correction
                    # J⁻¹r(trial) shrinks, although stiff components may raise ‖r‖ for a step
                    with np.errstate(all="ignore"):
                        bar = float(np.max(np.abs(lu.solve(-r_trial[unknown]))))
                    if bar <= (1.0 - alpha / 4.0) * step_norm:
                        accepted = True
                        break
                alpha *= 0.5
            iters += 1
            k_step += 1
            alphas.append(alpha if accepted else 0.0)
            if not accepted:
                if step_norm <= 1e4 * xtol * length:
                    break  # at the round-off floor of the residual: the increment is negligible
                jn = spla.norm(J, 1)
                cond = jn * step_norm / max(float(np.max(np.abs(r[unknown]))), 1e-300)
                raise fail(
                    f"the residual stagnates: the line search found no decrease along the Newton step "
                    f"after {max_halvings} halvings (‖δ‖_∞ = {step_norm:.3e}, Jacobian condition ≳ {cond:.1e}); "
                    "the problem may be singular or ill-posed, e.g. a free body under an unbalanced load",
                    rnorm,
                )
            state = trial
            r = r_trial
            if alpha == 1.0 and step_norm <= xtol * length:
                history.append(n_trial)
                factors.append(lam)
                break
    wall = time.perf_counter() - start

    rec = io.frame_record(sch, _Static(), state)
    records = {k: [v] for k, v in rec.items()}
    config = {
        "problem": problem.to_dict(),
        "run": {
            "solver": "newton",
            "scheme": sch.name,
            "scheme_options": sch.options(),
            "tol": tol,
            "xtol": xtol,
            "max_iter": max_iter,
            "jacobian": jacobian,
            "fd_step": fd_step,
            "load_steps": nsteps,
            "t": float(t),
        },
        "counters": {"newton_iterations": iters, "wall_time": wall},
    }
    name = problem.name or problem.medium.name
    ds = io.build_dataset(
        sch,
        records,
        config=config,
        history=io.history_line(f"cartan.solve_static(problem {name!r}, scheme={scheme!r}, tol={tol!r})"),
        title=f"{name}: static equilibrium of {problem.medium.name} on {g.name}",
    )
    ds["newton_residual"] = (
        "iteration",
        np.asarray(history, dtype=float),
        {"long_name": "Newton residual norm ‖w·W‖₂ on the unknowns", "units": "force"},
    )
    ds["load_factor"] = (
        "iteration",
        np.asarray(factors, dtype=float),
        {"long_name": "fraction of the external load applied", "units": "1"},
    )
    ds["newton_step_length"] = (
        "newton_step",
        np.asarray(alphas, dtype=float),
        {"long_name": "line-search step length α of each Newton step (0: rejected)", "units": "1"},
    )
    ds.attrs["newton_iterations"] = int(iters)
    ds.attrs["newton_wall_time"] = float(wall)
    ds.attrs["newton_jacobian"] = used
    ds.attrs["newton_residual_final"] = float(history[-1]) if history else 0.0
    ds.attrs["newton_converged"] = 1
    return ds
