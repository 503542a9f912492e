"""Compiled work over a scheme's operator set outside the step loops.

What ``cartan.simulate`` does around the steps — the CFL estimate once per run
(:meth:`~cartan.schemes.base.Scheme.dt_max`), the blow-up guard's energies at steps 1, 2, 4, 8 …
— would otherwise cost as much as thousands of compiled steps.  The functions here run it on a
scheme's compiled operators (:class:`~cartan.compiled.operators.OperatorSet`, operators of the
contract in :mod:`cartan.schemes._lattice_ops` only), so they serve every scheme with a set:

:func:`diag_stiffness_probe` (compiled) and :func:`compiled_stiffness_probe`
    the action v ↦ K v of the force Jacobian,
    ``K v = −[W(Φ exp(εv)) − W(Φ exp(−εv))]/(2ε)`` with W the force density at N = 0
    (``op_copy_config``, ``op_drift``, ``op_force`` on a copy of the configuration);
:func:`guard_energies`
    ``(K, V)``: the kinetic energy ``op_kinetic`` and the potential energy ``op_potential``
    (the discrete energy of paper §VI.C plus the conservative loads').

Both evaluate the reference methods' formulas (``Scheme.stiffness_probe``'s numpy products,
``Scheme.kinetic_energy``, the scheme's ``potential_energy``) in another order and differ from
them by round-off; both return None when the scheme has no operator set that covers the
state, and the caller then uses the reference methods.  Saved frames always use the
reference methods.

A set that serves some loops only (``OperatorSet.reason``, ``OperatorSet.loops``) runs the
diagnostics when it lists :data:`SERVED` among them: the collocation's set with
:class:`~cartan.problem.Driven` ends (:mod:`cartan.schemes._collocation_ops`), whose driven
nodes are held (``clamped``), so that the probe's drift leaves them where the power iteration
zeroes the directions (``v = 0`` there, ``W = 0`` there, as ``Scheme.dt_max`` does), whose
``op_kinetic`` adds their ½ w ξ·Mξ (``Scheme.kinetic_energy`` with N = ξ there) and whose
``op_potential`` is a clamped set's.  The supports' power R·ξ (the weak-form raw force at the
driven nodes) is not the diagnostics' business: the loops book it in ``external_work``
(``op_powers``), which the guard reads from the state.

:func:`loop_fragment` adds the compiled functions to every generated module
(:data:`cartan.compiled.operators.LOOP_SOURCES`); they compile on first call only.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from .codegen import Fragment, njit_source

__all__ = ["SERVED", "compiled_stiffness_probe", "diag_stiffness_probe", "guard_energies", "loop_fragment"]

#: the name under which an operator set that serves some loops only (``OperatorSet.loops``)
#: lists these diagnostics, the probe's and the guard's energies (``OperatorSet.serves``: a
#: function name of the set's module, here the probe's)
SERVED = "diag_stiffness_probe"


# ---------------------------------------------------------------------------- compiled
# Plain Python compiled inside each generated module, where ``op_*`` are the scheme's
# operators and ``R_`` the dimension of the algebra.

def diag_stiffness_probe(D, C0, Cs, V, eps, t, Wp, Wm, out, K):
    """``out = −(W(C0 exp(εV)) − W(C0 exp(−εV)))/(2ε)`` with W = ``op_force`` at N = 0 and time
    ``t``; ``Cs`` is scratch of ``C0``'s layout (``op_new_config``), ``C0`` is not modified.
    ``V``, ``Wp``, ``Wm``, ``out`` ``[n, r]``."""
    n = V.shape[0]
    N = np.zeros((n, R_))  # noqa: F821
    op_copy_config(C0, Cs)  # noqa: F821
    op_drift(D, Cs, eps, V, K)  # noqa: F821
    op_force(D, Cs, t, N, Wp, K)  # noqa: F821
    op_copy_config(C0, Cs)  # noqa: F821
    op_drift(D, Cs, -eps, V, K)  # noqa: F821
    op_force(D, Cs, t, N, Wm, K)  # noqa: F821
    for i in range(n):
        for k in range(R_):  # noqa: F821
            out[i, k] = -(Wp[i, k] - Wm[i, k]) / (2.0 * eps)


def loop_fragment() -> Fragment:
    """The diagnostics' compiled functions as one fragment of a generated module."""
    return Fragment(source=njit_source(diag_stiffness_probe))


# ---------------------------------------------------------------------------- Python side
def _operators(scheme, state) -> Any | None:
    """The scheme's operator set when compiled diagnostics may use it for ``state``: the numba
    backend, ``scheme.compiled_diagnostics`` set, a set that serves the diagnostics (every loop,
    or :data:`SERVED` among its ``loops``) and accepts the state's layout; None otherwise."""
    from .._backend import get_backend

    if get_backend() != "numba" or not getattr(scheme, "compiled_diagnostics", False):
        return None
    operators = getattr(scheme, "compiled_operators", None)
    ops = operators() if operators is not None else None
    if ops is None or not ops.serves(SERVED) or not ops.accepts(state):
        return None
    return ops


def compiled_stiffness_probe(scheme, state, eps: float) -> Callable[[np.ndarray], np.ndarray] | None:
    """``v ↦ K v`` of :meth:`~cartan.schemes.base.Scheme.stiffness_probe` on the scheme's
    compiled operators (:func:`diag_stiffness_probe`).

    Parameters
    ----------
    scheme : Scheme
    state : State
        The linearisation point; read once (packed into the operators' layout), never modified.
    eps : float
        Difference step ε.

    Returns
    -------
    callable or None
        ``probe(v)`` for v ``[*shape, r]`` → K v ``[*shape, r]`` (a new array, the shape of
        ``state.S``), the force at time ``state.t``; None when the scheme has no operator set
        covering the state (see :func:`_operators`).
    """
    ops = _operators(scheme, state)
    if ops is None:
        return None
    from .codegen import first_call

    module = ops.generated()
    data = ops.data
    C0 = ops.pack(state)
    Cs = module.op_new_config(C0)
    work = module.op_work(data)
    shape = np.shape(state.S)
    n = ops.nodes
    r = int(np.prod(shape)) // n
    Wp, Wm = np.empty((n, r)), np.empty((n, r))
    eps, t = float(eps), float(state.t)
    what = f"the stiffness probe for {ops.label}"

    def probe(v: np.ndarray) -> np.ndarray:
        V = np.ascontiguousarray(v, dtype=float).reshape(n, r)
        out = np.empty((n, r))
        with first_call(module, "diag_stiffness_probe", what):
            module.diag_stiffness_probe(data, C0, Cs, V, eps, t, Wp, Wm, out, work)
        return out.reshape(shape)

    return probe


def _energy_methods_are_the_sets(scheme) -> bool:
    """Whether ``op_kinetic`` and ``op_potential`` compute this scheme's energies: the base
    ``Scheme.kinetic_energy`` and the medium's base ``kinetic``, and the ``potential_energy``
    of the class that defines ``compiled_operators`` (a subclass that overrides one but not
    the other is declined)."""
    from ..medium import Medium

    cls = type(scheme)
    # the base class's kinetic energy (the deepest class of the MRO that defines it), which
    # op_kinetic computes; read from the MRO so that this layer imports no scheme module
    base = [c for c in cls.__mro__ if "kinetic_energy" in vars(c)][-1]
    if cls.kinetic_energy is not vars(base)["kinetic_energy"] or type(scheme.medium).kinetic is not Medium.kinetic:
        return False
    owner = next(c for c in cls.__mro__ if "compiled_operators" in vars(c))
    return cls.potential_energy is getattr(owner, "potential_energy", None)


def _kernels_describe_potential(medium) -> bool:
    """Whether the medium's energy kernel agrees with its ``potential_at`` at a few strains near
    the rest strain (to 1e-9 of the energy's size: the two evaluate one formula in another
    order); the stress kernel is checked when the operator set is built."""
    kernels = medium.point_kernels()
    if kernels is None:
        return False
    X0 = np.ascontiguousarray(np.asarray(medium.rest_strain(), dtype=float))
    params = np.ascontiguousarray(kernels.params, dtype=float).ravel()
    rng = np.random.default_rng(0)
    for _ in range(3):
        X = np.ascontiguousarray(X0 + 0.05 * rng.standard_normal(X0.shape))
        U = float(kernels.energy(X, X0, params))
        ref = float(np.asarray(medium.potential_at(X[None], X0[None]), dtype=float).reshape(-1)[0])
        if not abs(U - ref) <= 1e-9 * max(abs(ref), 1e-300):
            return False
    return True


def guard_energies(scheme, state) -> tuple[float, float] | None:
    """``(K, V)`` of ``state`` on the scheme's compiled operators, or None without them.

    K = ``op_kinetic`` = ``Scheme.kinetic_energy`` = ½ Σᵢ wᵢ Sᵢ·M⁺Sᵢ over the unclamped nodes;
    V = ``op_potential`` = the scheme's ``potential_energy``: the discrete internal energy
    (paper §VI.C) plus the conservative loads' energies.  None — the caller then uses the
    reference methods — with the numpy backend, ``scheme.compiled_diagnostics`` cleared, no
    operator set covering the state, energy methods other than the ones the set implements
    (:func:`_energy_methods_are_the_sets`), or a medium whose energy kernel does not describe
    its potential.

    Parameters
    ----------
    scheme : Scheme
    state : State
        Read only.

    Returns
    -------
    tuple of float or None
    """
    ops = _operators(scheme, state)
    if ops is None:
        return None
    held = ops.__dict__.setdefault("_guard", {})
    if "ok" not in held:
        held["ok"] = _energy_methods_are_the_sets(scheme) and _kernels_describe_potential(scheme.medium)
    if not held["ok"]:
        return None
    from .codegen import first_call

    module = ops.generated()
    if "work" not in held:
        held["work"] = module.op_work(ops.data)
    S = np.ascontiguousarray(state.S, dtype=float).reshape(ops.nodes, -1)
    with first_call(module, "op_potential", f"the energies for {ops.label}"):
        K = float(module.op_kinetic(ops.data, S))
        V = float(module.op_potential(ops.data, ops.pack(state), held["work"]))
    return K, V
