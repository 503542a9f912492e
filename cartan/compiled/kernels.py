"""Kernel declarations: how a group's and a medium's point kernels enter a generated module.

Group kernels
    ``g_<op>`` for every ``op`` of :data:`GROUP_OPS` (signatures in
    :meth:`cartan.groups.base.SymmetryGroup.point_kernels`), and the fused operations of
    :data:`FUSED_OPS` (a product with a matrix, without the matrix, when the group has them).
Medium kernels
    ``m_energy(X, X0, p) -> float`` and ``m_stress(X, X0, p, Q)`` — the potential energy
    density U and the stress Q = ∂U/∂X at one point, X, X0 and Q of shape ``(d, r)`` (the
    strain, the local rest strain, the stress written in place), ``p`` the medium's parameter
    vector (float64, 1-D).  See :class:`cartan.medium.MediumKernels`.
"""

from __future__ import annotations

import importlib

from .codegen import Fragment

__all__ = ["GROUP_OPS", "group_fragment", "kernel_stem", "medium_batch", "medium_fragment"]

#: the group operations a generated loop may call
GROUP_OPS = ("exp", "log", "compose", "inverse", "hat", "Ad", "ad", "dexp_inv", "E")

#: operations a group may provide in closed form (``<prefix>_<op>_point``); otherwise they are
#: built from :data:`GROUP_OPS` in the generated module
_FUSED = """
def g_{op}({arg}, v, out):
    A = np.empty((R_, R_))
    g_{matrix}({arg}, A)
    for k in range(R_):
        s = 0.0
        for j in range(R_):
            s += A[j, k] * v[j]
        out[k] = s
"""
FUSED_OPS = {op: _FUSED.format(op=op, arg=arg, matrix=matrix)
             for op, arg, matrix in (("Ad_T", "g", "Ad"), ("dexp_inv_T", "xi", "dexp_inv"))}
#: both ends of an edge at once: ``dexp⁻¹(−ξ) = dexp⁻¹(ξ) + ad_ξ`` (``x/(eˣ − 1)`` at −x is
#: ``x/(eˣ − 1) + x``), so ``dexp⁻¹(−ξ)ᵀv`` is ``dexp⁻¹(ξ)ᵀv + ad_ξᵀv``
FUSED_OPS["dexp_inv_T_pair"] = """
def g_dexp_inv_T_pair(xi, v, out, out_neg):
    g_dexp_inv_T(xi, v, out)
    A = np.empty((R_, R_))
    g_ad(xi, A)
    for k in range(R_):
        s = out[k]
        for j in range(R_):
            s += A[j, k] * v[j]
        out_neg[k] = s
"""
#: the edge passes of the lattice's force over the edges ``lo ≤ e < hi``: ``XI[e] = log G[e]``, and
#: both ends' terms ``VT[e] = s_e dexp⁻¹(ξ_e)ᵀq_e``, ``VH[e] = s_e dexp⁻¹(−ξ_e)ᵀq_e`` (``s_e = scale[e]``,
#: or 1 for an empty ``scale``); here one point kernel per edge (vectorised across edges:
#: ``se3_log_chunk_point``, ``se3_dexp_inv_T_pair_chunk_point``)
FUSED_OPS["log_chunk"] = """
def g_log_chunk(G, lo, hi, XI):
    for e in range(lo, hi):
        g_log(G[e], XI[e])
"""
FUSED_OPS["dexp_inv_T_pair_chunk"] = """
def g_dexp_inv_T_pair_chunk(XI, Q, scale, lo, hi, VT, VH):
    vec = np.empty(R_)
    vec2 = np.empty(R_)
    scaled = scale.shape[0] > 0
    for e in range(lo, hi):
        g_dexp_inv_T_pair(XI[e], Q[e], vec, vec2)
        s = scale[e] if scaled else 1.0
        for k in range(R_):
            VT[e, k] = s * vec[k]
            VH[e, k] = s * vec2[k]
"""
#: the lattice's update by the nodes' motions ``Dn`` (``op_move``): ``G[e] ← Di[tail[e]] G[e] Dn[head[e]]``
#: over edges, and ``Di[i] ← Dn[i]⁻¹``, ``Φ_i ← Φ_i Dn_i`` over nodes (rows of Φ among them)
FUSED_OPS["move_chunk"] = """
def g_move_chunk(Di, Dn, G, tail, head, lo, hi):
    tmp = np.empty((M_, M_))
    for e in range(lo, hi):
        g_compose(Di[tail[e]], G[e], tmp)
        g_compose(tmp, Dn[head[e]], G[e])
"""
FUSED_OPS["frames_chunk"] = """
def g_frames_chunk(Dn, Di, Phi, lo, hi):
    tmp = np.empty((M_, M_))
    for i in range(lo, hi):
        g_inverse(Dn[i], Di[i])
    for i in range(lo, min(hi, Phi.shape[0])):
        for a in range(M_):
            for b in range(M_):
                tmp[a, b] = Phi[i, a, b]
        g_compose(tmp, Dn[i], Phi[i])
"""
#: ``out[a] = Ad_{g⁻¹} X[a]`` for every row of ``X`` ``(k, r)`` (the strains of a node moved by g)
FUSED_OPS["Ad_inv_apply"] = """
def g_Ad_inv_apply(g, X, out, work):
    gi, A = work[0], work[1]
    g_inverse(g, gi)
    g_Ad(gi, A)
    for a in range(X.shape[0]):
        for k in range(R_):
            s = 0.0
            for j in range(R_):
                s += A[k, j] * X[a, j]
            out[a, k] = s
"""
#: ``out[a] = 𝓔(τ, ξ) V[a]`` for every row of ``V`` ``(k, r)``
FUSED_OPS["E_apply"] = """
def g_E_apply(tau, xi, V, out, work):
    Em = work[2]
    g_E(tau, xi, Em)
    for a in range(V.shape[0]):
        for k in range(R_):
            s = 0.0
            for j in range(R_):
                s += Em[k, j] * V[a, j]
            out[a, k] = s
"""

#: ``out = dexp⁻¹(ξ) v`` (the RKMK stage increments σ̇ = dexp⁻¹_{−σ} N)
FUSED_OPS["dexp_inv_apply"] = """
def g_dexp_inv_apply(xi, v, out, work):
    A = work[1]
    g_dexp_inv(xi, A)
    for k in range(R_):
        s = 0.0
        for j in range(R_):
            s += A[k, j] * v[j]
        out[k] = s
"""

#: ``E ← exp(ξ)`` and ``s ← Ad_Eᵀ s`` in place: the free flow of a frozen velocity at a node
#: (``S ← Ad*_{exp(τN)} S``, paper §V); ``s`` an ``(r,)`` row, E ``(m, m)``
FUSED_OPS["coad_exp"] = """
def g_coad_exp(xi, s, E, work):
    g_exp(xi, E)
    out = work[1][0]
    g_Ad_T(E, s, out)
    for k in range(R_):
        s[k] = out[k]
"""

#: ``E = exp(t b_k)``, ``s ← Ad_Eᵀ s`` and ``acc ← acc E`` in place: the free flow along one basis
#: axis k (a piece of ``lie-verlet``'s free flow with a diagonal kinetic metric), ``s`` ``(r,)``,
#: ``acc`` ``(m, m)``; here from ``g_exp``, ``g_Ad_T`` and ``g_compose`` (closed forms:
#: ``so3_axis_flow_point``, ``se3_axis_flow_point``, ``poincare_axis_flow_point``)
FUSED_OPS["axis_flow"] = """
def g_axis_flow(k, t, s, acc, work):
    E, tmp, vec = work[0], work[3], work[4]
    xi, out = vec[0], vec[1]
    for j in range(R_):
        xi[j] = 0.0
    xi[k] = t
    g_exp(xi, E)
    g_Ad_T(E, s, out)
    for j in range(R_):
        s[j] = out[j]
    g_compose(acc, E, tmp)
    for a in range(M_):
        for b in range(M_):
            acc[a, b] = tmp[a, b]
"""

#: ``lie-verlet``'s free flow at the nodes ``lo ≤ i < hi`` when every piece is axial (``_flow_plan`` of the
#: lattice's operators: per piece its τ, directions and ``(P_p)_kk``): ``Dn_i`` from the identity, then per
#: piece the times of its directions (zero at clamped nodes and held components) and ``g_axis_flow`` along
#: each; whether a node moved.  The operators call it only where the group has it in closed form
#: (``AXIAL_FLOW_CLOSED_``, a constant of the generated module: ``se3_axial_flow_chunk_point``,
#: ``se2_axial_flow_chunk_point``), and
#: otherwise run these same steps themselves
FUSED_OPS["axial_flow_chunk"] = """
def g_axial_flow_chunk(lo, hi, S, Dn, any_clamped, clamped, any_held, held, npieces, tau, naxes, axes, coef):
    wk = g_work()
    TK = np.empty((max(hi - lo, 0), R_))
    xi = np.zeros(R_)
    for i in range(lo, hi):
        g_exp(xi, Dn[i])
    moved = False
    for p in range(npieces):
        for c in range(naxes[p]):
            k = axes[p, c]
            for i in range(lo, hi):
                t = tau[p] * (coef[p, c] * S[i, k])
                if (any_clamped and clamped[i]) or (any_held and held[i, k]):
                    t = 0.0
                TK[i - lo, c] = t
        for c in range(naxes[p]):
            k = axes[p, c]
            for i in range(lo, hi):
                t = TK[i - lo, c]
                if t != 0.0:
                    g_axis_flow(k, t, S[i], Dn[i], wk)
                    moved = True
    return moved
"""

#: the scratch of the default fused operations, allocated once by their callers and passed as
#: ``work`` (closed forms ignore it): ``(m × m, r × r, r × r, m × m, 2 × r)``
_WORK = """
def g_work():
    return (np.empty((M_, M_)), np.empty((R_, R_)), np.empty((R_, R_)), np.empty((M_, M_)), np.empty((2, R_)))
"""


#: 𝓔 and dexp⁻¹ for a group without closed forms: the Van Loan block exponential
_VANLOAN = """
def g_E(dt, xi, out):
    A = np.empty((R_, R_))
    g_ad(xi, A)
    _vanloan_E(dt, A, out)


def g_dexp_inv(xi, out):
    A = np.empty((R_, R_))
    g_ad(xi, A)
    _vanloan_E(1.0, A, out)
    out[:, :] = np.linalg.inv(out)
"""


def group_fragment(module: str, prefix: str, ops=GROUP_OPS) -> Fragment | None:
    """``g_<op>`` bound to ``<module>.<prefix>_<op>_point``; None when one of ``ops`` is
    missing, except ``E`` and ``dexp_inv``, which come from the Van Loan block exponential
    (:mod:`cartan.groups._generic_kernels`) when the module has neither.  The fused operations
    of :data:`FUSED_OPS` are bound the same way when the module has them, and built from the
    matrices otherwise:

    ``g_Ad_T(g, v, out)``                      Ad_gᵀv
    ``g_dexp_inv_T(xi, v, out)``               dexp⁻¹(ξ)ᵀv
    ``g_dexp_inv_T_pair(xi, v, out, out_neg)`` dexp⁻¹(ξ)ᵀv and dexp⁻¹(−ξ)ᵀv
    ``g_Ad_inv_apply(g, X, out, work)``        ``out[a] = Ad_{g⁻¹} X[a]``, X and out ``(k, r)``
    ``g_E_apply(tau, xi, V, out, work)``       ``out[a] = 𝓔(τ, ξ) V[a]``, V and out ``(k, r)``
    ``g_dexp_inv_apply(xi, v, out, work)``     ``out = dexp⁻¹(ξ) v``
    ``g_coad_exp(xi, s, E, work)``             ``E = exp(ξ)``, ``s ← Ad_Eᵀs`` in place
    ``g_axis_flow(k, t, s, acc, work)``        ``E = exp(t b_k)``, ``s ← Ad_Eᵀs``, ``acc ← acc E`` in place
    ``g_log_chunk(G, lo, hi, XI)``             ``XI[e] = log G[e]`` for ``lo ≤ e < hi``, G ``(E, m, m)``, XI ``(E, r)``
    ``g_dexp_inv_T_pair_chunk(XI, Q, scale, lo, hi, VT, VH)``  ``VT[e] = s_e dexp⁻¹(ξ_e)ᵀq_e``,
                                               ``VH[e] = s_e dexp⁻¹(−ξ_e)ᵀq_e`` (``s_e = scale[e]``, 1 if empty)
    ``g_move_chunk(Di, Dn, G, tail, head, lo, hi)``  ``G[e] ← Di[tail[e]] G[e] Dn[head[e]]`` for ``lo ≤ e < hi``
    ``g_axial_flow_chunk(lo, hi, S, Dn, …)``   the free flow of every (axial) piece at nodes ``lo ≤ i < hi``
    ``g_frames_chunk(Dn, Di, Phi, lo, hi)``    ``Di[i] ← Dn[i]⁻¹``, ``Φ_i ← Φ_i Dn_i`` (rows of Φ), ``lo ≤ i < hi``

    ``work`` is the scratch ``g_work()`` returns (allocated once by the caller; closed forms do
    not touch it); ``out`` must not alias the inputs."""
    mod = importlib.import_module(module)
    imports = {}
    vanloan = not any(hasattr(mod, f"{prefix}_{op}_point") for op in ("E", "dexp_inv"))
    for op in ops:
        name = f"{prefix}_{op}_point"
        if vanloan and op in ("E", "dexp_inv"):
            continue
        if not hasattr(mod, name):
            return None
        imports[f"g_{op}"] = (module, name)
    frag = Fragment(imports=imports)
    if vanloan:
        frag.imports["_vanloan_E"] = ("cartan.groups._generic_kernels", "vanloan_E_point")
        frag.source = _VANLOAN
    return with_fused(frag, module, prefix)


def with_fused(frag: Fragment, module: str | None = None, prefix: str = "") -> Fragment:
    """Add the fused operations to a group's fragment: those it binds already, else the module's
    closed forms where it has them, else the defaults of :data:`FUSED_OPS`; ``g_work()``, the
    defaults' scratch; and the constant ``AXIAL_FLOW_CLOSED_``, whether ``g_axial_flow_chunk``
    is a closed form (the lattice's free flow calls it only then)."""
    mod = importlib.import_module(module) if module else None
    sources = [frag.source] if frag.source.strip() else []
    closed = set()
    for op, default in FUSED_OPS.items():
        name = f"{prefix}_{op}_point"
        if f"g_{op}" in frag.imports:  # bound by the group already
            closed.add(op)
            continue
        if mod is not None and hasattr(mod, name):
            frag.imports[f"g_{op}"] = (module, name)
            closed.add(op)
        else:
            sources.append(default)
    frag.constants.setdefault("AXIAL_FLOW_CLOSED_", "axial_flow_chunk" in closed)
    if "g_work" not in frag.imports:
        sources.append(_WORK)
    frag.source = "\n\n".join(s.strip("\n") + "\n" for s in sources)
    return frag


def _importable(func) -> bool:
    module = getattr(func, "__module__", None)
    if not module or module == "__main__":
        return False
    try:
        return getattr(importlib.import_module(module), func.__name__, None) is not None
    except ImportError:
        return False


def medium_fragment(kernels) -> Fragment:
    """``m_energy`` and ``m_stress`` bound to a medium's declared point kernels (and
    ``m_coupled_velocity``, ``m_coupled_stress`` when it declares them, a Lagrangian coupling N
    and X, and ``m_coupled_jacobian``, ∂N/∂S, when declared too; ``m_accumulator_rate``, the
    rates of per-node accumulators): imported from their
    module, or, when that module cannot be imported (a script, a notebook, ``exec``), from
    :mod:`cartan.compiled.runtime`, where they are registered under a name derived from their
    code."""
    from . import runtime

    imports = {}
    for alias, func in (("m_energy", kernels.energy), ("m_stress", kernels.stress),
                        ("m_coupled_velocity", getattr(kernels, "coupled_velocity", None)),
                        ("m_coupled_stress", getattr(kernels, "coupled_stress", None)),
                        ("m_accumulator_rate", getattr(kernels, "accumulator_rate", None)),
                        ("m_coupled_jacobian", getattr(kernels, "coupled_jacobian", None))):
        if func is None:
            continue
        py = getattr(func, "py_func", func)
        if _importable(py):
            imports[alias] = (py.__module__, py.__name__)
        else:
            imports[alias] = (runtime.__name__, runtime.register(py))
    return Fragment(imports=imports)


_BATCH = """
def energy_batch(X, X0, p, out):
    for i in range(X.shape[0]):
        out[i] = m_energy(X[i], X0[i], p)


def stress_batch(X, X0, p, out):
    for i in range(X.shape[0]):
        m_stress(X[i], X0[i], p, out[i])
"""


def kernel_stem(kernels) -> str:
    """A file-name stem naming a medium's point kernels (``energy-stress`` function names): the
    generated modules are named by the kernels they compile, not by the medium, so that media
    declaring the same kernels (every ``QuadraticMedium``) share them; the coupled kernels and
    the accumulator rate, when declared, join the stem."""
    funcs = (kernels.energy, kernels.stress, getattr(kernels, "coupled_velocity", None),
             getattr(kernels, "coupled_stress", None), getattr(kernels, "accumulator_rate", None))
    return "-".join(getattr(getattr(f, "py_func", f), "__name__", "kernel") for f in funcs if f is not None)


def medium_batch(kernels):
    """A generated module with ``energy_batch(X, X0, p, out)`` and ``stress_batch(X, X0, p, Q)``
    over ``[P, d, r]`` points: the kernels applied point by point (the reference path)."""
    from .codegen import generate

    key = (kernels.energy, kernels.stress)
    if key in _BATCHES:  # the reference path asks on every potential and stress call
        return _BATCHES[key]
    frag = medium_fragment(kernels)
    module = _BATCHES[key] = generate(f"batch-{kernel_stem(kernels)}", [frag, Fragment(source=_BATCH)])
    return module


_BATCHES: dict = {}
