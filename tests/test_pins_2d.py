"""Pins on lattices of d ≥ 2: position components of chosen nodes held by Lagrange multipliers.

A node is named per axis by ``start``, ``middle``, ``end`` or an index (a sequence, or a text
``"A,B"`` — the form of a scene's ``[continuation] pins`` keys), or by its flat index
(:func:`cartan.statics.pin_node`).  A square plate held only at its corners carries a quarter
of a uniform load at each corner (the symmetry of the square, and the balance of the forces:
the reactions add up to the load), the in-plane reactions vanish; bad pins are refused with one
line naming the key and the allowed values.  ``solve_static(pins=...)`` and ``[static] pins``
take the same pins.
"""

from __future__ import annotations

import json
import pathlib

import numpy as np
import pytest
from click.testing import CliRunner

import cartan
from cartan.cli import main
from cartan.continuation import continuation
from cartan.scene import SceneError, load_scene
from cartan.statics import _Equilibrium, pin_node

CORNERS = {"start,start": (0, 1, 2), "end,start": (1, 2), "start,end": (2,), "end,end": (2,)}


# ---------------------------------------------------------------------------- naming nodes
@pytest.mark.parametrize(("where", "index"), [
    ("start,start", (0, 0)), ("end,middle", (4, 2)), (("middle", "end"), (2, 3)), ((3, 0), (3, 0)),
    ("-1, 1", (4, 1)), ([0, "end"], (0, 3)), (7, (1, 3)), (-1, (4, 3)),
])
def test_a_node_is_named_per_axis_or_by_its_flat_index(where, index):
    assert pin_node(where, (5, 4)) == int(np.ravel_multi_index(index, (5, 4)))


def test_rod_nodes_keep_their_names():
    assert pin_node("start", (11,)) == 0 and pin_node("end", (11,)) == 10 and pin_node(5, (11,)) == 5


@pytest.mark.parametrize(("where", "shape", "message"), [
    ("centre,start", (5, 4), "pins: unknown node 'centre,start'; allowed: 2 entries"),
    ("5,0", (5, 4), "each 'start', 'middle', 'end' or an index (-5..4 along u, -4..3 along v)"),
    ((0, 0, 0), (5, 4), "unknown node (0, 0, 0)"),
    ("3", (5, 4), "unknown node '3'"),
    (20, (5, 4), "pins: node 20 out of range; allowed: 2 entries"),
    ("middle", (11,), "pins: unknown node 'middle'; allowed: 'start', 'end' or a node index -11..10"),
    (True, (5, 4), "unknown node True"),
])
def test_a_bad_node_names_the_allowed_values(where, shape, message):
    with pytest.raises(ValueError) as info:
        pin_node(where, shape)
    assert message in str(info.value)


# ---------------------------------------------------------------------------- the plate on corner pins
@pytest.fixture(scope="module")
def plate():
    med = cartan.medium("cosserat-surface", E=1.0, poisson=0.3, thickness=0.1)
    grid = cartan.Grid((3, 3), length=(1.0, 1.0))
    load = med.make_load("dead-load", force=[0.0, 0.0, -1e-5])
    return cartan.Problem(med, grid, med.initial_state(grid, "flat"), {}, [load])


def test_pins_are_validated_on_the_lattice(plate):
    with pytest.raises(ValueError, match=r"pins: component 2 of node \(2, 2\) is pinned twice"):
        _Equilibrium(plate, pins={"end,end": (2,), (2, 2): (2,)})
    held = cartan.Problem(plate.medium, plate.grid, plate.initial, {"u-start": cartan.Clamped()}, plate.loads)
    with pytest.raises(ValueError, match="pins: node 'start,end' is held by a clamped boundary"):
        _Equilibrium(held, pins={"start,end": (2,)})
    eq = _Equilibrium(plate, pins=CORNERS)
    assert eq.pins == [(0, 0), (0, 1), (0, 2), (6, 1), (6, 2), (2, 2), (8, 2)]


def test_a_plate_on_its_corners_carries_a_quarter_of_the_load_at_each(plate):
    """Reactions: z = q·A/4 at each corner (q A the load; the symmetry of the square; to the
    Newton tolerance 1e-10 of the forces), x and y at round-off; the pinned components held."""
    ds = continuation(plate, 1.0, 1.0, pins=CORNERS, detect=False)
    assert float(ds.load_factor[-1]) == 1.0
    r = ds.reaction.values[-1]
    z = r[[2, 4, 5, 6]]
    total = 1e-5 * 1.0 * 1.0
    assert abs(z.sum() - total) <= 1e-8 * total and np.allclose(z, total / 4, rtol=1e-6, atol=0.0)
    assert np.max(np.abs(r[[0, 1, 3]])) <= 1e-12 * total
    pos = ds.position.values[-1].reshape(3, 3, 3)
    assert np.max(np.abs(pos[[0, 2, 0, 2], [0, 0, 2, 2], 2])) <= 1e-12    # the corners stay at z = 0
    assert pos[1, 1, 2] < -1e-3                                          # the plate sags between them


def test_solve_static_holds_the_same_pins(plate):
    """``solve_static(pins=...)``: the equilibrium and the reactions of the path's end (λ = 1),
    to the Newton tolerances (forces 1e-10 of the load, positions at round-off)."""
    path = continuation(plate, 1.0, 1.0, pins=CORNERS, detect=False)
    ds = cartan.solve_static(plate, pins=CORNERS)
    assert list(ds.reaction.dims) == ["pin"]
    assert np.allclose(ds.reaction.values, path.reaction.values[-1], rtol=0.0, atol=1e-9 * 1e-5)
    assert np.allclose(ds.position.values[0].reshape(-1, 3), path.position.values[-1], rtol=0.0, atol=1e-9)
    assert json.loads(ds.attrs["cartan_config"])["run"]["pins"]["end,end"] == [2]


# ---------------------------------------------------------------------------- scenes
SCENE = pathlib.Path(cartan.__file__).parents[1] / "plugins" / "cartan_cosserat_surface" / "scenes" \
    / "plate-corner-pins.toml"


def test_the_scene_reads_its_pins():
    sc = load_scene(SCENE)
    assert sc.solver_options["pins"] == {"start,start": (0, 1, 2), "end,start": (1, 2), "start,end": (2,),
                                         "end,end": (2,)}


@pytest.mark.parametrize(("old", "new", "expected"), [
    ('"end,end" = ["z"]', '"end,centre" = ["z"]',
     "continuation.pins.end,centre: unknown node 'end,centre'; allowed: 2 entries (a sequence, or a text such as "
     "'end,middle'), each 'start', 'middle', 'end' or an index (-9..8 along u, -9..8 along v)"),
    ('"end,end" = ["z"]', '"9,0" = ["z"]', "continuation.pins.9,0: unknown node '9,0'"),
    ('"end,end" = ["z"]', '"0,0" = ["z"]', "continuation.pins.0,0: the node of 'start,start' again"),
    ('"end,end" = ["z"]', '"end,end" = ["w"]',
     "continuation.pins.end,end: unknown component 'w'; allowed: 'x', 'y', 'z' or an index 0..2"),
    ('"end,end" = ["z"]', '"end,end" = []', "continuation.pins.end,end: must be a non-empty list"),
    ('"end,end" = ["z"]', '"end,end" = ["z", "z"]', "continuation.pins.end,end: repeated component"),
    ('kind = "flat"', 'kind = "flat"\n[boundaries]\nv-end = { kind = "clamped" }',
     "continuation.pins.start,end: the node (0, 8) is on the clamped face v-end; pins hold free nodes"),
    ('pins = {', 'pins = 3 #', "continuation.pins: must be a table such as { \"start,start\" = "),
])
def test_bad_pins_are_one_line_scene_errors(tmp_path, old, new, expected):
    text = SCENE.read_text()
    assert old in text
    path = tmp_path / "pins.toml"
    path.write_text(text.replace(old, new, 1))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert "\n" not in msg and expected in msg, msg
    res = CliRunner().invoke(main, ["run", str(path), "-o", str(tmp_path / "x.nc")])
    assert res.exit_code != 0 and f"cartan: error: {msg}" in res.output


def test_a_static_scene_takes_pins(tmp_path):
    """``[static] pins``: the same keys as ``[continuation] pins``, errors named ``static.pins``."""
    text = SCENE.read_text().replace('mode = "continuation"', 'mode = "static"')
    head, _, tail = text.partition("[continuation]")
    pins = next(line for line in tail.splitlines() if line.startswith("pins = "))
    path = tmp_path / "static.toml"
    path.write_text(head + "[static]\ntol = 1e-10\n" + pins + "\n")
    assert load_scene(path).solver_options["pins"]["end,start"] == (1, 2)
    path.write_text(head + "[static]\n" + pins.replace('"end,end"', '"end,centre"') + "\n")
    with pytest.raises(SceneError, match="static.pins.end,centre: unknown node 'end,centre'"):
        load_scene(path)


@pytest.mark.slow
def test_the_corner_pins_scene(tmp_path):
    """``cartan run --scene plate-corner-pins``: the reactions are labelled by node and component,
    each corner carries q/4 = 2.5e-5 and the centre sags."""
    out = tmp_path / "pins.nc"
    res = CliRunner().invoke(main, ["run", "--scene", "plate-corner-pins", "-o", str(out)])
    assert res.exit_code == 0, res.output
    ds = cartan.open(out)
    assert list(ds["pin"].values) == ["start,start x", "start,start y", "start,start z", "end,start y",
                                      "end,start z", "start,end z", "end,end z"]
    z = ds.reaction.sel(pin=["start,start z", "end,start z", "start,end z", "end,end z"]).values[-1]
    assert np.allclose(z, 2.5e-5, rtol=1e-6, atol=0.0)
    assert float(ds.monitor[-1]) < -0.1
