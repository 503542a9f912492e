"""Compiled step loop of the ``kinematic`` integrator (prescribed velocity, paper §III.B).

The ``kinematic`` integrator (:class:`cartan.integrators.explicit.Kinematic`) moves the
configuration by ``Φ̇ = ΦN`` with ``N = f(t, u, X)`` given by the user, by RKMK of order 1, 2
or 4.  When ``f`` is a numba-compiled function (``@numba.njit``), the steps between two
saves run here, in one compiled loop that calls ``f`` directly; any other callable runs on
the Python path (a Python function cannot be called from compiled code without a round trip
through the interpreter at every stage).

Design
------
* **One loop for both schemes.**  :func:`kinematic_loop` is the RKMK step of
  ``cartan.integrators.explicit._rkmk`` with ``dynamics=False``: stage ``i`` drifts a copy of
  the configuration by ``σ_i = Δt Σ_j a_ij k_j``, evaluates the nodal strains and
  ``N_i = f(t + c_iΔt, u, X)`` (zero at clamped nodes), and sets ``k_i = dexp⁻¹_{−σ_i}N_i``;
  the step drifts the configuration by ``Δt Σ b_i k_i``.  What differs between the schemes
  — copying the configuration, the exact drift, the nodal strains, the powers and the
  blow-up test — comes in as compiled functions (numba dispatchers passed as arguments):
  :data:`LATTICE_OPS` (edges ``G_α`` and frames, nodal strains the averages of the adjacent
  edges' ``log(G_e)/h_α``), :data:`COLLOCATION_OPS` and :data:`COLLOCATION_ND_OPS` (d = 1 and
  d ≥ 2: nodal strains and frames, the strains are the unknowns).  The configuration
  travels as the tuple ``cfg`` and a stage copy of it.
* **Same operations as the reference path**, in the same order: the RKMK sums from zero in
  the order of the stages, the powers of ``Integrator.step`` at the velocity ``f`` gives at
  the start and the end of each step (trapezoidal rule), the blow-up test of the integrators
  without momentum (a finite configuration).  The velocity at the end of a step is the
  first stage's velocity of the next (same ``t``, same state), evaluated once.
* **Compilation.**  The loop takes ``f`` as an argument, so numba compiles it once per
  process and velocity function (a few seconds; not cached on disk, since the type of the
  argument is the function itself).  The scheme operations it calls come from numba's cache.
"""

from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

from ..groups.se3 import TAYLOR_D, TAYLOR_E, _dexp_coeffs_direct
from ..groups.so3 import SMALL_THETA2, TAYLOR_C, TAYLOR_CINV, _cinv_direct, horner
from ._collocation_compiled import MODE_NONE, _dexp_inv_neg, _increment
from ._collocation_compiled import _drift as _colloc_drift
from ._collocation_compiled import _powers as _colloc_powers
from ._collocation_compiled import _unstable as _colloc_unstable
from ._collocation_compiled_nd import _drift as _nd_drift
from ._collocation_compiled_nd import _ends as _nd_ends
from ._collocation_compiled_nd import _scheme_powers as _nd_powers
from ._lattice_compiled import (
    CHUNK,
    VEL_NONE,
    _chunk_scratch,
    _exp_drift_nd,
    _fails,
    _node_pass,
    _rk_dexp_pass,
    advance_context,
    finish_advance,
)
from ._lattice_compiled_kernels import GID_SE3, _jit, _se3_log_at, g_log
from ._lattice_compiled_plan import (
    CHECK_CONFIGURATION,
    I_CLAMPED,
    I_D,
    I_ESTR,
    I_GID,
    I_HS,
    I_PERIODIC,
    I_SHAPE,
    I_W,
)

__all__ = ["COLLOCATION_ND_OPS", "COLLOCATION_OPS", "LATTICE_OPS", "OPS", "advance", "is_compiled_velocity",
           "kinematic_loop"]


def is_compiled_velocity(f) -> bool:
    """True when ``f`` is a numba-compiled function (a CPU dispatcher from ``numba.njit``),
    which :func:`kinematic_loop` can call."""
    from numba.core.registry import CPUDispatcher

    return isinstance(f, CPUDispatcher)


# ---------------------------------------------------------------------------- shared pieces
@_jit
def take_velocity(res, clamped, N):
    """``N ← f``'s result ``res`` (``[*shape, r]``, or ``[r]`` for every node), zero at clamped
    nodes (``Kinematic._N``)."""
    n, r = N.shape
    flat = np.ascontiguousarray(res).reshape(-1)
    if flat.shape[0] == n * r:
        for i in range(n):
            for k in range(r):
                N[i, k] = flat[i * r + k]
    elif flat.shape[0] == r:
        for i in range(n):
            for k in range(r):
                N[i, k] = flat[k]
    else:
        raise ValueError("kinematic: velocity(t, u, X) must return N of shape [*grid.shape, r] or [r]")
    for i in range(n):
        if clamped[i]:
            for k in range(r):
                N[i, k] = 0.0


@_jit
def _dexp_stage(P, sigma, Nst, ksig, st, scr):
    """``ksig[st, i] = dexp⁻¹(−σ_i) Nst_i`` per node (the RKMK slope): on SE(3) in closed form
    (``_dexp_inv_neg`` of the collocation loops), else the lattice's pass with the group's
    matrix kernel (``scr``: its per-chunk scratch)."""
    if P[I_GID] != GID_SE3:
        _rk_dexp_pass(P, sigma, Nst, ksig, st, scr)
        return
    for i in range(Nst.shape[0]):
        sg = (sigma[i, 0], sigma[i, 1], sigma[i, 2], sigma[i, 3], sigma[i, 4], sigma[i, 5])
        a = (Nst[i, 0], Nst[i, 1], Nst[i, 2], Nst[i, 3], Nst[i, 4], Nst[i, 5])
        t2 = sg[3] * sg[3] + sg[4] * sg[4] + sg[5] * sg[5]
        if t2 < SMALL_THETA2:
            o = _dexp_inv_neg(sg, horner(t2, TAYLOR_CINV), horner(t2, TAYLOR_C), horner(t2, TAYLOR_D),
                              horner(t2, TAYLOR_E), a)
        else:
            _, c, d, e = _dexp_coeffs_direct(t2)
            o = _dexp_inv_neg(sg, _cinv_direct(t2), c, d, e, a)
        for k in range(6):
            ksig[st, i, k] = o[k]


@njit(error_model="numpy")
def kinematic_loop(copy, drift, strains, powers, fails, velocity, P, cfg, stage, work, u, Xn, S, N, A, b, c, t, dt,
                   nsteps, dissipated, external, with_power):
    """``nsteps`` RKMK steps of tableau ``(A, b, c)`` with the prescribed velocity
    ``N = velocity(t, u, Xn)`` (``Xn [*shape, d, r]`` the nodal strains, refreshed before each
    call; ``u [*shape, d]`` the node coordinates).

    ``copy(P, cfg, stage)``, ``drift(P, cfg, sigma, work)`` (``cfg ← cfg·exp(σ)``),
    ``strains(P, cfg, X3, work)`` (nodal strains ``[n, d, r]``), ``powers(P, cfg, N, S, work)``
    (dissipated and external power) and ``fails(P, cfg, S, work)`` (a non-finite
    configuration) are the scheme's operations.  ``N [n, r]`` is work space (the velocity at
    the current state).  Returns ``(steps done, t, dissipated, external)``.
    """
    clamped = P[I_CLAMPED]
    n, r = S.shape
    s = b.shape[0]
    X3 = Xn.reshape(n, Xn.size // (n * r), r)
    ksig = np.empty((s, n, r))
    sigma = np.empty((n, r))
    Nst = np.empty((n, r))
    scr = _chunk_scratch((n + CHUNK - 1) // CHUNK, r, 1, 0)
    strains(P, cfg, X3, work)
    take_velocity(velocity(t, u, Xn), clamped, N)
    p0d, p0e = powers(P, cfg, N, S, work) if with_power else (0.0, 0.0)
    done = 0
    for step in range(nsteps):
        for st in range(s):
            moved = _increment(ksig, A[st], st, dt, sigma)
            if st == 0 and not moved:
                Nst[:] = N  # the state itself at t + c₀Δt = t: the velocity already in hand
            else:
                copy(P, cfg, stage)
                if moved:
                    drift(P, stage, sigma, work)
                strains(P, stage, X3, work)
                take_velocity(velocity(t + c[st] * dt, u, Xn), clamped, Nst)
            if moved:
                _dexp_stage(P, sigma, Nst, ksig, st, scr)
            else:
                ksig[st] = Nst  # dexp⁻¹(0) = I
        _increment(ksig, b, s, dt, sigma)
        drift(P, cfg, sigma, work)
        t = t + dt
        done += 1
        if with_power or step + 1 < nsteps:
            strains(P, cfg, X3, work)
            take_velocity(velocity(t, u, Xn), clamped, N)
        if with_power:
            p1d, p1e = powers(P, cfg, N, S, work)
            dissipated = dissipated + 0.5 * dt * (p0d + p1d)
            external = external + 0.5 * dt * (p0e + p1e)
            p0d, p0e = p1d, p1e
        if fails(P, cfg, S, work):
            break
    return done, t, dissipated, external


# ---------------------------------------------------------------------------- lattice operations
# cfg = (Gs, Phi): the edges of each axis [ne_α, m, m] and the frames [n or 1, m, m];
# work = (D, OUT, INC, PART, scr, W, E, inv): the lattice passes' work arrays, a force and an
# edge-strain buffer [max ne_α, r]
@_jit
def _lattice_copy(P, cfg, stage):
    for a in range(len(cfg[0])):
        stage[0][a][:] = cfg[0][a]
    stage[1][:] = cfg[1]


@_jit
def _lattice_drift(P, cfg, sigma, work):
    D, OUT, INC, PART, scr, W, E, inv = work
    _exp_drift_nd(P, cfg[0], cfg[1], sigma, 1.0, D, OUT, INC, scr)


@_jit
def _lattice_strains(P, cfg, X3, work):
    """``Lattice.nodal_strains``: per axis, the mean of the strains ``log(G_e)/h_α`` of the edges
    out of and into each node (the one edge at the ends of an open axis)."""
    Gs = cfg[0]
    E = work[-2]
    gid = P[I_GID]
    d = P[I_D]
    shp = P[I_SHAPE]
    per = P[I_PERIODIC]
    estr = P[I_ESTR]
    hs = P[I_HS]
    n, _, r = X3.shape
    for a in range(d):
        G = Gs[a]
        for e in range(G.shape[0]):
            if gid == GID_SE3:
                x = _se3_log_at(G, e)
                for k in range(6):
                    E[e, k] = x[k] / hs[a]
            else:
                g_log(gid, G[e], E[e])
                for k in range(r):
                    E[e, k] = E[e, k] / hs[a]
        na = shp[a]
        sa = estr[a, a]
        for i in range(n):
            i2 = i % shp[2]
            i1 = (i // shp[2]) % shp[1]
            i0 = i // (shp[1] * shp[2])
            ia = i0 if a == 0 else (i1 if a == 1 else i2)
            base = i0 * estr[a, 0] + i1 * estr[a, 1] + i2 * estr[a, 2] - ia * sa
            eo = base + ia * sa
            ei = base + ((ia - 1) % na) * sa
            if per[a] or 0 < ia < na - 1:
                for k in range(r):
                    X3[i, a, k] = 0.5 * (E[eo, k] + E[ei, k])
            elif ia == 0:
                for k in range(r):
                    X3[i, a, k] = E[eo, k]
            else:
                for k in range(r):
                    X3[i, a, k] = E[ei, k]


@_jit
def _lattice_powers(P, cfg, N, S, work):
    D, OUT, INC, PART, scr, W, E, inv = work
    pd, pe, _, _ = _node_pass(P, OUT, INC, cfg[1], S, N, W, inv, 0.0, False, True, False, False, VEL_NONE, inv,
                              PART, scr)
    return pd, pe


@_jit
def _lattice_fails(P, cfg, S, work):
    D, OUT, INC, PART, scr, W, E, inv = work
    return _fails(P, CHECK_CONFIGURATION, math.inf, 0.0, 0.0, S, cfg[0], cfg[1], PART)


# ---------------------------------------------------------------------------- collocation operations
# cfg = (X [n, d·r], Phi [n or 1, m, m]); work = (Dc, S0, W, DN, D, scr, inv): the derivative
# operator, zero momentum, the force, derivative and exponential buffers, the helpers' scratch
# and 1/m (the d = 1 and the d ≥ 2 loops' layouts of Dc differ: two drifts and two powers)
@_jit
def _colloc_copy(P, cfg, stage):
    stage[0][:] = cfg[0]
    stage[1][:] = cfg[1]


@_jit
def _colloc_drift_op(P, cfg, sigma, work):
    Dc, S0, W, DN, D, scr, inv = work
    _colloc_drift(P, Dc, cfg[0], cfg[1], S0, W, sigma, 1.0, DN, D, scr, MODE_NONE)


@_jit
def _colloc_nd_drift_op(P, cfg, sigma, work):
    Dc, S0, W, DN, D, scr, inv = work
    _nd_drift(P, Dc, cfg[0], cfg[1], S0, W, sigma, 1.0, DN, D, scr, MODE_NONE)


@_jit
def _colloc_strains(P, cfg, X3, work):
    X = cfg[0]
    n, d, r = X3.shape
    for i in range(n):
        for a in range(d):
            for k in range(r):
                X3[i, a, k] = X[i, a * r + k]


@_jit
def _colloc_powers_op(P, cfg, N, S, work):
    return _colloc_powers(P, N, cfg[1], work[5])


@_jit
def _colloc_nd_powers_op(P, cfg, N, S, work):
    return _nd_powers(P, _nd_ends(work[0]), N, cfg[1], work[5])


@_jit
def _colloc_fails(P, cfg, S, work):
    return _colloc_unstable(CHECK_CONFIGURATION, math.inf, S, cfg[0], cfg[1], P[I_W], work[-1])


#: the scheme operations of :func:`kinematic_loop` (copy, drift, strains, powers, fails)
LATTICE_OPS = (_lattice_copy, _lattice_drift, _lattice_strains, _lattice_powers, _lattice_fails)
COLLOCATION_OPS = (_colloc_copy, _colloc_drift_op, _colloc_strains, _colloc_powers_op, _colloc_fails)
COLLOCATION_ND_OPS = (_colloc_copy, _colloc_nd_drift_op, _colloc_strains, _colloc_nd_powers_op, _colloc_fails)
OPS = {"lattice": LATTICE_OPS, "collocation": COLLOCATION_OPS, "collocation-nd": COLLOCATION_ND_OPS}


# ---------------------------------------------------------------------------- entry point
def _coordinates(scheme, cache: dict) -> np.ndarray:
    """Node coordinates ``u [*shape, d]`` (as ``Kinematic._N`` builds them), kept in ``cache``."""
    u = cache.get("kinematic_u")
    if u is None:
        grid = scheme.grid
        u = np.stack(np.meshgrid(*[grid.coordinates(a) for a in range(grid.d)], indexing="ij"), axis=-1)
        u = cache["kinematic_u"] = np.ascontiguousarray(u, dtype=float)
    return u


def advance(scheme, kind: str, P: tuple, cfg: tuple, work_of, integrator, state, dt: float, nsteps: int,
            kinetic_limit: float) -> bool:
    """Run up to ``nsteps`` steps of the ``kinematic`` ``integrator`` in compiled code; False,
    touching nothing, when its velocity is not a numba-compiled function.

    Parameters
    ----------
    scheme : Lattice or Collocation
    kind : {"lattice", "collocation", "collocation-nd"}
        Which operations (:data:`OPS`: the lattice, collocation d = 1, collocation d ≥ 2).
    P : tuple
        The scheme's compiled plan (lattice layout ``I_*``).
    cfg : tuple
        The state's configuration arrays, writable and updated in place: ``(Gs, Phi)`` on the
        lattice, ``(X [n, d·r], Phi)`` for collocation.
    work_of : callable
        ``work_of(inv) -> tuple``: the scheme's work arrays for the operations.
    integrator : Kinematic
    state : State
    dt : float
    nsteps : int
    kinetic_limit : float
        Unused (no momentum); the loop stops after a step that leaves a non-finite
        configuration.
    """
    from ..compiled.tableaux import TABLEAUX as _TABLEAUX

    if not is_compiled_velocity(integrator.velocity_field):
        return False
    nsteps = int(nsteps)
    if nsteps <= 0:
        return True
    t_start = time.perf_counter()
    nstep0, _, t0, diss, ext, _, _, cache, inv = advance_context(scheme, integrator, state, kinetic_limit)
    n, r = scheme.grid.size, scheme.group.dim
    u = _coordinates(scheme, cache)
    Xn = np.empty((*scheme.grid.shape, scheme.grid.d, r))
    stage = tuple(tuple(np.empty_like(g) for g in a) if isinstance(a, tuple) else np.empty_like(a) for a in cfg)
    A, b, c = (np.ascontiguousarray(x, dtype=float) for x in _TABLEAUX[integrator.order])
    S = np.ascontiguousarray(state.S, dtype=float).reshape(n, r)
    ops = OPS[kind]
    done, t, diss, ext = kinematic_loop(*ops, integrator.velocity_field, P, cfg, stage, work_of(inv), u, Xn, S,
                                        np.empty((n, r)), A, b, c, t0, float(dt), nsteps, diss, ext,
                                        bool(scheme.has_external_power()))
    return finish_advance(integrator, state, t, diss, ext, nstep0, done, 0, None, t_start)
