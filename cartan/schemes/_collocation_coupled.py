"""Lagrangians that couple velocity and strain, ℓ(N, X), on the ``collocation`` scheme.

A medium with :attr:`~cartan.medium.Medium.coupled_lagrangian` gives its Legendre map
pointwise: ``N = ∂H/∂S(S, X)`` (:meth:`~cartan.medium.Medium.velocity_at`), its inverse
``S = ∂ℓ/∂N(N, X)`` (:meth:`~cartan.medium.Medium.momentum_at`), the Hamiltonian stress
``Q = ∂H/∂X(S, X) = −∂ℓ/∂X`` (:meth:`~cartan.medium.Medium.stress_with`) and the Hamiltonian
density ``H(S, X) = ⟨S, N⟩ − ℓ`` (:meth:`~cartan.medium.Medium.hamiltonian`).

Discretisation (docs/design.md, "Media whose Lagrangian couples N and X")
-------------------------------------------------------------------------
On the collocation the momentum S_i, the strains X_{α,i} and the velocity N_i share the nodes,
so the discretisation is pointwise.  With the node momenta p_i = w_i S_i (w_i the quadrature
weights, the SBP norm on open axes) the discrete Hamiltonian is

    H_d = Σ_i w_i H(S_i, X_i),

and the scheme's operators are its derivatives:

    N_i = ∂H_d/∂p_i = ∂H/∂S(S_i, X_i)               (:func:`coupled_velocity`),
    Q^α_i = (1/w_i) ∂H_d/∂X_{α,i} = ∂H/∂X_α(S_i, X_i)  (the stress of ``Collocation.internal_force``),

the force ``W = Σ_α (D_αQ^α − ad_{X_α}ᵀQ^α)`` (plus the free ends' penalty) being the
collocation's with this stress.  The argument that conserves the uncoupled energy uses only
N = ∂H/∂S and Q = ∂H/∂X at each node, so it carries over unchanged: along
``Ẋ_α = D_αN − ad_N X_α``, ``Ṡ = ad_Nᵀ S + W``,

    dH_d/dt = Σ_i w_i [⟨N_i, Ṡ_i⟩ + Σ_α ⟨Q^α_i, Ẋ_{α,i}⟩]
            = Σ_α [Nᵀ(H D_α)Q^α + Q^αᵀ(H D_α)N]   (⟨N, ad_NᵀS⟩ = 0, ⟨N, ad_Xᵀ Q⟩ = ⟨Q, ad_N X⟩)
            = boundary terms (H D + (H D)ᵀ = diag(−1, 0, …, 0, 1)),

zero on periodic axes (D skew, w = h) and the free ends' load power ``Σ_ends P·N`` with their
penalty, as for ℓ = K − U.  For ℓ = K(N) − U(X) (the contract's defaults) the operators are the
collocation's usual ones: N_i = M⁺S_i, Q_i = ∂U/∂X(X_i), H_d = Σ w (K + U).

d ≥ 2: the formulas and the argument hold axis by axis (the tensor-product weights are a
diagonal SBP norm on every axis), but :class:`~cartan.schemes.base.Scheme` admits coupled media
for d = 1 only, as on the lattice: no medium with a d ≥ 2 coupled Lagrangian exists to test it.

Not supported with a coupled Lagrangian (``ValueError``): a stress-free ``reference``
configuration (the medium's Hamiltonian stress has no rest-strain form), held ends and
symmetry faces (their held components would need the constrained Legendre map), driven ends
(refused by the base scheme).  With the medium's coupled point kernels the compiled operators
(``Collocation.compiled_operators``, :mod:`cartan.schemes._collocation_ops`) run the same
pointwise maps in the loops of ``lie-euler``, ``forward-euler`` and ``rkmk4``; the other
integrators (``implicit-midpoint``) and media without those kernels take the numpy path.

Where it plugs in: the collocation names this module as its ``coupled_module``
(:attr:`cartan.schemes.base.Scheme.coupled_module`), so the base scheme's
:meth:`~cartan.schemes.base.Scheme.velocity`, :meth:`~cartan.schemes.base.Scheme.momentum` (the
stage momenta of ``implicit-midpoint``), :meth:`~cartan.schemes.base.Scheme.kinetic_energy` and
the initial momenta call :func:`coupled_velocity`, :func:`initial_momentum` and
:func:`kinetic_part`; the collocation's ``internal_force`` and ``_clamped_traction`` take the
stress from ``stress_with(S, X)``, and its constructor calls :func:`check_problem`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..state import State

__all__ = ["check_problem", "coupled_stress", "coupled_velocity", "hamiltonian", "initial_momentum", "kinetic_part"]

#: relative tolerance of the round trip N(S(N, X), X) = N in :func:`initial_momentum`
_ROUND_TRIP = 1e-9


def _strains(state: State) -> np.ndarray:
    """The nodal strains ``[*shape, d, r]``."""
    return state.arrays["X"]


def coupled_velocity(scheme: Any, state: State) -> np.ndarray:
    """``N_i = ∂H/∂S(S_i, X_i)`` ``[*shape, r]`` (module docstring), before the clamps.

    Raises
    ------
    ValueError
        From the medium: S outside the range of its Legendre map.
    """
    return np.array(scheme.medium.velocity_at(state.S, _strains(state)), dtype=float)


def coupled_stress(scheme: Any, state: State) -> np.ndarray:
    """``Q^α_i = ∂H/∂X_α(S_i, X_i)`` ``[*shape, d, r]``: the Hamiltonian stress at the nodes."""
    return np.asarray(scheme.medium.stress_with(state.S, _strains(state)), dtype=float)


def hamiltonian(scheme: Any, state: State) -> float:
    """The discrete Hamiltonian ``H_d = Σ_i w_i H(S_i, X_i)``."""
    return float(np.sum(scheme.weights * scheme.medium.hamiltonian(state.S, _strains(state))))


def kinetic_part(scheme: Any, state: State) -> float:
    """``H_d − Σ_i w_i U(X_i)``: the discrete Hamiltonian less the medium's internal potential
    (``Scheme.kinetic_energy``; with ``potential_energy`` the sum is H_d plus the loads' energies)."""
    X = _strains(state)
    med = scheme.medium
    return float(np.sum(scheme.weights * (med.hamiltonian(state.S, X) - med.potential(X))))


def initial_momentum(scheme: Any, state: State, N: np.ndarray, start: np.ndarray | None = None) -> np.ndarray:
    """The node momenta S ``[*shape, r]`` whose velocity (:func:`coupled_velocity`) at ``state``'s
    strains is ``N`` ``[*shape, r]``: ``S_i = ∂ℓ/∂N(N_i, X_i)``, pointwise (``start``, a first
    iterate on the lattice, is not needed: the map is inverted node by node), checked by the round
    trip ``N(S_i, X_i) = N_i`` on the live components to 1e-9 of the largest live |N| (at least
    1e-3 of the largest |N|, gauge components included).

    Raises
    ------
    ValueError
        When ``N`` is outside the range of the Legendre map (S not finite, the medium's inverse
        failing, or the round trip missing ``N``).
    """
    med = scheme.medium
    X = _strains(state)
    N = np.asarray(N, dtype=float)
    fail = (f"medium {med.name!r}: the velocity is outside the range of the Legendre map S(N, X) "
            "(no momentum found)")
    with np.errstate(all="ignore"):
        S = np.array(med.momentum_at(N, X), dtype=float)
    if not np.all(np.isfinite(S)):
        raise ValueError(fail)
    S[..., ~scheme.live] = 0.0
    try:
        back = np.asarray(med.velocity_at(S, X), dtype=float)
    except (ValueError, FloatingPointError, np.linalg.LinAlgError):
        raise ValueError(fail) from None
    live = scheme.live
    scale = max(float(np.max(np.abs(N[..., live]), initial=0.0)), 1e-3 * float(np.max(np.abs(N), initial=0.0)),
                1e-300)
    err = np.abs(back - N)[..., live]
    if scheme._clamped.any():  # (the clamped nodes' N is held at zero, not the Legendre map's)
        err = np.where(scheme._clamped[..., None], 0.0, err)
    if not np.all(np.isfinite(back)) or float(np.max(err, initial=0.0)) > _ROUND_TRIP * scale:
        raise ValueError(fail)
    return S


def check_problem(scheme: Any) -> None:
    """Refuse what the pointwise discretisation does not cover (module docstring).

    Raises
    ------
    ValueError
        A ``reference`` configuration, a :class:`~cartan.problem.Held` end or a
        :class:`~cartan.problem.Symmetry` face.
    """
    if scheme.problem.reference is not None:
        raise ValueError(f"reference: the collocation scheme takes no reference configuration with a "
                         f"Lagrangian that couples N and X (medium {scheme.medium.name!r}, "
                         "Medium.coupled_lagrangian); use scheme='lattice'")
    if scheme._clamped.ndim > scheme.grid.d:
        raise ValueError("boundaries: a Symmetry face or a Held end is not supported with a Lagrangian that "
                         f"couples N and X (medium {scheme.medium.name!r}, Medium.coupled_lagrangian)")
