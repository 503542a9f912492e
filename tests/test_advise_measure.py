"""``cartan advise`` on the quantity a static scene measures (``[static] measure = {node, component}``).

Resolution (``--tol``): the registered ``rod-timoshenko-static`` cantilever (lattice, second order
in h: VERIFICATION.md §2) on n = 11 nodes, its measure changed to the tip's axial displacement
``x`` (the shortening, 1 % of the deflection, not the largest displacement): the advice
extrapolates that quantity, and its recommendation is re-solved against a grid one level beyond
the advice's finest.  Held-strain twin: the stiff cantilever of ``docs/advise.md`` (EA = GA =
10⁴B/L², tip force 2B/L² along −y) on n = 11 nodes, measured at its tip.  Times are never
asserted.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import cartan
from cartan.advise import HELD_STRAINS, ResolutionAdvice, advise, advise_resolution
from cartan.scene import load_scene, scene

NAME, N, TOL = "rod-timoshenko-static", 11, 1e-3
#: the lattice's order in h and the window of the verification cases around it
ORDER, BELOW, ABOVE = 2.0, 0.2, 0.3


def _source(n: int, component: str = "x") -> dict:
    src = dict(scene(NAME).source)
    src["grid"] = dict(src["grid"]) | {"n": n}
    src["static"] = dict(src["static"]) | {"measure": {"node": "end", "component": component}}
    return src


def _tip(n: int, component: int = 0) -> float:
    """The tip's displacement component of an independent solve on n nodes."""
    sc = load_scene(_source(n))
    ds = cartan.solve_static(sc.problem, **sc.solver_options)
    x = np.asarray(ds["position"].isel(time=-1).values, dtype=float)
    x0 = np.asarray(sc.problem.initial.Phi, dtype=float)[..., 1:, 0]
    return float(x[-1, component] - x0[-1, component])


@pytest.fixture(scope="module")
def advice() -> ResolutionAdvice:
    return advise_resolution(load_scene(_source(N)), TOL)


#: three levels of static solves with two timed repeats each (≈ 2–4 s): in ``make test-slow``; the
#: fast suite checks the default (the scene's tip deflection) in ``tests/test_advise_static_tol.py``
@pytest.mark.slow
def test_the_advice_is_on_the_measured_quantity(advice):
    assert advice.quantity == "measure" and "displacement x of node end" in advice.output
    assert ORDER - BELOW <= advice.observed_order <= ORDER + ABOVE, str(advice)
    # the levels' values are the tip's axial displacement, the same material point on each grid
    assert advice.levels[0].value == pytest.approx(_tip(N), rel=1e-9, abs=1e-15)
    assert advice.scale == pytest.approx(abs(advice.levels[-1].value), rel=1e-12)
    # the shortening is about 1 % of the deflection: the positions' scale would be 90× larger
    assert advice.scale < 0.02 * 0.06777
    assert "value" in advice.table() and "extrapolated value" in str(advice)


@pytest.mark.slow
def test_the_measured_recommendation_meets_tol_against_a_finer_solve(advice):
    """The recommendation re-solved against n = 8N − 7 (one level beyond the advice's finest):
    the difference is its error minus the reference's, e·(1 − 2^(−p·k)) for k levels apart at
    the observed order, within 10 % (higher-order terms)."""
    rec = advice.recommended
    assert rec is not None and not advice.extrapolated, str(advice)
    assert all(c.relative_error > TOL for c in advice.levels if c.n < rec.n)
    ref = _tip(8 * N - 7)
    measured = abs(_tip(rec.n) - ref) / advice.scale
    levels_apart = int(round(math.log2((8 * N - 8) / (rec.n - 1))))
    assert measured <= TOL
    assert measured == pytest.approx(rec.relative_error * (1 - 2.0 ** (-advice.observed_order * levels_apart)),
                                     rel=0.1)
    # Richardson's extrapolated value is closer to the finer solve than the finest level is
    assert abs(advice.extrapolated_value - ref) < abs(advice.levels[-1].value - ref)


def test_positions_on_request_and_bad_quantity():
    positions = advise_resolution(load_scene(_source(N)), TOL, quantity="positions")
    assert positions.quantity == "positions" and "node positions" in positions.output
    assert math.isnan(positions.levels[0].value) and math.isnan(positions.extrapolated_value)
    assert positions.scale == pytest.approx(0.06777, rel=1e-2)  # the deflection, not the shortening
    with pytest.raises(ValueError, match="quantity"):
        advise_resolution(load_scene(_source(N)), TOL, quantity="tip")
    src = _source(N)
    src["static"] = {k: v for k, v in src["static"].items() if k != "measure"}
    with pytest.raises(ValueError, match="declares no measure"):
        advise_resolution(load_scene(src), TOL, quantity="measure")


# ---------------------------------------------------------------------------- a twin on the measure
STIFF = {
    "name": "stiff-cantilever", "mode": "static", "medium": "cosserat-rod",
    "parameters": {"stretch_shear": [1e4, 1e4, 1e4], "bend_twist": [1.0, 1.0, 1.0],
                   "mass": 1.0, "rotational_inertia": [0.01, 0.01, 0.01]},
    "grid": {"n": 11, "length": 1.0},
    "boundaries": {"start": {"kind": "clamped"},
                   "end": {"kind": "free", "load": [0.0, -2.0, 0.0, 0.0, 0.0, 0.0]}},
    "initial": {"kind": "straight"},
    "static": {"load_steps": 2, "max_iterations": 40, "measure": {"node": "end", "component": "y"}},
}


@pytest.mark.slow  # six static solves of each model (≈ 2 s)
def test_the_twin_is_compared_on_the_measured_quantity():
    """The filament changes the tip deflection by the stretch the constraint removes, |F|L/EA =
    2e-4; the estimate neglects a term second order in F/EA (it vanishes for EA = GA under a dead
    end force), so estimate and check agree to 1e-3 relative."""
    report = advise(load_scene(STIFF), check=True)
    fil = report[HELD_STRAINS]
    assert fil.error_estimate == pytest.approx(2.0 / 1e4, rel=0.01)
    assert fil.error_estimate == pytest.approx(fil.measured_difference, rel=1e-3)
    assert fil.error_scale == pytest.approx(0.4934, rel=0.01)  # the tip deflection: the scale
    assert fil.recommended and "on the scene's measure, displacement y of node end" in fil.note
    assert "|displacement y of node end: full − held|" in fil.check_note
