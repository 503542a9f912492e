"""Pictures of surfaces (a d = 2 medium in space): the deformed surface in 3D, coloured by a
chosen node variable (:func:`cartan.plotting.plot_run`, ``cartan plot --field``)."""

from __future__ import annotations

import matplotlib
import numpy as np
import pytest
import xarray as xr

matplotlib.use("Agg")

from cartan.plotting import plot_run  # noqa: E402


def _surface_run(nt: int = 3, nu: int = 5, nv: int = 4) -> xr.Dataset:
    """A fabricated run of a plate bending into a cylinder: ``position [time, u, v, 3]``."""
    t = np.linspace(0.0, 1.0, nt)
    u, v = np.linspace(0.0, 1.0, nu), np.linspace(0.0, 0.6, nv)
    U, V = np.meshgrid(u, v, indexing="ij")
    pos = np.zeros((nt, nu, nv, 3))
    for i, ti in enumerate(t):
        pos[i, ..., 0], pos[i, ..., 1], pos[i, ..., 2] = U, V, -0.3 * ti * U**2
    zeros = np.zeros(nt)
    return xr.Dataset(
        {"position": (("time", "u", "v", "row"), pos), "kinetic_energy": ("time", zeros),
         "potential_energy": ("time", zeros + 1.0),
         "mean_curvature": (("time", "u", "v"), np.broadcast_to(0.3 * t[:, None, None], (nt, nu, nv)).copy()),
         "total_momentum": (("time", "component"), np.zeros((nt, 6)))},
        coords={"time": t})


def test_a_surface_is_drawn_in_3d_coloured_by_a_field(tmp_path):
    ds = _surface_run()
    fig = plot_run(ds, tmp_path / "s.png", field="mean_curvature")
    surface_axes = [ax for ax in fig.axes if ax.name == "3d"]
    assert len(surface_axes) == 1 and surface_axes[0].collections  # the faces (and the initial wireframe)
    assert (tmp_path / "s.png").stat().st_size > 0
    plot_run(ds)  # default colouring: the displacement's norm


def test_an_unknown_field_names_the_choices():
    with pytest.raises(ValueError, match="node fields: mean_curvature"):
        plot_run(_surface_run(), field="no_such_field")


# ---------------------------------------------------------------------------- solids (d = 3)
def _solid_run(nt: int = 2, n: int = 4) -> xr.Dataset:
    """A fabricated run of a unit block sheared along x: ``position [time, u, v, w, 3]``,
    ``x = u + γ t w``, and a node field ``sigma = t u`` with units."""
    t = np.linspace(0.0, 1.0, nt)
    c = np.linspace(0.0, 1.0, n)
    U, V, W = np.meshgrid(c, c, c, indexing="ij")
    pos = np.zeros((nt, n, n, n, 3))
    for i, ti in enumerate(t):
        pos[i, ..., 0], pos[i, ..., 1], pos[i, ..., 2] = U + 0.3 * ti * W, V, W
    zeros = np.zeros(nt)
    sigma = t[:, None, None, None] * U[None]
    return xr.Dataset(
        {"position": (("time", "u", "v", "w", "row"), pos, {"units": "length"}),
         "kinetic_energy": ("time", zeros), "potential_energy": ("time", zeros + 1.0),
         "sigma": (("time", "u", "v", "w"), sigma, {"long_name": "normal stress", "units": "force/length^2"}),
         "total_momentum": (("time", "component"), np.zeros((nt, 6)))},
        coords={"time": t, "u": c, "v": c, "w": c})


def _axes3d(fig):
    return [ax for ax in fig.axes if ax.name == "3d"]


def _vertices(poly) -> np.ndarray:
    """The 3D vertices ``[n, k, 3]`` of a Poly3DCollection (matplotlib keeps them privately:
    ``_faces`` from 3.10, ``_vec`` before)."""
    if hasattr(poly, "_faces"):
        return np.asarray(poly._faces)
    n = len(poly._segslices)
    return np.asarray(poly._vec[:3].T).reshape(n, -1, 3)


def _faces_of(ax):
    """The polygons ``[n, 4, 3]`` of the (single) polygon collection of a 3D axes, and the collection."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    polys = [c for c in ax.collections if isinstance(c, Poly3DCollection)]
    assert len(polys) == 1
    return _vertices(polys[0]), polys[0]


def test_a_solid_is_drawn_as_its_outer_faces_coloured_by_a_field(tmp_path):
    ds = _solid_run()
    fig = plot_run(ds, tmp_path / "block.png", field="sigma")
    assert (tmp_path / "block.png").stat().st_size > 0
    (ax,) = _axes3d(fig)
    quads, poly = _faces_of(ax)
    n = ds.sizes["u"]
    assert quads.shape == (6 * (n - 1) ** 2, 4, 3)  # six faces of (n - 1)² cells each
    # every vertex lies on the boundary of the deformed block (u, v or w at 0 or 1 in material terms)
    last = ds["position"].values[-1]
    boundary = np.concatenate([f.reshape(-1, 3) for f in
                               (last[0], last[-1], last[:, 0], last[:, -1], last[:, :, 0], last[:, :, -1])])
    dist = np.min(np.linalg.norm(quads.reshape(-1, 1, 3) - boundary[None], axis=-1), axis=1)
    assert np.max(dist) <= 1e-12
    # the faces take several colours (sigma = u varies along u), the colour bar names the field and units
    assert len(np.unique(np.round(poly.get_facecolor(), 6), axis=0)) >= n - 1
    labels = [a.get_ylabel() for a in fig.axes if a.name != "3d"]
    assert "normal stress [force/length^2]" in labels
    # the default colouring is the displacement's norm, in the position's units
    fig = plot_run(ds)
    assert "|displacement| [length]" in [a.get_ylabel() for a in fig.axes]


def test_a_slice_of_a_solid_is_drawn_on_the_same_colour_scale():
    ds = _solid_run()
    fig = plot_run(ds, field="sigma", slice="v=1")
    block, cut = _axes3d(fig)
    assert "slice v" in cut.get_title() and "node 1" in cut.get_title()
    verts, surface = _faces_of(cut)
    verts = verts.reshape(-1, 3)
    n = ds.sizes["u"]
    plane = ds["position"].values[-1][:, 1]  # the material plane v = node 1, deformed
    assert len(surface.get_facecolor()) == (n - 1) ** 2
    dist = np.min(np.linalg.norm(verts[:, None] - plane.reshape(1, -1, 3), axis=-1), axis=1)
    assert np.max(dist) <= 1e-12
    limits = [a.get_ylim() for a in fig.axes if a.get_label() == "<colorbar>"]
    assert len(limits) == 2 and limits[0] == limits[1]  # both colour bars show the same scale
    assert np.allclose(limits[0], (0.0, 1.0))  # sigma = t u at t = 1
    # the default node index is the middle one
    fig = plot_run(ds, slice="w")
    assert "node 2" in _axes3d(fig)[1].get_title()


@pytest.mark.parametrize("spec, message", [
    ("q", "choose an axis u, v, w"),
    ("u=4", r"out of range, 0 ≤ INDEX ≤ 3"),
    ("u=x", "must be an integer"),
])
def test_a_bad_slice_names_the_choices(spec, message):
    with pytest.raises(ValueError, match=message):
        plot_run(_solid_run(), slice=spec)


def test_only_a_solid_can_be_sliced():
    with pytest.raises(ValueError, match="only a solid .* d = 2"):
        plot_run(_surface_run(), slice="u")


def test_cli_plot_slice_option(tmp_path):
    from click.testing import CliRunner

    from cartan.cli import main

    run = tmp_path / "block.nc"
    _solid_run().to_netcdf(run)
    res = CliRunner().invoke(main, ["plot", str(run), "-o", str(tmp_path / "b.png"), "--slice", "w=1",
                                    "--field", "sigma"])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "b.png").stat().st_size > 0
    res = CliRunner().invoke(main, ["plot", str(run), "-o", str(tmp_path / "c.png"), "--slice", "z"])
    assert res.exit_code == 2
    assert res.stderr.count("\n") == 1 and res.stderr.startswith(f"cartan: error: {run}: slice 'z': ")
    assert not (tmp_path / "c.png").exists()


@pytest.fixture(scope="module")
def solid_run() -> xr.Dataset:
    """A 4³ cosserat-solid block clamped at u = 0 and pressed on u = 1, a short run."""
    import cartan

    solid = cartan.medium("cosserat-solid")
    grid = cartan.Grid((4, 4, 4), length=1.0, periodic=False)
    problem = cartan.Problem(solid, grid, solid.initial_state(grid, "undeformed"),
                             boundaries={"u-start": cartan.Clamped(),
                                         "u-end": cartan.Free(load=[-0.2, 0.0, 0.0, 0.0, 0.0, 0.0])})
    # the reference path: the picture is tested here, the compiled loop by the solid's own tests
    return cartan.simulate(problem, integrator="lie-verlet", dt=0.02, t_end=0.6, save_every=10, progress=False,
                           compiled=False)


def test_a_cosserat_solid_run_is_drawn_as_a_block(solid_run, tmp_path):
    fig = plot_run(solid_run, tmp_path / "solid.png", field="displacement_x", slice="u")
    assert (tmp_path / "solid.png").stat().st_size > 0
    block, cut = _axes3d(fig)
    quads, poly = _faces_of(block)
    assert quads.shape == (6 * 9, 4, 3)
    # the pressed face moved against the load: the static end shortening is 0.2/E ≈ 0.065 at the
    # default moduli (E = G(3λ + 2G)/(λ + G), G = μ + κ/2), reached in about one wave transit
    # (c_p = √(λ + 2μ) ≈ 1.7); the faces drawn end at least half of it short of x = 1
    E = 1.25 * (3.0 + 2.5) / 2.25
    assert np.max(quads[..., 0]) < 1.0 - 0.5 * 0.2 / E
    assert cut.get_title() == "slice u = 0.6667 (node 2)"  # the middle node of four along u ∈ [0, 1]


# ---------------------------------------------------------------------------- a medium's own picture
def test_the_medium_is_read_from_the_file():
    from cartan.plotting import medium_name

    ds = _surface_run()
    assert medium_name(ds) is None
    ds.attrs["source"] = "cartan 0.1.0; medium 'cosserat-surface' from cartan 0.1.0"
    assert medium_name(ds) == "cosserat-surface"
    ds.attrs["cartan_config"] = '{"problem": {"medium": "relativistic-rod"}}'
    assert medium_name(ds) == "relativistic-rod"  # the run configuration first


def test_a_medium_without_a_picture_gets_the_generic_one():
    from cartan.medium import Medium

    assert Medium.draw(_surface_run(), None) is False  # the default draws nothing
    ds = _surface_run()
    ds.attrs["source"] = "cartan 0.1.0; medium 'no-such-medium' from elsewhere 1.0"  # not installed here
    fig = plot_run(ds)
    assert len(_axes3d(fig)) == 1 and "energies" in [a.get_title() for a in fig.axes]


@pytest.fixture(scope="module")
def string_run() -> xr.Dataset:
    """A collapsing Nambu–Goto loop (32 nodes) over a quarter of its period."""
    import math

    import cartan

    rod = cartan.medium("relativistic-rod")
    grid = cartan.Grid(32, length=2 * math.pi, periodic=True)
    problem = cartan.Problem(rod, grid, rod.initial_state(grid, "loop"))
    h = grid.spacing[0]
    # the reference path: the picture is tested here, the compiled loop by the string's own tests
    return cartan.simulate(problem, integrator="lie-verlet", dt=0.5 * h, t_end=8 * h, save_every=2, progress=False,
                           compiled=False)


def test_the_relativistic_string_draws_its_worldlines(string_run, tmp_path, monkeypatch):
    from cartan_relativistic.pictures import main as pictures_main
    from cartan_relativistic.string import RelativisticRod

    from cartan.plotting import medium_name

    assert medium_name(string_run) == "relativistic-rod"
    calls = []
    original = RelativisticRod.draw.__func__

    def spy(cls, ds, fig):
        calls.append(ds)
        return original(cls, ds, fig)

    monkeypatch.setattr(RelativisticRod, "draw", classmethod(spy))
    fig = plot_run(string_run, tmp_path / "string.png")
    assert len(calls) == 1 and calls[0] is string_run
    titles = [a.get_title() for a in fig.axes]
    assert "string at equal lab times" in titles and any(t.startswith("worldlines") for t in titles)
    assert "energies" not in titles
    # a worldline per drawn node: lab time against the distance from the centre, from t = 0
    (world,) = [a for a in fig.axes if a.get_title().startswith("worldlines")]
    lines = [ln for ln in world.get_lines() if ln.get_linestyle() == "-"]
    assert len(lines) == 8 and all(np.isclose(ln.get_ydata()[0], 0.0) for ln in lines)
    assert (tmp_path / "string.png").stat().st_size > 0
    # --generic (or a field) bypasses the medium's picture
    fig = plot_run(string_run, generic=True)
    assert len(calls) == 1 and "energies" in [a.get_title() for a in fig.axes]
    # the module's own command line still works on a run file
    string_run.to_netcdf(tmp_path / "string.nc")
    assert pictures_main([str(tmp_path / "string.nc"), str(tmp_path / "own.png")]) == 0
    assert (tmp_path / "own.png").stat().st_size > 0


def test_a_medium_picture_that_declines_leaves_the_generic_one(string_run):
    ds = string_run.drop_vars(["lab_x"])  # the string's picture needs its lab-frame outputs
    fig = plot_run(ds)
    assert "energies" in [a.get_title() for a in fig.axes]


def test_a_static_solid_is_drawn_over_its_initial_block():
    run = _solid_run(nt=2)
    ds = run.isel(time=[-1])
    ds["initial_position"] = (("u", "v", "w", "row"), run["position"].values[0])
    ds["newton_residual"] = ("iteration", np.array([1.0, 1e-3, 1e-9]))
    fig = plot_run(ds, slice="u=0")
    block, cut = _axes3d(fig)
    assert block.get_title() == "equilibrium" and "node 0" in cut.get_title()
    # coloured by the displacement from the initial block: zero on the sheared block's base w = 0
    bars = [a.get_ylim() for a in fig.axes if a.name != "3d" and a.get_label() == "<colorbar>"]
    assert len(bars) == 2 and bars[0] == bars[1]  # the block and the slice on one colour scale
    assert bars[0][0] == 0.0 and np.isclose(bars[0][1], 0.3)  # |Δx| = 0.3 w, largest at w = 1
    assert any(a.get_title().startswith("Newton") for a in fig.axes)
