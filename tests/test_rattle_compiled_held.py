"""The compiled ``rattle`` loop (:mod:`cartan.integrators.rattle_loop`) with held components
(:class:`cartan.Held` ends, :class:`cartan.Symmetry` faces) against the Python step.

The loop's node operators (``P``, the quasi-Newton blocks, the predictor's acceleration) are
restricted to each node's free components by the operator set's ``held`` mask, as the Python
step's per-node blocks are: the compiled and the Python runs, 50 steps in three blocks (1, 2,
47), agree to round-off in the state, the rows stay at round-off, the held components do not
move, and ``Rattle.support_reaction`` (the reaction on the held components, the rows' tension
included) agrees too.

Slow: each run compiles the filament's rattle loop on first use (45–90 s on a fresh cache).
"""

from __future__ import annotations

import numpy as np
import pytest
from test_rattle_held import filament, hanging, pinned_arc
from toys import run_both

import cartan
from cartan.integrators import Rattle
from cartan.schemes.lattice import Lattice

#: compiled against Python, relative to the largest value: both converge the multipliers to
#: |c| ≤ 1e-13 and differ in the order of their sums only (round-off ≈ 1e-16 per evaluation),
#: over 50 steps (measured below 1e-14)
TOL = 1e-12
#: the reaction: the force-level multipliers of both states (their rows' rate by a central
#: difference, round-off ≈ 1e-16/ε₀ ≈ 1e-10 relative, :meth:`Rattle._rows_rate_exact`)
REACTION_TOL = 1e-10
NSTEPS = 50
BLOCKS = (1, 2, NSTEPS - 3)


def _rel(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b), initial=0.0)) / max(float(np.max(np.abs(b), initial=0.0)), 1e-300)


def _symmetric_half() -> cartan.Problem:
    """The half s ≤ L/2 of the ball-jointed arc with a ``Symmetry`` face at s = L/2 (the node
    slides in the plane x = 0 and turns about x only; tests/test_rattle_held.py)."""
    full = pinned_arc(pin=(0, 1, 2))
    return cartan.Problem(full.medium, cartan.Grid(6, length=0.5), cartan.InitialState(Phi=full.initial.Phi[:6].copy()),
                          {"start": cartan.Held((0, 1, 2)), "end": cartan.Symmetry()}, loads=full.loads)


def _uniformly_damped() -> cartan.Problem:
    """The pinned arc with damping proportional to its inertia (the closing matrix s·I: the
    closing projection reuses the factors of B P Bᵀ)."""
    fil = filament()
    problem = pinned_arc()
    return cartan.Problem(fil, problem.grid, problem.initial, problem.boundaries,
                          loads=[*problem.loads, cartan.Damping([0.5, 0.5, 0.5, 0.025, 0.025, 0.025])])


def test_the_compiled_loop_takes_held_components():
    """Held ends and Symmetry faces are no reason to leave the steps to Python (no compilation:
    the reason only)."""
    assert Rattle().compiled_reason(Lattice(pinned_arc())) is None
    assert Rattle().compiled_reason(Lattice(_symmetric_half())) is None
    ops = Lattice(pinned_arc()).compiled_operators()
    assert ops.ok and ops.data.any_held and ops.data.held[0].tolist() == [True] * 5 + [False]


CASES = {
    "pinned-arc": (pinned_arc, 2e-3),
    "symmetry-half": (_symmetric_half, 2e-3),
    # non-uniform damping (its closing matrix is not s·I: the closing projection's own factors)
    "pinned-damped": (lambda: hanging(damping=[8.0, 8.0, 8.0, 0.5, 0.5, 0.5]), 4e-3),
    "pinned-uniform-damping": (_uniformly_damped, 2e-3),
}


@pytest.mark.slow  # (compiles the filament's rattle loop on first use: 45–90 s on a fresh cache)
@pytest.mark.parametrize("case", list(CASES))
def test_compiled_held_run_matches_the_python_step(case, monkeypatch):
    make_problem, dt = CASES[case]
    problem = make_problem()
    ran = []
    original = Rattle.compiled_loop

    def spy(self, *args, **kwargs):
        spec = original(self, *args, **kwargs)
        ran.append(None if spec is None else spec[0])
        return spec

    monkeypatch.setattr(Rattle, "compiled_loop", spy)
    scheme, (ref, ref_integ), (fast, fast_integ) = run_both(Lattice, problem, Rattle, dt, NSTEPS, BLOCKS)
    assert ran == ["rattle_loop"] * len(BLOCKS) and fast_integ.compiled_declined is None
    start = scheme.initial_state()
    assert fast.scalars["nstep"] == ref.scalars["nstep"] == NSTEPS and fast.t == ref.t
    assert _rel(ref.arrays["Phi"], start.arrays["Phi"]) > 1e-4  # it moved
    assert _rel(fast.S, ref.S) <= TOL
    for key in ref.arrays:
        assert _rel(fast.arrays[key], ref.arrays[key]) <= TOL, key
    for key in ("dissipated_energy", "external_work"):
        assert abs(fast.scalars[key] - ref.scalars[key]) <= TOL * max(abs(ref.scalars[key]), 1.0), key
    assert fast_integ.niter == ref_integ.niter  # the same iterations
    # the rows at round-off, the held components at rest (exactly) and in place
    assert fast_integ.constraint_residual(scheme, fast) <= 1e-13
    mask = np.broadcast_to(scheme._clamped, fast.S.shape) if scheme._clamped.ndim == 1 else scheme._clamped
    assert mask.any()
    assert np.all(fast.S[mask] == 0.0) and np.all(fast_integ.velocity(scheme, fast)[mask] == 0.0)
    pins = [i for i in range(scheme.grid.shape[0]) if mask[i, :3].all()]
    assert pins
    x0, x1 = scheme.frames(start)[pins, 1:, 0], scheme.frames(fast)[pins, 1:, 0]
    assert np.array_equal(x0, x1)
    if case == "symmetry-half":
        assert abs(scheme.frames(fast)[-1, 1, 0]) <= 1e-15  # the face node stays in the plane x = 0
    R_ref, R_fast = Rattle().support_reaction(scheme, ref), Rattle().support_reaction(scheme, fast)
    assert np.max(np.abs(R_ref)) > 0.0
    assert _rel(R_fast, R_ref) <= REACTION_TOL
