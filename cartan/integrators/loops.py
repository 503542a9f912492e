"""The compiled step loops: one per integrator family, written once, general in scheme and d.

Each loop is plain Python compiled inside a generated module (:mod:`cartan.compiled.codegen`)
next to a scheme's operator set (``op_*``, :mod:`cartan.compiled.operators`) and the group's
point kernels (``g_*``); it takes the steps exactly as the integrator's ``_step`` takes them
in Python (same formulas, round-off apart), books the loads' powers by the trapezoidal rule
like :meth:`cartan.integrators.base.Integrator.step`, and stops after the first step whose
momentum (``check = 1``; configuration for ``check = 2``) is not finite or whose kinetic
energy exceeds ``limit``.

Every loop returns ``(done, nforce, t, dissipated, external)``.

The loops of ``lie-euler``/``forward-euler`` and ``rkmk4`` take the velocity and the force of a
state through :func:`op_state_velocity` and :func:`op_state_force`, which receive both the
configuration and the momentum: ``op_velocity`` and ``op_force`` here, rebound by a set whose
Lagrangian couples N and X (docs/design.md, the compiled layer, "Coupled Lagrangians").

The loops of ``lie-verlet``, ``lie-euler``/``forward-euler`` and ``rkmk4`` (with momentum) call
:func:`op_accumulate` with the velocity of the state at their start and after every step: a
no-op here, rebound by a set that integrates a medium's per-node accumulators
(:mod:`cartan.accumulators`, :func:`cartan.schemes._lattice_ops.accumulate_fragment`).

The loops of ``lie-verlet`` and ``lie-euler``/``forward-euler`` begin with ``D = unmanaged_(D)``
(:mod:`cartan.compiled.unmanaged`): the operators they call receive the data's arrays without
reference counts, which numba otherwise takes per array at every call (docs/performance.md,
"Generated loops"); ``rkmk_loop`` measured slower with it and keeps the counted data.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..compiled.codegen import Fragment, njit_source

__all__ = ["kinematic_fragment", "loop_fragment"]

# names the loops read from the generated module (the scheme's operators, the group's kernels)
# noqa comments below mark them for the linter.


def op_drive(D, N):
    """N ← ξ at the driven nodes (:class:`~cartan.problem.Driven` ends): nothing here; an
    operator set with driven nodes rebinds it after the loops (``OperatorSet.late``,
    :func:`cartan.schemes._lattice_ops.driven_fragment`), with the velocity and constraint
    operators, which then give ξ and ∂K/∂N(ξ) there themselves."""
    return


def op_state_velocity(D, C, S, N, K):
    """N of the state (C, S): ``op_velocity(D, S, N)`` here, the configuration unused.  A set
    whose Legendre map depends on the strain (a Lagrangian coupling N and X) rebinds it after
    the loops (``OperatorSet.late``, :func:`cartan.schemes._lattice_ops.coupled_fragment`);
    the loops of ``lie-euler``, ``forward-euler`` and ``rkmk4`` call it."""
    op_velocity(D, S, N)  # noqa: F821


def op_state_force(D, C, S, t, N, W, K):
    """The force W at the state (C, S) and velocity N: ``op_force(D, C, t, N, W, K)`` here, the
    momentum unused (rebound with :func:`op_state_velocity` where the stress depends on S)."""
    op_force(D, C, t, N, W, K)  # noqa: F821


def op_accumulate(D, C, S, N, dt, begin):
    """The per-node accumulators' trapezoidal update at the state (C, S) of velocity N: nothing
    here.  A set that integrates them (``OperatorSet.accumulates``) rebinds it after the loops
    (``OperatorSet.late``): with ``begin`` it keeps the rates of the loop's first state, else it
    adds ``½Δt (r(before) + r(after))`` and keeps the new rates (:func:`cartan.accumulators.add`)."""
    return


def _coad_exp(D, tau, N, S):
    """S_i ← Ad_{exp(τN_i)}ᵀ S_i at every node (the free flow of frozen N)."""
    xi = np.empty(R_)  # noqa: F821
    E = np.empty((M_, M_))  # noqa: F821
    wk = g_work()  # noqa: F821
    for i in range(S.shape[0]):
        for k in range(R_):  # noqa: F821
            xi[k] = tau * N[i, k]
        g_coad_exp(xi, S[i], E, wk)  # noqa: F821


def _blown(D, C, S, check, limit):
    """The blow-up test after a step (see the module docstring)."""
    if check == 1:
        for i in range(S.shape[0]):
            for k in range(R_):  # noqa: F821
                if not np.isfinite(S[i, k]):
                    return True
        e = op_kinetic(D, S)  # noqa: F821
        return not (e <= limit)
    return not op_finite_config(C)  # noqa: F821


def _damped(D, W, N):
    """W ← W − ΓN at every node: the force at a new state from its velocity-free part W(N = 0)
    (the linear ``Damping`` of the closing kick)."""
    for i in range(W.shape[0]):
        for k in range(R_):  # noqa: F821
            W[i, k] -= D.damp[k] * N[i, k]


def _book(D, C, S, N, t, dt, p0d, p0e, diss, ext, K, check, limit):
    """After a step: the loads' powers at its end (velocity ``N``), their trapezoidal
    integrals, and the blow-up test; returns ``(p1d, p1e, dissipated, external, blown)``."""
    p1d, p1e = op_powers(D, C, N, t, K)  # noqa: F821
    return (p1d, p1e, diss + 0.5 * dt * (p0d + p1d), ext + 0.5 * dt * (p0e + p1e),
            _blown(D, C, S, check, limit))


def lie_verlet_loop(D, C, S, W, have_w, velocity_free, pieces, fracs, closing, t, dt, nsteps, diss, ext, check,
                    limit):
    """``lie-verlet``: half kick, exact free flow split into pieces (``pieces`` ``[P, r, r]``,
    ``fracs`` of Δt, palindromic), half kick; W carries the force between steps (FSAL).  With
    damping (not ``velocity_free``) the closing kick is implicit in the damping,
    ``S⁺ = closing·(S½ + ½Δt W(N = 0))`` with ``closing = (I + ½ΔtΓM⁺)⁻¹`` ``[r, r]``."""
    D = unmanaged_(D)  # noqa: F821 - its arrays without reference counts (cartan.compiled.unmanaged)
    K = op_work(D)  # noqa: F821
    n = S.shape[0]
    N = np.empty((n, R_))  # noqa: F821
    Dn = np.empty((n, M_, M_))  # noqa: F821
    rhs = np.empty(R_)  # noqa: F821
    nforce = 0
    op_velocity(D, S, N)  # noqa: F821
    op_accumulate(D, C, S, N, dt, True)
    p0d, p0e = op_powers(D, C, N, t, K)  # noqa: F821
    done = 0
    for _ in range(nsteps):
        if not (have_w and velocity_free):
            op_force(D, C, t, N, W, K)  # noqa: F821
            nforce += 1
        for i in range(n):
            for k in range(R_):  # noqa: F821
                S[i, k] += 0.5 * dt * W[i, k]
        op_constrain(D, S)  # noqa: F821
        op_free_flow(D, C, S, pieces, fracs, dt, Dn, K)  # noqa: F821
        op_constrain(D, S)  # noqa: F821
        t1 = t + dt
        if velocity_free:
            op_velocity(D, S, N)  # noqa: F821
            op_force(D, C, t1, N, W, K)  # noqa: F821
            for i in range(n):
                for k in range(R_):  # noqa: F821
                    S[i, k] += 0.5 * dt * W[i, k]
        else:
            N[:] = 0.0
            op_force(D, C, t1, N, W, K)  # noqa: F821
            for i in range(n):
                for k in range(R_):  # noqa: F821
                    rhs[k] = S[i, k] + 0.5 * dt * W[i, k]
                for k in range(R_):  # noqa: F821
                    v = 0.0
                    for j in range(R_):  # noqa: F821
                        v += closing[k, j] * rhs[j]
                    S[i, k] = v
        nforce += 1
        have_w = True
        op_constrain(D, S)  # noqa: F821
        op_velocity(D, S, N)  # noqa: F821
        if not velocity_free:
            _damped(D, W, N)
        op_accumulate(D, C, S, N, dt, False)
        t = t1
        done += 1
        p0d, p0e, diss, ext, blown = _book(D, C, S, N, t, dt, p0d, p0e, diss, ext, K, check, limit)
        if blown:
            break
    return done, nforce, t, diss, ext


def _lie_poisson(N, S, W, out):
    """``out_i = W_i + ad_{N_i}ᵀ S_i`` at every node: Ṡ of the momentum balance (paper §V)."""
    xi = np.empty(R_)  # noqa: F821
    A = np.empty((R_, R_))  # noqa: F821
    for i in range(S.shape[0]):
        for k in range(R_):  # noqa: F821
            xi[k] = N[i, k]
        g_ad(xi, A)  # noqa: F821
        for k in range(R_):  # noqa: F821
            v = W[i, k]
            for j in range(R_):  # noqa: F821
                v += A[j, k] * S[i, j]
            out[i, k] = v


def euler_loop(D, C, S, geometric, t, dt, nsteps, diss, ext, check, limit):
    """``lie-euler`` (``geometric``: S⁺ = Ad*_{exp ΔtN}S + 𝓔(Δt, N)ᵀW, exact drift) and
    ``forward-euler`` (S += Δt(ad_NᵀS + W), naive drift)."""
    D = unmanaged_(D)  # noqa: F821 - its arrays without reference counts (cartan.compiled.unmanaged)
    K = op_work(D)  # noqa: F821
    n = S.shape[0]
    N = np.empty((n, R_))  # noqa: F821
    W = np.empty((n, R_))  # noqa: F821
    Sdot = np.empty((n, R_))  # noqa: F821
    E = np.empty((R_, R_))  # noqa: F821
    xi = np.empty(R_)  # noqa: F821
    op_state_velocity(D, C, S, N, K)
    op_accumulate(D, C, S, N, dt, True)
    p0d, p0e = op_powers(D, C, N, t, K)  # noqa: F821
    done = 0
    for _ in range(nsteps):
        op_state_force(D, C, S, t, N, W, K)
        if geometric:
            _coad_exp(D, dt, N, S)
            for i in range(n):
                for k in range(R_):  # noqa: F821
                    xi[k] = N[i, k]
                g_E(dt, xi, E)  # noqa: F821
                for k in range(R_):  # noqa: F821
                    s = 0.0
                    for j in range(R_):  # noqa: F821
                        s += E[j, k] * W[i, j]
                    S[i, k] += s
            op_drift(D, C, dt, N, K)  # noqa: F821
        else:
            _lie_poisson(N, S, W, Sdot)
            for i in range(n):
                for k in range(R_):  # noqa: F821
                    S[i, k] += dt * Sdot[i, k]
            op_drift_naive(D, C, dt, N, K)  # noqa: F821
        op_constrain(D, S)  # noqa: F821
        t = t + dt
        op_state_velocity(D, C, S, N, K)
        op_accumulate(D, C, S, N, dt, False)
        done += 1
        p0d, p0e, diss, ext, blown = _book(D, C, S, N, t, dt, p0d, p0e, diss, ext, K, check, limit)
        if blown:
            break
    return done, done, t, diss, ext


def _kinematic_velocity(D, C, t, N):
    """The prescribed N = f(t, u, X) of ``kinematic`` (paper §III.B): ``k_velocity`` the user's
    kernel, u ``[*shape, d]`` the node coordinates, X ``[*shape, d, r]`` the nodal strains of C;
    f returns ``[*shape, r]`` (or ``[r]``, the same at every node); zero at clamped nodes."""
    n = N.shape[0]
    X = np.empty((n, D_, R_))  # noqa: F821
    op_nodal_strains(D, C, X)  # noqa: F821
    u = D.coords.reshape(D.shape + (D_,))  # noqa: F821
    res = k_velocity(t, u, X.reshape(D.shape + (D_, R_)))  # noqa: F821
    flat = np.ascontiguousarray(res).reshape(-1)
    if flat.shape[0] == n * R_:  # noqa: F821
        for i in range(n):
            for k in range(R_):  # noqa: F821
                N[i, k] = flat[i * R_ + k]  # noqa: F821
    elif flat.shape[0] == R_:  # noqa: F821
        for i in range(n):
            for k in range(R_):  # noqa: F821
                N[i, k] = flat[k]
    else:
        raise ValueError("kinematic: velocity(t, u, X) must return N of shape [*grid.shape, r] or [r]")
    if D.any_clamped:
        for i in range(n):
            if D.clamped[i]:
                for k in range(R_):  # noqa: F821
                    N[i, k] = 0.0


def _stage_velocity(D, C, S, t, mode, gam_inv, N, W, K):
    """N at a stage: from the momentum (``mode = 0``), the overdamped N = Γ⁻¹W(N = 0)
    (``mode = 1``) or the prescribed velocity of ``kinematic`` (``mode = 2``, in a module
    generated with the user's kernel, where ``KINEMATIC_`` is True; elsewhere the branch is
    compiled away); returns the number of force evaluations (0 or 1)."""
    if KINEMATIC_ and mode == 2:  # noqa: F821
        _kinematic_velocity(D, C, t, N)
        return 0
    if mode == 0:
        op_state_velocity(D, C, S, N, K)
        return 0
    n = N.shape[0]
    for i in range(n):
        for k in range(R_):  # noqa: F821
            N[i, k] = 0.0
    op_force(D, C, t, N, W, K)  # noqa: F821
    for i in range(n):
        zero = D.any_clamped and D.clamped[i]
        for k in range(R_):  # noqa: F821
            N[i, k] = 0.0 if zero else W[i, k] * gam_inv[k]
    op_drive(D, N)
    return 1


def rkmk_loop(D, C, S, A, b, c, dynamics, mode, gam_inv, N0, have, t, dt, nsteps, diss, ext, check, limit):
    """Explicit Runge–Kutta–Munthe-Kaas with the tableau ``(A, b, c)`` as data: ``rkmk4``
    (``dynamics``, N from S), ``overdamped`` (``mode = 1``: N = Γ⁻¹W(N = 0); order 1 is
    Lie–Euler, order 2 Heun) and ``kinematic`` (``mode = 2``: N = f(t, u, X) prescribed);
    Φ(t + s) = Φ(t) exp(σ(s)), σ̇ = dexp⁻¹_{−σ}N.

    Overdamped velocities cost a force each and are not recomputed where known: ``N0``
    ``[n, r]`` is the velocity of the initial state when ``have[0]`` (the integrator's cache),
    the velocity computed for the powers at the end of a step is the first stage's of the next,
    and on return ``N0``/``have`` hold the final state's velocity when it was computed."""
    K = op_work(D)  # noqa: F821
    n = S.shape[0]
    s_count = b.shape[0]
    ksig = np.zeros((s_count, n, R_))  # noqa: F821
    kS = np.zeros((s_count, n, R_))  # noqa: F821
    sigma = np.empty((n, R_))  # noqa: F821
    Sst = S.copy()
    N = np.empty((n, R_))  # noqa: F821
    W = np.empty((n, R_))  # noqa: F821
    wk = g_work()  # noqa: F821
    xi = np.empty(R_)  # noqa: F821
    row = np.empty(R_)  # noqa: F821
    Cst = op_new_config(C)  # noqa: F821
    nforce = 0
    known = mode == 1 and have[0] != 0  # N holds the velocity of (C, t)
    if known:
        N[:, :] = N0
    elif mode != 1 or D.has_power:
        nforce += _stage_velocity(D, C, S, t, mode, gam_inv, N, W, K)
        known = mode == 1
    else:
        N[:, :] = 0.0
    if mode == 0:
        op_accumulate(D, C, S, N, dt, True)
    p0d, p0e = op_powers(D, C, N, t, K)  # noqa: F821
    done = 0
    for _ in range(nsteps):
        for st in range(s_count):
            any_sigma = False
            for i in range(n):
                for k in range(R_):  # noqa: F821
                    v = 0.0
                    for j in range(st):
                        if A[st, j] != 0.0:
                            v += dt * A[st, j] * ksig[j, i, k]
                    sigma[i, k] = v
                    if v != 0.0:
                        any_sigma = True
                    if dynamics:
                        u = S[i, k]
                        for j in range(st):
                            if A[st, j] != 0.0:
                                u += dt * A[st, j] * kS[j, i, k]
                        Sst[i, k] = u
            op_copy_config(C, Cst)  # noqa: F821
            if any_sigma:
                op_drift(D, Cst, 1.0, sigma, K)  # noqa: F821
            ti = t + c[st] * dt
            if not (st == 0 and known):
                nforce += _stage_velocity(D, Cst, Sst, ti, mode, gam_inv, N, W, K)
            for i in range(n):
                for k in range(R_):  # noqa: F821
                    xi[k] = -sigma[i, k]
                    row[k] = N[i, k]
                g_dexp_inv_apply(xi, row, ksig[st, i], wk)  # noqa: F821
            if dynamics:
                op_state_force(D, Cst, Sst, ti, N, W, K)
                nforce += 1
                _lie_poisson(N, Sst, W, kS[st])
        for i in range(n):
            for k in range(R_):  # noqa: F821
                v = 0.0
                for st in range(s_count):
                    v += dt * b[st] * ksig[st, i, k]
                sigma[i, k] = v
        op_drift(D, C, 1.0, sigma, K)  # noqa: F821
        if dynamics:
            for i in range(n):
                for k in range(R_):  # noqa: F821
                    v = 0.0
                    for st in range(s_count):
                        v += dt * b[st] * kS[st, i, k]
                    S[i, k] += v
            op_constrain(D, S)  # noqa: F821
        t = t + dt
        known = False
        if mode == 0 or D.has_power:
            nforce += _stage_velocity(D, C, S, t, mode, gam_inv, N, W, K)
            known = mode == 1
        if mode == 0:
            op_accumulate(D, C, S, N, dt, False)
        done += 1
        p0d, p0e, diss, ext, blown = _book(D, C, S, N, t, dt, p0d, p0e, diss, ext, K, check, limit)
        if blown:
            break
    if mode == 1:
        have[0] = 1 if known else 0
        if known:
            N0[:, :] = N
    return done, nforce, t, diss, ext


LOOPS = {"lie_verlet_loop": lie_verlet_loop, "euler_loop": euler_loop, "rkmk_loop": rkmk_loop}


def loop_fragment() -> Fragment:
    """The loops and their helpers as one fragment of a generated module (``KINEMATIC_`` False:
    :func:`kinematic_fragment` sets it in the modules that carry a prescribed velocity)."""
    return Fragment(imports={"unmanaged_": ("cartan.compiled.unmanaged", "unmanaged")}, constants={"KINEMATIC_": False},
                    source=njit_source(op_drive, op_state_velocity, op_state_force, op_accumulate, _coad_exp, _blown,
                                       _damped, _book, lie_verlet_loop, _lie_poisson, euler_loop, _kinematic_velocity,
                                       _stage_velocity, rkmk_loop))


def _closure_digest(py: Callable) -> int | None:
    """A digest of the values a closure captures (0 for none; None when one is not a number,
    a string or an array), so that closures of the same code over other values get their own
    generated module (numba freezes captured values into the machine code)."""
    import hashlib

    cells = py.__closure__ or ()
    if not cells:
        return 0
    digest = hashlib.sha256()
    for cell in cells:
        value = cell.cell_contents
        if isinstance(value, (bool, int, float, str, np.number, np.bool_)):
            digest.update(repr((type(value).__name__, value)).encode())
        elif isinstance(value, np.ndarray) and value.dtype.kind in "biuf":
            digest.update(repr((value.dtype.str, value.shape)).encode() + np.ascontiguousarray(value).tobytes())
        else:
            return None
    return int(digest.hexdigest()[:15], 16)


def kinematic_fragment(velocity: Callable) -> Fragment | None:
    """The user's velocity ``f(t, u, X) -> N`` (a numba-compiled function, or its Python
    function) as the kernel ``k_velocity`` of a generated module, and ``KINEMATIC_`` True (the
    fragment comes after :func:`loop_fragment`); None for a closure over values other than
    numbers, strings and arrays.  An importable function is imported from its module; any
    other (a script, a notebook, a closure) is registered in :mod:`cartan.compiled.runtime`
    under a name derived from its code."""
    import importlib

    from ..compiled import runtime

    py = getattr(velocity, "py_func", velocity)
    closure = _closure_digest(py)
    if closure is None:
        return None
    module, name = getattr(py, "__module__", None), getattr(py, "__name__", "")
    importable = False
    if module and module != "__main__" and not closure:
        try:
            found = getattr(importlib.import_module(module), name, None)
        except ImportError:
            found = None
        importable = getattr(found, "py_func", found) is py
    where = (module, name) if importable else (runtime.__name__, runtime.register(py))
    constants = {"KINEMATIC_": True}
    if closure:
        constants["K_CLOSURE_"] = closure  # the captured values: part of the module's text, hence of its key
    return Fragment(imports={"k_velocity": where}, constants=constants)
