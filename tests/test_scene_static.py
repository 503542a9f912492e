"""Static and continuation scenes: ``mode = "static"`` / ``"continuation"`` in scene files, ``cartan run``
and ``cartan plot`` on them, the registered cosserat scenes, and their one-line errors."""

from __future__ import annotations

import json
import math
import pathlib
import textwrap

import numpy as np
import pytest
from click.testing import CliRunner

import cartan
from cartan.cli import main
from cartan.continuation import continuation
from cartan.plotting import plot_load_displacement, result_kind
from cartan.scene import SceneError, load_scene
from cartan.statics import solve_static

# A short Timoshenko cantilever (VERIFICATION.md §4 material, 21 nodes): static mode
STATIC = textwrap.dedent(
    """
    name = "cantilever-static"
    mode = "static"
    medium = "cosserat-rod"
    [parameters]
    E = 1e6
    G = 1e4
    radius = 0.25
    density = 5000.0
    shear_coefficient = 0.9642857142857143
    [grid]
    n = 21
    length = 3.0
    [boundaries]
    start = { kind = "clamped" }
    end = { kind = "free", load = [0.0, 0.0, -15.0, 0.0, 0.0, 0.0] }
    [initial]
    kind = "straight"
    [static]
    tol = 1e-10
    max_iterations = 20
    measure = { node = "end", component = "z" }
    """
)

# A pinned–pinned planar column (B = 1, L = 1, 21 nodes) through its first bifurcation: continuation mode
COLUMN = textwrap.dedent(
    """
    name = "column"
    mode = "continuation"
    medium = "planar-cosserat-rod"
    [parameters]
    stretch_shear = [1e6, 1e6]
    bending = 1.0
    mass = 1.0
    rotational_inertia = 1.0
    [grid]
    n = 21
    length = 1.0
    [boundaries]
    start = { kind = "free" }
    end = { kind = "free", load = [-1.0, 0.0, 0.0] }
    [initial]
    kind = "straight"
    [continuation]
    parameter = "end"
    lambda_max = 12.0
    ds = 0.05
    max_steps = 60
    measure = { node = "middle", component = "y" }
    pins = { start = ["x", "y"], end = ["y"] }
    branch_switch = true
    """
)


def write(tmp_path: pathlib.Path, text: str, name: str = "scene.toml") -> pathlib.Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def run_cli(*args: str):
    return CliRunner().invoke(main, list(args))


# ---------------------------------------------------------------------------- static
def test_static_scene_round_trips_through_cartan_run(tmp_path):
    path = write(tmp_path, STATIC)
    out = tmp_path / "static.nc"
    res = run_cli("run", str(path), "-o", str(out))
    assert res.exit_code == 0, res.output
    assert f"wrote {out}" in res.output and "Newton iterations" in res.output
    ds = cartan.open(out)
    assert result_kind(ds) == "static" and ds.sizes["time"] == 1

    # the same problem solved directly
    rod = cartan.medium("cosserat-rod", E=1e6, G=1e4, radius=0.25, density=5000.0, shear_coefficient=27 / 28)
    grid = cartan.Grid(21, length=3.0)
    problem = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                             {"start": cartan.Clamped(), "end": cartan.Free(load=[0, 0, -15.0, 0, 0, 0])})
    direct = solve_static(problem, tol=1e-10, max_iter=20)
    # same algorithm, same data: equal to round-off of the position (|x| ≤ 3)
    np.testing.assert_allclose(ds["position"].values, direct["position"].values, rtol=0, atol=1e-13)
    assert ds.attrs["newton_iterations"] == direct.attrs["newton_iterations"]
    np.testing.assert_array_equal(ds["initial_position"].values, grid.coordinates(0)[:, None] * [1, 0, 0])
    tip = float(ds["position"].isel(time=0, node=-1, row=2))
    assert ds.attrs["measured_displacement"] == tip  # z of the end node, initially at z = 0
    assert ds.attrs["measure"] == "displacement z of node end"

    # CF attributes, history and configuration, as for dynamic runs
    assert ds.attrs["Conventions"].startswith("CF-")
    assert "cartan run" in ds.attrs["history"] and str(path) in ds.attrs["history"]
    cfg = json.loads(ds.attrs["cartan_config"])
    assert cfg["mode"] == "static" and cfg["scene"]["name"] == "cantilever-static"
    assert cfg["scene_path"] == str(path) and cfg["run"]["max_iter"] == 20
    assert cfg["problem"]["medium"] == "cosserat-rod"
    assert not list(tmp_path.glob(".*.tmp"))  # the atomic write left no temporary file


def test_static_initial_guess_from_a_run_file(tmp_path):
    """Newton's method started from a converged equilibrium (``initial_guess``) stops at once."""
    first = load_scene(write(tmp_path, STATIC)).run(output=tmp_path / "first.nc")
    seeded = STATIC.replace("max_iterations = 20", 'max_iterations = 20\ninitial_guess = "first.nc"')
    sc = load_scene(write(tmp_path, seeded, "seeded.toml"))
    assert sc.initial_guess == tmp_path / "first.nc"  # relative to the scene file
    again = sc.run()
    assert first.attrs["newton_iterations"] >= 2
    assert again.attrs["newton_iterations"] <= 1
    np.testing.assert_allclose(again["position"].values, first["position"].values, rtol=0, atol=1e-12)


def test_static_run_that_fails_exits_1_and_writes_nothing(tmp_path):
    """A soft rod under a large tip load with one Newton iteration allowed: ConvergenceError."""
    text = STATIC.replace("E = 1e6", "E = 1e3").replace("max_iterations = 20", "max_iterations = 1")
    out = tmp_path / "fail.nc"
    res = run_cli("run", str(write(tmp_path, text)), "-o", str(out))
    assert res.exit_code == 1, res.output
    assert res.output.startswith("cartan: error: solve_static: no equilibrium") and res.output.count("\n") == 1
    assert not out.exists()


def test_simulate_refuses_static_scenes(tmp_path):
    sc = load_scene(write(tmp_path, STATIC))
    assert sc.mode == "static" and "mode='static'" in repr(sc)
    with pytest.raises(SceneError, match="mode = 'static'.*Scene.run"):
        cartan.simulate(sc)
    with pytest.raises(ValueError, match="dynamic scenes only"):
        sc.run(dt=0.1)


# ---------------------------------------------------------------------------- continuation
def _column_direct():
    rod = cartan.medium("planar-cosserat-rod", stretch_shear=[1e6, 1e6], bending=1.0, mass=1.0,
                        rotational_inertia=1.0)
    grid = cartan.Grid(21, length=1.0)
    problem = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                             {"start": cartan.Free(), "end": cartan.Free(load=[-1.0, 0.0, 0.0])})
    return continuation(problem, 12.0, 0.05, max_points=60, branch_switch=True,
                        pins={"start": (0, 1), "end": (1,)},
                        monitor=lambda d: float(d["position"].isel(time=0, node=10, row=1)))


def test_continuation_scene_round_trips_through_cartan_run(tmp_path):
    path = write(tmp_path, COLUMN)
    out = tmp_path / "column.nc"
    res = run_cli("run", str(path), "-o", str(out))
    assert res.exit_code == 0, res.output
    assert "bifurcation at λ = " in res.output
    ds = cartan.open(out)
    assert result_kind(ds) == "continuation"
    direct = _column_direct()
    for name in ("load_factor", "monitor", "branch", "critical_load"):
        np.testing.assert_allclose(ds[name].values, direct[name].values, rtol=1e-12, atol=1e-13, err_msg=name)
    assert list(ds["critical_kind"].values) == list(direct["critical_kind"].values) == ["bifurcation"]
    # the recorded displacement is the midspan y of the stored shapes
    np.testing.assert_array_equal(ds["monitor"].values, ds["position"].isel(node=10, row=1).values)
    # P_cr of the 21-node lattice: π²B/L²·(1 + π²h²/12) up to O(h⁴) ≈ 6e-6 at h = 0.05 (measured 1.7e-6)
    p_cr = float(ds["critical_load"][0])
    assert abs(p_cr / math.pi**2 - 1 - math.pi**2 * 0.05**2 / 12) < 1e-5, p_cr
    assert ds["branch"].values[-1] == 1 and ds["monitor"].values[-1] > 0.1  # on the buckled branch
    assert ds["load_factor"].values[-1] == pytest.approx(12.0, abs=1e-12)
    # CF attributes, history and configuration
    assert ds.attrs["Conventions"].startswith("CF-") and ds.attrs["source"].startswith("cartan ")
    assert "cartan run" in ds.attrs["history"]
    cfg = json.loads(ds.attrs["cartan_config"])
    assert cfg["mode"] == "continuation" and cfg["run"]["parameter"] == "end"
    assert cfg["run"]["pins"] == {"start": [0, 1], "end": [1]} and cfg["scene"]["name"] == "column"
    assert ds["monitor"].attrs["units"] == "length" and "node middle" in ds["monitor"].attrs["long_name"]
    assert ds["u"].values[-1] == pytest.approx(1.0)


def test_plot_static_and_continuation_results(tmp_path):
    static = tmp_path / "static.nc"
    column = tmp_path / "column.nc"
    load_scene(write(tmp_path, STATIC)).run(output=static)
    load_scene(write(tmp_path, COLUMN, "column.toml")).run(output=column)
    for nc in (static, column):
        png = nc.with_suffix(".png")
        res = run_cli("plot", str(nc))
        assert res.exit_code == 0, res.output
        assert png.stat().st_size > 20_000 and str(png) in res.output
    # the chart: one line per branch, the second starting at the bifurcation, which is marked
    ds = cartan.open(column)
    fig = plot_load_displacement(ds, tmp_path / "chart.png")
    ax = fig.axes[0]
    lines = {ln.get_label(): ln for ln in ax.get_lines()}
    primary, switched = lines["primary path"], lines["after the branch switch"]
    c_lam, c_w = float(ds["critical_load"][0]), float(ds["critical_monitor"][0])
    assert switched.get_xydata()[0] == pytest.approx([c_w, c_lam])
    assert len(primary.get_xdata()) == int((ds["branch"] == 0).sum())
    marker = next(ln for label, ln in lines.items() if label.startswith("bifurcation"))
    assert marker.get_xydata()[0] == pytest.approx([c_w, c_lam])
    assert (tmp_path / "chart.png").stat().st_size > 10_000
    with pytest.raises(ValueError, match="not a continuation result"):
        plot_load_displacement(cartan.open(static))


# ---------------------------------------------------------------------------- registered scenes
def test_registered_timoshenko_scene_via_cli(tmp_path):
    """``rod-timoshenko-static`` (n = 101): the tip deflection lies 3.2e-4–3.9e-4 below the linear
    Timoshenko value (geometric nonlinearity 3.2e-4 plus the lattice's O(h²) error 1.6e-5 at n = 101,
    VERIFICATION.md §4 and tests/test_statics.py)."""
    out = tmp_path / "tim.nc"
    res = run_cli("run", "--scene", "rod-timoshenko-static", "-o", str(out))
    assert res.exit_code == 0, res.output
    ds = cartan.open(out)
    L, r, E, G, F = 3.0, 0.25, 1e6, 1e4, 15.0
    A, inertia = math.pi * r**2, math.pi * r**4 / 4
    linear = F * L / (27 / 28 * G * A) + F * L**3 / (3 * E * inertia)
    rel = -ds.attrs["measured_displacement"] / linear - 1
    assert -4e-4 < rel < -3e-4, rel
    assert ds.attrs["newton_iterations"] <= 5


def test_registered_continuation_scenes():
    """``rod-euler-buckling`` (n = 101): P_cr = π²B/L²·(1 + π²h²/12) within 5e-6 (the lattice's
    second-order error; measured 1e-8); ``rod-elastica-continuation``: the path holds PL²/B = 1, 2, 10
    exactly with tip deflections within 3e-5 of the elastica tabulated to 5 decimals (measured ≤ 1e-5: the
    table's rounding, the stretch P/(EA) = 1e-5 at PL²/B = 10 and the O(h²) lattice error at n = 101)."""
    euler = cartan.scene("rod-euler-buckling").run()
    p_cr = float(euler["critical_load"][0])
    assert abs(p_cr / math.pi**2 - 1 - math.pi**2 * 0.01**2 / 12) < 5e-6, p_cr
    assert euler["branch"].values[-1] == 1 and euler["load_factor"].values[-1] == pytest.approx(1.5 * math.pi**2)
    elastica = cartan.scene("rod-elastica-continuation").run()
    lam = elastica["load_factor"].values
    for alpha, tip in {1.0: 0.30172, 2.0: 0.49346, 10.0: 0.81061}.items():
        i = int(np.argmin(np.abs(lam - alpha)))
        assert lam[i] == pytest.approx(alpha, abs=1e-12)
        assert abs(-float(elastica["monitor"][i]) - tip) < 3e-5, (alpha, float(elastica["monitor"][i]))
    assert elastica.sizes["critical"] == 0


# ---------------------------------------------------------------------------- errors
@pytest.mark.parametrize(
    ("text", "edit", "expected"),
    [
        (STATIC, lambda s: s.replace('mode = "static"', 'mode = "quasi"'),
         "mode: unknown mode 'quasi'; allowed: 'dynamic', 'static', 'continuation'"),
        (STATIC, lambda s: s + "[run]\ndt = 0.1\n", "run: a [run] table belongs to mode = 'dynamic' scenes"),
        (STATIC, lambda s: s.replace('mode = "static"\n', ""), "static: a [static] table belongs to mode = 'static'"),
        (STATIC, lambda s: s.replace("tol = 1e-10", "tol = 1e-10\nfoo = 1"), "static.foo: unknown key; allowed:"),
        (STATIC, lambda s: s.replace("tol = 1e-10", "tol = -1.0"), "static.tol: must be > 0"),
        (STATIC, lambda s: s.replace("max_iterations = 20", "max_iterations = 0"),
         "static.max_iterations: must be an integer in 1..10000"),
        (STATIC, lambda s: s.replace('node = "end"', 'node = "tip"'),
         "static.measure.node: unknown node 'tip'; allowed: 'start', 'middle', 'end' or an index"),
        (STATIC, lambda s: s.replace('node = "end"', "node = 21"), "static.measure.node: must be"),
        (STATIC, lambda s: s.replace('component = "z"', 'component = "w"'),
         "static.measure.component: unknown component 'w'; allowed: 'x', 'y', 'z', 'magnitude'"),
        (STATIC, lambda s: s.replace("max_iterations = 20", 'initial_guess = "nowhere.nc"'),
         "static.initial_guess: no such file"),
        (COLUMN, lambda s: s.replace("lambda_max = 12.0\n", ""), "continuation.lambda_max: missing key"),
        (COLUMN, lambda s: s.replace("ds = 0.05", "ds = 0.0"), "continuation.ds: must be > 0"),
        (COLUMN, lambda s: s.replace("ds = 0.05", "ds = 0.05\nds_min = 0.1"), "continuation.ds_min: must be ≤ ds"),
        (COLUMN, lambda s: s.replace("max_steps = 60", "max_steps = 1"),
         "continuation.max_steps: must be an integer in 2..100000"),
        (COLUMN, lambda s: s.replace('parameter = "end"', 'parameter = "start"'),
         "continuation.parameter: unknown load 'start'; allowed: 'all', 'end'"),
        (COLUMN, lambda s: s.replace('["x", "y"]', '["x", "q"]'),
         "continuation.pins.start: unknown component 'q'; allowed: 'x', 'y' or an index 0..1"),
        (COLUMN, lambda s: s.replace('start = { kind = "free" }', 'start = { kind = "clamped" }'),
         "continuation.pins.start: the start is clamped"),
        (COLUMN, lambda s: s.replace("branch_switch = true", 'branch_switch = "yes"'),
         "continuation.branch_switch: must be true or false"),
        (COLUMN, lambda s: s.replace("branch_switch = true", "switch_direction = 2"),
         "continuation.switch_direction: must be 1 or -1"),
        (COLUMN, lambda s: s.replace("ds = 0.05", "ds = 0.05\nstops = [20.0]"),
         "continuation.stops: must be a list of load factors in (0, lambda_max = 12)"),
        (COLUMN, lambda s: s.replace("load = [-1.0, 0.0, 0.0]", "load = [0.0, 0.0, 0.0]"),
         "continuation: the scene has no external load for λ to scale"),
        (COLUMN, lambda s: s + '[[loads]]\nkind = "uniform-force"\ncomponents = [0.0, -1.0, 0.0]\n',
         "continuation.parameter: λ scales every external load together, but the scene also has loads[0]"),
        (COLUMN, lambda s: s.replace('mode = "continuation"\n', 'mode = "static"\n'),
         "continuation: a [continuation] table belongs to mode = 'continuation' scenes"),
    ],
)
def test_bad_sections_are_one_line_scene_errors(tmp_path, text, edit, expected):
    path = write(tmp_path, edit(text))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith(f"{path}: "), msg
    assert expected in msg, msg


@pytest.mark.parametrize(
    ("text", "args", "expected"),
    [
        (COLUMN.replace("ds = 0.05", "ds = -1.0"), [], "continuation.ds: must be > 0"),
        (STATIC.replace('component = "z"', 'component = "w"'), [], "unknown component 'w'"),
        (STATIC, ["--dt", "0.1", "--t-end", "1"], "--dt, --t-end: only for dynamic scenes"),
        (COLUMN, ["--scheme", "collocation"], "--scheme: continuation runs use the 'lattice' scheme only"),
    ],
)
def test_cli_errors_write_nothing(tmp_path, text, args, expected):
    path = write(tmp_path, text)
    out = tmp_path / "out.nc"
    res = run_cli("run", str(path), "-o", str(out), *args)
    assert res.exit_code == 2, res.output
    assert res.output.startswith("cartan: error: ") and res.output.count("\n") == 1, res.output
    assert expected in res.output and "Traceback" not in res.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.toml"]
