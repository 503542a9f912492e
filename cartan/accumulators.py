"""Per-node accumulators a medium declares: ``a_i(t) = ∫₀ᵗ r_i dt`` integrated along a run.

A medium that declares :meth:`~cartan.medium.Medium.accumulators` (``{name: (long_name,
units)}``) and gives their rates (:meth:`~cartan.medium.Medium.accumulator_rates`, one value
per node from the configuration, the nodal strains and the velocities) has them integrated by
:func:`cartan.simulate` over every step by the trapezoidal rule,

    a ← a + ½Δt [r(state before the step) + r(state after)],

second order in Δt for a smooth rate.  The values live in the state
(``state.arrays["accumulator_<name>"]``, ``[*grid.shape]``, zero at t = 0), so they are copied
with it, written to the checkpoint and continued exactly by a restart; every saved frame
records them as the output variable ``name`` ``(time, *nodes)`` with the declared long name
and units.  A rate is a function of the state alone, so the rate after a step, kept for the
next one, equals the one a restart computes afresh: restarts stay bit for bit.

The update runs on the reference (numpy) path after each step (:func:`add`), or inside the
generated loops of the lattice and the collocation (``lie-verlet``, ``lie-euler``/``forward-euler``,
``rkmk4``, ``implicit-midpoint``'s Newton blocks; with a Lagrangian coupling N and X all but
``lie-verlet``) when the medium's point kernels
give the rates at a node from its velocity (:attr:`cartan.medium.MediumKernels.accumulator_rate`;
on the collocation the nodal velocity of the loop, N(S_i, X_i) for a coupled Lagrangian): the
loops' ``op_accumulate`` hook (:mod:`cartan.integrators.loops`,
:func:`cartan.schemes._lattice_ops.accumulate_fragment`) applies the same update in the same
floating-point order, ``a + (½Δt)(r₀ + r₁)``, so the two paths differ only by the round-off of
the states they step (measured bit for bit on the elastic string on both schemes with the
explicit loops; ``implicit-midpoint``, whose compiled and numpy steps agree to the Newton
tolerance's round-off, to 1e-12; ``tests/test_accumulators_compiled.py``,
``tests/test_accumulators_collocation_compiled.py``).  ``implicit_loop``
(:mod:`cartan.integrators.newton`) takes the rates at the start of each call and after every
step from the velocity ``op_state_velocity`` gives, as :func:`rates` takes them from
``Scheme.velocity``.  Without that kernel, or for the other
compiled paths (the hand-written loops), such a medium steps one by
one on the numpy path (:func:`cartan.simulate`).  Media that declare none (all but a few) are
untouched.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .state import State

__all__ = ["PREFIX", "declared", "key", "rates", "start", "values"]

#: the prefix of an accumulator's entry in ``State.arrays``
PREFIX = "accumulator_"


def declared(medium: Any) -> dict[str, tuple[str, str]]:
    """The medium's accumulators ``{name: (long_name, units)}``, checked (``{}`` for most media).

    Raises
    ------
    ValueError
        Naming the medium: an entry that is not ``(long_name, units)`` with string members, or
        a name that is not a non-empty identifier.
    """
    fn = getattr(medium, "accumulators", None)
    acc = fn() if callable(fn) else {}
    if not acc:
        return {}
    label = f"medium {getattr(medium, 'name', type(medium).__name__)!r}"
    if not isinstance(acc, dict):
        raise ValueError(f"{label}: accumulators() must return a dict {{name: (long_name, units)}}, got {acc!r}")
    for name, entry in acc.items():
        if not isinstance(name, str) or not name.isidentifier():
            raise ValueError(f"{label}: accumulator names must be identifiers, got {name!r}")
        if not (isinstance(entry, tuple) and len(entry) == 2 and all(isinstance(e, str) for e in entry)):
            raise ValueError(f"{label}: accumulators()[{name!r}] must be (long_name, units), got {entry!r}")
    return dict(acc)


def key(name: str) -> str:
    """The entry of accumulator ``name`` in ``State.arrays``."""
    return PREFIX + name


def start(scheme: Any, state: State) -> State:
    """Add the medium's accumulators, zero, to a state that lacks them (in place; returned)."""
    for name in declared(scheme.medium):
        state.arrays.setdefault(key(name), np.zeros(scheme.grid.shape))
    return state


def rates(scheme: Any, integrator: Any, state: State) -> dict[str, np.ndarray]:
    """The medium's accumulator rates ``{name: [*grid.shape]}`` at ``state`` (the configuration,
    nodal strains and velocities that :func:`cartan.io.frame_record` gives ``outputs``).

    Raises
    ------
    ValueError
        When the medium does not return a finite-shaped ``[*grid.shape]`` array for every name.
    """
    med = scheme.medium
    acc = declared(med)
    Phi = np.asarray(scheme.frames(state))
    sp = getattr(med, "space", None)  # (as cartan.io.frame_record gives outputs())
    q = sp.act(Phi, sp.q_r) if sp is not None else Phi
    X = np.asarray(scheme.nodal_strains(state))
    N = integrator.velocity(scheme, state) if not integrator.uses_momentum else scheme.velocity(state)
    out = med.accumulator_rates(q, X, np.asarray(N), scheme.grid)
    shape = tuple(scheme.grid.shape)
    result = {}
    for name in acc:
        if name not in out:
            raise ValueError(f"medium {med.name!r}: accumulator_rates() did not return {name!r}")
        r = np.asarray(out[name], dtype=float)
        if r.shape != shape:
            raise ValueError(f"medium {med.name!r}: accumulator rate {name!r} has shape {r.shape}, the grid's "
                             f"{shape}")
        result[name] = r
    return result


def add(state: State, dt: float, before: dict[str, np.ndarray], after: dict[str, np.ndarray]) -> None:
    """``a ← a + ½Δt (r_before + r_after)`` for every accumulator (in place)."""
    for name, r0 in before.items():
        k = key(name)
        state.arrays[k] = state.arrays[k] + 0.5 * dt * (r0 + after[name])


def values(medium: Any, grid: Any, state: State) -> dict[str, np.ndarray]:
    """The accumulators of ``state`` ``{name: [*grid.shape]}`` (copies); NaN where the state has
    none (a state not advanced by :func:`cartan.simulate`, e.g. a static solution)."""
    return {name: (np.array(state.arrays[key(name)], dtype=float) if key(name) in state.arrays
                   else np.full(tuple(grid.shape), np.nan))
            for name in declared(medium)}
