"""Point forces in scene files: the core's ``kind = "node-force"`` load (:class:`cartan.NodeForce`)
on d = 1, 2, 3 grids, the ``shell-pinched-cylinder`` scene against its registered case, and bad input."""

from __future__ import annotations

import pathlib
import re
import textwrap
import tomllib

import numpy as np
import pytest
from click.testing import CliRunner

import cartan
from cartan import NodeForce
from cartan.cli import main
from cartan.scene import SceneError, load_scene
from cartan.statics import solve_static

# A Timoshenko cantilever (11 nodes, L = 3) with a point force on its tip node, large enough to
# turn the tip by 30° (measured), so that a dead and a follower force give different equilibria.
P = [0.0, 0.0, -40.0, 0.0, 0.0, 0.0]
ROD = textwrap.dedent(
    f"""
    name = "cantilever-point-force"
    mode = "static"
    medium = "cosserat-rod"
    [parameters]
    E = 1e5
    G = 1e4
    radius = 0.25
    density = 5000.0
    shear_coefficient = 0.9642857142857143
    [grid]
    n = 11
    length = 3.0
    [boundaries]
    start = {{ kind = "clamped" }}
    [[loads]]
    kind = "node-force"
    at = [3.0]
    force = {P}
    [initial]
    kind = "straight"
    [static]
    tol = 1e-10
    max_iterations = 30
    measure = {{ node = "end", component = "z" }}
    """
)
PINCHED = pathlib.Path(cartan.__file__).parents[1] / "plugins" / "cartan_cosserat_surface" / "scenes" / \
    "shell-pinched-cylinder.toml"


def _rod_problem(**end) -> cartan.Problem:
    rod = cartan.medium("cosserat-rod", E=1e5, G=1e4, radius=0.25, density=5000.0, shear_coefficient=27 / 28)
    grid = cartan.Grid(11, length=3.0)
    boundaries = {"start": cartan.Clamped(), **({"end": cartan.Free(**end)} if end else {})}
    return cartan.Problem(rod, grid, rod.initial_state(grid, "straight"), boundaries)


def _edit(text: str, old: str, new: str) -> str:
    assert old in text
    return text.replace(old, new)


# ---------------------------------------------------------------------------- d = 1
@pytest.mark.parametrize("frame", ["spatial", "body"])
def test_rod_tip_point_force_is_the_free_end_load(frame):
    """A node force on the tip node of a cantilever (``at`` the tip) is the end's load of ``Free``:
    a dead load for ``frame = "spatial"``, a follower load for ``"body"`` — same equilibrium to
    round-off, and the same as the Problem built in Python with NodeForce, bit for bit."""
    text = ROD if frame == "spatial" else _edit(ROD, "at = [3.0]", 'at = [3.0]\nframe = "body"')
    sc = load_scene(tomllib.loads(text))
    (load,) = sc.problem.loads
    assert isinstance(load, NodeForce) and load.node == (10,) and load.frame == frame
    ds = sc.run()
    end = solve_static(_rod_problem(load=P, follower=frame == "body"), tol=1e-10, max_iter=30)
    # the same equilibrium (positions ≤ 3; both converged to ‖r‖ ≤ 1e-10·40 by the same Newton steps)
    np.testing.assert_allclose(ds["position"].values, end["position"].values, rtol=0, atol=1e-12)
    assert ds.attrs["newton_iterations"] == end.attrs["newton_iterations"]
    base = _rod_problem()
    python = cartan.Problem(base.medium, base.grid, base.initial, base.boundaries,
                            [NodeForce(base.grid, P, node=-1, frame=frame)])
    direct = solve_static(python, tol=1e-10, max_iter=30)
    np.testing.assert_array_equal(ds["position"].values, direct["position"].values)
    assert ds.attrs["measured_displacement"] == float(direct["position"].values[0, -1, 2])  # z₀ = 0


def test_rod_tip_point_force_in_a_dynamic_run():
    """A dynamic run (lie-verlet, lattice) with a node force on the tip follows the free end's load:
    positions and external work equal to round-off (measured 2e-15 and 3e-19 after 50 steps)."""
    doc = tomllib.loads((pathlib.Path(cartan.__file__).parents[1] / "plugins" / "cartan_cosserat" / "scenes" /
                         "rod-cantilever-gravity.toml").read_text())
    doc["run"].update(t_end=0.1, save_every=10)
    point = load_scene({**doc, "loads": [{"kind": "node-force", "node": -1, "force": [0.0, 0.0, -0.05, 0, 0, 0]}]})
    end = load_scene({**doc, "loads": [], "boundaries": {
        "start": {"kind": "clamped"}, "end": {"kind": "free", "load": [0.0, 0.0, -0.05, 0, 0, 0]}}})
    a, b = point.simulate(), end.simulate()
    assert float(a["external_work"][-1]) > 1e-6  # the force did work
    np.testing.assert_allclose(a["position"].values, b["position"].values, rtol=0, atol=1e-13)
    np.testing.assert_allclose(a["external_work"].values, b["external_work"].values, rtol=1e-10, atol=0)


def test_rod_dead_and_follower_point_forces_differ():
    """The frame matters: the tip turns, so a follower force shortens the span less than a dead one."""
    dead = load_scene(tomllib.loads(ROD)).run()
    body = load_scene(tomllib.loads(_edit(ROD, "at = [3.0]", 'at = [3.0]\nframe = "body"'))).run()
    x_dead, x_body = (float(d["position"].values[0, -1, 0]) for d in (dead, body))
    assert abs(x_dead - x_body) > 1e-2, (x_dead, x_body)


def test_at_takes_the_nearest_node_and_node_counts_from_the_end():
    grid = cartan.Grid(11, length=3.0)  # h = 0.3
    assert NodeForce(grid, P, at=0.44).node == (1,) and NodeForce(grid, P, at=0.46).node == (2,)
    assert NodeForce(grid, P, at=3.0 + 1e-9).node == (10,)  # a written decimal's rounding
    assert NodeForce(grid, P, node=-1).node == NodeForce(grid, P, node=[10]).node == (10,)
    ring = cartan.Grid(10, length=3.0, periodic=True)  # h = 0.3: the last half cell belongs to node 0
    assert NodeForce(ring, P, at=2.9).node == (0,) and NodeForce(ring, P, at=2.8).node == (9,)


# ---------------------------------------------------------------------------- d = 3
def test_solid_corner_point_force_d3():
    """d = 3 (micropolar solid): the nearest node of ``at`` receives the force — the weighted nodal
    forces sum to it — in the spatial frame, rotated into a turned frame as a free end's dead load."""
    doc = {"name": "block", "mode": "static", "medium": "cosserat-solid", "grid": {"shape": [3, 4, 5], "length": 1.0},
           "boundaries": {"u-start": {"kind": "clamped"}}, "initial": {"kind": "undeformed"},
           "loads": [{"kind": "node-force", "at": [1.0, 0.3, 0.52], "force": [1.0, 2.0, 3.0, 0.5, 0.0, 0.0]}]}
    sc = load_scene(doc)
    (load,) = sc.problem.loads
    assert load.node == (2, 1, 2)
    grid, Phi = sc.problem.grid, np.array(sc.problem.initial.Phi)
    nodal = load.force(Phi, None, 0.0) * grid.node_weights()[..., None]
    expected = np.zeros((*grid.shape, 6))
    expected[2, 1, 2] = doc["loads"][0]["force"]
    np.testing.assert_allclose(nodal, expected, rtol=1e-15, atol=0)  # frames are the identity
    g = sc.problem.medium.group
    Phi[2, 1, 2] = g.exp(np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.5 * np.pi]))  # turned by 90° about z
    nodal = load.force(Phi, None, 0.0)[2, 1, 2] * grid.node_weights()[2, 1, 2]
    np.testing.assert_allclose(nodal, [2.0, -1.0, 3.0, 0.0, -0.5, 0.0], rtol=0, atol=1e-15)  # Rᵀf, Rᵀm


# ---------------------------------------------------------------------------- d = 2: the pinched cylinder
def test_pinched_cylinder_scene_is_the_registered_case(tmp_path):
    """``cartan run --scene shell-pinched-cylinder`` reports the deflection under the load, the case's
    value at n_v = 17 (the same problem: equal to round-off; measured bit for bit)."""
    from cartan_cosserat_surface.cases_shells import PinchedCylinder, pinched_cylinder_problem

    out = tmp_path / "pinched.nc"
    res = CliRunner().invoke(main, ["run", "--scene", "shell-pinched-cylinder", "-o", str(out)])
    assert res.exit_code == 0, res.output
    printed = re.search(r"displacement z of node \[0, 16\] = (\S+)\)", res.output)
    assert printed, res.output
    w_scene = -cartan.open(out).attrs["measured_displacement"]
    assert float(printed.group(1)) == pytest.approx(-w_scene, rel=1e-5)  # printed to 6 digits
    case = PinchedCylinder()
    problem, node = pinched_cylinder_problem(17, shear_correction=case.shear_correction)
    assert node == (0, 16) and problem.grid.shape == (26, 17)
    w_case = case.deflection(solve_static(problem, tol=1e-10), problem)
    assert w_scene == pytest.approx(w_case, rel=1e-12, abs=0)
    assert w_case == pytest.approx(1.6722e-5, rel=1e-4)  # the documented n_v = 17 value, 8.5 % below w∞


# ---------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        ("at = [3.0]", "at = [3.5]", "at = [3.5] is outside the chart: u = 3.5 is not in [0, 3]"),
        ("at = [3.0]", "at = [-0.1]", "at = [-0.1] is outside the chart"),
        ("at = [3.0]", "at = [1.0, 2.0]", "at must have 1 coordinate(s)"),
        ("at = [3.0]", "at = [3.0]\nnode = 10", "give exactly one of node"),
        ("at = [3.0]", "", "give exactly one of node"),
        ("at = [3.0]", "node = 11", "node must be 1 integer(s), one per axis, in -11..10, got 11"),
        ("at = [3.0]", "node = 1.5", "node must be 1 integer(s)"),
        ("at = [3.0]", 'at = [3.0]\nframe = "world"', "frame must be 'spatial' or 'body'"),
        ("at = [3.0]", "at = [3.0]\nweight = 2.0", "loads[0].weight: unknown key; allowed: at, force, frame, node"),
        (f"force = {P}", "force = [0.0, 0.0, -40.0]", "force must have 6 components (the dimension of SE3"),
        (f"force = {P}", "", "loads[0].force: missing key"),
    ],
)
def test_bad_node_forces_are_refused(tmp_path, old, new, expected):
    """``load_scene`` raises a one-line SceneError (a ValueError) naming the key; ``cartan run`` prints
    it as ``cartan: error:``, exits with status 2 and writes nothing."""
    path = tmp_path / "scene.toml"
    path.write_text(_edit(ROD, old, new))
    with pytest.raises(ValueError) as info:
        load_scene(path)
    assert isinstance(info.value, SceneError)
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith(f"{path}: loads[0]"), msg
    assert expected in msg, msg
    res = CliRunner().invoke(main, ["run", str(path), "-o", str(tmp_path / "out.nc")])
    assert res.exit_code == 2, res.output
    assert res.output.startswith("cartan: error: ") and res.output.count("\n") == 1, res.output
    assert expected in res.output and "Traceback" not in res.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.toml"]


def test_pinched_cylinder_point_outside_the_chart_is_refused():
    """d = 2: a point beyond the half-length (L/2 = 300) is outside the octant's chart."""
    doc = tomllib.loads(PINCHED.read_text())
    doc["loads"][0]["at"] = [0.0, 301.0]
    with pytest.raises(SceneError, match=r"loads\[0\] \(node-force\): at = \[0.0, 301.0\] is outside the chart: "
                                         r"v = 301 is not in \[0, 300\]"):
        load_scene(doc)
    doc["loads"][0]["at"] = [0.0, 300.0, 0.0]
    with pytest.raises(SceneError, match=r"at must have 2 coordinate\(s\)"):
        load_scene(doc)
