"""Compiled work of the ``lattice`` scheme's SE(3) rod loops outside the steps (``docs/performance.md``).

:meth:`cartan.schemes.lattice.Lattice.compiled_advance` runs the steps of SE(3) rods
(:mod:`cartan.schemes._lattice_compiled`) in numba; what ``cartan.simulate`` does around the
steps, once per run or once per save, would otherwise cost as much as thousands of compiled
steps.  This module offers the plan of such a problem (the same plan the step loops use) to
that work; every other problem uses the generated diagnostics
(:mod:`cartan.compiled.diagnostics`):

:func:`compiled_stiffness_probe`
    the action v ↦ K v of the force Jacobian for the CFL estimate
    (:meth:`~cartan.schemes.base.Scheme.dt_max`): two drifts and two force evaluations of the
    loops' structure-of-arrays passes per product (:func:`cartan.schemes._lattice_compiled.force_once`);
:func:`guard_energies`
    the kinetic and potential energy of a state for the blow-up guard of ``cartan.simulate``,
    from the plan's quadratic energy ``U = ½(X − X₀)ᵀC(X − X₀)`` (paper §VI.C) instead of the
    medium's generic ``stress``/``potential`` calls.

Both compute the formulas of the reference methods (``Lattice.drift``/``force``,
``Scheme.kinetic_energy``, ``Lattice.potential_energy``) and differ from them by round-off;
both return None when the problem has no compiled plan (the caller then uses the reference
methods).  Saved frames always use the reference methods.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..state import State

__all__ = ["compiled_stiffness_probe", "guard_energies", "lattice_plan"]


def lattice_plan(scheme) -> tuple | None:
    """The compiled plan of a lattice scheme's problem (built once and kept on the scheme, as
    ``Lattice.compiled_advance`` does), or None: not a lattice, not an SE(3) rod (d = 1), the
    numpy backend, or a problem that does not qualify."""
    from .lattice import Lattice

    if not isinstance(scheme, Lattice) or scheme.grid.d != 1:
        return None
    return scheme.compiled_plan("_lattice_compiled")


def _arrays(scheme, state: State) -> tuple[np.ndarray, np.ndarray] | None:
    """``(G [ne, m, m], Phi [n or 1, m, m])`` of a d = 1 lattice state, or None for another layout."""
    key = scheme._key(0)
    frame_key = "Phi" if scheme.track else "Phi_root"
    if set(state.arrays) != {key, frame_key}:
        return None
    G = np.asarray(state.arrays[key], dtype=float)
    Phi = np.asarray(state.arrays[frame_key], dtype=float)
    return G, (Phi if scheme.track else Phi.reshape(1, *Phi.shape))


def compiled_stiffness_probe(scheme, state: State, eps: float) -> Callable[[np.ndarray], np.ndarray] | None:
    """``v ↦ K v = −[W(Φ exp(εv)) − W(Φ exp(−εv))]/(2ε)`` (W at N = 0) in compiled kernels.

    Parameters
    ----------
    scheme : Lattice
    state : State
        Linearisation point; read once, never modified.
    eps : float
        Difference step.

    Returns
    -------
    callable or None
        ``probe(v)``, v ``[n, r]`` → K v ``[n, r]`` (a new array), or None when the scheme
        has no compiled plan for the problem.
    """
    plan = lattice_plan(scheme)
    arrays = _arrays(scheme, state) if plan is not None else None
    if arrays is None:
        return None
    from ._lattice_compiled import force_once

    G0, Phi0 = (np.array(a, dtype=float, order="C") for a in arrays)
    n, r = np.shape(state.S)
    zero = np.zeros((n, r))
    W_plus = np.empty((n, r))
    W_minus = np.empty((n, r))
    eps = float(eps)

    def probe(v: np.ndarray) -> np.ndarray:
        v = np.ascontiguousarray(v, dtype=float).reshape(n, r)
        for tau, W in ((eps, W_plus), (-eps, W_minus)):
            force_once(scheme, plan, G0, Phi0, zero, W, v, tau)
        return -(W_plus - W_minus) / (2 * eps)

    return probe


def guard_energies(scheme, state: State) -> tuple[float, float] | None:
    """``(K, V)`` of ``state`` from the compiled plan's data, or None without a plan.

    K = ½ Σᵢ wᵢ Σ_k S_ik²/m_k over live components and free (not clamped) nodes;
    V = h Σ_e ½(ξ_e/h − X₀)ᵀC(ξ_e/h − X₀), ξ_e = log G_e, plus the energies of the
    conservative loads (``Σᵢ wᵢ U(Φᵢ)``), as in ``Lattice.potential_energy``.  Only for the
    scheme, medium and energy methods of the core (overridden ones get None).
    """
    from ..medium import Medium, QuadraticMedium
    from .base import Scheme
    from .lattice import Lattice

    plan = lattice_plan(scheme)
    if plan is None or not scheme.compiled_diagnostics:
        return None
    medium = scheme.medium
    if (
        type(scheme).kinetic_energy is not Scheme.kinetic_energy
        or type(scheme).potential_energy is not Lattice.potential_energy
        or type(scheme).frames is not Lattice.frames
        or type(medium).kinetic is not Medium.kinetic
        or type(medium).potential is not QuadraticMedium.potential
    ):
        return None
    cache = scheme.__dict__.setdefault("_guard_energy_data", {})
    if not cache:
        X0, C = medium.quadratic_energy()  # checked against stress() when the plan was built
        cache["inv"] = np.where(scheme.live, 1.0 / np.where(scheme.live, scheme.mass, 1.0), 0.0)
        cache["weights"] = np.asarray(scheme.weights, dtype=float)
        cache["moving"] = np.where(scheme._clamped, 0.0, cache["weights"])
        cache["X0"], cache["C"] = np.asarray(X0, dtype=float), np.asarray(C, dtype=float)
        cache["h"] = float(scheme.h[0])
    S = np.asarray(state.S)
    K = 0.5 * float(cache["moving"] @ ((S * S) @ cache["inv"]))
    h = cache["h"]
    D = scheme.group.log(state.arrays[scheme._key(0)]) / h - cache["X0"]
    V = 0.5 * h * float(np.vdot(D, D @ cache["C"]))
    conservative = [load for load in scheme.problem.loads if load.conservative]
    if conservative:
        Phi = scheme.frames(state)
        for load in conservative:
            V += float(np.sum(cache["weights"] * load.energy(Phi)))
    return K, V
