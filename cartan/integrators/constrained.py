"""``rattle``: lie-verlet with the medium's constrained strains held by multipliers.

A medium that holds strain components fixed (:meth:`~cartan.medium.Medium.constrained_strains`,
paper §III.E: the inextensible, unshearable filament, θ = (1, 0, 0)) moves on the manifold
c(Φ) = 0 of :class:`cartan.constraints.StrainConstraints` (one row per lattice edge and
component).  Its equations of motion carry the constraint forces — the fictitious stresses of
§IV.E, edge stresses conjugate to the held components — as Lagrange multipliers:

    w Ṡ = w(ad_NᵀS + W) + B_c(Φ)ᵀν,        c(Φ) = 0        (so B_c(Φ) N = 0),

with B_c the exact strain rate of the drift (the rows of ``StrainConstraints.matrix``).  The
step is RATTLE (Andersen 1983; Leimkuhler & Skeel 1994) on the lie-verlet splitting:

1. half kick with the position multiplier ν:  S½ = Sₙ + ½Δt(Wₙ + B_c(Φₙ)ᵀν/w);
2. lie-verlet's exact split free flow over Δt from (Φₙ, S½), giving Φₙ₊₁(ν);
3. ν solves c(Φₙ₊₁(ν)) = 0 — a chord iteration from the prediction λₙ + (ν − λ)*: λₙ the
   force-level multiplier (the one that keeps the constraints' acceleration at zero), plus the
   offset between ν and λ extrapolated from the last three steps, 3oₙ₋₁ − 3oₙ₋₂ + oₙ₋₃
   (oₖ = (ν − λ)ₖ; linear or constant when only two or one are at hand). The offset changes by
   O(Δt) of itself from step to step (ν is the force-level multiplier to O(Δt): the offset is
   smooth, the step-to-step variation of λ, fast waves included, is in λₙ), so its quadratic
   extrapolation is 3–15 times closer to the converged ν than the last offset alone.  The
   offsets travel in ``State.memory`` (``rattle_offset`` ``(3, ncon)``, newest first, with the
   Δt that left each, ``rattle_offset_dt`` ``(3,)``; checkpoints carry them, so restarts stay
   bit for bit); the leading ones left by steps of the same Δt are used, none after a
   configuration projection.  The stored ν gets one more correction with the last
   matrix (a solve, no flow): the converged ν is fixed to the tolerance only, and that noise
   would otherwise enter the next prediction.  The prediction changes where the iteration
   starts, not where it ends.  The chord matrix is ½Δt·Δt·B_c(Φₙ) P B_c(Φₙ)ᵀ
   (P = M⁺/w per node on the unknowns), the matrix the predictor factors anyway; it is the
   flow's Jacobian to O(Δt|N|), so an iteration gains one to three digits.  Should one gain
   less than a factor 4, the iteration turns to the quasi-Newton matrix
   ½Δt B_c(Φ̃) D B_c(Φₙ)ᵀ (Φ̃ the current trial, D = dexp(−ΔtÑ)·Δt·M⁺/w per node).  Converged
   to round-off (|c| ≤ 1e-13, or stagnating below 1e-10 with the quasi-Newton matrix, times
   max(1, |value|): a stall of the chord iteration is not round-off, it turns to that matrix); two trial
   flows per step on the damped relaxation of ``benchmarks/filament_speed.py`` (one to two once
   the motion is slow), four to five near the time step's limit;
4. closing half kick with the velocity multiplier μ:  Sₙ₊₁ = S½ + ½Δt(Wₙ₊₁ + B_c(Φₙ₊₁)ᵀμ/w),
   μ such that B_c(Φₙ₊₁)Nₙ₊₁ = 0 — one linear solve (with ``Damping`` loads the kick is
   implicit in the damping as in lie-verlet, and μ is solved with it).

The constraints hold at every step to the iteration's tolerance (round-off: the rows are
X_e[k] − value_k of the exact edge strains), the velocities are tangent to the constraint
manifold, and the constraint forces do no work, so the energy balance of the run is the one of
lie-verlet (second order, bounded energy error for conservative media).  The time step is
limited by the waves the constraints leave (bending and twist for a filament), not by those
they remove.  The state a step starts from is first brought onto the manifold if it is not
(a configuration projection along M⁺Bᵀ, then the velocity projection): a sampled initial
shape need not satisfy the constraints to round-off.

Driven ends (:class:`~cartan.problem.Driven`, held at the velocity ξ): the driven nodes move in
the split free flow by exp(Δtξ) (lie-verlet's condition on ξ), and their velocity enters the
rows, ``B_c N = B_u N_u + B_d ξ`` (:meth:`~cartan.constraints.StrainConstraints.fixed_rate`): the
velocity projections solve ``B_u N_u = −B_d ξ``, the position multipliers hold the rows after
the flow that moved the driven nodes.  The support balances the constraint force ``B_dᵀλ`` on
them as well (:meth:`Rattle.support_reaction`), whose power ``−λᵀB_dξ`` is booked as external
work with the scheme's; the first step from rest books the kinetic energy the velocity
projection gives the free nodes as the support's impulsive work.  The compiled loop takes them
as the Python step does (the operator set's driven nodes, their ξ and ∂K/∂N(ξ); the rows' force
on them, with λ at every step's end from the rows' rate to round-off, a central difference as
in :meth:`Rattle._rows_rate_exact`).

Held components (:class:`~cartan.problem.Held` ends, :class:`~cartan.problem.Symmetry` faces:
the scheme's clamp mask ``[*shape, r]``): their velocity and momentum are zeroed after every kick
as lie-verlet's (``scheme.constrain``), and the node moves in the free components' subalgebra.
The rows take them as fixed, as a clamped node's: the unknowns are the free live components of
each node (``P`` and the quasi-Newton matrix are per-node blocks restricted to them; the
problem checks that the kinetic metric does not couple held and free components), an edge
between two wholly held nodes has no row, and the held columns add nothing to ``B_c N`` (their
velocity is zero).  :meth:`Rattle.support_reaction` gives the reaction on every held component,
the constraint force on it included.  The compiled loop restricts its node operators to the
free components by the operator set's ``held`` mask: the same steps, round-off apart.

Runs on any scheme that supplies its rows, ``scheme.constraint_rows(unknown, state)``: the
``lattice``'s :class:`~cartan.constraints.StrainConstraints` on its edges (whose strains are
exact) and, with the same interface (``ncon``, ``values``, ``matrix``, ``fixed_rate``,
``fixed_force``, and ``rows_rate`` for Ḃ_c N), the ``collocation`` scheme's
:class:`~cartan.constraints.NodalStrainConstraints`, the held components of its stored nodal
strains, with ``B_c δ = P(D δ + ad_X δ)`` from the compatibility equation (paper §III) and the
combination dependent at a straight configuration (the odd–even mode) left out
(docs/integrators.md, "rattle on the collocation scheme"; numpy step only).  A medium without
constrained strains gets lie-verlet's steps unchanged.  On an open chain of nodes (d = 1, not
periodic) whose operator set compiles (group and medium point kernels, the loads of the
generated loops), the steps run in the generated ``rattle_loop``
(:mod:`cartan.integrators.rattle_loop`): the same formulas, with the multiplier systems
block-tridiagonal and solved in O(n) (:mod:`cartan.compiled.banded`); its steps agree with
the Python step to round-off.  Everything else (d ≥ 2, a periodic chain, loads or media the
operator set declines) runs the Python step below, with sparse LU solves;
:meth:`Rattle.compiled_reason` says why.

Multiplier systems on d ≥ 2 lattices (the Kirchhoff–Love surface): ``B_c P B_cᵀ`` couples every
row with its neighbours on both axes and has a condition ∝ h⁻² (≈ 1e10 on the plate at h/a = 0.1:
the rotary inertia ρh³/12), so a local iteration does not converge and the Python step factorises
it.  Each configuration's matrix is factorised once, as a symmetric positive definite matrix
(SuperLU with the minimum-degree ordering of A + Aᵀ, no row pivoting, symmetric mode: ≈ 3 times
fewer factor entries and 5 times less time than the general LU's column ordering at 8,192
rows), and the factors are kept with the rows ``B_c`` they belong to: the closing velocity
projection's at Φₙ₊₁ serve the next step's predictor, chord iteration and stored correction, so
a step factorises once (twice with ``Damping`` loads, whose closing matrix differs).  The steps
are those of the general LU at every use to round-off (``_REUSE_FACTORS`` False gives that
path; ``tests/test_rattle_d2.py``).  The d = 1 chains keep the general LU.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..schemes.base import Scheme, State
from .explicit import LieVerlet, _closing_matrix

__all__ = ["Rattle"]

#: quasi-Newton iterations of the position multipliers allowed per step
_MAX_ITERATIONS = 40
#: the chord iteration turns to the trial's Newton matrix when an iteration gains less than this
_SLOW = 0.25


#: the error of a driven problem whose rows are dependent (the Python step's and the compiled loop's)
_DEPENDENT = ("rattle: the constraint rows are dependent at this configuration (their multiplier system is "
              "singular): a straight filament held at both ends, by a clamp and a Driven end at the distance of "
              "its length, has no slack to move; start from a slack shape (e.g. an arc) or free one end")


#: the keys of ``State.memory`` that carry the multipliers' offsets ν − λ of the last steps and their Δt
_OFFSET = "rattle_offset"
_OFFSET_DT = "rattle_offset_dt"


#: the offsets ν − λ kept: the predictor extrapolates up to this many (quadratically for three)
_HISTORY = 3

#: d ≥ 2 lattices: factorise each configuration's ``B_c P B_cᵀ`` once, symmetric-mode (module docstring,
#: "Multiplier systems on d ≥ 2 lattices"); False: the general LU at every use (the d = 1 path's solves)
_REUSE_FACTORS = True


def _splu_spd(A: Any) -> Any:
    """SuperLU factors of the symmetric positive definite ``A`` (CSC): a symmetric fill-reducing
    ordering of A + Aᵀ (minimum degree), no row pivoting, the symmetric mode — a Cholesky-like LU,
    stable on an SPD matrix, with ≈ 3 times fewer factor entries than the column ordering of the
    general LU on a d = 2 lattice's ``B P Bᵀ``; the general LU when it meets a zero pivot."""
    import scipy.sparse.linalg as spla

    try:
        return spla.splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    except RuntimeError:
        return spla.splu(A)


def _stored(state: State, ncon: int) -> tuple[np.ndarray, np.ndarray] | None:
    """``(ν − λ (3, ncon), their Δt (3,))`` of ``state.memory`` (the last three steps, newest
    first; Δt = 0: none) when it holds a pair that fits these rows."""
    off, at = state.memory.get(_OFFSET), state.memory.get(_OFFSET_DT)
    if off is None or at is None or np.shape(off) != (_HISTORY, ncon) or np.shape(at) != (_HISTORY,):
        return None
    return off, at


def _offset(state: State, ncon: int, dt: float) -> tuple[np.ndarray | None, int]:
    """``(the predicted offset (ncon,), k)``: the offsets ν − λ of the last k steps taken with
    this Δt (the leading run of ``state.memory``'s, at most three) extrapolated to this step —
    o₀, 2o₀ − o₁ or 3o₀ − 3o₁ + o₂ (o₀ the newest: constant, linear or quadratic in the step
    number); ``(None, 0)`` when there is none (the predictor is then λ alone)."""
    stored = _stored(state, ncon)
    if stored is None:
        return None, 0
    off, at = stored
    k = 0
    while k < _HISTORY and float(at[k]) == dt:
        k += 1
    if k == 0:
        return None, 0
    if k == 1:
        return off[0], 1
    if k == 2:
        return 2.0 * off[0] - off[1], 2
    return 3.0 * off[0] - 3.0 * off[1] + off[2], 3


def _remember(state: State, ncon: int, new: np.ndarray, dt: float, keep: bool) -> None:
    """Put this step's offset ``new`` (ncon,) first in ``state.memory``'s, the older ones moved
    down (``keep`` False: they no longer count, their Δt is cleared — after a projection)."""
    off, at = _stored(state, ncon) or (np.zeros((_HISTORY, ncon)), np.zeros(_HISTORY))
    off = np.concatenate([new[None, :], off[:-1]])
    at = np.concatenate([[dt], at[:-1] if keep else np.zeros(_HISTORY - 1)])
    state.memory[_OFFSET], state.memory[_OFFSET_DT] = off, at


def _memory(state: State, ncon: int) -> tuple[np.ndarray, np.ndarray]:
    """The arrays ``(ν − λ (3, ncon), their Δt (3,))`` of ``state.memory`` that the compiled
    loop reads and updates in place; zeros (no offset: Δt = 0) when the state holds none that
    fit."""
    off, at = _stored(state, ncon) or (np.zeros((_HISTORY, ncon)), np.zeros(_HISTORY))
    off, at = _writable(off), _writable(at)
    state.memory[_OFFSET], state.memory[_OFFSET_DT] = off, at
    return off, at


def _writable(a: np.ndarray) -> np.ndarray:
    """``np.require(a, dtype=float, requirements=["C", "W"])``, checked first (the array
    itself when it is one already: the usual case, at every call of the compiled loop)."""
    if isinstance(a, np.ndarray) and a.dtype == np.float64 and a.flags.c_contiguous and a.flags.writeable:
        return a
    return np.require(a, dtype=float, requirements=["C", "W"])


class Rattle(LieVerlet):
    """RATTLE on the lie-verlet splitting: second order, symplectic, constraints to round-off.

    See the module docstring for the step.  Options: none.  Counters as lie-verlet's, plus
    ``niter`` (quasi-Newton iterations of the position multipliers, summed over the steps).
    """

    name = "rattle"
    order = 2
    symplectic = True
    stability = 2.0
    #: honours the medium's constrained strains (:meth:`~cartan.medium.Medium.constrained_strains`)
    constrained = True

    def reset(self) -> None:
        super().reset()
        self.niter = 0
        self._held: tuple | None = None
        self._metrics: dict = {}
        self._matrix_at: tuple | None = None  # (state key, B_c at the state the last step ended on)
        self._closing_B = None
        self._factored: list = []  # [(B_c, closing key, SuperLU of B_c P B_cᵀ)], newest first (d ≥ 2)
        self._failure: tuple | None = None
        self._loop_args: tuple | None = None  # (scheme, problem, Δt, the loop's fixed arguments)
        #: why the last :meth:`compiled_loop` left the steps to Python (None: it did not)
        self.compiled_declined: str | None = None

    # ------------------------------------------------------------------ driven ends
    @staticmethod
    def _rows_residual(scheme: Scheme, state: State, B, N: np.ndarray, held: tuple) -> np.ndarray:
        """``B_c N`` ``(ncon,)`` of the full velocity N ``[*shape, r]``: the unknowns' columns
        ``B N[unknown]`` plus, with :class:`~cartan.problem.Driven` ends, the driven nodes'
        ``B_d ξ`` (:meth:`~cartan.constraints.StrainConstraints.fixed_rate`)."""
        con, unknown, _, _ = held
        res = B @ N[unknown]
        if getattr(scheme, "_driven", None) is not None:
            res = res + con.fixed_rate(state, N)
        return res

    def _multipliers(self, scheme: Scheme, state: State) -> tuple[np.ndarray, tuple] | None:
        """The force-level multipliers λ ``(ncon,)`` at ``state`` — :meth:`_predict`'s equation
        with the rows' acceleration to round-off (:meth:`_rows_rate_exact`) — and the
        constraints, when the medium has rows; else None.  Kept for the state they were computed
        at (the powers at a step's end are the next step's start)."""
        if scheme.medium.constrained_strains() is None:
            return None
        held = self._constraints(scheme, state)
        con, unknown, nodes, _ = held
        if not con.ncon:
            return None
        key = (id(state), id(state.S), state.t, state.scalars.get("nstep", 0))
        cached = self.__dict__.get("_lambda_at")
        if cached is not None and cached[0] == key:
            return cached[1], held
        from .explicit import _adT

        B = con.matrix(state)
        lu = self._factors(scheme, B, None, held)
        N = scheme.velocity(state)
        acc = scheme.medium.velocity(_adT(scheme.group, N, state.S) + self._kick_force(scheme, state))
        lam = -lu.solve(B @ acc[unknown] + self._rows_rate_exact(scheme, state, N, held))
        self._lambda_at = (key, lam)
        return lam, held

    def _rows_rate_exact(self, scheme: Scheme, state: State, N: np.ndarray, held: tuple) -> np.ndarray:
        """``Ḃ_c N`` ``(ncon,)`` to round-off (unlike :meth:`_rows_rate`'s truncated series, a
        guess): the central difference of the exact rows' rate ``B_c(Φ exp(εN)) N`` over
        ε = ±ε₀, ε₀ = 1e-5/max|N| (truncation ≈ ε₀²|N|³, round-off ≈ 1e-16/ε₀: ≈ 1e-10 relative)."""
        con, unknown, _, _ = held
        if getattr(con, "exact_rate", False):  # the scheme's rows give Ḃ_c N in closed form (collocation)
            return con.rows_rate(state, N)
        eps = 1e-5 / max(float(np.max(np.abs(N), initial=0.0)), 1e-300)
        rates = []
        for sign in (1.0, -1.0):
            moved = state.copy()
            scheme.drift(moved, sign * eps, N, exact=True)
            rates.append(con.matrix(moved) @ N[unknown] + con.fixed_rate(moved, N))
        return (rates[0] - rates[1]) / (2.0 * eps)

    def step(self, scheme: Scheme, state: State, dt: float) -> None:
        """As :meth:`Integrator.step`; with driven ends of a medium with rows, a state on the
        constraints whose velocity is not tangent (the driven nodes set in motion from rest: the
        first step) is first given the tangent velocity (the velocity projection of the step),
        its kinetic energy's change booked as ``external_work``: the work of the support's
        impulse, which the constraint impulses pass on to the free nodes."""
        self._check_driven(scheme)
        if getattr(scheme, "_driven", None) is None or scheme.medium.constrained_strains() is None:
            super().step(scheme, state, dt)
            return
        try:
            held = self._constraints(scheme, state)
            con, _, _, scale = held
            if con.ncon and float(np.max(np.abs(con.values(state)), initial=0.0)) <= 1e-10 * scale:
                K0 = scheme.kinetic_energy(state)
                self._project_velocity(scheme, state, con.matrix(state), None, 0.5 * dt, held, skip_tangent=True)
                state.scalars["external_work"] = (state.scalars.get("external_work", 0.0)
                                                  + scheme.kinetic_energy(state) - K0)
            super().step(scheme, state, dt)
        except RuntimeError as exc:  # (scipy's splu: "Factor is exactly singular")
            if "singular" not in str(exc):
                raise
            raise ValueError(_DEPENDENT) from None

    def support_reaction(self, scheme: Scheme, state: State) -> np.ndarray:
        """The supports' reaction ``[*shape, r]`` on the held components: every component of the
        clamped and driven nodes, the held components of :class:`~cartan.problem.Held` ends and
        :class:`~cartan.problem.Symmetry` faces (zero elsewhere).

        On a held component k of node i the momentum stays zero, so its balance
        ``w Ṡ = w(ad_NᵀS + W) + B_cᵀλ + R`` gives ``R_k = −w(W + ad_NᵀS)_k − (B_cᵀλ)_k``: the
        scheme's reaction (:meth:`~cartan.schemes.base.Scheme.support_reaction`, the force of the
        rest of the body and the loads, W before it is zeroed there) minus the constraint force
        ``B_cᵀλ`` (λ the force-level multipliers at ``state``: the rows' tension and shear on the
        edges that end there), which the support balances too.

        On the ``collocation`` scheme W is its raw force (``force(raw=True)``: the clamped
        end's stress enters as a free end's natural-condition term, so that ``−wW`` is the
        weak-form force ``Lᵀ(wQ)`` less the loads, w the SBP weights) and ``B_cᵀλ`` the nodal
        rows' (:meth:`~cartan.constraints.NodalStrainConstraints.fixed_force`); its reaction
        balances the loads to the scheme's O(h²) (the discrete D has no product rule:
        docs/integrators.md, "rattle on the collocation scheme"), the lattice's to round-off.

        Parameters
        ----------
        scheme : Lattice or Collocation
        state : State

        Returns
        -------
        numpy.ndarray ``[*shape, r]``
        """
        from .explicit import _adT

        mask = scheme._clamped
        if mask.ndim == scheme.grid.d:  # whole nodes held: the scheme's reaction
            R = scheme.support_reaction(state)
            mask = np.broadcast_to(mask[..., None], R.shape)
        else:  # held components: the balance of each, as the scheme's on whole nodes
            N = scheme.velocity(state)
            W = scheme.force(state, N, state.t, raw=True)
            R = -scheme.weights[..., None] * (W + _adT(scheme.group, N, state.S))
            R[~mask] = 0.0
        mask = mask & scheme.live
        R[..., ~scheme.live] = 0.0
        got = self._multipliers(scheme, state)
        if got is not None:
            lam, (con, _, _, _) = got
            R[mask] -= con.fixed_force(state, lam).reshape(R.shape)[mask]
        return R

    def _powers(self, scheme: Scheme, state: State) -> dict[str, float]:
        """The base class' powers plus, at driven ends of a medium with rows, the power
        ``−λᵀB_d ξ`` of the constraint force on the driven nodes, part of the reaction's."""
        p = super()._powers(scheme, state)
        got = None if getattr(scheme, "_driven", None) is None else self._multipliers(scheme, state)
        if got is not None:
            lam, (con, _, _, _) = got
            mask, Nd, _ = scheme._driven
            p = dict(p)
            p["external"] -= float(np.sum(con.fixed_force(state, lam).reshape(Nd.shape)[mask] * Nd[mask]))
        return p

    # ------------------------------------------------------------------ compiled loop
    def compiled_reason(self, scheme: Scheme) -> str | None:
        """Why the compiled loop (:mod:`cartan.integrators.rattle_loop`) does not take this
        problem's steps, or None when it does (the medium's rows on an open chain of nodes:
        d = 1, not periodic, every edge with an unknown; the operator set's own conditions —
        group and medium point kernels, data-like loads — are checked by
        :meth:`~cartan.integrators.base.Integrator.run_compiled_loop`)."""
        if not hasattr(scheme, "edge_nodes") or not hasattr(scheme, "edge_strains"):
            return (f"scheme {scheme.name!r} has no edge strains: the generated rattle_loop holds the lattice's edge "
                    "rows only (the collocation's nodal rows run the Python step)")
        grid = scheme.grid
        if grid.d != 1:
            return (f"d = {grid.d}: the multiplier systems are block-tridiagonal for a chain of nodes only "
                    "(d = 1); a banded solve for d ≥ 2 is not written")
        if grid.periodic[0]:
            return "a periodic axis closes the chain (the multiplier systems are not block-tridiagonal)"
        n = int(grid.shape[0])
        tails, heads = scheme.edge_nodes()
        if n < 2 or not (np.array_equal(tails[0], np.arange(n - 1)) and np.array_equal(heads[0], np.arange(1, n))):
            return "the edges do not form a chain of nodes"
        return None

    def compiled_loop(self, scheme: Scheme, state: State, dt: float):
        """``rattle_loop`` (:mod:`cartan.integrators.rattle_loop`) when :meth:`compiled_reason`
        is None; lie-verlet's loop when the medium holds nothing fixed; otherwise None (the
        Python step), the reason in ``self.compiled_declined``.

        The arguments that depend on the problem and Δt only (the free flow's pieces, the
        closing matrix, the held components and their values) are built at the first call for
        a (scheme, problem, Δt) and reused by the later calls of a run, which only take the
        force carried between steps (first-same-as-last) and fresh ``status``/``info``."""
        self.compiled_declined = None
        if scheme.medium.constrained_strains() is None:
            return super().compiled_loop(scheme, state, dt)
        cached = self._loop_args
        if cached is not None and cached[0] is scheme and cached[1] is scheme.problem and cached[2] == dt:
            static = cached[3]
        else:
            static = self._loop_static(scheme, state, dt)
            self._loop_args = (scheme, scheme.problem, dt, static)
        if isinstance(static, str):
            self.compiled_declined = static
            return None
        if static is None:  # no rows: lie-verlet's loop
            return super().compiled_loop(scheme, state, dt)
        velocity_free, pieces, fracs, closing, comp, value, scale = static
        r = scheme.group.dim
        offset, offset_dt = _memory(state, (int(scheme.grid.shape[0]) - 1) * comp.size)
        key = (id(state), state.t, state.scalars.get("nstep", 0))
        have = self._fsal is not None and self._fsal[0] == key  # (lie-verlet's first-same-as-last force)
        W = (np.array(self._fsal[1], dtype=float) if have else np.zeros(state.S.shape)).reshape(-1, r)
        status = np.zeros(2, dtype=np.int64)
        info = np.zeros(1)
        return "rattle_loop", (W, bool(have), velocity_free, pieces, fracs, closing, comp, value, scale,
                               offset.reshape(_HISTORY, -1, comp.size), offset_dt, status, info)

    def _loop_static(self, scheme: Scheme, state: State, dt: float) -> tuple | str | None:
        """The arguments of ``rattle_loop`` fixed by (scheme, problem, Δt): ``(velocity_free,
        pieces, fracs, closing, comp, value, scale)``; the reason (a string) when the loop does
        not take the steps; None when the medium holds no row on this lattice."""
        reason = self.compiled_reason(scheme)
        if reason is not None:
            return reason
        con, unknown, nodes, scale = self._constraints(scheme, state)
        if not con.ncon:
            return None
        if not all(bool(a.all()) for a in con.active):
            return "an edge joins two fixed nodes (no row there: the chain of rows is broken)"
        _, (_, _, velocity_free, pieces, fracs, closing) = super().compiled_loop(scheme, state, dt)
        comp = np.ascontiguousarray(con.comp, dtype=np.int64)
        value = np.ascontiguousarray(con.value, dtype=float)  # (the loop reads these: shared by the calls)
        return bool(velocity_free), pieces, fracs, closing, comp, value, float(scale)

    def compiled_loop_done(self, state: State, args: tuple) -> None:
        super().compiled_loop_done(state, args)
        self._matrix_at = None
        if len(args) > 6:  # rattle_loop (not lie-verlet's, for a medium without constraints)
            status, info = args[-2], args[-1]
            self.niter += int(status[1])
            self._failure = (int(status[0]), float(info[0]), state.t)

    def run_compiled_loop(self, scheme: Scheme, state: State, dt: float, nsteps: int,
                          kinetic_limit: float = float("inf")) -> bool:
        """The base class' generated loop, then the Python step's errors for a step that failed
        (the state is the one that step started from): :class:`~cartan.statics.ConvergenceError`
        when the multipliers' iteration did not converge, ``ValueError`` when the initial
        configuration could not be brought onto the constraints or, with driven ends, when the
        rows are dependent (a singular multiplier system)."""
        self._failure = None
        ran = super().run_compiled_loop(scheme, state, dt, nsteps, kinetic_limit)
        failure, self._failure = self._failure, None
        if ran and failure is not None and failure[0]:
            code, err, t = failure
            if code == 2:
                raise ValueError(f"rattle: the initial configuration is too far from the constrained strains (max "
                                 f"|X_e[k] − value_k| = {err:.3e} after {_MAX_ITERATIONS} projection steps)")
            if code == 3 and getattr(scheme, "_driven", None) is not None:
                raise ValueError(_DEPENDENT)
            from ..statics import ConvergenceError

            raise ConvergenceError(
                f"rattle: the constrained strains were not met at t = {t:.6g} (max |X_e[k] − value_k| = {err:.3e} "
                f"after at most {_MAX_ITERATIONS} iterations); reduce dt", _MAX_ITERATIONS, err, [err])
        return ran

    # ------------------------------------------------------------------ setup
    def _constraints(self, scheme: Scheme, state: State):
        """``(StrainConstraints, unknown mask [*shape, r], nodes with unknowns, tolerance)`` of
        the scheme, built once."""
        if self._held is not None and self._held[0] is scheme:
            return self._held[1]
        r = scheme.group.dim
        unknown = np.broadcast_to(scheme.live, (*scheme.grid.shape, r)).copy()
        unknown[scheme._clamped] = False
        con = scheme.constraint_rows(unknown, state)  # the scheme's rows (lattice: edges; collocation: nodes)
        if con.ncon and scheme.grid.glued is not None:
            raise ValueError("integrator 'rattle' does not support strain constraints on a grid with a glued axis "
                             "(Grid.glued, the sphere's chart): its multiplier systems take no ghost ends; use "
                             "cartan.solve_static or a constraint-free medium")
        flat = unknown.reshape(-1, r)
        nodes = np.flatnonzero(flat.any(axis=1))
        scale = max(1.0, float(np.max(np.abs(con.value), initial=0.0)))
        held = (con, unknown, nodes, scale)
        self._held = (scheme, held)
        return held

    def _metric(self, scheme: Scheme, nodes: np.ndarray, unknown: np.ndarray, closing: np.ndarray | None):
        """``P`` ``(nunk, nunk)`` (CSR): N on the unknowns of a nodal impulse I on them is ``P I``,
        blocks ``(M⁺·closing)[u_i, u_i]/w_i`` (closing the damped kick's matrix, or I; u_i the
        node's unknown components: its live ones, less those a :class:`~cartan.problem.Held` end
        or a :class:`~cartan.problem.Symmetry` face holds, whose metric does not couple them with
        the others, checked by the problem)."""
        key = (id(scheme), None if closing is None else closing.tobytes())
        cache = self._metrics
        if key in cache:
            return cache[key]
        if len(cache) > 4:
            cache.clear()
        A = scheme.inverse_metric if closing is None else scheme.inverse_metric @ closing
        w = scheme.weights.reshape(-1)[nodes]
        P = self._node_blocks(nodes, unknown, np.broadcast_to(A, (nodes.size, *A.shape)) / w[:, None, None])
        cache[key] = P
        return P

    def _reuses(self, scheme: Scheme, con: Any) -> bool:
        """Whether the multiplier systems take :meth:`_factors`' kept symmetric-mode factors: the
        lattice's edge rows on d ≥ 2 (``_REUSE_FACTORS``); the d = 1 chains and the scheme's own
        rows (collocation) factorise at every use with the general LU."""
        return _REUSE_FACTORS and scheme.grid.d >= 2 and hasattr(con, "tails")

    def _factors(self, scheme: Scheme, B: Any, closing: np.ndarray | None, held: tuple) -> Any:
        """The SuperLU factors of ``B P Bᵀ`` ``(ncon, ncon)`` (P of :meth:`_metric` with
        ``closing``).  On d ≥ 2 lattices (:meth:`_reuses`) they are kept for the matrix object
        ``B`` — the rows at one configuration — so that the closing velocity projection's factors
        at Φₙ₊₁ are the next step's predictor and chord factors (one factorisation per step
        instead of two, none for a repeated kick of the closing fixed point), and without
        ``closing`` (``B P Bᵀ`` symmetric positive definite when the rows are independent) the
        matrix is factorised in symmetric mode (:func:`_splu_spd`)."""
        import scipy.sparse.linalg as spla

        con, unknown, nodes, _ = held
        reuse = self._reuses(scheme, con)
        key = None if closing is None else closing.tobytes()
        for B_kept, key_kept, lu in self._factored if reuse else ():
            if B_kept is B and key_kept == key:
                return lu
        A = (B @ self._metric(scheme, nodes, unknown, closing) @ B.T).tocsc()
        if not reuse:
            return spla.splu(A)
        lu = _splu_spd(A) if closing is None else spla.splu(A)
        self._factored = [(B, key, lu), *self._factored[:1]]
        return lu

    @staticmethod
    def _node_blocks(nodes: np.ndarray, unknown: np.ndarray, blocks: np.ndarray):
        """The block-diagonal ``(nunk, nunk)`` (CSR) of the per-node ``blocks`` ``[nb, r, r]``
        restricted to each node's unknown components (rows and columns in the order of
        ``N[unknown]``)."""
        import scipy.sparse as sp

        r = unknown.shape[-1]
        flat = unknown.reshape(-1, r)
        index = -np.ones(flat.shape, dtype=np.int64)
        index[flat] = np.arange(int(flat.sum()))
        idx = index[nodes]  # [nb, r]
        ok = (idx[:, :, None] >= 0) & (idx[:, None, :] >= 0)
        rows = np.broadcast_to(idx[:, :, None], ok.shape)[ok]
        cols = np.broadcast_to(idx[:, None, :], ok.shape)[ok]
        nunk = int(flat.sum())
        return sp.csr_matrix((blocks[ok], (rows, cols)), shape=(nunk, nunk))

    def _flow_jacobian(self, scheme: Scheme, state: State, dt: float, held: tuple):
        """``(nunk, nunk)`` (CSR): the drift at Φₙ₊₁ of a change of the impulse on the unknowns,
        ``dexp(−ΔtN_i)·Δt·M⁺/w_i`` per node on its unknown components (exp(Δt(N + δN)) =
        exp(ΔtN) exp(dexp(−ΔtN)ΔtδN); N the trial's velocity, exact for the unsplit flow, to
        O(Δt²|N|²) for lie-verlet's; at a node with held components N and δN lie in the free
        components' subalgebra, which dexp(−ΔtN) maps onto itself)."""
        _, unknown, nodes, _ = held
        r = scheme.group.dim
        N = scheme.velocity(state).reshape(-1, r)[nodes]
        E = scheme.group.dexp(-dt * N)  # [nb, r, r]
        w = scheme.weights.reshape(-1)[nodes]
        u = unknown.reshape(-1, r)[nodes]  # [nb, r]: δN lives on the node's unknowns
        A = np.where(u[:, :, None] & u[:, None, :], scheme.inverse_metric, 0.0)
        blocks = dt * np.einsum("nij,njk->nik", E, A) / w[:, None, None]
        return self._node_blocks(nodes, unknown, blocks)

    def _impulse(self, unknown: np.ndarray, weights: np.ndarray, vec: np.ndarray) -> np.ndarray:
        """The force density ``[*shape, r]`` of the nodal impulse ``vec`` on the unknowns."""
        out = np.zeros(unknown.shape)
        out[unknown] = vec
        return out / weights[..., None]

    # ------------------------------------------------------------------ projections
    def _project_velocity(self, scheme: Scheme, state: State, B, closing: np.ndarray | None, half: float,
                          held: tuple, skip_tangent: bool = False) -> None:
        """Add the impulse ``½Δt·closing·B_cᵀμ/w`` that makes ``B_c N = 0`` (one linear solve)."""
        import scipy.sparse.linalg as spla

        con, unknown, nodes, _ = held
        Nfull = scheme.velocity(state)
        N = Nfull[unknown]
        res = self._rows_residual(scheme, state, B, Nfull, held)
        if skip_tangent and np.max(np.abs(res), initial=0.0) <= 1e-13 * abs(B).max() * np.max(np.abs(N), initial=0.0):
            return  # tangent to round-off already
        if self._reuses(scheme, con):  # the kept factors of B P Bᵀ (the ½Δt divided out)
            mu = -self._factors(scheme, B, closing, held).solve(res) / half
        else:
            P = self._metric(scheme, nodes, unknown, closing)
            A = (B @ P @ B.T).tocsc() * half
            mu = -spla.splu(A).solve(res)
        imp = self._impulse(unknown, scheme.weights, B.T @ mu)
        if closing is not None:
            imp = np.einsum("kl,...l->...k", closing, imp)
        state.S = state.S + half * imp
        scheme.constrain(state)

    def _project_configuration(self, scheme: Scheme, state: State, held: tuple) -> None:
        """Bring Φ onto c(Φ) = 0 by Gauss–Newton steps δ = −P Bᵀ(B P Bᵀ)⁻¹c along the drift
        (the M-weighted least correction); ``ValueError`` when it does not converge."""
        con, unknown, nodes, scale = held
        P = self._metric(scheme, nodes, unknown, None)
        c = con.values(state)
        for _ in range(_MAX_ITERATIONS):
            if np.max(np.abs(c), initial=0.0) <= 1e-13 * scale:
                return
            B = con.matrix(state)
            delta = -(P @ (B.T @ self._factors(scheme, B, None, held).solve(c)))
            full = np.zeros(unknown.shape)
            full[unknown] = delta
            scheme.drift(state, 1.0, full, exact=True)
            c_next = con.values(state)
            if np.max(np.abs(c_next)) > 0.5 * np.max(np.abs(c)) and np.max(np.abs(c_next)) <= 1e-10 * scale:
                return  # at round-off
            c = c_next
        raise ValueError(f"rattle: the initial configuration is too far from the constrained strains (max |X_e[k] − "
                         f"value_k| = {np.max(np.abs(c)):.3e} after {_MAX_ITERATIONS} projection steps)")

    def _predict(self, scheme: Scheme, state: State, B, W: np.ndarray, held: tuple, lu) -> np.ndarray:
        """The force-level multiplier λ at the step's start, the guess of the step's ν (plus
        the last step's offset ν − λ, :func:`_offset`): the one that keeps the constraints'
        acceleration at zero, ``d/dt(B_c N) = 0`` with ``Ṡ = ad_NᵀS + W + B_cᵀλ/w``, i.e.
        ``(B P B_cᵀ)λ = −B[M⁺(ad_NᵀS + W)] − Ḃ_c N`` (:meth:`_rows_rate`); ``lu`` the factors of
        ``B P Bᵀ``."""
        from .explicit import _adT

        con, unknown, nodes, _ = held
        N = scheme.velocity(state)
        acc = scheme.medium.velocity(_adT(scheme.group, N, state.S) + W)
        return -lu.solve(B @ acc[unknown] + self._rows_rate(scheme, state, N, con))

    @staticmethod
    def _rows_rate(scheme: Scheme, state: State, N: np.ndarray, con) -> np.ndarray:
        """``Ḃ_c N`` ``(ncon,)``: the rows' second derivative along the drift Φ ← Φ exp(εN), N
        constant (``[*shape, r]``).  Per edge, ξ = hX_e and ξ(ε) = log(exp(−εN_i) exp(ξ) exp(εN_j)),
        with ξ' = dexp⁻¹(−ξ)N_j − dexp⁻¹(ξ)N_i (the rows times h) and, from the series
        dexp⁻¹(x) = Σ B_k/k! ad_xᵏ (B₁ = −½, B₂ = 1/6),

            ξ'' = ½[ξ', N_i + N_j] + (1/12)(ad_ξ ad_ξ' + ad_ξ' ad_ξ)(N_j − N_i) + O(|ξ|³|ξ'||N|),

        the rate ξ''[comp]/h.  The terms left out are ≈ (4/720)|ξ|³ of the first (|ξ| = h|X_e|:
        4e-6 relative measured at n = 11 under the tip wrench against a fourth-order difference):
        a starting guess, whose error is O(Δt) anyway (the steps take the same iterations with
        the exact rate and with the one-sided difference this replaces)."""
        if hasattr(con, "rows_rate"):  # the scheme's rows (collocation): exact
            return con.rows_rate(state, N)
        g, r = scheme.group, scheme.group.dim
        Nf = N.reshape(-1, r)
        out = []
        for axis, active in enumerate(con.active):
            xi = g.log(state.arrays[scheme._key(axis)]).reshape(-1, r)[active]
            a, b = Nf[con.tails[axis][active]], Nf[con.heads[axis][active]]
            A, adx = g.dexp_inv(xi), g.ad(xi)
            u = np.einsum("eij,ej->ei", A + adx, b) - np.einsum("eij,ej->ei", A, a)
            adu = g.ad(u)
            d = b - a
            xdd = 0.5 * np.einsum("eij,ej->ei", adu, a + b) + (1.0 / 12.0) * (
                np.einsum("eij,ej->ei", adx, np.einsum("eij,ej->ei", adu, d))
                + np.einsum("eij,ej->ei", adu, np.einsum("eij,ej->ei", adx, d)))
            out.append((xdd[:, con.comp] / scheme.h[axis]).ravel())
        return np.concatenate(out) if out else np.zeros(0)

    #: :meth:`constraint_residual` takes the scheme's edge strains when the caller has them
    #: (:func:`cartan.io.frame_record`)
    residual_from_edge_strains = True

    def constraint_residual(self, scheme: Scheme, state: State,
                            edge_strains: list[np.ndarray] | None = None) -> float:
        """max |X_e[k] − value_k| over the constrained edges and components (0 when none).

        ``edge_strains``, when given, is ``scheme.edge_strains(state)`` (per axis
        ``[*edge_shape, r]``), already computed by the caller: the rows' values are taken from
        it as :meth:`~cartan.constraints.StrainConstraints.values` takes them (the same numbers)."""
        if scheme.medium.constrained_strains() is None:
            return 0.0
        con = self._constraints(scheme, state)[0]
        if edge_strains is None or not con.ncon or not hasattr(con, "tails"):
            return float(np.max(np.abs(con.values(state)), initial=0.0))
        big = 0.0
        for x, active in zip(edge_strains, con.active, strict=True):
            xe = x.reshape(-1, con.r_dim)[:, con.comp] - con.value
            big = max(big, float(np.max(np.abs(xe[active]), initial=0.0)))
        return big

    # ------------------------------------------------------------------ step
    def _step(self, scheme: Scheme, state: State, dt: float) -> None:
        if scheme.medium.constrained_strains() is None:  # nothing held: lie-verlet's step
            super()._step(scheme, state, dt)
            return
        held = self._constraints(scheme, state)
        con, unknown, nodes, scale = held
        if not con.ncon:
            super()._step(scheme, state, dt)
            return
        import scipy.sparse.linalg as spla

        half = 0.5 * dt
        # the step starts on the manifold, with a tangent velocity
        c0 = con.values(state)
        offset, nprev = _offset(state, con.ncon, dt)
        if np.max(np.abs(c0), initial=0.0) > 1e-10 * scale:
            self._project_configuration(scheme, state, held)
            self._fsal = self._matrix_at = None
            offset, nprev = None, 0
        key = (id(state), state.t, state.scalars.get("nstep", 0))
        B0 = self._matrix_at[1] if self._matrix_at is not None and self._matrix_at[0] == key else con.matrix(state)
        self._project_velocity(scheme, state, B0, None, half, held, skip_tangent=True)
        W0 = self._kick_force(scheme, state)
        S0 = state.S.copy()
        arrays0 = {k: v.copy() for k, v in state.arrays.items()}
        # B₀ P B₀ᵀ: the predictor's matrix and, times ½Δt·Δt, the chord matrix of the iteration
        lu0 = self._factors(scheme, B0, None, held)
        lam = self._predict(scheme, state, B0, W0, held, lu0)
        nu = lam if offset is None else lam + offset
        lu = None
        prev = np.inf
        for it in range(_MAX_ITERATIONS + 1):
            state.S = S0 + half * (W0 + self._impulse(unknown, scheme.weights, B0.T @ nu))
            scheme.constrain(state)
            state.arrays = {k: v.copy() for k, v in arrays0.items()}
            self._free_flow(scheme, state, dt)
            c = con.values(state)
            err = float(np.max(np.abs(c), initial=0.0))
            # a stall means round-off only with Newton's matrix; the chord's stalls turn to it below
            if err <= 1e-13 * scale or (lu is not None and err <= 1e-10 * scale and err > 0.5 * prev):
                break
            if not np.isfinite(err) or it == _MAX_ITERATIONS:
                state.S, state.arrays = S0, arrays0
                from ..statics import ConvergenceError

                raise ConvergenceError(
                    f"rattle: the constrained strains were not met at t = {state.t:.6g} (max |X_e[k] − value_k| = "
                    f"{err:.3e} after {it} iterations); reduce dt", it, err, [err])
            if lu is None and it > 0 and err > _SLOW * prev:  # the chord gains too little: Newton's matrix
                B1 = con.matrix(state)
                lu = spla.splu((B1 @ self._flow_jacobian(scheme, state, dt, held) @ B0.T).tocsc() * half)
            nu = nu - (lu0.solve(c) / (half * dt) if lu is None else lu.solve(c))
            prev = err
        self.niter += it
        # the next step's offset ν − λ, ν with one more correction of the last matrix (no flow: the
        # converged ν is fixed to the tolerance only, the corrected one to its square)
        nu = nu - (lu0.solve(c) / (half * dt) if lu is None else lu.solve(c))
        _remember(state, con.ncon, nu - lam, dt, nprev > 0)
        t1 = state.t + dt
        W1 = self._closing_kick(scheme, state, dt, t1)
        self._fsal = ((id(state), t1, state.scalars.get("nstep", 0) + 1), W1)
        self._matrix_at = ((id(state), t1, state.scalars.get("nstep", 0) + 1), self._closing_B)

    def _closing_kick(self, scheme: Scheme, state: State, dt: float, t1: float) -> np.ndarray:
        """lie-verlet's closing kick (implicit in linear damping, a fixed point for other
        velocity-dependent forces), each kick followed by the velocity multiplier's impulse
        (:meth:`_settle`): ``S⁺ = S½ + ½Δt(W(Φ⁺, N⁺) + B_cᵀμ/w)`` with ``B_c N⁺ = 0``; returns
        the W applied (without the reaction: the next step's first kick has its own multipliers)."""
        con = self._constraints(scheme, state)[0] if scheme.medium.constrained_strains() is not None else None
        self._closing_B = con.matrix(state) if con is not None and con.ncon else None
        return super()._closing_kick(scheme, state, dt, t1)

    def _settle(self, scheme: Scheme, state: State, half: float, gamma: np.ndarray | None) -> None:
        """The velocity projection after a closing kick: with damping the impulse passes through
        the kick's closing matrix ``(I + ½ΔtΓM⁺)⁻¹`` (μ is solved with the damping)."""
        if self._closing_B is None:  # nothing held: lie-verlet's kick
            return
        closing = None if gamma is None else _closing_matrix(scheme, gamma, 2.0 * half)
        self._project_velocity(scheme, state, self._closing_B, closing, half, self._constraints(scheme, state))

    def options(self) -> dict[str, Any]:
        return {}
