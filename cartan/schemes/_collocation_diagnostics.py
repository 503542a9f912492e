"""Compiled work of the ``collocation`` scheme outside its step loops (``docs/schemes.md``).

:meth:`cartan.schemes.collocation.Collocation.compiled_advance` runs the steps of qualifying
problems in numba; the CFL estimate that ``cartan.simulate`` takes once per run
(:meth:`~cartan.schemes.base.Scheme.dt_max`, a power iteration of about 18 stiffness
products) would otherwise cost as much as hundreds of compiled steps of a short rod.  This
module offers the compiled plan of a problem (the one the step loops use) to that work:

:func:`compiled_stiffness_probe`
    the action v ↦ K v of the force Jacobian: one call of
    :func:`~cartan.schemes._collocation_compiled.stiffness_once` per product, i.e. two exact
    drifts (paper §V, Eq. (X LGI)) and two force evaluations of the compiled loops' kernels
    (``_drift``, ``_force``: the kernels of ``drift_once`` and ``force_once``), in one
    compiled call.

It computes the formulas of the reference methods (``Collocation.drift``/``force``) and
differs from them by round-off; it returns None when the problem has no compiled plan (the
caller then uses the reference methods).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .base import State

__all__ = ["collocation_plan", "compiled_stiffness_probe"]


def collocation_plan(scheme) -> tuple | None:
    """The compiled plan ``(P, Dc)`` of a collocation scheme's problem (built once and kept on
    the scheme, as ``Collocation.compiled_advance`` does), or None: not a collocation scheme,
    the numpy backend, or a problem that does not qualify.

    Raises
    ------
    ValueError
        When the medium's ``quadratic_energy`` is malformed or disagrees with its ``stress``
        (:func:`~cartan.schemes._collocation_compiled.build_plan`).
    """
    from .collocation import Collocation

    if not isinstance(scheme, Collocation):
        return None
    return scheme.compiled_plan("_collocation_compiled")


def _arrays(scheme, state: State) -> tuple[np.ndarray, np.ndarray] | None:
    """``(X [n, r], Phi [n or 1, m, m])`` of a d = 1 collocation state (C-ordered copies), or
    None for another layout (d ≥ 2 among them: the reference stiffness products)."""
    frame_key = "Phi" if scheme.track else "Phi_root"
    if set(state.arrays) != {"X", frame_key}:
        return None
    n, r = np.shape(state.S)[0], np.shape(state.S)[-1]
    X = np.asarray(state.arrays["X"], dtype=float)
    if X.shape != (n, 1, r):
        return None
    Phi = np.array(state.arrays[frame_key], dtype=float, order="C")
    return np.array(X.reshape(n, r), order="C"), (Phi if scheme.track else Phi.reshape(1, *Phi.shape))


def compiled_stiffness_probe(scheme, state: State, eps: float) -> Callable[[np.ndarray], np.ndarray] | None:
    """``v ↦ K v = −[W(Φ exp(εv)) − W(Φ exp(−εv))]/(2ε)`` (W at N = 0) in compiled kernels.

    Parameters
    ----------
    scheme : Collocation
    state : State
        Linearisation point; read once (copied), never modified.
    eps : float
        Difference step.

    Returns
    -------
    callable or None
        ``probe(v)``, v ``[n, r]`` → K v ``[n, r]`` (a new array), or None when the scheme
        has no compiled plan for the problem or the state another layout.
    """
    plan = collocation_plan(scheme)
    arrays = _arrays(scheme, state) if plan is not None else None
    if arrays is None:
        return None
    from ._collocation_compiled import stiffness_once

    P, Dc = plan
    X0, Phi0 = arrays
    shape = X0.shape
    eps = float(eps)

    def probe(v: np.ndarray) -> np.ndarray:
        v = np.ascontiguousarray(v, dtype=float).reshape(shape)
        K = np.empty(shape)
        stiffness_once(P, Dc, X0, Phi0, v, eps, K)
        return K

    return probe
