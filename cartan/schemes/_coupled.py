"""Lagrangians that couple velocity and strain, ℓ(N, X), on the ``lattice`` (d = 1).

A medium with :attr:`~cartan.medium.Medium.coupled_lagrangian` gives its Legendre map
pointwise: ``N = ∂H/∂S(S, X)`` (:meth:`~cartan.medium.Medium.velocity_at`), the Hamiltonian
stress ``Q = ∂H/∂X(S, X) = −∂ℓ/∂X`` (:meth:`~cartan.medium.Medium.stress_with`) and the
Hamiltonian density ``H(S, X) = ⟨S, N⟩ − ℓ`` (:meth:`~cartan.medium.Medium.hamiltonian`).

Discretisation (docs/design.md, "Media whose Lagrangian couples N and X")
-------------------------------------------------------------------------
The momentum lives at the nodes, the strain on the edges.  Each edge e = (i → j) of length h
is split into two halves, one per end node, and the discrete Hamiltonian is

    H_d = Σ_e (h/2) [H(S_i, X_e) + H(S_j, X_e)],

with the node momenta p_i = w_i S_i (w_i = Σ_{e∋i} h/2, the lattice's node weight).  Its
derivatives are what the lattice needs, with no change to the integrators:

    N_i = ∂H_d/∂p_i = Σ_{e∋i} (h/2w_i) ∂H/∂S(S_i, X_e)        (:func:`coupled_velocity`),
    Q_e = (1/h) ∂H_d/∂X_e = ½[∂H/∂X(S_i, X_e) + ∂H/∂X(S_j, X_e)]  (:func:`coupled_stress`),

the edge stress that the lattice pulls back to the nodes through dexp⁻¹ as for a potential.
Every edge strain enters H_d with its full weight (no averaging of strains onto nodes, which
would leave the zigzag mode without energy).  The semi-discrete system
``Φ̇_i = Φ_i N_i``, ``ṗ_i = ad_{N_i}ᵀ p_i + F_i`` is Lie–Poisson × canonical with the
Hamiltonian H_d: H_d is conserved by its flow, and when H is invariant under the left action
the momentum map ``Σ w_i Ad*_{Φ_i⁻¹} S_i`` is conserved too.  For ℓ = K(N) − U(X) it is the
lattice's usual system (N_i = M⁺S_i, Q_e = ∂U/∂X(X_e)).

These are the reference path's operators.  A medium that declares its coupled point kernels
(:class:`cartan.medium.MediumKernels` ``coupled_velocity``, ``coupled_stress``) runs the same
formulas in the lattice's generated loops of ``rkmk4``, ``lie-euler`` and ``forward-euler``
(:func:`cartan.schemes._lattice_ops.coupled_fragment`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..scatter import scatter_add
from ..state import State

__all__ = ["coupled_stress", "coupled_velocity", "hamiltonian", "initial_momentum", "kinetic_part"]

#: iterations and relative tolerance of :func:`initial_momentum`
_ITERATIONS, _TOL = 60, 1e-14


def _half_edges(scheme: Any, state: State) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(tail nodes ``[E]``, head nodes ``[E]``, edge strains ``[E, 1, r]``, h) of a d = 1 lattice."""
    nodes = np.arange(scheme.grid.shape[0])
    tail, head = scheme._ends(nodes, 0)
    h = float(scheme.h[0])
    X = scheme.group.log(state.arrays[scheme._key(0)]) / h
    return tail, head, X[:, None, :], h


def _to_nodes(scheme: Any, tail: np.ndarray, head: np.ndarray, at_tail: np.ndarray, at_head: np.ndarray,
              h: float) -> np.ndarray:
    """``Σ_{e∋i} (h/2w_i) f(i, e)`` from the half-edge values at the tails and heads ``[E, r]``."""
    out = np.zeros((scheme.grid.shape[0], at_tail.shape[-1]))
    scatter_add(out, tail, 0.5 * h * at_tail)
    scatter_add(out, head, 0.5 * h * at_head)
    return out / np.asarray(scheme.weights, dtype=float)[:, None]


def coupled_velocity(scheme: Any, state: State) -> np.ndarray:
    """``N_i = Σ_{e∋i} (h/2w_i) N(S_i, X_e)`` ``[n, r]`` (module docstring)."""
    tail, head, X, h = _half_edges(scheme, state)
    med = scheme.medium
    return _to_nodes(scheme, tail, head, med.velocity_at(state.S[tail], X), med.velocity_at(state.S[head], X), h)


def coupled_stress(scheme: Any, state: State, X: np.ndarray) -> np.ndarray:
    """``Q_e = ½[Q(S_i, X_e) + Q(S_j, X_e)]`` ``[E, r]`` for the edge strains ``X`` ``[E, r]``."""
    nodes = np.arange(scheme.grid.shape[0])
    tail, head = scheme._ends(nodes, 0)
    med = scheme.medium
    full = np.asarray(X, dtype=float)[:, None, :]
    return 0.5 * (med.stress_with(state.S[tail], full) + med.stress_with(state.S[head], full))[:, 0, :]


def hamiltonian(scheme: Any, state: State) -> float:
    """The discrete Hamiltonian ``H_d = Σ_e (h/2)[H(S_i, X_e) + H(S_j, X_e)]``."""
    tail, head, X, h = _half_edges(scheme, state)
    med = scheme.medium
    return float(0.5 * h * np.sum(med.hamiltonian(state.S[tail], X) + med.hamiltonian(state.S[head], X)))


def kinetic_part(scheme: Any, state: State) -> float:
    """``H_d − Σ_e h U(X_e)``: the discrete Hamiltonian less the medium's internal potential
    (``Scheme.kinetic_energy``; with ``potential_energy`` the sum is H_d plus the loads' energies)."""
    tail, head, X, h = _half_edges(scheme, state)
    med = scheme.medium
    H = 0.5 * (med.hamiltonian(state.S[tail], X) + med.hamiltonian(state.S[head], X))
    return float(h * np.sum(H - med.potential(X)))


def initial_momentum(scheme: Any, state: State, N: np.ndarray, start: np.ndarray | None = None) -> np.ndarray:
    """The node momenta S ``[n, r]`` whose discrete velocity (:func:`coupled_velocity`) is ``N``.

    Starts from the half-edge average of the pointwise Legendre map ``S(N_i, X_e)`` and corrects
    it by ``S ← S + Σ_e (h/2w_i)[S(N_i, X_e) − S(N_i(S), X_e)]`` (a Newton step with the
    half-edge average of ∂S/∂N for the Jacobian) until ``N(S)`` matches ``N`` on the live
    components to 1e-14 of the largest live component of ``N`` (at least 1e-3 of its largest
    component, gauge components included: N₀ = c in a temporal gauge).  A
    ``start`` ``[n, r]`` (a nearby solution, e.g. the previous stage's momenta) replaces the
    half-edge average as the first iterate; the fixed point is the same.

    Raises
    ------
    ValueError
        When the iteration does not converge (the Legendre map is not invertible there).
    """
    tail, head, X, h = _half_edges(scheme, state)
    med = scheme.medium
    N = np.asarray(N, dtype=float)

    def legendre(Nt: np.ndarray, Nh: np.ndarray) -> np.ndarray:
        return _to_nodes(scheme, tail, head, med.momentum_at(Nt[tail], X), med.momentum_at(Nh[head], X), h)

    target = legendre(N, N)
    S = target.copy() if start is None or np.shape(start) != target.shape else np.array(start, dtype=float)
    live = ~np.asarray(med.gauge_mask(), dtype=bool)
    # relative to the largest live velocity, but at least 1e-3 of the largest component of N, the
    # gauge ones included (N₀ = c in the temporal gauge): a zero live velocity (a string at rest,
    # the stage ξ = 0) is met to the round-off of the medium's own inverse, not to 1e-300
    scale = max(float(np.max(np.abs(N[..., live]), initial=0.0)), 1e-3 * float(np.max(np.abs(N), initial=0.0)),
                1e-300)
    trial = state.copy()
    for _ in range(_ITERATIONS):
        trial.S = S
        Nd = coupled_velocity(scheme, trial)
        if float(np.max(np.abs((Nd - N)[..., live]), initial=0.0)) <= _TOL * scale:
            return S
        S = S + target - legendre(Nd, Nd)
    raise ValueError(f"medium {med.name!r}: the initial velocity is outside the range of the Legendre map "
                     "N(S, X) (no momentum found)")
