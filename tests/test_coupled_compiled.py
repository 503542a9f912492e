"""The compiled path of Lagrangians that couple N and X (docs/design.md, "Media whose Lagrangian
couples N and X"; docs/media/relativistic-rod.md §3): the elastic relativistic string through the
lattice's generated loops (:func:`cartan.schemes._lattice_ops.coupled_fragment`).

Fast tests check the declarations (the medium's coupled kernels, the operator set's loops, the
integrators that decline).  Slow tests compile the loops of ``rkmk4`` and ``lie-euler`` (≈ 60 s and
15 s on a fresh cache) and compare them with the numpy path (``simulate(..., compiled=False)``):
the same formulas in the same order — the half-edge Legendre maps are Newton's method converged
to round-off on both paths — so every saved field agrees to 1e-12 of its scale (round-off of 20
steps; measured: bit for bit).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from cartan_relativistic.elastic import ElasticLaw
from cartan_relativistic.string import RelativisticRod
from toys import elastic_string

import cartan
from cartan.integrators.explicit import RKMK4, LieEuler, Overdamped
from cartan.schemes.lattice import Lattice

pytestmark = pytest.mark.filterwarnings("ignore::cartan.StabilityWarning")

LAWS = {"quadratic": {"stiffness": 0.25}, "quartic": {"law": ElasticLaw.quartic(0.25, 0.5)}}


def _problem(kind: str, law: str = "quadratic", n: int = 9):
    """An elastic string without clocks (the clocks in the loops: tests/test_accumulators_compiled.py):
    ``free``, ``clamped`` or ``ring`` (:func:`toys.elastic_string`)."""
    return elastic_string(kind, n, law=LAWS[law])


# ---------------------------------------------------------------------------- declarations
def test_elastic_string_declares_coupled_kernels_for_the_built_in_laws():
    for law in LAWS:
        kernels = _problem("free", law).medium.point_kernels()
        assert kernels.coupled_velocity is not None and kernels.coupled_stress is not None
    bare = ElasticLaw(lambda lam: 0.1 * (lam - 1) ** 2, lambda lam: 0.2 * (lam - 1), lambda lam: 0.2 + 0 * lam)
    assert cartan.medium("relativistic-rod", energy="elastic", law=bare).point_kernels() is None


class _CoupledNambuGoto(RelativisticRod):
    """A coupled medium whose kernels give the potential only (no coupled kernels)."""

    coupled_lagrangian = True


def test_coupled_medium_without_coupled_kernels_is_declined():
    grid = cartan.Grid(8, length=2 * math.pi, periodic=True)
    med = _CoupledNambuGoto()
    scheme = Lattice(cartan.Problem(med, grid, med.initial_state(grid, "loop")))
    ops = scheme.compiled_operators()
    assert not ops.ok and not ops.loops and "coupled point kernels" in ops.reason
    state = scheme.initial_state()
    assert RKMK4().run_compiled_loop(scheme, state, 0.01, 2) is False


def test_integrators_without_momentum_decline_a_coupled_lagrangian():
    """overdamped shares rkmk4's loop but carries no momentum: the numpy path (before any compile)."""
    scheme = Lattice(_problem("free"))
    state = scheme.initial_state()
    assert Overdamped().run_compiled_loop(scheme, state, 0.01, 2) is False
    assert state.t == 0.0


# ---------------------------------------------------------------------------- slow: compiled loops
@pytest.mark.slow
@pytest.mark.parametrize("kind", ["free", "clamped", "ring"])
@pytest.mark.parametrize("law", list(LAWS))
@pytest.mark.parametrize(("name", "cls"), [("rkmk4", RKMK4), ("lie-euler", LieEuler)])
def test_compiled_coupled_run_is_the_numpy_run(generated_runs, name, cls, law, kind):
    problem = _problem(kind, law)
    calls = generated_runs
    kw = dict(integrator=name, dt=0.01, t_end=0.2, save_every=5, progress=False)
    compiled = cartan.simulate(problem, **kw)
    assert calls and all(calls)  # every block ran in the generated loop
    calls.clear()
    reference = cartan.simulate(problem, compiled=False, **kw)
    assert not calls
    assert compiled.sizes["time"] == reference.sizes["time"] == 5
    for key in reference.data_vars:  # state (X, N, S, frames), energies, charges, the medium's outputs
        a, b = compiled[key].values, reference[key].values
        assert np.abs(a - b).max() <= 1e-12 * max(np.abs(b).max(), 1e-300), key
    moved = reference["S"].values
    assert np.abs(moved[-1] - moved[0]).max() > 1e-3  # (the run is not at rest)


@pytest.mark.slow
def test_forward_euler_runs_the_coupled_string_compiled(generated_runs):
    """forward-euler shares lie-euler's loop (naive drift, S += Δt Ṡ): the same run as numpy
    over 10 steps (unstable at every Δt, so a short run)."""
    problem = _problem("clamped", "quartic")
    calls = generated_runs
    kw = dict(integrator="forward-euler", dt=0.005, t_end=0.05, save_every=5, progress=False)
    compiled = cartan.simulate(problem, **kw)
    assert calls and all(calls)
    reference = cartan.simulate(problem, compiled=False, **kw)
    for key in ("S", "frame", "kinetic_energy", "potential_energy", "energy", "total_momentum"):
        a, b = compiled[key].values, reference[key].values
        assert np.abs(a - b).max() <= 1e-12 * max(np.abs(b).max(), 1e-300), key


@pytest.mark.slow
def test_compiled_coupled_loop_books_the_steps_like_the_numpy_steps():
    """run_compiled_loop against Integrator.step on the same state: t, nstep, the force count and
    the state agree (the loop works on copies and writes them back)."""
    scheme = Lattice(_problem("clamped", "quartic"))
    a = scheme.initial_state()
    b = a.copy()
    ia, ib = RKMK4(), RKMK4()
    assert ia.run_compiled_loop(scheme, a, 0.01, 7)
    for _ in range(7):
        ib.step(scheme, b, 0.01)
    assert a.t == b.t and a.scalars["nstep"] == b.scalars["nstep"] == 7 and ia.nforce == 4 * 7
    assert np.abs(a.S - b.S).max() <= 1e-12 * np.abs(b.S).max()
    for key in b.arrays:
        assert np.abs(a.arrays[key] - b.arrays[key]).max() <= 1e-12 * np.abs(b.arrays[key]).max()


@pytest.mark.slow
@pytest.mark.parametrize("cls", [RKMK4, LieEuler])
def test_a_failed_legendre_solve_stops_the_compiled_run(cls):
    """A momentum outside the range of the Legendre map (p = 2μc along an unstretched string):
    the numpy path raises ValueError (Medium.velocity_at), the compiled loop raises too, naming
    the Legendre map, and leaves the state as it was."""
    scheme = Lattice(_problem("free"))
    state = scheme.initial_state()
    state.S[4, 1:4] = [2.0, 0.0, 0.0]
    with pytest.raises(ValueError, match="subluminal velocity"):
        cls().step(scheme, state.copy(), 0.01)
    before = state.copy()
    with pytest.raises(ValueError, match="Legendre map N\\(S, X\\) of the medium has no inverse"):
        cls().run_compiled_loop(scheme, state, 0.01, 3)
    assert state.t == before.t and np.array_equal(state.S, before.S)
    assert all(np.array_equal(state.arrays[k], before.arrays[k]) for k in before.arrays)
