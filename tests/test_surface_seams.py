"""Periodic seams of surfaces: pictures drawn across them, and the flat periodic strip.

* The core's pictures (:mod:`cartan.plotting`) add one layer of nodes on every periodic axis —
  the first layer moved by the axis's holonomy, recorded in the run configuration
  (``problem.holonomy``) — so that a tube or a periodic strip has no gap between its last and
  first nodes; a closed rod (d = 1) is drawn as a closed curve.
* The ``"flat"`` initial state of the surface media on a periodic axis is a periodic strip: its
  holonomy is the translation by the period along the axis's direction in space (as the
  ``"cylinder"``'s along a periodic v), so the edge across the seam carries no strain and the
  strip, moved rigidly, no force.
"""

from __future__ import annotations

import json

import matplotlib
import numpy as np
import pytest
import xarray as xr

matplotlib.use("Agg")

import cartan  # noqa: E402
from cartan.plotting import _close_seams, _closed, _seams, plot_continuation, plot_static  # noqa: E402
from cartan.problem import InitialState, Problem  # noqa: E402
from cartan.schemes.lattice import Lattice  # noqa: E402

SE3 = cartan.group("SE3")


def _translation(t) -> np.ndarray:
    H = np.eye(4)
    H[1:, 0] = t
    return H


def _tube(nu: int = 8, nv: int = 3, radius: float = 1.0, period: float = 1.0) -> np.ndarray:
    """Nodes ``[nu, nv, 3]`` of a tube around y, periodic around (closed) and along (period)."""
    phi = 2 * np.pi * np.arange(nu) / nu
    y = period * np.arange(nv) / nv
    P, Y = np.meshgrid(phi, y, indexing="ij")
    return np.stack([radius * np.sin(P), Y, radius * np.cos(P)], axis=-1)


def _config(periodic, holonomy=None) -> str:
    problem = {"medium": "cosserat-surface", "grid": {"periodic": list(periodic)}}
    if holonomy is not None:
        problem["holonomy"] = {str(a): np.asarray(H).tolist() for a, H in holonomy.items()}
    return json.dumps({"problem": problem})


# ---------------------------------------------------------------------------- closing the seams
def test_close_seams_places_the_wrap_layer_by_the_holonomy():
    tube = _tube()
    values = np.arange(tube.shape[0] * tube.shape[1], dtype=float).reshape(tube.shape[:2])
    H = {1: _translation([0.0, 1.0, 0.0])}
    closed, vals = _close_seams(tube, values, (True, True), H)
    assert closed.shape == (9, 4, 3) and vals.shape == (9, 4)
    assert np.array_equal(closed[8, :3], tube[0])                      # around: the identity closes it
    assert np.allclose(closed[:8, 3], tube[:, 0] + [0.0, 1.0, 0.0])    # along: the first ring one period on
    assert np.array_equal(vals[8, :3], values[0]) and np.array_equal(vals[:8, 3], values[:, 0])
    # a screw holonomy (a quarter turn about y with the period): the wrap is R x + t
    c, s = 0.0, 1.0
    screw = np.eye(4)
    screw[1:, 1:] = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
    screw[2, 0] = 1.0
    closed, _ = _close_seams(tube, None, (False, True), {1: screw})
    assert np.allclose(closed[:, 3], tube[:, 0] @ screw[1:, 1:].T + [0.0, 1.0, 0.0])


def test_close_seams_leaves_an_axis_open_when_it_cannot_close_it():
    tube = _tube()
    # along y with no holonomy recorded: the first ring is a period away from the last, not next to it
    closed, _ = _close_seams(tube, None, (True, True), {})
    assert closed.shape == (9, 3, 3)
    # a holonomy that does not act on these points (not positions, or the wrong size)
    assert _close_seams(tube, None, (False, True), {1: np.eye(4)}, affine=False)[0].shape == tube.shape
    assert _close_seams(tube, None, (False, True), {1: np.eye(3)})[0].shape == tube.shape
    # open axes stay open
    assert _close_seams(tube, None, (False, False), {})[0].shape == tube.shape


def test_a_closed_rod_is_closed_and_the_configuration_is_read_from_the_file():
    ring = np.stack([np.cos(np.linspace(0, 2 * np.pi, 12, endpoint=False)),
                     np.sin(np.linspace(0, 2 * np.pi, 12, endpoint=False)), np.zeros(12)], axis=-1)
    ds = xr.Dataset({"position": (("time", "u", "row"), ring[None])},
                    attrs={"cartan_config": _config([True])})
    assert _seams(ds) == ((True,), {})
    closed, _ = _closed(ds, ring)
    assert closed.shape == (13, 3) and np.array_equal(closed[-1], closed[0])
    ds.attrs["cartan_config"] = "not json"
    assert _seams(ds) == ((), {}) and _closed(ds, ring)[0].shape == ring.shape


def test_the_run_configuration_records_the_holonomy():
    med = cartan.medium("cosserat-surface")
    grid = cartan.Grid((6, 3), length=(2 * np.pi, 1.0), periodic=(True, True))
    cfg = Problem(med, grid, med.initial_state(grid, "cylinder")).to_dict()
    assert cfg["holonomy"] == {"1": _translation([0.0, 1.0, 0.0]).tolist()}
    plate = cartan.Grid((4, 3), length=(1.0, 1.0))
    assert "holonomy" not in Problem(med, plate, med.initial_state(plate, "flat")).to_dict()


def test_a_static_tube_is_drawn_without_a_gap():
    """The equilibrium panel of a tube periodic around and along (a translation holonomy):
    n_u × n_v faces, the seams' included (an open drawing has (n_u − 1)(n_v − 1))."""
    nu, nv = 8, 3
    tube = _tube(nu, nv)
    H = {1: _translation([0.0, 1.0, 0.0])}
    ds = xr.Dataset(
        {"position": (("time", "u", "v", "row"), 1.1 * tube[None]), "initial_position": (("u", "v", "row"), tube),
         "newton_residual": ("iteration", [1.0, 1e-12])},
        attrs={"cartan_config": _config([True, True], H)})
    fig = plot_static(ds)
    ax = next(a for a in fig.axes if a.name == "3d")
    faces = [c for c in ax.collections if type(c).__name__ == "Poly3DCollection"]
    assert len(faces) == 1 and len(faces[0].get_facecolor()) == nu * nv
    ds.attrs["cartan_config"] = _config([False, False])
    ax = next(a for a in plot_static(ds).axes if a.name == "3d")
    faces = [c for c in ax.collections if type(c).__name__ == "Poly3DCollection"]
    assert len(faces[0].get_facecolor()) == (nu - 1) * (nv - 1)


def test_the_node_lines_of_a_continuation_cross_the_seams():
    """The shapes along a continuation path: the lines around a closed tube have n_u + 1 points,
    the last the first; the lines along it end one period on."""
    nu, nv = 8, 3
    tube = _tube(nu, nv).reshape(nu * nv, 3)
    H = {1: _translation([0.0, 1.0, 0.0])}
    ds = xr.Dataset({"load_factor": ("path", [0.0, 1.0]), "monitor": ("path", [0.0, 0.1]),
                     "position": (("path", "node", "row"), np.stack([tube, 1.1 * tube]))},
                    attrs={"grid_shape": [nu, nv], "cartan_config": _config([True, True], H)})
    ax = next(a for a in plot_continuation(ds).axes if a.name == "3d")
    lines = [np.array(line.get_data_3d()).T for line in ax.get_lines()]
    around = [p for p in lines if len(p) == nu + 1]
    along = [p for p in lines if len(p) == nv + 1]
    assert len(around) == 2 * (nv + 1) and len(along) == 2 * (nu + 1)
    assert all(np.allclose(p[-1], p[0]) for p in around)
    assert all(np.isclose(p[-1, 1] - p[0, 1], 1.0) for p in along)


# ---------------------------------------------------------------------------- the flat periodic strip
def _force(med, grid, init: InitialState) -> float:
    sch = Lattice(Problem(med, grid, init))
    return float(np.max(np.abs(sch.internal_force(sch.initial_state()))))


@pytest.mark.parametrize("periodic", [(True, False), (False, True), (True, True)])
def test_a_flat_periodic_strip_has_no_force_across_its_seam(periodic):
    """Flat, translated and turned by a rotation (origin, rotation): the holonomy on each periodic
    axis α is the translation by L_α·rotation·e_α, and the closing edges carry no strain — the
    force is at round-off (its scale without the holonomy: E h, 0.1 here)."""
    med = cartan.medium("cosserat-surface", E=1.0, thickness=0.1)
    grid = cartan.Grid((5, 4), length=(1.0, 0.6), periodic=periodic)
    rot = SE3.exp(np.array([0.0, 0.0, 0.0, 0.3, -0.5, 0.8]))[1:, 1:]
    init = med.initial_state(grid, "flat", origin=[0.4, -1.0, 2.0], rotation=rot)
    H = init.holonomy
    assert sorted(H) == [a for a in range(2) if periodic[a]]
    for a, Ha in H.items():
        assert np.allclose(Ha, _translation(grid.length[a] * rot[:, a]), atol=1e-15)
    assert _force(med, grid, init) <= 1e-13
    # a rigid motion of the strip moves its holonomy with it (H → g H g⁻¹) and keeps it force-free
    g = SE3.exp(np.array([0.2, 0.1, -0.3, 0.4, 0.2, -0.1]))
    moved = InitialState(Phi=SE3.compose(g, init.Phi),
                         holonomy={a: g @ Ha @ np.linalg.inv(g) for a, Ha in H.items()})
    assert _force(med, grid, moved) <= 1e-13
    # without the holonomy the closing edge spans the strip backwards: a large force
    assert _force(med, grid, InitialState(Phi=init.Phi)) > 1e-3


def test_the_flat_strip_and_the_cylinder_close_their_axial_axis_alike():
    """A periodic v: both shapes repeat after L_v along y (their axial direction, e₂ = y)."""
    med = cartan.medium("cosserat-surface")
    grid = cartan.Grid((6, 3), length=(2 * np.pi, 1.5), periodic=(True, True))
    cyl = med.initial_state(grid, "cylinder").holonomy
    flat = med.initial_state(cartan.Grid((6, 3), length=(1.0, 1.5), periodic=(False, True)), "flat").holonomy
    assert np.array_equal(cyl[1], flat[1]) and np.array_equal(flat[1], _translation([0.0, 1.5, 0.0]))
    # the surface media on SE(3) share the initial states: a Kirchhoff–Love strip as well
    kl = cartan.medium("kirchhoff-love").initial_state(cartan.Grid((4, 3), periodic=(True, False)), "flat")
    assert np.allclose(kl.holonomy[0], _translation([1.0, 0.0, 0.0]))
