"""Every medium in the repository passes the conformance kit (cartan.testing.check_medium)."""

from __future__ import annotations

import numpy as np
import pytest
from toys import QuadraticMedium

import cartan
from cartan.testing import ConformanceError, check_medium

#: constructor parameters for the registered media (small, fast, well-conditioned)
PARAMS = {
    "cosserat-rod": {"E": 1e4, "G": 1e4 / 3, "radius": 0.05, "density": 1000.0},
    "planar-cosserat-rod": {"E": 1e4, "G": 1e4 / 3, "radius": 0.05, "density": 1000.0},
    "sphere-rod": {},
    "sigma-model": {},
}


#: media whose every scheme × integrator compiles for a minute or more on a fresh cache: in
#: ``make test-slow``; their compiled loops run in the fast suite through their own test files
SLOW_MEDIA = {"cosserat-rod", "planar-cosserat-rod", "cosserat-solid", "cosserat-surface", "relativistic-rod",
              "sigma-model", "sphere-rod"}


@pytest.mark.parametrize("name", [pytest.param(name, marks=[pytest.mark.slow] if name in SLOW_MEDIA else [])
                                  for name in sorted(cartan.registry("media"))])
def test_registered_media_conform(name):
    report = check_medium(name, PARAMS.get(name, {}))
    assert report.passed and not report.failed
    # a medium holding strain components fixed runs in statics only (its time integration is skipped, with why)
    statics_only = any("constrained_strains" in s for s in report.skipped)
    assert statics_only or any("lattice × lie-verlet" in p for p in report.passed)


def test_kit_catches_a_stress_that_is_not_the_gradient():
    class Wrong(QuadraticMedium):
        name = "wrong-medium"

        def stress(self, X):
            return 1.01 * super().stress(X)

    with pytest.raises(ConformanceError, match="stress = ∂U/∂X"):
        check_medium(Wrong())


def test_kit_catches_negative_inertia_and_reports_without_raising():
    class Negative(QuadraticMedium):
        name = "negative-medium"

        def inertia(self):
            m = super().inertia().copy()
            m[0] = -1.0
            return m

    report = check_medium(Negative(), raise_on_failure=False, schemes=["lattice"], integrators=["lie-verlet"])
    assert any("inertia" in f for f in report.failed)
    assert "1 failed" in str(report) or "failed" in str(report)


@pytest.mark.slow
def test_kit_runs_every_combination_for_a_toy_medium():
    report = check_medium(QuadraticMedium("SE2", mass=np.ones(3), stiffness=np.full(3, 3.0)))
    schemes, integrators = cartan.registry("schemes"), cartan.registry("integrators")
    for s in schemes:
        for i in integrators:
            assert any(p.startswith(f"{s} × {i}: shapes") for p in report.passed), (s, i)
