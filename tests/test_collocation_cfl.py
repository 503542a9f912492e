"""The compiled stiffness probe of the collocation scheme (``cartan.schemes._collocation_diagnostics``).

``Scheme.dt_max`` estimates the CFL step by a power iteration on the stiffness products of
``Scheme.stiffness_probe``.  For collocation problems with a compiled plan the products run in
one compiled call (two exact drifts and two force evaluations of the compiled loops' kernels);
they must agree with the numpy products (``Collocation.drift``/``force``) to the round-off of
a central difference, and ``dt_max`` with the numpy estimate to far better than the power
iteration's own stopping tolerance (1e-3 between successive Rayleigh quotients).
"""

from __future__ import annotations

import numpy as np
import pytest
from test_collocation_compiled import CASES, _NotQuadratic, _rel, rod_problem, toy_problem

import cartan
from cartan.integrators import RKMK4, LieVerlet, Overdamped
from cartan.problem import Clamped, Problem
from cartan.schemes import _collocation_compiled as cc
from cartan.schemes import _collocation_diagnostics as cd
from cartan.schemes.collocation import Collocation

#: the forces carry round-off of about 1e-16 of their size, which the central difference
#: divides by 2ε = 2e-7: products agree to ~1e-9 of their size (measured ≤ 8e-10); margin 12×
PRODUCT_TOL = 1e-8
#: the power iteration stops when two Rayleigh quotients agree to 1e-3; with products equal to
#: 1e-8 it takes the same path and the estimates agree to about that (measured ≤ 2.3e-10)
DT_TOL = 1e-7


def _numpy_probe(scheme, state):
    scheme.compiled_diagnostics = False
    try:
        return scheme.stiffness_probe(state)
    finally:
        scheme.compiled_diagnostics = True


def _count_compiled(monkeypatch) -> list:
    calls = []
    real = cc.stiffness_once
    monkeypatch.setattr(cc, "stiffness_once", lambda *a: calls.append(1) or real(*a))
    return calls


@pytest.mark.parametrize("group", ["SO2", "SE2", "SO3", "SE3"])
@pytest.mark.parametrize(("kind", "derivative"), CASES, ids=[f"{k}-{d}" for k, d in CASES])
def test_compiled_products_and_estimates_match_numpy(kind, derivative, group, monkeypatch):
    calls = _count_compiled(monkeypatch)
    scheme = Collocation(toy_problem(group, kind), derivative=derivative)
    state = scheme.initial_state()
    before = state.copy()
    v = np.random.default_rng(2).standard_normal(state.S.shape)
    K = scheme.stiffness_probe(state)(v)
    assert calls == [1]
    assert _rel(K, _numpy_probe(scheme, state)(v)) <= PRODUCT_TOL
    assert np.abs(K).max() > 0
    for integ in (RKMK4(), Overdamped()):
        fast = integ.dt_max(scheme, state)
        scheme.compiled_diagnostics = False
        ref = integ.dt_max(scheme, state)
        scheme.compiled_diagnostics = True
        assert abs(fast / ref - 1.0) <= DT_TOL
    assert len(calls) > 10  # the power iterations ran on the compiled products
    # the linearisation point is left as it was
    assert np.array_equal(state.S, before.S)
    assert all(np.array_equal(state.arrays[k], before.arrays[k]) for k in before.arrays)


@pytest.mark.parametrize("track", [False, True])
def test_rod_under_gravity_and_dead_load(track, monkeypatch):
    """The SE(3) rod with a dead end load and gravity (frames needed: stepped at every node),
    and the same rod clamped without loads (only the root frame stepped)."""
    calls = _count_compiled(monkeypatch)
    rod = rod_problem(False, n=14)
    problem = rod if track else Problem(rod.medium, rod.grid, rod.initial, {"start": Clamped()})
    scheme = Collocation(problem, derivative="fd4")
    assert scheme.track == track
    state = scheme.initial_state()
    v = np.random.default_rng(3).standard_normal(state.S.shape)
    assert _rel(scheme.stiffness_probe(state)(v), _numpy_probe(scheme, state)(v)) <= PRODUCT_TOL
    assert calls == [1]


def test_simulate_uses_the_compiled_estimate(monkeypatch):
    """``cartan.simulate`` chooses Δt from ``dt_max`` when none is given: the compiled products
    are taken there, and the run is the same as with the numpy estimate."""
    calls = _count_compiled(monkeypatch)
    kw = dict(t_end=2e-3, save_every=10, scheme="collocation", scheme_options={"derivative": "fd4"},
              integrator="rkmk4")
    fast = cartan.simulate(rod_problem(False), **kw)
    assert calls
    ref = cartan.simulate(rod_problem(False), **kw, compiled=False)
    assert fast.step.values[-1] == ref.step.values[-1]
    assert _rel(fast["X"].values, ref["X"].values) <= 1e-10


def test_falls_back_without_a_plan():
    base = toy_problem("SE3", "free")
    unplanned = Collocation(Problem(_NotQuadratic("SE3"), base.grid, base.initial))
    assert cd.collocation_plan(unplanned) is None
    assert cd.compiled_stiffness_probe(unplanned, unplanned.initial_state(), 1e-7) is None
    planned = Collocation(base)
    with cartan.use_backend("numpy"):
        assert cd.collocation_plan(planned) is None
    state = planned.initial_state()
    state.arrays["extra"] = state.arrays["X"].copy()  # another state layout
    assert cd.compiled_stiffness_probe(planned, state, 1e-7) is None
    # the numpy probe still answers for both
    for scheme in (unplanned, planned):
        st = scheme.initial_state()
        assert np.isfinite(LieVerlet().dt_max(scheme, st))
