"""The compiled diagnostics (:mod:`cartan.compiled.diagnostics`: the CFL probe of
``Scheme.dt_max`` and the blow-up guard's energies) on the collocation's and the lattice's
operator sets with :class:`cartan.Driven` ends, against the numpy path.

Each set serves them (``OperatorSet.loops`` lists ``diagnostics.SERVED``): its driven nodes are
held, so the probe's drift and force leave them as ``Scheme.dt_max`` does (v = 0 and W = 0
there), its ``op_kinetic`` adds their ½wξ·Mξ (``Scheme.kinetic_energy`` with N = ξ there) and
its ``op_potential`` is a clamped set's.  The rod is the arc of
tests/test_collocation_driven_compiled.py (clamped at s = 0, driven at s = 1), moved by 20
compiled ``lie-verlet`` steps so that N, the strains and the driven end's frame are not the
initial ones.

Slow tests: the driven rod's ``lie-verlet`` loop (compiled by
tests/test_collocation_driven_compiled.py as well, the same module) and the probe and the
energies compile on first use (≈ 70 s, 17 s and 3 s on a fresh cache).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from test_collocation_driven_compiled import TWIST, _arc
from toys import rel_error

import cartan
from cartan.compiled import diagnostics
from cartan.integrators import LieVerlet
from cartan.schemes.collocation import Collocation
from cartan.schemes.lattice import Lattice

#: both schemes' sets with driven ends serve the diagnostics
SCHEMES = pytest.mark.parametrize("make", [Collocation, Lattice], ids=["collocation", "lattice"])

#: the forces carry round-off of about 1e-16 of their size, which the central difference divides
#: by 2ε = 2e-7: products agree to ~1e-9 of their size (measured 6e-11); margin 10×
PRODUCT_TOL = 1e-8
#: the power iteration stops when two Rayleigh quotients agree to 1e-3; with products equal to
#: 1e-8 it takes the same path and the estimates agree to about that (measured 3e-11)
DT_TOL = 1e-7
#: the energies: the same sums in another order (round-off, measured ≤ 2.2e-16)
ENERGY_TOL = 1e-12


def _damped_arc(n: int = 11) -> cartan.Problem:
    """The driven arc under damping (a drag for the overdamped rate)."""
    return _arc(TWIST, n=n, loads=[cartan.Damping([0.1] * 6)])


@SCHEMES
def test_the_driven_set_serves_the_diagnostics(make):
    """No compilation: the set with driven ends serves the diagnostics (and still not rattle's
    loop), ``_operators`` hands it to them for the scheme's state and declines it with the numpy
    backend, ``compiled_diagnostics`` cleared, or another state layout."""
    scheme = make(_damped_arc())
    ops = scheme.compiled_operators()
    state = scheme.initial_state()
    assert ops.data.any_driven and not ops.ok and "diagnostics" in ops.reason
    # (the lattice's rattle loop takes driven ends; the collocation's nodal rows run the Python step)
    assert ops.serves(diagnostics.SERVED) and ops.serves("rattle_loop") == (make is Lattice)
    assert diagnostics._operators(scheme, state) is ops
    with cartan.use_backend("numpy"):
        assert diagnostics._operators(scheme, state) is None
    other = state.copy()
    first = next(iter(other.arrays))
    other.arrays["extra"] = other.arrays[first].copy()
    assert diagnostics._operators(scheme, other) is None
    scheme.compiled_diagnostics = False
    assert diagnostics._operators(scheme, state) is None


@pytest.fixture(scope="module", params=[Collocation, Lattice], ids=["collocation", "lattice"])
def moved(request):
    """(scheme, state): the damped driven arc after 20 compiled lie-verlet steps, its
    diagnostics compiled whatever its size (``compiled_diagnostics_from = 0``)."""
    scheme = request.param(_damped_arc())
    scheme.compiled_diagnostics_from = 0
    state = scheme.initial_state()
    state.scalars.setdefault("nstep", 0)
    assert LieVerlet().run_compiled_loop(scheme, state, 1e-3, 20)
    return scheme, state


def _numpy(scheme, fn):
    scheme.compiled_diagnostics = False
    try:
        return fn()
    finally:
        scheme.compiled_diagnostics = True


@pytest.mark.slow  # (the driven rod's loop and the probe compile on first use: ≈ 90 s on a fresh cache)
def test_cfl_products_and_estimates_match_numpy(moved):
    scheme, state = moved
    before = state.copy()
    probe = scheme.stiffness_probe(state)
    assert probe.__module__ == "cartan.compiled.diagnostics"
    v = np.random.default_rng(2).standard_normal(state.S.shape)
    K = probe(v)
    ref = _numpy(scheme, lambda: scheme.stiffness_probe(state))(v)
    assert probe is not None and rel_error(K, ref) <= PRODUCT_TOL and np.abs(K).max() > 0
    for rate in ("inertial", "overdamped"):
        fast = scheme.dt_max(state, rate=rate)
        slow = _numpy(scheme, lambda rate=rate: scheme.dt_max(state, rate=rate))
        assert abs(fast / slow - 1.0) <= DT_TOL, rate
    # the linearisation point is left as it was
    assert np.array_equal(state.S, before.S)
    assert all(np.array_equal(state.arrays[k], before.arrays[k]) for k in before.arrays)


@pytest.mark.slow  # (the driven rod's loop and the energies compile on first use)
def test_guard_energies_match_the_reference(moved):
    """K includes the driven node's ½wξ·Mξ: without it the compiled K would miss
    ``Scheme.kinetic_energy`` by that much (checked to be far above round-off)."""
    scheme, state = moved
    K, V = diagnostics.guard_energies(scheme, state)
    Kr, Vr = scheme.kinetic_energy(state), scheme.potential_energy(state)
    assert K == pytest.approx(Kr, rel=ENERGY_TOL) and V == pytest.approx(Vr, rel=ENERGY_TOL)
    mask, Nd, _ = scheme._driven
    driven = float(np.sum(scheme.weights[mask] * scheme.medium.kinetic(Nd[mask])))
    assert driven > 1e-6 * Kr and V > 0


@pytest.mark.slow  # (the driven rod's loop, the probe and the energies compile on first use)
@pytest.mark.parametrize("scheme_name", ["collocation", "lattice"])
def test_simulate_runs_the_compiled_diagnostics(monkeypatch, scheme_name):
    """``cartan.simulate`` with a driven end (on either scheme) takes its default Δt from the
    compiled probe and its guard's energies from the set (counted), and the run is the numpy
    path's (the guard only tests; the CFL estimate agrees to ``DT_TOL`` and the default Δt,
    rounded from it, is the same, the results agree to the compiled loops' round-off, 1e-12 over
    a few steps, tests/test_collocation_driven_compiled.py, with a margin for 24 steps: 1e-9)."""
    from cartan.schemes.base import Scheme

    probes, energies = [], []
    real_probe, real_energies = diagnostics.compiled_stiffness_probe, diagnostics.guard_energies
    monkeypatch.setattr(diagnostics, "compiled_stiffness_probe",
                        lambda *a: probes.append(1) or real_probe(*a))
    monkeypatch.setattr(diagnostics, "guard_energies",
                        lambda *a: (lambda r: energies.append(r is not None) or r)(real_energies(*a)))
    monkeypatch.setattr(Scheme, "compiled_diagnostics_from", 0)
    problem = _damped_arc()
    kw = dict(integrator="lie-verlet", scheme=scheme_name, t_end=1.0, save_every=8, progress=False)
    fast = cartan.simulate(problem, **kw)
    assert probes and energies and all(energies)
    count = len(energies)
    ref = cartan.simulate(problem, **kw, compiled=False)  # the numpy path: steps and diagnostics
    assert len(energies) == count
    (dt, fast_max), (dt_ref, ref_max) = ((c["dt"], c["dt_max"]) for c in
                                         (json.loads(ds.attrs["cartan_config"])["run"] for ds in (fast, ref)))
    assert fast_max == pytest.approx(ref_max, rel=DT_TOL) and fast_max != ref_max  # (two computations)
    assert dt == dt_ref and fast.step.values[-1] == ref.step.values[-1] >= 20
    for name in ("S", "X", "kinetic_energy", "potential_energy", "external_work"):
        assert rel_error(fast[name].values, ref[name].values) <= 1e-9, name
