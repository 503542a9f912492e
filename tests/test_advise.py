"""``cartan advise``: the reductions a scene admits, measured, and the check against the reduced model.

The filament's prediction is the displacement ∫R(θ − θ₀)ds its constraint removes (cartan.advise);
the check solves the filament built from the rod's data.  The times are reported, never asserted.
"""

from __future__ import annotations

import json
import math
import pathlib

import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner

import cartan
from cartan.advise import (
    HELD_STRAINS,
    LARGE_RADIUS,
    PLANAR,
    Advice,
    HeldStrainMedium,
    advise,
    held_strain_problem,
    plane_limit_problem,
)
from cartan.cli import main
from cartan.scene import Scene


def stiff_cantilever(ratio: float = 1e4, alpha: float = 2.0, planar: bool = False) -> dict:
    """Clamped cantilever, L = 1, B = 1, EA = GA = ratio·B/L², dead tip force α·B/L² along −y, n = 41."""
    if planar:
        medium, params = "planar-cosserat-rod", {"stretch_shear": [ratio, ratio], "bending": 1.0, "mass": 1.0,
                                                 "rotational_inertia": 0.01}
        load = [0.0, -alpha, 0.0]
    else:
        medium, params = "cosserat-rod", {"stretch_shear": [ratio] * 3, "bend_twist": [1.0, 1.0, 1.0], "mass": 1.0,
                                          "rotational_inertia": [0.01] * 3}
        load = [0.0, -alpha, 0.0, 0.0, 0.0, 0.0]
    return {"name": f"stiff-cantilever-{'planar' if planar else 'se3'}", "mode": "static", "medium": medium,
            "parameters": params, "grid": {"n": 41, "length": 1.0},
            "boundaries": {"start": {"kind": "clamped"}, "end": {"kind": "free", "load": load}},
            "initial": {"kind": "straight"}, "static": {"load_steps": 2, "max_iterations": 40}}


def toml(data: dict) -> str:
    """The scene dicts above as TOML (flat values, one level of inline tables)."""

    def value(v):
        if isinstance(v, str):
            return f'"{v}"'
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{k} = {value(x)}" for k, x in v.items()) + " }"
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return repr(v)

    top = [f"{k} = {value(v)}" for k, v in data.items() if not isinstance(v, dict)]
    tables = [f"[{k}]\n" + "\n".join(f"{kk} = {value(vv)}" for kk, vv in v.items())
              for k, v in data.items() if isinstance(v, dict)]
    return "\n".join(top) + "\n\n" + "\n\n".join(tables) + "\n"


@pytest.fixture(scope="module")
def checked() -> Advice:
    report = advise(cartan.load_scene(stiff_cantilever()), check=True)
    print(report)  # the measured time ratios (not asserted)
    return report


# ---------------------------------------------------------------------------- the stiff cantilever
def test_stiff_cantilever_recommends_the_filament_and_predicts_the_difference(checked):
    fil = checked[HELD_STRAINS]
    assert fil.admitted and fil.recommended
    # stretch and shear of the stiff rod: |F|/EA with |F| = α = 2, EA = 1e4
    assert fil.indicator == pytest.approx(2e-4, rel=0.01)
    assert fil.measured_difference > 0
    # the prediction within a factor 2 of the measured tip difference (the task's bound)
    assert 0.5 <= fil.error_estimate / fil.measured_difference <= 2.0
    assert fil.relative_error <= checked.rtol
    assert math.isfinite(fil.time_ratio) and fil.time_ratio > 0
    assert fil.speedup_estimate > 1.0  # the filament's explicit step is not limited by axial and shear waves
    assert HELD_STRAINS in checked.recommended


def test_planar_cantilever_is_an_exact_reduction(checked):
    red = checked[PLANAR]
    assert red.kind == "exact" and red.admitted
    assert red.error_estimate == 0.0
    assert red.measured_difference <= 1e-10  # round-off of the two Newton solves (tol 1e-10)
    assert not checked[LARGE_RADIUS].admitted


def test_report_table_and_text(checked, tmp_path):
    ds = checked.to_dataset()
    assert ds.sizes["reduction"] == 3
    assert list(ds["reduction"].values) == [HELD_STRAINS, PLANAR, LARGE_RADIUS]
    assert int(ds["recommended"].sel(reduction=HELD_STRAINS)) == 1
    assert float(ds["error_estimate"].sel(reduction=HELD_STRAINS)) == checked[HELD_STRAINS].error_estimate
    assert ds.attrs["Conventions"] == "CF-1.11" and ds.attrs["checked"] == 1
    path = tmp_path / "advice.nc"
    ds.to_netcdf(path)
    back = xr.open_dataset(path)
    assert float(back["measured_difference"][0]) == pytest.approx(checked[HELD_STRAINS].measured_difference)
    d = checked.to_dict()
    assert d["reductions"][2]["indicator"] is None  # NaN → None (JSON)
    text = str(checked)
    assert f"{HELD_STRAINS} [approximate]: RECOMMENDED" in text
    assert "measured difference" in text


@pytest.mark.parametrize("stretch_shear, gravity", [([1e4, 1e3, 1e3], None), ([1e3, 1e4, 1e4], None),
                                                    ([1e3] * 3, 5.0)])
def test_prediction_beyond_the_isotropic_tip_load(stretch_shear, gravity):
    """EA ≠ GA (the displacement the constraint removes is no longer parallel to the force, and the
    lever arms change: measured ratio 1.27 and 0.90) and a distributed load (gravity along −y on a
    free end): the first-order estimate stays within the factor 2."""
    data = stiff_cantilever()
    data["parameters"]["stretch_shear"] = stretch_shear
    if gravity is not None:
        data["loads"] = [{"kind": "gravity", "g": [0.0, -gravity, 0.0]}]
        data["boundaries"]["end"] = {"kind": "free"}
    fil = advise(cartan.load_scene(data), check=True)[HELD_STRAINS]
    assert fil.admitted and fil.measured_difference > 1e-4
    assert 0.5 <= fil.error_estimate / fil.measured_difference <= 2.0


def test_soft_timoshenko_beam_keeps_the_rod():
    """Shear-dominated (GA·L²/EI ≈ 5.5): the filament would miss a third of the tip deflection."""
    report = advise("rod-timoshenko-static", check=True)
    fil = report[HELD_STRAINS]
    assert fil.admitted and not fil.recommended
    assert fil.relative_error > 0.1
    assert 0.5 <= fil.error_estimate / fil.measured_difference <= 2.0
    assert not report[PLANAR].admitted  # the load is along z, the rod on the x axis with e₃ = +z


def test_held_strains_of_the_rod_are_the_filament():
    """The held-strain twin of a Cosserat rod solves like the registered Kirchhoff filament with
    the rod's B, C and rest curvature (same energy in π, same constraint θ = (1, 0, 0))."""
    kappa = [0.3, -0.5, 0.8]
    rod = cartan.medium("cosserat-rod", stretch_shear=[1e3] * 3, bend_twist=[0.7, 1.0, 2.0], mass=1.0,
                        rotational_inertia=[0.01] * 3, rest_curvature=kappa)
    grid = cartan.Grid(21, length=1.0)
    load = cartan.Free(load=[0.5, -1.5, 1.0, 0.4, 0.3, -0.5])
    prob = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"), {"start": cartan.Clamped(), "end": load})
    held = held_strain_problem(prob)  # the twin the rod declares: the registered filament with its data
    fil = cartan.medium("filament", bending=[1.0, 2.0], twist=0.7, rest_curvature=kappa[1:], rest_twist=kappa[0])
    assert held.medium.name == "filament" and held.medium.parameters() == fil.parameters()
    # the core's generic held-strain twin of the same rod solves like it
    ref = cartan.Problem(HeldStrainMedium(rod), grid, prob.initial, {"start": cartan.Clamped(), "end": load})
    a = cartan.solve_static(held, load_steps=2, max_iter=40)
    b = cartan.solve_static(ref, load_steps=2, max_iter=40)
    assert float(a.attrs["constraint_residual_max"]) <= 1e-10
    assert float(abs(a.position - b.position).max()) <= 1e-9  # two Newton solves, tol 1e-10
    assert float(abs(a.position - a.position.isel(node=0)).max()) > 0.3  # it bent
    report = advise(prob)  # a Problem is advised as a static problem
    assert report.mode == "static" and report[HELD_STRAINS].admitted
    assert not report[PLANAR].admitted  # out-of-plane end load
    with pytest.raises(ValueError, match="already holds"):
        HeldStrainMedium(fil)
    with pytest.raises(ValueError, match="SE"):
        HeldStrainMedium(cartan.medium("sphere-rod"))


def test_planar_rod_holds_its_strains_on_se2():
    report = advise(cartan.load_scene(stiff_cantilever(planar=True)), check=True)
    fil = report[HELD_STRAINS]
    assert fil.recommended
    assert 0.5 <= fil.error_estimate / fil.measured_difference <= 2.0
    assert report[PLANAR].note.startswith("the medium 'planar-cosserat-rod' is not on SE(3)")


def test_continuation_path_of_a_pinned_column():
    """Euler buckling of the stiff planar column (EA/B = 1e6) followed through the bifurcation to
    1.5 P_cr: the planar elastica (the held-strain twin) follows the same branch; the shortening
    P/EA the constraint removes is predicted at the path's end (on the node positions: the scene's
    measure, the mid-span deflection, is left out; the twin does not change it to first order)."""
    src = dict(cartan.scene("rod-euler-buckling").source)
    src["continuation"] = {k: v for k, v in src["continuation"].items() if k != "measure"}
    report = advise(cartan.load_scene(src), check=True)
    fil = report[HELD_STRAINS]
    assert report.mode == "continuation" and "path points" in report.pilot
    assert fil.recommended
    # the axial strain at 1.5 P_cr = 14.8 over EA = 1e6
    assert fil.indicator == pytest.approx(1.5 * math.pi**2 / 1e6, rel=0.01)
    assert 0.5 <= fil.error_estimate / fil.measured_difference <= 2.0


# ---------------------------------------------------------------------------- dynamic scenes
def test_dynamic_scene_reports_the_filament_without_recommending_it():
    report = advise("rod-cantilever-gravity", pilot_steps=20)
    fil = report[HELD_STRAINS]
    assert report.mode == "dynamic" and "pilot run" in report.pilot
    assert fil.admitted and not fil.recommended
    assert "not recommended unmeasured" in fil.note
    assert fil.indicator > 0.01  # the soft rod shears visibly under gravity
    assert math.isnan(fil.measured_difference)  # no check asked


@pytest.mark.slow  # compiles the filament's rattle loop (≈ 100 s on a fresh cache)
def test_dynamic_check_runs_the_held_strain_twin_with_rattle():
    """With check, the twin of a dynamic scene runs (rattle, its own step) over the pilot's time:
    a measured difference of the order of the estimate and a measured time ratio; recommended
    only when within rtol and faster."""
    report = advise("rod-cantilever-gravity", check=True, pilot_steps=20)
    fil = report[HELD_STRAINS]
    assert "rattle" in fil.check_note
    assert math.isfinite(fil.measured_difference) and math.isfinite(fil.time_ratio)
    assert fil.measured_difference > 0.0
    assert fil.recommended == (fil.relative_error <= report.rtol and fil.time_ratio > 1.0)


#: the stiff rod of ``examples/stiff-rod-swing.toml`` (EA = GA = 1e6 B/L², n = 11, to t = 0.5)
STIFF_SWING = pathlib.Path(__file__).resolve().parents[1] / "examples" / "stiff-rod-swing.toml"


@pytest.mark.slow  # compiles the filament's rattle loop (≈ 2 min on a fresh cache); ≈ 10⁴ rod steps
def test_stiff_rod_in_time_states_the_measured_ratio_of_its_twin():
    """The whole run as the pilot: the filament (rattle, its own CFL step, ≈ 100 × the rod's)
    answers the stiff rod within rtol (its strains move by 1.6e-5; the measured difference, 1e-4
    of the 1.07 swing, includes the two runs' different time-step errors), and the report states
    the measured time ratios — whole runs and steps alone — not the CFL ratio, as the gain.
    No time is asserted: the recommendation follows the measured ratio, whatever it is."""
    report = advise(STIFF_SWING, check=True, pilot_steps=20000)
    fil = report[HELD_STRAINS]
    assert "t = 0.5" in report.pilot and fil.admitted
    assert fil.relative_error <= report.rtol and fil.indicator < 1e-4
    assert fil.measured_difference <= report.rtol * fil.error_scale
    assert fil.speedup_estimate > 50.0  # the CFL ratio: ≈ √(EA/B)·h/… ≈ 100
    assert math.isfinite(fil.time_ratio) and fil.time_ratio > 0.0
    r = fil.time_ratio
    pace = f"{r:.3g}× faster than" if r >= 1.0 else f"{1.0 / r:.3g}× slower than"
    assert f"measured: the twin runs the pilot {pace} the medium" in fil.note
    assert "steps alone" in fil.check_note and "untimed warm-up" in fil.check_note
    assert fil.recommended == (fil.time_ratio > 1.0)


def test_a_pilot_that_blows_up_says_so_and_leaves_no_file(tmp_path, monkeypatch):
    """A pilot writes nothing: its blow-up is an error naming the pilot, and the last good
    state that :func:`cartan.simulate` keeps for a user's run is removed."""
    import tempfile

    from cartan.simulate import InstabilityError

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    from cartan.scene import scene as registered_scene

    scene = registered_scene("rod-cantilever-gravity")
    scene.dt *= 1e3
    with pytest.raises(InstabilityError, match="^pilot run unstable") as info:
        advise(scene, pilot_steps=50)
    assert "last good state" not in str(info.value)
    assert list(tmp_path.iterdir()) == []


def test_sphere_rod_large_radius_prediction_matches_the_check():
    """L/r = 0.05, clamped at s = 0, with drag (mapped to the plane at equal dissipated power): the
    Richardson estimate from r and 2r against the planar rod's run."""
    grid = cartan.Grid(21, length=2.0)
    u = grid.coordinates()
    vel = np.stack([0.1 * np.sin(math.pi * u / 2), 0.5 * np.cos(math.pi * u / 2), np.full(21, 0.3)], -1)
    rod = cartan.medium("sphere-rod", radius=40.0, stiffness=[20.0, 10.0], bending=1.0, density=1.0,
                        rotational_inertia=0.05)
    prob = cartan.Problem(rod, grid, rod.initial_state(grid, "arc", curvature=1.0, centered=True,
                                                      physical_velocity=vel),
                          {"start": cartan.Clamped(), "end": cartan.Free()},
                          [rod.make_load("drag", gamma_T=2.0, gamma_R=0.5)], name="sphere-arc")
    sc = Scene(problem=prob, name="sphere-arc", mode="dynamic", integrator="lie-verlet", dt=2e-3, t_end=0.5)
    assert plane_limit_problem(prob).medium.name == "planar-cosserat-rod"
    report = advise(sc, check=True, pilot_steps=250)
    sph = report[LARGE_RADIUS]
    assert sph.admitted and sph.indicator == pytest.approx(0.05)
    assert sph.recommended
    assert 0.5 <= sph.error_estimate / sph.measured_difference <= 2.0
    assert not report[HELD_STRAINS].admitted and not report[PLANAR].admitted


def test_closed_sphere_rod_has_no_planar_limit():
    report = advise("sphere-rod-relax", pilot_steps=5)
    assert not report[LARGE_RADIUS].admitted and "closed" in report[LARGE_RADIUS].note


# ---------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("kwargs, match", [
    ({"rtol": 0.0}, "rtol"), ({"rtol": 2.0}, "rtol"), ({"pilot_steps": 1}, "pilot_steps"),
    ({"check": "yes"}, "check"),
])
def test_api_rejects_bad_options(kwargs, match):
    with pytest.raises(ValueError, match=match):
        advise(cartan.load_scene(stiff_cantilever()), **kwargs)


def test_api_rejects_other_types():
    with pytest.raises(TypeError):
        advise(42)


def _one_error_line(res) -> str:
    assert res.exit_code == 2, (res.stdout, res.stderr)
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("cartan: error: ")]
    assert len(lines) == 1, res.stderr
    assert res.stdout == ""
    return lines[0]


def test_cli_check_prints_the_report_and_writes_the_table(tmp_path):
    scene = tmp_path / "stiff.toml"
    scene.write_text(toml(stiff_cantilever()))
    out = tmp_path / "advice.nc"
    res = CliRunner().invoke(main, ["advise", str(scene), "--check", "-o", str(out)])
    assert res.exit_code == 0, (res.stdout, res.stderr)
    assert f"{HELD_STRAINS} [approximate]: RECOMMENDED" in res.stdout
    assert "check: measured difference" in res.stdout
    assert out.is_file()
    assert int(xr.open_dataset(out)["recommended"][0]) == 1
    res = CliRunner().invoke(main, ["advise", str(scene), "--json", "--rtol", "1e-4"])
    assert res.exit_code == 0, (res.stdout, res.stderr)
    data = json.loads(res.stdout)
    held = data["reductions"][0]
    assert held["name"] == HELD_STRAINS and held["measured_difference"] is None
    assert not held["recommended"] and held["relative_error"] > 1e-4  # 3.9e-4 of the deflection


@pytest.mark.parametrize("args, text", [
    (["missing.toml"], "no such file"),
    (["SCENE", "--scene", "rod-timoshenko-static"], "one of them"),
    (["--scene", "no-such-scene"], "no-such-scene"),
    ([], "give a scene file"),
    (["SCENE", "--rtol", "0"], "--rtol"),
    (["SCENE", "--pilot-steps", "1"], "--pilot-steps"),
    (["SCENE", "--rtol", "abc"], "abc"),
    (["SCENE", "-o", "no/such/dir/out.nc"], "does not exist"),
    (["BROKEN"], "BROKEN"),
])
def test_cli_bad_input_is_one_line_and_writes_nothing(tmp_path, monkeypatch, args, text):
    monkeypatch.chdir(tmp_path)
    pathlib.Path("scene.toml").write_text(toml(stiff_cantilever()))
    pathlib.Path("broken.toml").write_text("medium = [unclosed\n")
    args = [{"SCENE": "scene.toml", "BROKEN": "broken.toml"}.get(a, a) for a in args]
    before = sorted(p.name for p in tmp_path.iterdir())
    res = CliRunner().invoke(main, ["advise", *args])
    line = _one_error_line(res)
    assert text.replace("BROKEN", "broken.toml") in line, line
    assert sorted(p.name for p in tmp_path.iterdir()) == before
