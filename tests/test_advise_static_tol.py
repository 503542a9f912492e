"""``cartan advise --tol`` on a static scene: the coarsest grid whose equilibrium is within tol.

The scene is the registered ``rod-timoshenko-static`` (cosserat-rod cantilever under a dead tip
force, lattice scheme) on a grid of :data:`N` = 11 nodes: the advice solves n = 11, 21, 41.  The
lattice scheme is second order in h (VERIFICATION.md §2, the ``rod-cantilever-elastica`` case:
``space_order = 2``); the observed order is checked in the window the verification cases use,
``[p − 0.2, p + 0.3]`` (``tests/test_verification_cases.py``).  The recommendations are re-solved
here and compared with an independent finer reference, one refinement level beyond the grid
compared.  Solve times are reported by the advice, never asserted.
"""

from __future__ import annotations

import json
import math
import pathlib

import numpy as np
import pytest
from click.testing import CliRunner

import cartan
from cartan.advise import (
    ResolutionAdvice,
    ResolutionCandidate,
    advise,
    advise_resolution,
    choose_method,
)
from cartan.cli import main
from cartan.scene import Scene, load_scene, scene

NAME = "rod-timoshenko-static"
#: nodes of the scene's grid in the study (the registered scene has 101)
N = 11
#: requested relative accuracy: between the estimated errors of n = 11 (1.6e-3) and n = 21 (4.1e-4)
TOL = 1e-3
#: a tolerance below the finest level's estimate (1.0e-4 at n = 41): extrapolated
STRICT = 1e-5
#: the lattice scheme's order in h, and the window of the verification cases around it
ORDER, BELOW, ABOVE = 2.0, 0.2, 0.3


def _source(n: int) -> dict:
    src = dict(scene(NAME).source)
    src["grid"] = dict(src["grid"]) | {"n": n}
    return src


def _scene(n: int) -> Scene:
    return load_scene(_source(n))


def _positions(n: int) -> np.ndarray:
    sc = _scene(n)
    ds = cartan.solve_static(sc.problem, **sc.solver_options)
    return np.asarray(ds["position"].isel(time=-1).values, dtype=float)


def _relative_difference(coarse: int, fine: int, scale: float) -> float:
    """max over the coarse grid's nodes of |x(coarse) − x(fine)| / scale (fine − 1 a multiple of coarse − 1)."""
    every = (fine - 1) // (coarse - 1)
    assert every * (coarse - 1) == fine - 1
    a, b = _positions(coarse), _positions(fine)[::every]
    return float(np.max(np.linalg.norm(a - b, axis=-1))) / scale


@pytest.fixture(scope="module")
def advice() -> ResolutionAdvice:
    return advise_resolution(_scene(N), TOL)


@pytest.fixture(scope="module")
def strict() -> ResolutionAdvice:
    return advise_resolution(_scene(N), STRICT)


def test_levels_and_observed_order_match_the_lattice_scheme(advice):
    assert [c.n for c in advice.levels] == [N, 2 * N - 1, 4 * N - 3]
    assert advice.scheme == "lattice" and advice.mode == "static" and "path" not in advice.output
    assert ORDER - BELOW <= advice.observed_order <= ORDER + ABOVE, str(advice)
    # every level carries the order its estimate used, the errors fall with n, times are measured
    assert all(c.order == advice.observed_order for c in advice.levels)
    errs = [c.relative_error for c in advice.levels]
    assert errs[0] > errs[1] > errs[2] > 0.0
    assert all(c.wall_time > 0 and c.newton_iterations >= 1 for c in advice.levels)
    # the scale is the tip deflection: linear theory gives 0.06777 (the scene's description)
    assert advice.scale == pytest.approx(0.06777, rel=1e-2)
    # the error is that of the scene's own measure, the tip deflection z
    assert advice.quantity == "measure" and "displacement z of node end" in advice.output
    assert advice.scale == pytest.approx(abs(advice.levels[-1].value), rel=1e-12)
    assert abs(advice.extrapolated_value - advice.levels[-1].value) == pytest.approx(
        advice.levels[-1].error, rel=1e-9)  # Richardson: m(∞) − m(4n−3) = d₁/(2^p − 1)


def test_recommendation_is_the_coarsest_level_within_tol(advice):
    rec = advice.recommended
    assert rec is not None and not advice.extrapolated and not advice.capped, str(advice)
    assert advice.recommended_n == rec.n and rec.relative_error <= TOL
    coarser = [c for c in advice.levels if c.n < rec.n]
    assert all(c.relative_error > TOL for c in coarser)
    assert rec.n == 2 * N - 1  # 1.6e-3 at n = 11 > TOL ≥ 4.1e-4 at n = 21


def test_recommended_grid_meets_tol_against_a_finer_reference(advice):
    """Re-solve the recommendation and compare it with n = 8N − 7 (one level beyond the advice's
    finest): the difference is its error minus the reference's (≈ 1/16 of it at order 2), so it
    must be within tol and close to the estimate (Richardson at the observed order 2.000:
    |x(21) − x(81)| = e(21)·(1 − 4⁻²) up to higher-order terms, within 10 %)."""
    rec = advice.recommended
    ref_n = 8 * N - 7
    measured = _relative_difference(rec.n, ref_n, advice.scale)
    assert measured <= TOL
    assert measured == pytest.approx(rec.relative_error * (1 - 4.0 ** -2), rel=0.1)


def test_too_strict_tol_is_an_extrapolation_that_meets_tol_when_solved(strict):
    assert strict.recommended is None and strict.extrapolated and not strict.capped, str(strict)
    n = strict.recommended_n
    assert n > strict.levels[-1].n and (n - 1) % (N - 1) == 0  # the scene's nodes stay nodes
    assert strict.predicted_error <= STRICT
    # the smallest such grid: one multiple of N − 1 fewer intervals is predicted above tol
    e2, m2, p = strict.levels[-1].relative_error, strict.levels[-1].n - 1, strict.observed_order
    assert e2 * (m2 / (n - 1 - (N - 1))) ** p > STRICT
    assert "extrapolated" in str(strict) and "extrapolated" in strict.note
    # solved here against one refinement beyond it (2n − 1 nodes)
    assert _relative_difference(n, 2 * n - 1, strict.scale) <= STRICT


def test_unreachable_tol_is_capped_at_max_n():
    capped = advise_resolution(_scene(N), 1e-9, max_n=1001)
    assert capped.extrapolated and capped.capped and capped.recommended is None
    assert capped.recommended_n == 1001 and capped.predicted_error > 1e-9
    assert "max_n = 1001" in capped.note and "capped" in str(capped)


def test_choice_rule_on_given_levels():
    """The rule (data, not measurements): the coarsest level within tol; levels without an
    estimate are skipped."""
    levels = [ResolutionCandidate(11, "lattice", relative_error=2e-3), ResolutionCandidate(21, "lattice"),
              ResolutionCandidate(41, "lattice", relative_error=1e-4), ResolutionCandidate(81, "lattice",
                                                                                          relative_error=2e-5)]
    rec, cheapest = choose_method(levels, 1e-3, cost=lambda c: c.n, error=lambda c: c.relative_error)
    assert rec is levels[2] and cheapest is levels[0]
    assert choose_method(levels, 1e-6, cost=lambda c: c.n, error=lambda c: c.relative_error)[0] is None


def test_report_json_and_dispatch(advice):
    data = json.loads(json.dumps(advice.to_dict()))
    assert data["recommended_n"] == advice.recommended_n and len(data["levels"]) == 3
    assert data["recommended"]["n"] == advice.recommended_n and data["levels"][-1]["difference"] is None
    text = str(advice)
    assert f"recommended: n = {advice.recommended_n}" in text and "<- recommended" in advice.table()
    assert isinstance(advise(_scene(N), tol=TOL), ResolutionAdvice)


@pytest.mark.parametrize("kwargs, text", [
    ({"tol": 0.0}, "tol"), ({"tol": -1.0}, "tol"), ({"tol": math.nan}, "tol"), ({"tol": math.inf}, "tol"),
    ({"tol": 1e-3, "max_n": 2}, "max_n"),
])
def test_bad_arguments(kwargs, text):
    with pytest.raises(ValueError, match=text):
        advise_resolution(_scene(N), **kwargs)


def test_problem_and_dynamic_scene_are_refused():
    with pytest.raises(ValueError, match="Problem"):
        advise_resolution(_scene(N).problem, TOL)
    with pytest.raises(ValueError, match="Problem"):
        advise(_scene(N).problem, tol=TOL)
    with pytest.raises(ValueError, match="static or continuation scene"):
        advise_resolution("rod-butterfly", TOL)


def test_continuation_is_advised_at_its_final_point():
    """``rod-elastica-continuation`` (planar rod, EA/B = 1e6, tip load to PL²/B = 10) on n = 11:
    the paths end on λ = 10 exactly on every level, the lattice order shows at the final point,
    and the recommendation, re-solved, meets tol against a path one level finer."""
    src = dict(scene("rod-elastica-continuation").source)
    src["grid"] = dict(src["grid"]) | {"n": N}
    res = advise(load_scene(src), tol=TOL)
    assert isinstance(res, ResolutionAdvice) and res.mode == "continuation"
    assert "final point λ = 10 " in res.output
    assert ORDER - BELOW <= res.observed_order <= ORDER + ABOVE, str(res)
    n = res.recommended_n
    assert n > 0 and (res.recommended is not None or res.extrapolated), str(res)

    def final(m: int) -> np.ndarray:
        sc = load_scene(src | {"grid": dict(src["grid"]) | {"n": m}})
        path = cartan.continuation(sc.problem, **sc.solver_options)
        assert float(path["load_factor"].values[-1]) == pytest.approx(10.0, rel=1e-12)
        return np.asarray(path["position"].isel(path=-1).values, dtype=float).reshape(m, -1)

    ref = final(2 * n - 1)[::2]
    assert float(np.max(np.linalg.norm(final(n) - ref, axis=-1))) / res.scale <= TOL


@pytest.fixture()
def scene_file(tmp_path) -> pathlib.Path:
    import cartan_cosserat

    text = (pathlib.Path(cartan_cosserat.__file__).parent / "scenes" / f"{NAME}.toml").read_text()
    assert "n = 101\n" in text
    path = tmp_path / "static.toml"
    path.write_text(text.replace("n = 101\n", f"n = {N}\n"))
    return path


def test_cli_tol_json(scene_file):
    res = CliRunner().invoke(main, ["advise", str(scene_file), "--tol", "1e-3", "--json"])
    assert res.exit_code == 0, (res.stdout, res.stderr)
    data = json.loads(res.stdout)
    assert data["recommended_n"] == 2 * N - 1 and data["recommended"]["relative_error"] <= 1e-3
    assert [lv["n"] for lv in data["levels"]] == [N, 2 * N - 1, 4 * N - 3]


@pytest.mark.parametrize("args, text", [
    (["FILE", "--tol", "0"], "--tol"),
    (["FILE", "--tol", "nan"], "--tol"),
    (["FILE", "--tol", "abc"], "abc"),
    (["FILE", "--tol", "-1e-3"], "--tol"),
])
def test_cli_bad_tol_is_one_line(scene_file, args, text):
    args = [str(scene_file) if a == "FILE" else a for a in args]
    res = CliRunner().invoke(main, ["advise", *args])
    assert res.exit_code == 2, (res.stdout, res.stderr)
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("cartan: error: ") and res.stdout == "", res.stderr
    assert text in lines[0], lines[0]


def test_cli_tol_text_and_chart(scene_file, tmp_path):
    chart = tmp_path / "res.png"
    res = CliRunner().invoke(main, ["advise", str(scene_file), "--tol", "1e-5", "--chart", str(chart)])
    assert res.exit_code == 0, (res.stdout, res.stderr)
    assert "recommended: n = " in res.stdout and "(extrapolated;" in res.stdout and f"wrote {chart}" in res.stdout
    assert chart.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_richardson_estimates_on_given_differences():
    """The estimates on data: an exact C·h² sequence, round-off, and a non-asymptotic one."""
    from cartan.advise import TOL_MIN_ORDER, _richardson

    e = [1e-2 * 4.0 ** -k for k in range(3)]  # e(h) = C h², three levels
    p, est = _richardson(e[0] - e[1], e[1] - e[2], 1e-14)
    assert p == pytest.approx(2.0, rel=1e-12) and est == pytest.approx(e, rel=1e-12)
    p, est = _richardson(3e-6, 1e-16, 1e-14)  # the refined grids agree to round-off
    assert math.isnan(p) and est == [3e-6, 1e-16, 1e-16]
    p, est = _richardson(1e-4, 1e-4 * 2.0 ** -0.4, 1e-14)  # order 0.4 < TOL_MIN_ORDER: no estimate
    assert p == pytest.approx(0.4) and p < TOL_MIN_ORDER and all(math.isnan(x) for x in est)


# ---------------------------------------------------------------------------- a d = 2 grid
#: the Navier plate (cosserat-surface, simply supported, uniform pressure) on 5 × 5 nodes: the
#: advice solves 5², 9², 17²; the lattice is second order on it (the case plate-navier-thin)
PLATE, PLATE_SHAPE, PLATE_TOL = "plate-navier", [5, 5], 1e-2


def _plate_source(shape: list[int]) -> dict:
    src = dict(scene(PLATE).source)
    src["grid"] = dict(src["grid"]) | {"shape": shape}
    centre = dict(src["static"]["measure"]) | {"node": [n // 2 for n in shape]}
    src["static"] = dict(src["static"]) | {"measure": centre}
    return src


@pytest.fixture(scope="module")
def plate_advice() -> ResolutionAdvice:
    return advise_resolution(load_scene(_plate_source(PLATE_SHAPE)), PLATE_TOL)


def test_d2_grid_is_refined_along_every_axis_with_its_measured_node(plate_advice):
    from cartan.advise import _refined_scene

    fine = _refined_scene(load_scene(_plate_source(PLATE_SHAPE)))
    assert fine.problem.grid.shape == (9, 9)
    assert list(fine.source["static"]["measure"]["node"]) == [4, 4]  # the centre stays the centre
    assert [c.shape for c in plate_advice.levels] == [(5, 5), (9, 9), (17, 17)]
    assert [c.n for c in plate_advice.levels] == [25, 81, 289]


def test_d2_observed_order_and_recommendation_meet_tol(plate_advice):
    """Second order within the verification window; the recommended grid, re-solved, is within
    tol of a reference one level finer than the study's finest (33 × 33)."""
    assert ORDER - BELOW <= plate_advice.observed_order <= ORDER + ABOVE
    assert plate_advice.recommended is not None and not plate_advice.extrapolated
    shape = list(plate_advice.recommended_shape)
    coarse, fine = load_scene(_plate_source(shape)), load_scene(_plate_source([2 * n - 1 for n in shape]))
    a = cartan.solve_static(coarse.problem, **coarse.solver_options)["position"].isel(time=-1).values
    b = cartan.solve_static(fine.problem, **fine.solver_options)["position"].isel(time=-1).values
    diff = float(np.max(np.linalg.norm(a - b[::2, ::2], axis=-1)))
    assert diff / plate_advice.scale <= PLATE_TOL, (diff, plate_advice.scale)
