"""``cartan advise --tol``: the cheapest integrator and Δt that reach an accuracy on a dynamic scene.

The scene is the registered ``rod-butterfly`` (cosserat-rod, lattice, n = 41, Δt = 5e-3) over its
first :data:`STEPS` steps.  The recommendation is re-run here and compared with a reference run
made here (rkmk4 at Δt/8, fourth order: its own error is ≈ 8⁻⁴ of rkmk4's at Δt, far below
``TOL``).  Times are reported by the advice, never asserted.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

import cartan
from cartan.advise import (
    TOL_REFERENCE_DIVISOR,
    MethodAdvice,
    MethodCandidate,
    advise,
    advise_method,
    choose_method,
)
from cartan.cli import main
from cartan.scene import load_scene, scene

SCENE = "rod-butterfly"
#: steps of the scene's Δt in the study (t = 0.2)
STEPS = 40
#: requested accuracy (length units; the rod is 3 long): between the errors of the sweep's
#: second-order runs (≈ 4e-8 … 4e-6 at t = 0.2), so that the choice is not trivial
TOL = 1e-6


def _final(ds) -> np.ndarray:
    return np.asarray(ds["position"].isel(time=-1).values, dtype=float)


#: the whole sweep compiles every integrator's loop for the rod (≈ 3 min on a fresh cache, most of it
#: loops no other fast test needs): its tests are in ``make test-slow``; the fast suite keeps the
#: lie-verlet sweep, the dispatch and the bad input
SWEEP = pytest.mark.slow


@pytest.fixture(scope="module")
def advice() -> MethodAdvice:
    return advise_method(scene(SCENE), TOL, pilot_steps=STEPS)


@SWEEP
def test_recommendation_meets_tol_when_run(advice):
    sc = scene(SCENE)
    rec = advice.recommended
    assert rec is not None, str(advice)
    assert rec.error <= TOL
    assert advice.t_end == pytest.approx(STEPS * sc.dt)
    ref = cartan.simulate(sc, integrator="rkmk4", dt=sc.dt / TOL_REFERENCE_DIVISOR, t_end=advice.t_end,
                          save_every=STEPS, progress=False, reduce=False)
    run = cartan.simulate(sc, integrator=rec.integrator, dt=rec.dt, t_end=advice.t_end, save_every=STEPS,
                          progress=False, reduce=False)
    err = float(np.max(np.linalg.norm(_final(run) - _final(ref), axis=-1)))
    assert err <= TOL, (err, str(advice))
    assert err == pytest.approx(rec.error, rel=1e-6, abs=1e-12)  # the same runs, deterministic


def test_choice_is_the_cheapest_within_tol():
    """The rule on given costs (data, not measurements): the cheapest finished run within tol is
    recommended, the cheapest finished run is the fastest; failures and misses are never chosen."""
    runs = [MethodCandidate("lie-verlet", "lattice", 0.01, "ok", error=2e-6, wall_time=1.0),
            MethodCandidate("rkmk4", "lattice", 0.02, "ok", error=5e-7, wall_time=3.0),
            MethodCandidate("rkmk4", "lattice", 0.01, "ok", error=3e-8, wall_time=5.0),
            MethodCandidate("lie-euler", "lattice", 0.04, "unstable", wall_time=0.1),
            MethodCandidate("lie-verlet", "lattice", 0.005, "ok", error=5e-7, wall_time=2.0)]
    assert choose_method(runs, 1e-6) == (runs[4], runs[0])
    assert choose_method(runs, 1e-7) == (runs[2], runs[0])
    assert choose_method(runs, 1e-9) == (None, runs[0])
    assert choose_method(runs[3:4], 1.0) == (None, None)


@SWEEP
def test_recommendation_is_the_cheapest_within_tol(advice):
    ok = [c for c in advice.candidates if c.ok]
    assert {c.integrator for c in advice.candidates} == {"lie-verlet", "rkmk4", "implicit-midpoint", "lie-euler"}
    # the choice among the measured runs (the rule itself: test_choice_is_the_cheapest_within_tol)
    assert (advice.recommended, advice.fastest) == choose_method(advice.candidates, TOL)
    assert advice.recommended.ok and advice.recommended.error <= TOL
    # errors fall with Δt at each integrator's order: lie-verlet 2 (ratio 4 per halving), rkmk4 4
    for name, order in (("lie-verlet", 2), ("rkmk4", 4)):
        e = [c.error for c in sorted(ok, key=lambda c: c.dt) if c.integrator == name]
        ratios = np.array(e[1:]) / np.array(e[:-1])
        assert np.all(ratios > 0.6 * 2 ** order), (name, e)
    # the reference's estimated error is far below tol
    assert advice.reference_error < TOL / 100
    text = str(advice)
    assert "recommended: " + advice.recommended.integrator in text
    assert json.loads(json.dumps(advice.to_dict()))["recommended"]["dt"] == advice.recommended.dt


def test_unreachable_tol_recommends_nothing_and_beyond_cfl_is_not_run():
    # lie-verlet alone, at Δt up to 2^7 times the scene's: above 2× its CFL estimate it is not run
    adv = advise_method(scene(SCENE), 1e-30, pilot_steps=8, integrators=("lie-verlet",), dt_powers=(0, 5, 7),
                        schemes=())
    assert adv.recommended is None
    assert "recommended: none" in str(adv)
    dt_max = adv.candidates[0].dt_max
    assert 0 < dt_max < math.inf
    assert [c.status for c in adv.candidates] == ["ok"] + ["beyond CFL"] * 2  # 0.16, 0.64 > 2 × 0.053
    assert "stability map" in str(adv)


@SWEEP
def test_a_run_that_blows_up_is_a_failure_not_an_error():
    # lie-euler has no stable Δt for undamped motion (CFL estimate 0): over t = 1 the energy
    # balance error of the butterfly grows past the blow-up threshold at Δt = 0.01, not at 0.005
    adv = advise_method(scene(SCENE), 1e-2, pilot_steps=200, integrators=("lie-euler",), dt_powers=(0, 1))
    small, large = adv.candidates
    assert small.ok and small.error < 1e-2
    assert large.status.startswith("unstable: "), large.status
    assert math.isnan(large.error) and adv.failures == [large]
    assert adv.recommended is small


@SWEEP
def test_spatial_check_falls_with_the_grid(advice):
    # the reference on n and 2n − 1 nodes: the lattice is second order in h, so halving h from
    # n = 21 to 41 divides the difference by about 4; the range (2, 8), an observed order in
    # (1, 3), allows for the pre-asymptotic grids (measured 6.7 at t = 0.2)
    assert advice.spatial_n == 81
    src = scene(SCENE).source
    coarse = advise_method(load_scene(dict(src) | {"grid": dict(src["grid"], n=21)}), TOL, pilot_steps=STEPS,
                           integrators=("rkmk4",), dt_powers=(0,))
    assert coarse.spatial_n == 41
    ratio = coarse.spatial_difference / advice.spatial_difference
    assert 2.0 < ratio < 8.0, (coarse.spatial_difference, advice.spatial_difference)
    assert advice.spatial_difference > TOL and "refine the grid" in str(advice)  # 6e-4: the grid dominates


def test_advise_with_tol_dispatches_and_checks_tol():
    with pytest.raises(ValueError, match="tol"):
        advise(SCENE, tol=0.0)
    with pytest.raises(ValueError, match="tol"):
        advise(SCENE, tol=math.nan)
    with pytest.raises(ValueError, match="dynamic"):  # a Problem carries no run settings to refine
        advise(scene("rod-timoshenko-static").problem, tol=1e-4)


@SWEEP
def test_cli_tol_prints_the_advice_and_writes_the_chart(tmp_path):
    chart = tmp_path / "wp.png"
    res = CliRunner().invoke(main, ["advise", "--scene", SCENE, "--tol", "1e-3", "--pilot-steps", "8",
                                    "--chart", str(chart)])
    assert res.exit_code == 0, (res.stdout, res.stderr)
    assert "recommended: " in res.stdout and f"wrote {chart}" in res.stdout
    assert chart.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("args, text", [
    (["--tol", "0"], "--tol"),
    (["--tol", "-1e-3"], "--tol"),
    (["--tol", "nan"], "--tol"),
    (["--tol", "abc"], "abc"),
    (["--chart", "c.png"], "--chart needs --tol"),
    (["--tol", "1e-3", "--check"], "--check"),
])
def test_cli_bad_tol_is_one_line_and_writes_nothing(tmp_path, monkeypatch, args, text):
    monkeypatch.chdir(tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    res = CliRunner().invoke(main, ["advise", "--scene", SCENE, *args])
    assert res.exit_code == 2, (res.stdout, res.stderr)
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("cartan: error: ")]
    assert len(lines) == 1 and res.stdout == "", res.stderr
    assert text in lines[0], lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == before
