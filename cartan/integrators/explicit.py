"""The explicit integrators of ARCHITECTURE.md §5.

Notation: the scheme supplies N(S), the force density W and the drift Φ ← Φ exp(τN); the
momentum obeys ``Ṡ = ad_Nᵀ S + W`` (paper §V with ad* = −adᵀ), i.e. ``Ṡ + ad*_N S = W``.

==================  =====  =========  ==========  =======================================
name                order  geometric  symplectic  update
==================  =====  =========  ==========  =======================================
``forward-euler``   1      no         no          Φ += ΔtΦN̂, S += Δt(ad_NᵀS + W)
``lie-euler``       1      yes        no          paper §V: S⁺ = Ad*_{exp ΔtN}S + 𝓔*(Δt,N)W,
                                                  Φ⁺ = Φ exp(ΔtN)
``lie-verlet``      2      yes        yes         half kick, exact split free flow, half kick
``rkmk4``           4      yes        no          Runge–Kutta–Munthe-Kaas, classical tableau
``overdamped``      1–2    yes        —           N = Γ⁻¹W(N = 0); Lie–Euler or RKMK2 (Heun)
``kinematic``       1–4    yes        —           N = f(t, u, X) prescribed; RKMK of that order
==================  =====  =========  ==========  =======================================
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from ..compiled.tableaux import TABLEAUX
from ..problem import Damping
from ..schemes.base import Scheme, State
from .base import Integrator

__all__ = ["ForwardEuler", "Kinematic", "LieEuler", "LieVerlet", "Overdamped", "RKMK4"]


def _adT(group, N: np.ndarray, S: np.ndarray) -> np.ndarray:
    """Lie–Poisson term ad_Nᵀ S = −ad*_N S, ``[..., r]``."""
    return np.einsum("...ji,...j->...i", group.ad(N), S)


def _coAd_exp(group, tau: float, N: np.ndarray, S: np.ndarray) -> np.ndarray:
    """Ad*_{exp(τN)} S = Ad_{exp(τN)}ᵀ S, the exact solution of Ṡ = ad_NᵀS for frozen N."""
    return np.einsum("...ji,...j->...i", group.Ad(group.exp(tau * N)), S)


class ForwardEuler(Integrator):
    """Naive explicit Euler on the matrix entries of Φ (and of the edge elements) and on S.

    The baseline that shows why geometry matters: Φ leaves the group at every step, and
    for undamped motion the method is unstable at every Δt (``stability = 0``).
    """

    name = "forward-euler"
    order = 1
    geometric = False
    stability = 0.0

    def _step(self, scheme: Scheme, state: State, dt: float) -> None:
        N = scheme.velocity(state)
        W = self.force(scheme, state, N, state.t)
        S_dot = _adT(scheme.group, N, state.S) + W
        scheme.drift(state, dt, N, exact=False)
        state.S = state.S + dt * S_dot
        scheme.constrain(state)

    def compiled_loop(self, scheme: Scheme, state: State, dt: float):
        return "euler_loop", (False,)


class LieEuler(Integrator):
    """The paper's Lie group integrator (§V), faithfully:

    ``S⁺ = Ad*_{exp(ΔtN)} S + 𝓔*(Δt, N) W`` with ``𝓔*(Δt, N) = 𝓔(Δt, N)ᵀ``, and the
    configuration advanced by ``Φ⁺ = Φ exp(ΔtN)`` (on the lattice: edges conjugated; on
    collocation: ``X⁺ = Ad_{exp(−ΔtN)}X + 𝓔(Δt,−N)∂_uN``).  First order; stays in G.
    """

    name = "lie-euler"
    order = 1
    stability = 0.0

    def _step(self, scheme: Scheme, state: State, dt: float) -> None:
        g = scheme.group
        N = scheme.velocity(state)
        W = self.force(scheme, state, N, state.t)
        S = _coAd_exp(g, dt, N, state.S) + np.einsum("...ji,...j->...i", g.E(dt, N), W)
        scheme.drift(state, dt, N, exact=True)
        state.S = S
        scheme.constrain(state)

    def compiled_loop(self, scheme: Scheme, state: State, dt: float):
        return "euler_loop", (True,)

    def driven_reason(self, scheme: Scheme) -> str | None:
        return None  # Φ ← Φ exp(ΔtN) with N = ξ at a driven node


def _abelian_pieces(group, live: np.ndarray) -> list[np.ndarray]:
    """Group the live basis directions into mutually commuting sets.

    Within a set K the sub-Hamiltonian ½Σ_{k∈K} S_k²/m_k generates a flow with N constant
    (its components S_K are invariant under Ad* by elements of the abelian subalgebra), so
    Φ ← Φ exp(τN), S ← Ad*_{exp τN} S is its exact solution.
    """
    r = group.dim
    eye = np.eye(r)
    pieces: list[list[int]] = []
    for k in range(r):
        if not live[k]:
            continue
        for piece in pieces:
            if all(np.max(np.abs(group.bracket(eye[k], eye[j]))) == 0.0 for j in piece):
                piece.append(k)
                break
        else:
            pieces.append([k])
    return [np.array(p) for p in pieces]


#: fixed-point iterations of lie-verlet's closing kick for nonlinear velocity-dependent forces
_CLOSING_ITERATIONS = 50


def _damping(scheme: Scheme) -> np.ndarray:
    """Γ: the summed coefficients of the problem's ``Damping`` loads, ``(r,)``."""
    gamma = np.zeros(scheme.group.dim)
    for load in scheme.problem.loads:
        if isinstance(load, Damping):
            gamma = gamma + np.asarray(load.coefficients, dtype=float)
    return gamma


def _closing_matrix(scheme: Scheme, gamma: np.ndarray, dt: float) -> np.ndarray:
    """``(I + ½ΔtΓM⁺)⁻¹``, ``(r, r)``: lie-verlet's closing kick implicit in linear damping."""
    return np.linalg.inv(np.eye(gamma.size) + 0.5 * dt * gamma[:, None] * scheme.inverse_metric)


class LieVerlet(Integrator):
    """Symplectic, explicit, second-order splitting that stays in G.

    ``S += ½Δt W``; exact free flow over Δt; ``S += ½Δt W``.  The free flow of the kinetic
    energy ½Σ S_k²/m_k is split into commuting blocks of basis directions
    (:func:`_abelian_pieces`; for SE(3): the three translations, then each rotation axis),
    each solved exactly, and composed palindromically (Strang) — the generalisation to any
    group of the splitting of the free rigid body (McLachlan 1993; Dullweber, Leimkuhler &
    McLachlan 1997).  The force at the end of a step is reused at the start of the next when
    no load depends on N (one force evaluation per step).

    With loads that depend on N (damping) the closing half kick is implicit in the velocity,
    ``S⁺ = S½ + ½Δt W(Φ⁺, N(S⁺))``, so that the damping impulse over a step is the trapezoidal
    ``−½ΔtΓ(N_n + N_{n+1})`` and the method stays second order (an explicit closing kick,
    with ``N(S½)``, is first order in the damping).  For linear damping (``Damping`` loads:
    W = W₀ − ΓN, N = M⁺S) it is solved in closed form, ``(I + ½ΔtΓM⁺)S⁺ = S½ + ½Δt W₀(Φ⁺)``,
    with one force evaluation (at N = 0), as in the compiled loops; other velocity-dependent
    forces by fixed-point iteration.
    """

    name = "lie-verlet"
    order = 2
    symplectic = True
    stability = 2.0

    def __init__(self, **options: Any):
        super().__init__(**options)
        self._fsal: tuple | None = None

    def reset(self) -> None:
        super().reset()
        self._fsal = None

    def _sequence(self, scheme: Scheme) -> list[tuple[np.ndarray, float]]:
        """The free flow's pieces and their fractions of Δt, palindromic (Strang), as
        ``(P, frac)`` with ``N_p = P S`` (P ``(r, r)``): for a diagonal metric the commuting
        blocks of basis directions (:func:`_abelian_pieces`), P = diag(1/m) on the block; for
        any other metric M the eigenvectors e of M⁺ (eigenvalue λ), P = λeeᵀ — the flow of
        ½λ(eᵀS)² keeps eᵀS, so N_p is constant along it and the piece is solved exactly."""
        key = (scheme.group, tuple(scheme.live), scheme.inverse_metric.tobytes())
        if getattr(self, "_seq_key", None) == key:
            return self._seq
        A = scheme.inverse_metric
        if scheme.diagonal_metric:
            mats = []
            for p in _abelian_pieces(scheme.group, scheme.live):
                P = np.zeros_like(A)
                P[p, p] = A[p, p]
                mats.append(P)
        else:
            live = scheme.live
            lam, vec = np.linalg.eigh(A[np.ix_(live, live)])
            mats = []
            for k in range(lam.size):
                e = np.zeros(A.shape[0])
                e[live] = vec[:, k]
                mats.append(lam[k] * np.outer(e, e))
        seq = [(P, 0.5) for P in mats[:-1]] + [(mats[-1], 1.0)] + [(P, 0.5) for P in reversed(mats[:-1])]
        self._seq_key, self._seq = key, seq
        return seq

    def driven_reason(self, scheme: Scheme) -> str | None:
        """None when the split free flow moves every driven node by exp(Δtξ): a diagonal kinetic
        metric and ξ's parts in the flow's pieces commuting (a rotation about one body axis, any
        translation); the reason otherwise."""
        if not scheme.diagonal_metric:
            return "with a non-diagonal kinetic metric its free flow holds the driven nodes"
        mask, Nd, _ = scheme._driven
        parts = [np.where(np.diag(P) != 0, Nd[mask], 0.0) for P, _ in self._sequence(scheme)]
        scale = float(np.max(np.abs(Nd[mask]), initial=0.0)) ** 2
        for i, a in enumerate(parts):
            for b in parts[i + 1:]:
                if float(np.max(np.abs(scheme.group.bracket(a, b)), initial=0.0)) > 1e-14 * scale:
                    return ("the driven velocity's parts in its split free flow do not commute (the end would "
                            "move by a product of their exponentials, not exp(Δtξ))")
        return None

    def _kick_force(self, scheme: Scheme, state: State) -> np.ndarray:
        N = scheme.velocity(state)
        key = (id(state), state.t, state.scalars.get("nstep", 0))
        velocity_free = scheme.problem.velocity_free
        if velocity_free and self._fsal is not None and self._fsal[0] == key:
            return self._fsal[1]
        return self.force(scheme, state, N, state.t)

    def _step(self, scheme: Scheme, state: State, dt: float) -> None:
        if getattr(scheme, "coupled_lagrangian", False):  # the split is exact for H = K(S) + U(X) only
            raise ValueError(f"{self.name} splits the Hamiltonian into K(S) + U(X); the medium's Lagrangian "
                             "couples N and X (Medium.coupled_lagrangian): use implicit-midpoint (symplectic), "
                             "rkmk4 or lie-euler")
        state.S = state.S + 0.5 * dt * self._kick_force(scheme, state)
        scheme.constrain(state)
        self._free_flow(scheme, state, dt)
        t1 = state.t + dt
        W1 = self._closing_kick(scheme, state, dt, t1)
        # cache the force at the new configuration for the next step's first kick
        self._fsal = ((id(state), t1, state.scalars.get("nstep", 0) + 1), W1)

    def _free_flow(self, scheme: Scheme, state: State, dt: float) -> None:
        """The exact split free flow over ``dt`` (configuration and momentum, in place)."""
        g = scheme.group
        for P, frac in self._sequence(scheme):
            if scheme.diagonal_metric:
                N = scheme.velocity(state)
                Np = np.zeros_like(N)
                piece = np.flatnonzero(np.diag(P))
                Np[..., piece] = N[..., piece]
            else:
                Np = state.S @ P.T
                Np[scheme._clamped] = 0.0
            if not Np.any():  # exp(0) = I: nothing moves
                continue
            tau = frac * dt
            state.S = _coAd_exp(g, tau, Np, state.S)
            scheme.drift(state, tau, Np, exact=True)
        scheme.constrain(state)

    def _closing_kick(self, scheme: Scheme, state: State, dt: float, t1: float) -> np.ndarray:
        """``S⁺ = S½ + ½Δt W(Φ⁺, N)`` with N = N(S⁺) (implicit, see the class docstring) when
        a force depends on N, else N(S½); returns the W applied.  :meth:`_settle` follows every
        kick (nothing here; rattle's velocity projection)."""
        problem = scheme.problem
        half = 0.5 * dt
        start = state.S
        if problem.velocity_free:
            W1 = self.force(scheme, state, scheme.velocity(state), t1)
        elif not getattr(scheme.medium, "velocity_dependent_forces", False) and all(
                isinstance(ld, Damping) for ld in problem.loads if ld.velocity_dependent):
            gamma = _damping(scheme)
            W0 = self.force(scheme, state, np.zeros_like(state.S), t1)
            rhs = start + half * W0
            if scheme.diagonal_metric:
                inv = np.diag(scheme.inverse_metric)
                state.S = rhs / (1.0 + half * gamma * inv)
            else:  # S⁺ = (I + ½ΔtΓM⁺)⁻¹ (S½ + ½Δt W₀)
                state.S = np.einsum("kl,...l->...k", _closing_matrix(scheme, gamma, dt), rhs)
            scheme.constrain(state)
            self._settle(scheme, state, half, gamma)
            return W0 - gamma * scheme.velocity(state)
        else:  # fixed point of S⁺ = S½ + ½Δt W(Φ⁺, N(S⁺)), from the explicit kick
            W1 = self.force(scheme, state, scheme.velocity(state), t1)
            for _ in range(_CLOSING_ITERATIONS):
                state.S = start + half * W1
                scheme.constrain(state)
                self._settle(scheme, state, half, None)
                W_next = self.force(scheme, state, scheme.velocity(state), t1)
                change = np.max(np.abs(W_next - W1), initial=0.0)
                W1 = W_next
                if change <= 1e-14 * np.max(np.abs(W1), initial=0.0):
                    break
        state.S = start + half * W1
        scheme.constrain(state)
        self._settle(scheme, state, half, None)
        return W1

    def _settle(self, scheme: Scheme, state: State, half: float, gamma: np.ndarray | None) -> None:  # noqa: B027
        """After a closing kick of ``half`` = ½Δt (``gamma``: the damping solved with it, or
        None): a hook for integrators that add an impulse to every kick; nothing here."""

    def compiled_loop(self, scheme: Scheme, state: State, dt: float):
        seq = self._sequence(scheme)
        r = scheme.group.dim
        pieces = np.ascontiguousarray([P for P, _ in seq], dtype=float)
        fracs = np.array([frac for _, frac in seq], dtype=float)
        key = (id(state), state.t, state.scalars.get("nstep", 0))
        have = self._fsal is not None and self._fsal[0] == key
        W = (np.array(self._fsal[1], dtype=float) if have else np.zeros(state.S.shape)).reshape(-1, r)
        velocity_free = scheme.problem.velocity_free
        closing = _closing_matrix(scheme, _damping(scheme), dt)
        return "lie_verlet_loop", (W, bool(have), bool(velocity_free), pieces, fracs, closing)

    def compiled_loop_done(self, state: State, args: tuple) -> None:
        self._fsal = ((id(state), state.t, state.scalars.get("nstep", 0)), args[0].reshape(state.S.shape))


# ---------------------------------------------------------------------------- RKMK family
_TABLEAUX = TABLEAUX


def _rkmk(integ: Integrator, scheme: Scheme, state: State, dt: float, order: int,
          velocity: Callable[[State, float], np.ndarray], dynamics: bool, first: np.ndarray | None = None) -> None:
    """One explicit Runge–Kutta–Munthe-Kaas step (Munthe-Kaas 1999).

    Φ(t+s) = Φ(t) exp(σ(s)) with ``σ̇ = dexp⁻¹_{−σ} N`` (right-trivialised: our ``dexp`` is
    the left Jacobian, and Φ̇ = ΦN), S by the same Runge–Kutta tableau on
    ``Ṡ = ad_NᵀS + W`` when ``dynamics`` is True; ``first``, when given, is the velocity of
    the first stage (the state's own, already known).
    """
    g = scheme.group
    A, b, c = _TABLEAUX[order]
    s = len(b)
    k_sig: list[np.ndarray] = []
    k_S: list[np.ndarray] = []
    for i in range(s):
        sigma = sum((dt * A[i, j] * k_sig[j] for j in range(i) if A[i, j]), np.zeros_like(state.S))
        stage = state.copy()
        if dynamics:
            stage.S = state.S + sum((dt * A[i, j] * k_S[j] for j in range(i) if A[i, j]), np.zeros_like(state.S))
        if np.any(sigma):
            scheme.drift(stage, 1.0, sigma, exact=True)
        t_i = state.t + c[i] * dt
        N = first if (i == 0 and first is not None) else velocity(stage, t_i)
        k_sig.append(np.einsum("...ij,...j->...i", g.dexp_inv(-sigma), N))
        if dynamics:
            W = integ.force(scheme, stage, N, t_i)
            k_S.append(_adT(g, N, stage.S) + W)
    sigma = sum(dt * b[i] * k_sig[i] for i in range(s))
    scheme.drift(state, 1.0, sigma, exact=True)
    if dynamics:
        state.S = state.S + sum(dt * b[i] * k_S[i] for i in range(s))
        scheme.constrain(state)


class RKMK4(Integrator):
    """Classical 4-stage Runge–Kutta–Munthe-Kaas: fourth order, stays in G, 4 forces/step."""

    name = "rkmk4"
    order = 4
    stability = 2.0 * np.sqrt(2.0)

    def _step(self, scheme: Scheme, state: State, dt: float) -> None:
        _rkmk(self, scheme, state, dt, 4, lambda st, t: scheme.velocity(st), dynamics=True)

    def driven_reason(self, scheme: Scheme) -> str | None:
        return None  # N = ξ at every stage: σ̇ = dexp⁻¹_{−σ}ξ = ξ (σ ∥ ξ), so σ = Δtξ

    def compiled_loop(self, scheme: Scheme, state: State, dt: float):
        A, b, c = _TABLEAUX[4]
        r = scheme.group.dim
        return "rkmk_loop", (A, b, c, True, 0, np.zeros(r), np.zeros((1, r)), np.zeros(1, dtype=np.int64))


class Overdamped(Integrator):
    """Gradient (overdamped) dynamics ``Γ N = W(N = 0)``: N = Γ⁻¹(D*Q + T), Γ the drag of the
    problem's :class:`~cartan.problem.Damping` loads.  ``order=1``: Lie–Euler; ``order=2``:
    RKMK2 (Heun).  Momentum is not evolved (S = 0)."""

    name = "overdamped"
    rate = "overdamped"
    stability = 2.0
    uses_momentum = False

    def __init__(self, order: int = 1):
        if order not in (1, 2):
            raise ValueError(f"order must be 1 or 2 for overdamped, got {order!r}")
        self.order = order
        self._cache: tuple | None = None
        super().__init__()

    def options(self):
        return {"order": self.order}

    def driven_reason(self, scheme: Scheme) -> str | None:
        return None  # N = ξ at a driven node: Lie–Euler's exp(ΔtN) and Heun's RKMK2 stages move it by exp(Δtξ)

    def drift_velocity(self, scheme: Scheme, state: State, t: float) -> np.ndarray:
        gam = scheme.drag()
        bad = scheme.live & ~(gam > 0)
        if bad.any():
            raise ValueError(
                "the overdamped integrator needs a Damping load with positive coefficients on every "
                f"non-gauge component; missing for components {np.flatnonzero(bad).tolist()}"
            )
        W = self.force(scheme, state, np.zeros_like(state.S), t)
        N = np.where(scheme.live, W / np.where(gam > 0, gam, 1.0), 0.0)
        N[scheme._clamped] = 0.0
        driven = getattr(scheme, "_driven", None)
        if driven is not None:  # a driven end moves with its prescribed ξ
            N[driven[0]] = driven[1][driven[0]]
        return N

    def velocity(self, scheme, state):
        key = (id(state), state.t, state.scalars.get("nstep", 0))
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        N = self.drift_velocity(scheme, state, state.t)
        self._cache = (key, N, False)  # (False: computed by the reference path)
        return N

    def _step(self, scheme: Scheme, state: State, dt: float) -> None:
        if self.order == 1:
            N = self.velocity(scheme, state)
            scheme.drift(state, dt, N, exact=True)
        else:
            _rkmk(self, scheme, state, dt, 2, lambda st, t: self.drift_velocity(scheme, st, t), dynamics=False,
                  first=self.velocity(scheme, state))
        state.S = np.zeros_like(state.S)

    def compiled_loop(self, scheme: Scheme, state: State, dt: float):
        gam = scheme.drag()
        if np.any(scheme.live & ~(gam > 0)):
            return None  # the Python step raises the error that names the components
        A, b, c = _TABLEAUX[self.order]
        gam_inv = np.where(scheme.live, 1.0 / np.where(gam > 0, gam, 1.0), 0.0)
        key = (id(state), state.t, state.scalars.get("nstep", 0))
        # only a velocity the compiled kernels computed (bit for bit what the loop would compute
        # from the state): then the steps do not depend on saves, and a restart continues exactly
        have = np.array([self._cache is not None and self._cache[0] == key and self._cache[2]], dtype=np.int64)
        N0 = (np.array(self._cache[1], dtype=float) if have[0] else np.zeros(state.S.shape)).reshape(-1, len(gam))
        return "rkmk_loop", (A, b, c, False, 1, gam_inv, N0, have)

    def compiled_loop_done(self, state: State, args: tuple) -> None:
        """S = 0 as :meth:`_step` leaves it; the velocity of the final state, when the loop
        computed it (for the powers), cached for the next step as :meth:`velocity` caches it."""
        state.S = np.zeros_like(state.S)
        N, have = args[-2], args[-1]
        if have[0]:
            self._cache = ((id(state), state.t, state.scalars.get("nstep", 0)), N.reshape(state.S.shape).copy(),
                           True)


def _named_velocity(name: str, options: dict[str, Any] | None) -> Callable:
    """The velocity function named ``"module:name"`` (a factory, called with ``options``, when
    ``options`` is given, even empty); a clear ``ValueError`` when it cannot be found."""
    import importlib

    module, sep, attr = name.partition(":")
    if not sep or not module or not attr:
        raise ValueError(f"velocity {name!r}: name a function as 'module:name' "
                         "(e.g. 'cartan_filament.binormal:binormal_velocity')")
    try:
        target = importlib.import_module(module)
        for part in attr.split("."):
            target = getattr(target, part)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"velocity {name!r} cannot be imported: {exc}") from None
    if not callable(target):
        raise ValueError(f"velocity {name!r} is not callable")
    if options is not None:
        try:
            target = target(**options)
        except TypeError as exc:
            raise ValueError(f"velocity_options of {name!r}: {exc}") from None
    return target


class Kinematic(Integrator):
    """Prescribed velocity N(t, u, X) (paper §III.B): the configuration follows
    Φ̇ = ΦN by RKMK of the requested order (1, 2 or 4).

    Parameters
    ----------
    velocity : callable ``(t, u, X) -> N``, or str ``"module:name"``
        ``t`` float, ``u`` node coordinates ``[*shape, d]``, ``X`` nodal strains
        ``[*shape, d, r]``; returns ``[*shape, r]``.  A string names an importable velocity
        function (or, with ``velocity_options``, even empty, a factory called with them that
        returns one):
        the form a scene file uses, e.g. ``velocity = "cartan_filament.binormal:binormal_velocity"``;
        the named form is recorded in :meth:`options`, so a restart rebuilds the same velocity.
    order : int
    velocity_options : dict, optional
        Keyword arguments of the factory named by ``velocity`` (only with a named velocity).
    """

    name = "kinematic"
    stability = np.inf
    uses_momentum = False

    def __init__(self, velocity: Callable | str | None = None, order: int = 4,
                 velocity_options: dict[str, Any] | None = None):
        self.velocity_name = velocity if isinstance(velocity, str) else None
        if velocity_options is not None and not isinstance(velocity_options, dict):
            raise ValueError(f"velocity_options must be a table of keyword arguments, got {velocity_options!r}")
        if velocity_options is not None and self.velocity_name is None:
            raise ValueError("velocity_options apply to a named velocity factory (velocity = 'module:name')")
        self.velocity_options = None if velocity_options is None else dict(velocity_options)
        if self.velocity_name is not None:
            velocity = _named_velocity(self.velocity_name, self.velocity_options)
        if velocity is None or not callable(velocity):
            raise ValueError("kinematic integrator needs velocity=callable(t, u, X) -> N, or the name "
                             "'module:function' of one")
        if order not in _TABLEAUX:
            raise ValueError(f"order must be one of {sorted(_TABLEAUX)}, got {order!r}")
        self.velocity_field = velocity
        self.order = order
        super().__init__()

    def options(self):
        if self.velocity_name is not None:
            out = {"order": self.order, "velocity": self.velocity_name}
            if self.velocity_options is not None:
                out["velocity_options"] = dict(self.velocity_options)
            return out
        return {"order": self.order, "velocity": getattr(self.velocity_field, "__name__", "callable")}

    def _N(self, scheme: Scheme, state: State, t: float) -> np.ndarray:
        grid = scheme.grid
        u = np.stack(np.meshgrid(*[grid.coordinates(a) for a in range(grid.d)], indexing="ij"), axis=-1)
        N = np.asarray(self.velocity_field(t, u, scheme.nodal_strains(state)), dtype=float)
        N = np.broadcast_to(N, (*grid.shape, scheme.group.dim)).copy()
        N[scheme._clamped] = 0.0
        return N

    def velocity(self, scheme, state):
        return self._N(scheme, state, state.t)

    def _step(self, scheme: Scheme, state: State, dt: float) -> None:
        _rkmk(self, scheme, state, dt, self.order, lambda st, t: self._N(scheme, st, t), dynamics=False)

    def compiled_loop(self, scheme: Scheme, state: State, dt: float):
        """``rkmk_loop`` with this order's tableau and N = f(t, u, X) (``mode = 2``) when the
        velocity is a numba-compiled function (``numba.njit``) that a generated module can take
        (:func:`cartan.integrators.loops.kinematic_fragment`); None (the Python path) otherwise."""
        if _velocity_fragment(self.velocity_field) is None:
            return None
        if np.ndim(getattr(scheme, "_clamped", False)) > scheme.grid.d:
            return None  # held components (Held ends, Symmetry faces): the loop zeroes clamped nodes only
        A, b, c = _TABLEAUX[self.order]
        r = scheme.group.dim
        return "rkmk_loop", (A, b, c, False, 2, np.zeros(r), np.zeros((1, r)), np.zeros(1, dtype=np.int64))

    def compiled_module(self, ops: Any) -> Any:
        """The generated module of ``ops``'s operators, every loop and this velocity (keyed by
        the velocity: its code, its module's source, its captured values), kept per set."""
        import importlib

        from ..compiled.codegen import generate
        from ..compiled.operators import LOOP_SOURCES

        cached = getattr(self, "_module", None)
        if cached is not None and cached[0] is ops:
            return cached[1]
        frag = _velocity_fragment(self.velocity_field)
        loops = [importlib.import_module(name).loop_fragment() for name in LOOP_SOURCES]
        stem = getattr(getattr(self.velocity_field, "py_func", self.velocity_field), "__name__", "velocity")
        module = generate(f"kinematic-{ops.key}-{stem}", [*ops.fragments, *loops, frag])
        self._module = (ops, module)
        return module


def _velocity_fragment(velocity: Callable):
    """The velocity's kernel fragment when it is a numba CPU dispatcher (``numba.njit``), else None."""
    from numba.core.registry import CPUDispatcher

    from .loops import kinematic_fragment

    if not isinstance(velocity, CPUDispatcher):
        return None
    return kinematic_fragment(velocity)
