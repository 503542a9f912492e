"""Newton's method of ``implicit-midpoint`` over a scheme's compiled operator set.

The stage residual of :mod:`cartan.integrators.implicit` (paper §V, the discrete Lagrangian of
that module's docstring)::

    R(ξ) = dexp⁻¹_ξᵀ μ − Δt B(ξ)ᵀ W_{k+½} − S_k,   μ = m ξ/Δt,   B(ξ) = (I + Ad_{exp(ξ/2)})⁻¹,
    W_{k+½} = W(Φ_k exp(ξ/2), ξ/Δt, t_k + Δt/2),

and the end of a step ``S_{k+1} = dexp⁻¹_{−ξ}ᵀ μ + Δt (W − BW)``, ``Φ_{k+1} = Φ_k exp(ξ)``, are
written once here as plain Python over the operators of a scheme
(:mod:`cartan.compiled.operators`: ``op_copy_config``, ``op_drift``, ``op_force``,
``op_velocity``, ``op_powers``, ``op_constrain``, ``op_kinetic``) and the group's point
kernels (``g_exp``, ``g_Ad``, ``g_dexp_inv_T``, ``g_hat``); :func:`loop_fragment` puts them in
the generated module of each (scheme, group, medium), so they run on every scheme with an
operator set and every group with point kernels.  ``B(ξ)ᵀW`` is solved per node by Gaussian
elimination with partial pivoting (:func:`_im_solve_T`, :func:`cartan.compiled.linalg.solve_augmented`).

Compiled functions of the generated module (``ImplicitMidpoint`` drives them):

``im_residual(D, C0, Cw, S, xi, dt, t, mass, dom, radius, B, K) -> bool``
    R(ξ) and its pieces ``B = [N, W, μ, BW, Dmu, R]`` (``[6, n, r]``) for the step's
    configuration ``C0`` (read only; ``Cw`` a work copy left at the midpoint); False when ξ
    is outside the domain of dexp⁻¹ (``dom``: how the group measures it, :func:`domain_rule`)
    or ``I + Ad_{exp(ξ/2)}`` is singular at a node (a zero pivot; not met inside that domain).
``im_momentum(xi, mu, W, BW, dt, out)``
    The end-of-step momentum.
``im_norm(w, idx, y)``, ``im_lu_solve(...)``
    The kinetic-energy norms over the unknowns and the substitutions of a SuperLU factorisation.
``op_stage_momentum(D, C, S, N, mass, mu, K) -> bool``, ``op_stage_held(D, C, S, N, K) -> bool``
    The stage momenta μ = m N, and no velocity for the components of ξ that are no unknowns.
    A set of a Lagrangian coupling N and X (``Medium.coupled_lagrangian``) rebinds them after
    the loops to :func:`im_coupled_momentum` (μ = ∂L/∂N at the midpoint strains: the set's
    discrete Legendre map inverted, over its ``op_coupled_logs`` and ``op_coupled_velocities``)
    and :func:`im_coupled_held` (the gauge components of ξ are Δt times the velocity at the
    start of the step, r⁰ = ct), and, when the medium declares ``MediumKernels.coupled_jacobian``,
    :func:`op_coupled_jacobian` (the Newton Jacobian of that inversion in closed form); the force
    is the set's ``op_state_force`` at (μ, X_{k+½}), the Hamiltonian stress (``op_force`` for
    every other set).
``implicit_loop(...)``
    Whole blocks of steps: the iteration of ``ImplicitMidpoint._step`` in its order, the end
    of each step and the bookkeeping of ``ImplicitMidpoint.step``, and the medium's per-node
    accumulators when the set integrates them (``ACCUMULATES_``, set by
    :func:`cartan.schemes._lattice_ops.accumulate_fragment`): ``op_accumulate`` with the velocity
    of the state at the start of the call and after every step (the trapezoidal rule of
    :func:`cartan.accumulators.add`, as :func:`cartan.simulate` applies it after a Python step);
    it returns to Python for a
    fresh Jacobian (:data:`NEED_JACOBIAN`, assembled by finite differences of ``im_residual``
    and factorised by ``scipy.sparse.linalg.splu``) and when a step fails.  Driven ends
    (:class:`~cartan.problem.Driven`, a set with driven nodes): ξ = Δtξ_d there in every
    iterate (``op_drive``), no unknown; the drift moves them by exp(Δtξ_d), the wrapped
    operators give their momentum ∂K/∂N(ξ_d) and the supports' power.

The Python glue — :class:`Stage` (the residual bound to a configuration), :class:`LUSolve`
and :class:`Blocks` (the loop's work arrays) — calls these compiled functions only.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..compiled.codegen import Fragment, njit_source

__all__ = ["DONE", "NEED_JACOBIAN", "Blocks", "LUSolve", "Stage", "domain_rule", "loop_fragment", "newton_module"]

#: what :func:`implicit_loop` returns with: the steps are done (or the blow-up test failed after
#: the last of them); a fresh Jacobian is needed at the current iterate; or the step failed
DONE, NEED_JACOBIAN, FAIL_NOT_FINITE, FAIL_MAX_ITER, FAIL_SINGULAR, FAIL_NO_DECREASE = range(6)
#: rows of a slot of the residual buffers ``BUF [2, 6, n·r]``: N, W, μ, BW, Dmu, R
_ROWS = 6


# ---------------------------------------------------------------------------- generated-module source
# Plain Python compiled in the generated module (free names: its globals, see the module docstring).

def _im_in_domain(xi, dom, radius):
    """Whether every node's ξ ``[n, r]`` is inside the injectivity radius of exp: the group's
    ``log_domain_norm`` is the Euclidean norm of ``ξ[dom[1]:dom[2]]`` (``dom[0] = 0``) or the
    spectral norm of ``hat(ξ)`` (``dom[0] = 1``)."""
    X = np.empty((M_, M_))  # noqa: F821
    for i in range(xi.shape[0]):
        if dom[0] == 0:
            a = 0.0
            for k in range(dom[1], dom[2]):
                a += xi[i, k] * xi[i, k]
            a = np.sqrt(a)
        else:
            g_hat(xi[i], X)  # noqa: F821
            a = np.sqrt(max(np.linalg.eigvalsh(-(X @ X))[-1], 0.0))
        if not a < radius:  # also NaN
            return False
    return True


def _im_solve_T(A, w, out, Mw):
    """``out = (I + A)⁻ᵀ w`` for one ``r × r`` matrix (``Mw`` ``[r, r + 1]`` work: the augmented
    matrix) by :func:`cartan.compiled.linalg.solve_augmented`; False on a zero or NaN pivot."""
    r = w.shape[0]
    for a in range(r):
        for b in range(r):
            Mw[a, b] = A[b, a]
        Mw[a, a] += 1.0
        Mw[a, r] = w[a]
    return solve_augmented(Mw, out)  # noqa: F821


def op_stage_momentum(D, C, S, N, mass, mu, K):
    """The stage momenta ``μ = m N`` ``[n, r]`` (a diagonal kinetic metric ``mass`` ``[r]``) at the
    midpoint configuration ``C`` (unused here, as the step's momentum ``S``); True.  A set of a
    Lagrangian coupling N and X rebinds it to :func:`im_coupled_momentum` after the loops."""
    for i in range(N.shape[0]):
        for k in range(R_):  # noqa: F821
            mu[i, k] = N[i, k] * mass[k]
    return True


def op_stage_held(D, C, S, N, K):
    """False: the components of ξ that are no unknowns start at zero (Δtξ_d at driven nodes).  A
    set of a Lagrangian coupling N and X rebinds it to :func:`im_coupled_held`."""
    return False


def op_coupled_jacobian(D, C, S, idx, J, K):
    """False: no closed form, :func:`im_coupled_momentum` takes forward differences.  A coupled set
    whose medium declares ``MediumKernels.coupled_jacobian`` rebinds it to ``J[i, a, b] =
    ∂N_i[idx[a]]/∂S_i[idx[b]]`` (``J`` ``[n, nl, nl]``, the live components ``idx``) at the momentum
    ``S`` of its last ``op_coupled_velocities`` (whose velocities it reuses), True unless the
    medium's kernel fails."""
    return False


def im_coupled_held(D, C, S, N, K):
    """``N`` ← the velocity of the state ``(C, S)`` (``op_state_velocity``); True: the components
    of ξ that are no unknowns (the gauge ones, r⁰ = ct in the temporal gauge) are Δt times it."""
    op_state_velocity(D, C, S, N, K)  # noqa: F821
    return True


def im_coupled_momentum(D, C, S, N, mass, mu, K):
    """The stage momenta μ ``[n, r]`` whose velocity at the configuration ``C`` is ``N`` on the live
    components (``Scheme.momentum``: the discrete Legendre map inverted), zero on the gauge ones;
    False when none is found (N outside the range of the Legendre map).

    Newton's method per node from the step's momentum ``S``: the set's ``op_coupled_velocities``
    (all nodes, node i's velocity depending on S_i alone) and its Jacobian — the set's closed form
    (:func:`op_coupled_jacobian`, the medium's ``coupled_jacobian`` kernel) or else forward
    differences along each live component, perturbing every node at once — until ``|N(μ) − N| ≤ 1e-14·scale``
    on the live components (the tolerance and scale of
    :func:`cartan.schemes._coupled.initial_momentum`); the Jacobian is kept while the error falls
    by 10 or more per iteration.  The set's ``op_coupled_keep`` then keeps what its force at μ
    can reuse (the lattice's half-edge velocities)."""
    n = N.shape[0]
    live = D.live
    idx = np.empty(R_, dtype=np.int64)  # noqa: F821
    nl = 0
    for k in range(R_):  # noqa: F821
        if live[k]:
            idx[nl] = k
            nl += 1
    big_live = 0.0
    big_all = 0.0
    for i in range(n):
        for k in range(R_):  # noqa: F821
            a = abs(N[i, k])
            big_all = max(big_all, a)
            if live[k]:
                big_live = max(big_live, a)
    scale = max(big_live, 1e-3 * big_all, 1e-300)
    for i in range(n):
        for k in range(R_):  # noqa: F821
            mu[i, k] = S[i, k] if live[k] else 0.0
    op_coupled_logs(D, C, K)  # noqa: F821
    Nd = np.empty((n, R_))  # noqa: F821
    Np = np.empty((n, R_))  # noqa: F821
    Nm = np.empty((n, R_))  # noqa: F821
    J = np.empty((n, nl, nl))
    Mw = np.empty((nl, nl + 1))
    dx = np.empty(nl)
    have_j = False
    err_prev = np.inf
    for _ in range(IM_COUPLED_ITER_):  # noqa: F821
        if not op_coupled_velocities(D, C, mu, Nd, K):  # noqa: F821
            return False
        err = 0.0
        for i in range(n):
            for a in range(nl):
                e = abs(Nd[i, idx[a]] - N[i, idx[a]])
                if not np.isfinite(e):
                    return False
                err = max(err, e)
        if err <= IM_COUPLED_TOL_ * scale:  # noqa: F821
            op_coupled_keep(D, C, mu, K)  # noqa: F821
            return True
        if not have_j or err > 0.1 * err_prev:
            if not op_coupled_jacobian(D, C, mu, idx[:nl], J, K):  # (closed form: at the velocities just found)
                pmax = 0.0
                for i in range(n):
                    for a in range(nl):
                        pmax = max(pmax, abs(mu[i, idx[a]]))
                for b in range(nl):
                    k = idx[b]
                    eps = 1e-7 * max(pmax, abs(mass[k]) * scale, 1e-300)
                    for i in range(n):
                        Nm[i, k] = mu[i, k]  # (kept: restored exactly)
                        mu[i, k] += eps
                    ok_p = op_coupled_velocities(D, C, mu, Np, K)  # noqa: F821
                    for i in range(n):
                        mu[i, k] = Nm[i, k]
                    if not ok_p:
                        return False
                    for i in range(n):
                        for a in range(nl):
                            J[i, a, b] = (Np[i, idx[a]] - Nd[i, idx[a]]) / eps
            have_j = True
        err_prev = err
        for i in range(n):
            for a in range(nl):
                for b in range(nl):
                    Mw[a, b] = J[i, a, b]
                Mw[a, nl] = N[i, idx[a]] - Nd[i, idx[a]]
            if not solve_augmented(Mw, dx):  # noqa: F821
                return False
            for a in range(nl):
                mu[i, idx[a]] += dx[a]
    return False


def im_residual(D, C0, Cw, S, xi, dt, t, mass, dom, radius, B, K):
    """The stage residual at ξ ``[n, r]`` into ``B`` ``[6, n, r]`` (N = ξ/Δt, W, μ, BW, Dmu, R);
    ``Cw`` ← the midpoint configuration ``C0·exp(ξ/2)``; False (nothing computed) outside the
    domain of dexp⁻¹, False (``B`` partly computed) where ``I + Ad_{exp(ξ/2)}`` is singular."""
    if not _im_in_domain(xi, dom, radius):
        return False
    op_copy_config(C0, Cw)  # noqa: F821
    op_drift(D, Cw, 0.5, xi, K)  # noqa: F821
    N, W, mu, BW, Dmu, R = B[0], B[1], B[2], B[3], B[4], B[5]
    n = xi.shape[0]
    for i in range(n):
        for k in range(R_):  # noqa: F821
            N[i, k] = xi[i, k] / dt
    if not op_stage_momentum(D, Cw, S, N, mass, mu, K):  # noqa: F821 - μ = m N, or ∂ℓ/∂N (coupled)
        return False
    op_state_force(D, Cw, mu, t + 0.5 * dt, N, W, K)  # noqa: F821 - op_force, or at (μ, X) (coupled)
    A = np.empty((R_, R_))  # noqa: F821
    Mw = np.empty((R_, R_ + 1))  # noqa: F821
    E = np.empty((M_, M_))  # noqa: F821
    h = np.empty(R_)  # noqa: F821
    x = np.empty(R_)  # noqa: F821
    m = np.empty(R_)  # noqa: F821
    vec = np.empty(R_)  # noqa: F821
    for i in range(n):
        for k in range(R_):  # noqa: F821
            h[k] = 0.5 * xi[i, k]
            x[k] = xi[i, k]
            m[k] = mu[i, k]
        g_exp(h, E)  # noqa: F821
        g_Ad(E, A)  # noqa: F821
        if not _im_solve_T(A, W[i], BW[i], Mw):
            return False
        g_dexp_inv_T(x, m, vec)  # noqa: F821
        for k in range(R_):  # noqa: F821
            Dmu[i, k] = vec[k]
            R[i, k] = vec[k] - dt * BW[i, k] - S[i, k]
    return True


def im_momentum(xi, mu, W, BW, dt, out):
    """``out = dexp⁻¹_{−ξ}ᵀ μ + Δt (W − BW)`` per node (all ``[n, r]``): the end-of-step momentum."""
    x = np.empty(R_)  # noqa: F821
    m = np.empty(R_)  # noqa: F821
    vec = np.empty(R_)  # noqa: F821
    for i in range(xi.shape[0]):
        for k in range(R_):  # noqa: F821
            x[k] = -xi[i, k]
            m[k] = mu[i, k]
        g_dexp_inv_T(x, m, vec)  # noqa: F821
        for k in range(R_):  # noqa: F821
            out[i, k] = vec[k] + dt * (W[i, k] - BW[i, k])


def im_norm(w, idx, y):
    """``sqrt(Σ_k w_k y[idx_k]²)`` for ``y`` flat: the kinetic-energy norms over the unknowns."""
    acc = 0.0
    for k in range(idx.shape[0]):
        v = y[idx[k]]
        acc += w[k] * (v * v)
    return np.sqrt(acc)


def im_lu_solve(Lp, Li, Lx, Ld, Up, Ui, Ux, Ud, perm_r, perm_c, b, x, y):
    """``x = A⁻¹b`` from SuperLU's factors ``Pr A Pc = L U`` (strict lower and upper parts as CSC
    arrays with their diagonals): one forward and one back substitution by columns (``y`` work)."""
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


def _im_slot(D, C, Cw, S, XI, BUF, a, dt, t, mass, dom, radius, K):
    """The stage residual at the iterate ``XI[a]`` into ``BUF[a]``."""
    n = S.shape[0]
    return im_residual(D, C, Cw, S, XI[a].reshape((n, R_)), dt, t, mass, dom, radius,  # noqa: F821
                       BUF[a].reshape((6, n, R_)), K)  # noqa: F821


def _im_norms(w_over_m, w_times_m, unk, S, Dmu, BW, xi):
    """``(‖S‖_*, ‖Dmu‖_*, ‖BW‖_*, ‖ξ‖_M)``, each summed in the order of :func:`im_norm`."""
    return (im_norm(w_over_m, unk, S), im_norm(w_over_m, unk, Dmu), im_norm(w_over_m, unk, BW),
            im_norm(w_times_m, unk, xi))


def implicit_loop(D, C, Cw, S, mass, dom, radius, unk, w_over_m, w_times_m, lu, have_lu, resume, XI, BUF, prev,
                  hist, ist, fst, has_power, t, dt, nsteps, diss, ext, limit, tol, contraction, xtol, max_iter,
                  max_halvings, predictor, reuse):
    """Up to ``nsteps`` steps of ``implicit-midpoint`` on ``(C, S)`` in place, Newton's iteration
    included, in the order of ``ImplicitMidpoint._step`` (see :class:`Blocks` for the arguments;
    the starting iterates are Δtξ_d at driven nodes, zero at the other fixed ones);
    returns ``(status, steps done, residual evaluations, Newton iterations of the steps done, t,
    dissipated, external, have_lu)``."""
    K = op_work(D)  # noqa: F821
    n = S.shape[0]
    r = R_  # noqa: F821
    nunk = unk.shape[0]
    Sf = S.reshape(n * r)
    Nv = np.empty((n, r))
    # driven ends (cartan.Driven): ξ = Δtξ_d at the driven nodes, no unknown (op_drive gives ξ_d
    # there in a set with driven nodes, nothing elsewhere); the starting iterates carry it
    drive = np.zeros((n, r))
    op_drive(D, drive)  # noqa: F821 - cartan.integrators.loops (rebound by a set with driven nodes)
    driven = False
    for i in range(n):
        for k in range(r):
            if drive[i, k] != 0.0:
                driven = True
    xd = np.empty(n * r)
    df = drive.reshape(n * r)
    for j in range(n * r):
        xd[j] = dt * df[j]
    b = np.empty(nunk)
    delta = np.empty(nunk)
    y = np.empty(nunk)
    cur, it, nhist, have_prev = ist[0], ist[1], ist[2], ist[3] != 0
    rn, dt_prev = fst[0], fst[1]
    done = 0
    nforce = 0
    iters = 0
    status = 0
    fresh = resume
    in_step = resume
    isunk = np.zeros(n * r, dtype=np.bool_)
    for k in range(nunk):
        isunk[unk[k]] = True
    if ACCUMULATES_:  # noqa: F821 - per-node accumulators: the rates at the start of the (current) step
        op_state_velocity(D, C, S, Nv, K)  # noqa: F821
        op_accumulate(D, C, S, Nv, dt, True)  # noqa: F821
    while done < nsteps:
        if not in_step:
            # ---- start of a step: the initial iterate
            if op_stage_held(D, C, S, Nv, K):  # noqa: F821 - (a coupled Lagrangian: the gauge components of ξ)
                Nf = Nv.reshape(n * r)
                for j in range(n * r):
                    if not isunk[j]:
                        xd[j] = dt * Nf[j]
            if not reuse:
                have_lu = False
            got = False
            a = 1 - cur
            if have_prev and predictor:
                q = dt / dt_prev
                xa = XI[a]
                xa[:] = xd
                for k in range(nunk):
                    xa[unk[k]] = q * prev[unk[k]]
                if _im_slot(D, C, Cw, S, XI, BUF, a, dt, t, mass, dom, radius, K):
                    nforce += 1
                    cur = a
                    got = True
            if not got:
                op_state_velocity(D, C, S, Nv, K)  # noqa: F821
                Nf = Nv.reshape(n * r)
                xa = XI[a]
                xa[:] = xd
                nonzero = driven
                for k in range(nunk):
                    j = unk[k]
                    v = dt * Nf[j]
                    xa[j] = v
                    if v != 0.0:
                        nonzero = True
                ok = _im_slot(D, C, Cw, S, XI, BUF, a, dt, t, mass, dom, radius, K)
                if ok:
                    nforce += 1
                cur = a
                if nonzero:
                    z = 1 - a
                    XI[z][:] = xd  # (ξ = 0 on the unknowns)
                    _im_slot(D, C, Cw, S, XI, BUF, z, dt, t, mass, dom, radius, K)
                    nforce += 1
                    if not ok or (im_norm(w_over_m, unk, BUF[z, 5]) < im_norm(w_over_m, unk, BUF[a, 5])):
                        cur = z
            rn = im_norm(w_over_m, unk, BUF[cur, 5])
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
                    status = 2
                    break
                s_norm, dmu_norm, bw_norm, xi_norm = _im_norms(w_over_m, w_times_m, unk, Sf, BUF[cur, 4],
                                                               BUF[cur, 3], XI[cur])
                floor = 2.0 ** -46 * (s_norm + dmu_norm + abs(dt) * bw_norm)  # 64 ε times the terms' size
                bound = tol * xi_norm / abs(dt)
                if floor > bound:
                    bound = floor
                if nunk == 0 or rn <= bound:
                    converged = True
                    break
                if it >= max_iter:
                    status = 3
                    break
                if not have_lu:
                    status = 1
                    break
            xc = XI[cur]
            Rc = BUF[cur, 5]
            for k in range(nunk):
                b[k] = -Rc[unk[k]]
            im_lu_solve(lu[0], lu[1], lu[2], lu[3], lu[4], lu[5], lu[6], lu[7], lu[8], lu[9], b, delta, y)
            big = 0.0
            finite = True
            for k in range(nunk):
                if not np.isfinite(delta[k]):
                    finite = False
                big = max(big, abs(delta[k]))
            if not finite:
                status = 4
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
                ok = _im_slot(D, C, Cw, S, XI, BUF, a, dt, t, mass, dom, radius, K)
                rn_t = np.inf
                if ok:
                    nforce += 1
                    rn_t = im_norm(w_over_m, unk, BUF[a, 5])
                it += 1
                if negligible and ok:
                    accepted = True  # a Newton step at the round-off level of ξ
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
                    have_lu = False
            elif not fresh:
                have_lu = False
            elif it >= max_iter:
                status = 3
                break
            else:
                status = 5
                break
        if not converged:
            break
        # ---- end of the step: powers at the midpoint, Φ ← Φ exp(ξ), S ← dexp⁻¹_{−ξ}ᵀ μ + Δt (W − BW)
        iters += it
        xi = XI[cur].reshape((n, r))
        B = BUF[cur].reshape((6, n, r))
        pd = 0.0
        pe = 0.0
        if has_power:
            op_copy_config(C, Cw)  # noqa: F821
            op_drift(D, Cw, 0.5, xi, K)  # noqa: F821
            pd, pe = op_powers(D, Cw, B[0], t + 0.5 * dt, K)  # noqa: F821
        im_momentum(xi, B[2], B[1], B[3], dt, S)
        op_drift(D, C, 1.0, xi, K)  # noqa: F821
        op_constrain(D, S)  # noqa: F821
        if ACCUMULATES_:  # noqa: F821 - a ← a + ½Δt (r(before) + r(after)), as cartan.accumulators.add
            op_state_velocity(D, C, S, Nv, K)  # noqa: F821
            op_accumulate(D, C, S, Nv, dt, False)  # noqa: F821
        t = t + dt
        diss = diss + dt * pd
        ext = ext + dt * pe
        prev[:] = XI[cur]
        have_prev = True
        dt_prev = dt
        in_step = False
        done += 1
        blown = False
        for j in range(n * r):
            if not np.isfinite(Sf[j]):
                blown = True
        if blown or not (op_kinetic(D, S) <= limit):  # noqa: F821
            break
    ist[0], ist[1], ist[2], ist[3] = cur, it, nhist, 1 if have_prev else 0
    fst[0], fst[1] = rn, dt_prev
    return status, done, nforce, iters, t, diss, ext, have_lu


def loop_fragment() -> Fragment:
    """The residual, the end of a step and Newton's loop as one fragment of a generated module."""
    return Fragment(imports={"solve_augmented": ("cartan.compiled.linalg", "solve_augmented")},
                    constants={"IM_COUPLED_ITER_": 60, "IM_COUPLED_TOL_": 1e-14, "ACCUMULATES_": False},
                    source=njit_source(_im_in_domain, _im_solve_T, op_stage_momentum, op_stage_held,
                                       op_coupled_jacobian, im_coupled_held, im_coupled_momentum, im_residual,
                                       im_momentum, im_norm, im_lu_solve, _im_slot, _im_norms, implicit_loop))


# ---------------------------------------------------------------------------- Python glue
def newton_module(ops: Any):
    """The generated module of the operator set ``ops`` that holds :func:`loop_fragment`: the
    set's own module when this module is one of its loop sources, else one generated for it
    (kept on ``ops``)."""
    from ..compiled import operators

    if __name__ in operators.LOOP_SOURCES:
        return ops.generated()
    module = getattr(ops, "_newton_module", None)
    if module is None:
        from ..compiled.codegen import generate

        module = generate(f"ops-newton-{ops.key}", [*ops.fragments, loop_fragment()])
        ops._newton_module = module
    return module


def domain_rule(group: Any) -> np.ndarray | None:
    """How :func:`_im_in_domain` measures ``group.log_domain_norm``: ``[0, lo, hi]`` when it is the
    Euclidean norm of ``ξ[lo:hi]``, ``[1, 0, 0]`` when it is the spectral norm of ``hat(ξ)`` (the
    largest rotation angle), found by comparing on random ξ; None when neither."""
    r = group.dim
    xs = np.random.default_rng(7).standard_normal((8, r))
    ref = np.asarray(group.log_domain_norm(xs), dtype=float)

    def same(v: np.ndarray) -> bool:
        return bool(np.all(np.abs(v - ref) <= 1e-12 * np.maximum(np.abs(ref), 1.0)))

    for lo in range(r):
        for hi in range(r, lo, -1):
            if same(np.linalg.norm(xs[:, lo:hi], axis=-1)):
                return np.array([0, lo, hi], dtype=np.int64)
    try:
        X = np.asarray(group.hat(xs), dtype=float)
        spectral = np.sqrt(np.maximum(np.linalg.eigvalsh(-(X @ X))[:, -1], 0.0))
    except (AttributeError, ValueError, np.linalg.LinAlgError):
        return None
    return np.array([1, 0, 0], dtype=np.int64) if same(spectral) else None


def _contiguous(a: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64).reshape(shape)


class Stage:
    """The compiled stage residual of one problem over its operator set.

    Parameters
    ----------
    ops : OperatorSet
        The scheme's operators (``ops.ok``).
    module : module
        The generated module holding :func:`loop_fragment` (:func:`newton_module`).
    mass : ndarray, shape (r,)
        The diagonal kinetic metric (μ = m N).
    dom : ndarray of int64, shape (3,)
        :func:`domain_rule` of the group.
    radius : float
        The group's injectivity radius.
    shape : tuple of int
        The shape of the momentum ``[*grid.shape, r]``.
    """

    def __init__(self, ops: Any, module: Any, mass: np.ndarray, dom: np.ndarray, radius: float,
                 shape: tuple[int, ...]):
        self.ops, self.module = ops, module
        self.mass = np.ascontiguousarray(mass, dtype=np.float64)
        self.dom, self.radius = dom, float(radius)
        self.shape = tuple(shape)
        self.n, self.r = ops.nodes, int(self.shape[-1])
        self.K = module.op_work(ops.data)
        self._base: tuple | None = None

    def accepts(self, state: Any) -> bool:
        return bool(self.ops.accepts(state)) and np.shape(state.S) == self.shape

    def bind_arrays(self, C: tuple, S: np.ndarray) -> None:
        """Evaluate at the configuration ``C`` (packed) and momentum ``S`` ``[n, r]`` (read only)."""
        self._base = (C, S, tuple(np.empty_like(c) for c in C))

    def bind(self, state: Any) -> None:
        """Evaluate at ``state`` (its configuration packed once, its momentum read)."""
        self.bind_arrays(self.ops.pack(state), _contiguous(state.S, (self.n, self.r)))
        self.t = float(state.t)

    def __call__(self, xi: np.ndarray, dt: float, t: float | None = None) -> dict[str, np.ndarray] | None:
        """``{"R", "W", "BW", "mu", "Dmu"}`` ``[*shape, r]`` at ξ ``[*shape, r]`` (force at
        ``t + Δt/2``, ``t`` the bound state's time by default), or None outside the domain of dexp⁻¹."""
        if self._base is None:
            raise RuntimeError("Stage.bind(state) must be called before evaluating")
        C, S, Cw = self._base
        B = np.empty((_ROWS, self.n, self.r))
        ok = self.module.im_residual(self.ops.data, C, Cw, S, _contiguous(xi, (self.n, self.r)), float(dt),
                                     float(self.t if t is None else t), self.mass, self.dom, self.radius, B, self.K)
        if not ok:
            return None
        return {k: B[i].reshape(self.shape) for i, k in enumerate(("N", "W", "mu", "BW", "Dmu", "R")) if k != "N"}

    def velocity(self, state: Any) -> np.ndarray:
        """The velocity of ``state`` by the operators (``[*shape, r]``): N = M⁺S, or the discrete
        Legendre map of a Lagrangian coupling N and X (``op_state_velocity``)."""
        N = np.empty((self.n, self.r))
        self.module.op_state_velocity(self.ops.data, self.ops.pack(state), _contiguous(state.S, (self.n, self.r)),
                                      N, self.K)
        return N.reshape(self.shape)

    def drifted(self, state: Any, xi: np.ndarray, tau: float) -> Any:
        """A copy of ``state`` at ``Φ exp(τξ)``."""
        out = state.copy()
        C = self.ops.pack(state)
        self.module.op_drift(self.ops.data, C, float(tau), _contiguous(xi, (self.n, self.r)), self.K)
        self.ops.unpack(out, C)
        return out

    def advance(self, state: Any, xi: np.ndarray, res: dict[str, np.ndarray], dt: float) -> None:
        """End of the step: ``S ← dexp⁻¹_{−ξ}ᵀ μ + Δt (W − BW)``, ``Φ ← Φ exp(ξ)`` (new arrays)."""
        n, r = self.n, self.r
        x = _contiguous(xi, (n, r))
        S_new = np.empty((n, r))
        self.module.im_momentum(x, _contiguous(res["mu"], (n, r)), _contiguous(res["W"], (n, r)),
                                _contiguous(res["BW"], (n, r)), float(dt), S_new)
        C = self.ops.pack(state)
        self.module.op_drift(self.ops.data, C, 1.0, x, self.K)
        self.ops.unpack(state, C)
        state.S = S_new.reshape(self.shape)

    def norm(self, w: np.ndarray, idx: np.ndarray, y: np.ndarray) -> float:
        """:func:`im_norm` of ``y`` (any shape, flattened)."""
        return float(self.module.im_norm(w, idx, _contiguous(y, (-1,))))


class LUSolve:
    """The solve of a ``scipy.sparse.linalg.splu`` factorisation by :func:`im_lu_solve` (the same
    factors; round-off apart SuperLU's solution); ``solve(b)`` returns a new array."""

    def __init__(self, lu: Any, solve: Any):
        import scipy.sparse as sp

        def parts(T: Any, k: int) -> tuple:
            T = sp.csc_matrix(T)
            off = sp.csc_matrix(sp.tril(T, -1) if k < 0 else sp.triu(T, 1))
            return (off.indptr.astype(np.int64), off.indices.astype(np.int64),
                    np.ascontiguousarray(off.data, dtype=np.float64),
                    np.ascontiguousarray(T.diagonal(), dtype=np.float64))

        self.shape = lu.shape
        self._solve = solve
        self._args = (*parts(lu.L, -1), *parts(lu.U, 1), np.ascontiguousarray(lu.perm_r, np.int64),
                      np.ascontiguousarray(lu.perm_c, np.int64))
        self._work = np.empty(lu.shape[0])

    def solve(self, b: np.ndarray) -> np.ndarray:
        x = np.empty(self.shape[0])
        self._solve(*self._args, np.ascontiguousarray(b, dtype=np.float64), x, self._work)
        return x


class Blocks:
    """The work arrays of :func:`implicit_loop` for one stage and set of unknowns, and its call.

    Parameters
    ----------
    stage : Stage
    unk : ndarray of int64, shape (nunk,)
        The unknowns, as indices into ``S.ravel()``.
    w_over_m, w_times_m : ndarray, shape (nunk,)
        The weights of the norms ``‖R‖_*`` and ``‖N‖_M`` at the unknowns.
    """

    def __init__(self, stage: Stage, unk: np.ndarray, w_over_m: np.ndarray, w_times_m: np.ndarray):
        n, r = stage.n, stage.r
        self.stage = stage
        self.unk = np.ascontiguousarray(unk, dtype=np.int64)
        self.w_over_m = np.ascontiguousarray(w_over_m, dtype=np.float64)
        self.w_times_m = np.ascontiguousarray(w_times_m, dtype=np.float64)
        self.XI = np.zeros((2, n * r))
        self.BUF = np.zeros((2, _ROWS * n * r))
        self.prev = np.zeros(n * r)
        self.hist = np.zeros(1)
        self.ist = np.zeros(4, dtype=np.int64)
        self.fst = np.zeros(2)
        i0, f0 = np.zeros(0, dtype=np.int64), np.zeros(0)
        self.no_lu = (np.zeros(1, dtype=np.int64), i0, f0, f0, np.zeros(1, dtype=np.int64), i0, f0, f0, i0, i0)

    def start(self, prev: np.ndarray | None, dt_prev: float, max_iter: int) -> None:
        """Begin a block: ``prev`` the previous step's ξ (None: none) and its ``dt_prev``."""
        self.ist[:] = (0, 0, 0, prev is not None)
        self.fst[:] = (0.0, dt_prev)
        if prev is not None:
            self.prev[:] = np.ravel(prev)
        if self.hist.shape[0] < max_iter + 1:
            self.hist = np.zeros(max_iter + 1)

    def run(self, C: tuple, S: np.ndarray, Cw: tuple, lu: LUSolve | None, resume: bool, t: float, dt: float,
            nsteps: int, dissipated: float, external: float, kinetic_limit: float, has_power: bool,
            options: tuple) -> tuple:
        """One call of :func:`implicit_loop` on ``(C, S)`` (updated in place); ``options`` =
        ``(tol, contraction, xtol, max_iter, max_halvings, predictor, reuse)``."""
        st = self.stage
        tol, contraction, xtol, max_iter, max_halvings, predictor, reuse = options
        BUF = self.BUF.reshape(2, _ROWS, -1)
        return st.module.implicit_loop(
            st.ops.data, C, Cw, S, st.mass, st.dom, st.radius, self.unk, self.w_over_m, self.w_times_m,
            self.no_lu if lu is None else lu._args, lu is not None, bool(resume), self.XI, BUF, self.prev,
            self.hist, self.ist, self.fst, bool(has_power), float(t), float(dt), int(nsteps), float(dissipated),
            float(external), float(kinetic_limit), float(tol), float(contraction), float(xtol), int(max_iter),
            int(max_halvings), bool(predictor), bool(reuse))

    def iterate(self) -> np.ndarray:
        """The current iterate ξ ``[*shape, r]`` of the step in progress (a copy)."""
        return self.XI[self.ist[0]].reshape(self.stage.shape).copy()

    def previous(self) -> np.ndarray:
        """ξ ``[*shape, r]`` of the last step done (a copy)."""
        return self.prev.reshape(self.stage.shape).copy()

    def progress(self) -> tuple[int, float, list[float]]:
        """``(iterations, ‖R‖_*, history)`` of the step in progress."""
        return int(self.ist[1]), float(self.fst[0]), [float(x) for x in self.hist[: self.ist[2]]]
