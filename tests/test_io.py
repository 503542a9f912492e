"""Run output: Dataset layout and attributes, netCDF round trip, atomic writes, and safe files:
checksums, only regular files replaced, stale temporary files, checkpoints checked field by field."""

from __future__ import annotations

import datetime
import json
import math
import os
import pathlib
import stat

import numpy as np
import pytest
import xarray as xr
from test_scene import CANTILEVER, toy_registry
from toys import QuadraticMedium

import cartan
from cartan import io
from cartan.api import Grid, InitialState, Problem, load_scene, simulate
from cartan.plugins import reset_registry
from cartan.schemes.base import State


@pytest.fixture(scope="module")
def run():
    """A short toy-rod cantilever run (gravity, end load, damping) saved every 2 steps."""
    toy_registry()
    try:
        yield simulate(load_scene(CANTILEVER))
    finally:
        reset_registry()


def test_layout(run):
    ds = run
    assert dict(ds.sizes) == {"time": 6, "node": 9, "edge": 8, "component": 6, "row": 3, "col": 3}
    assert ds["X"].dims == ("time", "edge", "component")
    for name in ("N", "S"):
        assert ds[name].dims == ("time", "node", "component")
    assert ds["position"].dims == ("time", "node", "row")
    assert ds["frame"].dims == ("time", "node", "row", "col")
    for name in (
        "kinetic_energy",
        "potential_energy",
        "dissipated_energy",
        "external_work",
        "integrability_residual",
        "closure_residual",
        "group_defect",
    ):
        assert ds[name].dims == ("time",), name
    assert ds["total_momentum"].dims == ("time", "component")
    np.testing.assert_allclose(ds["time"], np.arange(6) * 0.02, atol=1e-15)
    np.testing.assert_array_equal(ds["step"], np.arange(0, 11, 2))
    np.testing.assert_allclose(ds["u"], np.linspace(0, 1, 9))
    np.testing.assert_allclose(ds["u_edge"], (np.arange(8) + 0.5) / 8)
    assert list(ds["row"].values) == ["x", "y", "z"] and list(ds["col"].values) == ["d1", "d2", "d3"]


def test_fields_match_the_configuration(run):
    ds = run
    # straight rod along x at t = 0, clamped end fixed, frames orthonormal, strains at rest
    np.testing.assert_allclose(ds.position.isel(time=0).sel(row="x"), np.linspace(0, 1, 9), atol=1e-14)
    np.testing.assert_array_equal(ds.position.isel(node=0), 0.0 * ds.position.isel(node=0))
    R = ds.frame.values
    np.testing.assert_allclose(
        np.einsum("...ji,...jk->...ik", R, R), np.broadcast_to(np.eye(3), R.shape), atol=1e-12
    )
    np.testing.assert_allclose(ds.X.isel(time=0), np.broadcast_to([1, 0, 0, 0, 0, 0], (8, 6)), atol=1e-14)
    assert float(ds.position.isel(time=-1, node=-1).sel(row="z")) < 0  # sags under gravity and end load
    assert np.all(ds.dissipated_energy.values[1:] > 0) and np.all(ds.external_work.values[1:] > 0)
    assert float(ds.group_defect.max()) < 1e-12
    # the lattice keeps exact integrability: stored strains are those of the frames
    assert float(ds.integrability_residual.max()) < 1e-10


def test_every_variable_has_units_and_long_name(run):
    for name, var in run.variables.items():
        if name in ("row", "col"):
            assert "long_name" in var.attrs
            continue
        assert var.attrs.get("units"), name
        assert var.attrs.get("long_name"), name
    assert run.kinetic_energy.attrs["units"] == "energy"
    assert run.position.attrs["units"] == "length"
    assert run.time.attrs["units"] == "time"


def test_global_attributes(run):
    a = run.attrs
    assert a["Conventions"] == "CF-1.11"
    assert "toy-rod" in a["title"]
    stamp, command = a["history"].split(" ", 1)
    assert datetime.datetime.fromisoformat(stamp).tzinfo is not None
    assert command.startswith("cartan.simulate(scene 'toy-cantilever'")
    assert a["source"].startswith(f"cartan {cartan.__version__}")
    assert "local" in a["source"]  # the distribution of the in-process toy plugin is named
    cfg = json.loads(a["cartan_config"])
    assert cfg["problem"]["medium"] == "toy-rod"
    assert cfg["problem"]["boundaries"]["start"] == {"kind": "clamped"}
    assert (
        cfg["run"]["integrator"] == "lie-verlet"
        and cfg["run"]["dt"] == 0.01
        and cfg["run"]["save_every"] == 2
    )
    assert cfg["run"]["dt_max"] > 0
    assert (
        cfg["counters"]["nstep"] == 10
        and cfg["counters"]["nforce"] >= 10
        and cfg["counters"]["wall_time"] > 0
    )
    assert cfg["scene"]["name"] == "toy-cantilever"


def test_write_and_open_round_trip(run, tmp_path):
    path = io.write_dataset(run, tmp_path / "run.nc")
    back = cartan.api.open(path)
    xr.testing.assert_identical(back, run)
    assert sorted(os.listdir(tmp_path)) == ["run.nc"]
    lazy = io.open_dataset(path, lazy=True)
    try:
        xr.testing.assert_identical(lazy.load(), run)
    finally:
        lazy.close()


def test_atomic_write_leaves_previous_file_intact(run, tmp_path, monkeypatch):
    path = tmp_path / "run.nc"
    io.write_dataset(run.isel(time=slice(0, 2)), path)
    before = path.read_bytes()

    real = xr.Dataset.to_netcdf

    def failing(self, target, *args, **kwargs):
        real(self, target, *args, **kwargs)  # the temporary file is complete ...
        raise OSError("disk full")  # ... but something fails before the rename

    monkeypatch.setattr(xr.Dataset, "to_netcdf", failing)
    with pytest.raises(OSError, match="disk full"):
        io.write_dataset(run, path)
    assert sorted(os.listdir(tmp_path)) == ["run.nc"]
    assert path.read_bytes() == before

    with pytest.raises(OSError, match="disk full"):
        io.write_dataset(run, tmp_path / "new.nc")
    assert sorted(os.listdir(tmp_path)) == ["run.nc"]


def test_checkpoint_group_is_separate(run, tmp_path):
    from cartan.schemes.base import State

    st = State(
        0.25, np.arange(6.0).reshape(1, 6), {"Phi": np.eye(4)[None]}, {"nstep": 3, "external_work": 0.1}
    )
    path = io.write_dataset(
        run, tmp_path / "run.nc", checkpoint=io.checkpoint_dataset(st, {"nframes": 2, "x": [1]})
    )
    xr.testing.assert_identical(cartan.api.open(path), run)  # the root group is the run
    state, info, records, attrs = io.read_checkpoint(path)
    assert state.t == 0.25 and state.scalars == {"nstep": 3, "external_work": 0.1}
    np.testing.assert_array_equal(state.S, st.S)
    np.testing.assert_array_equal(state.arrays["Phi"], st.arrays["Phi"])
    assert info == {"nframes": 2, "x": [1]}
    assert len(records["time"]) == 2 and len(records["X"]) == 2
    assert attrs["Conventions"] == "CF-1.11"
    with pytest.raises(ValueError, match="no checkpoint"):
        io.read_checkpoint(io.write_dataset(run, tmp_path / "plain.nc"))


class SO3Medium(QuadraticMedium):
    """Quadratic medium on SO(3) with the frame bundle of the sphere as its space."""

    def __init__(self):
        super().__init__("SO3", mass=[1.0, 1.0, 2.0], stiffness=[1.0, 1.0, 2.0], rest=[0.0, 0.0, 1.0])
        self.space = cartan.space("frame-S2")


def test_frame_bundle_of_the_sphere_gives_position_and_frame():
    medium = SO3Medium()
    grid = Grid(7, 1.0)
    Phi = medium.group.exp(grid.coordinates(0)[:, None] * np.array([0.3, 0.0, 1.0]))
    ds = simulate(Problem(medium, grid, InitialState(Phi=Phi)), dt=0.01, t_end=0.02, save_every=1)
    np.testing.assert_allclose(ds.frame.isel(time=0), Phi, atol=1e-14)
    np.testing.assert_allclose(ds.position.isel(time=0), Phi[:, :, 2], atol=1e-14)  # r·e₃ with r = 1
    assert "field" not in ds


def test_field_valued_space_gives_field():
    medium = SO3Medium()
    medium.space = cartan.space("sphere", n=2)
    grid = Grid(7, 1.0)
    Phi = medium.group.exp(grid.coordinates(0)[:, None] * np.array([0.3, 0.0, 1.0]))
    ds = simulate(Problem(medium, grid, InitialState(Phi=Phi)), dt=0.01, t_end=0.02, save_every=1)
    assert "position" not in ds and "frame" not in ds
    assert ds["field"].dims[:2] == ("time", "node")
    np.testing.assert_allclose(ds.field.isel(time=0), Phi[:, :, 2], atol=1e-14)  # Φ·e₃


class PlateMedium(QuadraticMedium):
    """Quadratic SE(3) medium on a 2-D grid, additive over the axes."""

    material_dim = 2
    separable_axes = True

    def __init__(self):
        super().__init__("SE3", mass=np.ones(6), stiffness=np.full(6, 5.0))

    def rest_strain(self):
        return np.eye(6)[:2]

    def potential(self, X):
        d = X - self.rest_strain()
        return 0.5 * np.einsum("...ak,k,...ak->...", d, self.C, d)

    def stress(self, X):
        return (X - self.rest_strain()) * self.C


def test_two_dimensional_layout():
    medium = PlateMedium()
    grid = Grid((4, 3), (1.0, 0.5))
    u, v = np.meshgrid(grid.coordinates(0), grid.coordinates(1), indexing="ij")
    xi = u[..., None] * np.eye(6)[0] + v[..., None] * np.eye(6)[1]
    N = np.zeros((4, 3, 6))
    N[..., 2] = 0.1 * u
    ds = simulate(
        Problem(medium, grid, InitialState(Phi=medium.group.exp(xi), N=N)),
        dt=0.01,
        t_end=0.02,
        save_every=1,
        scheme_options={"track_frames": True},
    )
    assert ds["X"].dims == ("time", "u", "v", "axis", "component")
    assert ds["position"].dims == ("time", "u", "v", "row")
    assert list(ds["axis"].values) == ["u", "v"]
    np.testing.assert_allclose(ds["v"], [0, 0.25, 0.5])
    np.testing.assert_allclose(
        ds.X.isel(time=0).sel(axis="v"), np.broadcast_to(np.eye(6)[1], (4, 3, 6)), atol=1e-14
    )


# ---------------------------------------------------------------------------- hardening: files
def damage_data(path, value: float) -> None:
    """Flip one byte of the stored float64 ``value`` (the first occurrence in the file): a
    damaged data chunk, as a bad disk sector would leave it."""
    data = bytearray(pathlib.Path(path).read_bytes())
    at = data.find(np.float64(value).tobytes())
    assert at >= 0, f"{value!r} is not stored in {path}"
    data[at + 3] ^= 0xFF
    pathlib.Path(path).write_bytes(bytes(data))


def test_variables_carry_fletcher32_checksums(run, tmp_path):
    import netCDF4

    st = State(0.1, np.ones((2, 6)), {"Phi": np.eye(4)[None]}, {"nstep": 1})
    path = io.write_dataset(run, tmp_path / "run.nc", checkpoint=io.checkpoint_dataset(st, {"nframes": 2}))
    with netCDF4.Dataset(path) as nc:
        for name in ("X", "position", "kinetic_energy", "time", "step"):
            assert nc.variables[name].filters()["fletcher32"], name
        assert nc.groups["checkpoint"].variables["S"].filters()["fletcher32"]


def test_damaged_file_is_detected_when_read(run, tmp_path):
    path = io.write_dataset(run, tmp_path / "run.nc")
    damage_data(path, float(run.time[-1]))
    with pytest.raises(ValueError, match=r"run\.nc: damaged or not a netCDF file"):
        cartan.open(path)
    (tmp_path / "junk.nc").write_bytes(b"not a netCDF file at all")
    with pytest.raises(ValueError, match="damaged or not a netCDF file"):
        cartan.open(tmp_path / "junk.nc")
    with pytest.raises(FileNotFoundError):
        cartan.open(tmp_path / "missing.nc")
    with pytest.raises(ValueError, match="is a device, not a regular file"):
        cartan.open("/dev/zero")
    with pytest.raises(ValueError, match="is a directory, not a regular file"):
        io.read_checkpoint(tmp_path)


def test_only_regular_files_are_replaced(run, tmp_path):
    with pytest.raises(ValueError, match="/dev/null: is a device; only regular files are replaced"):
        io.write_dataset(run, "/dev/null")
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
    (tmp_path / "folder.nc").mkdir()
    with pytest.raises(ValueError, match="is a directory"):
        io.write_dataset(run, tmp_path / "folder.nc")
    assert sorted(os.listdir(tmp_path)) == ["folder.nc"]


def test_check_output(tmp_path):
    assert io.check_output(tmp_path / "new.nc") == tmp_path / "new.nc"
    with pytest.raises(ValueError, match="the output folder .*missing.* does not exist"):
        io.check_output(tmp_path / "missing" / "out.nc")
    (tmp_path / "file").write_text("")
    with pytest.raises(ValueError, match="is not a folder"):
        io.check_output(tmp_path / "file" / "out.nc")
    with pytest.raises(ValueError, match="is a device"):
        io.check_output("/dev/null")
    assert io.lastgood_path(tmp_path / "out.nc") == tmp_path / "out.lastgood.nc"
    assert io.lastgood_path("run") == pathlib.Path("run.lastgood.nc")
    assert io.lastgood_path("a.lastgood.nc") == pathlib.Path("a.lastgood.lastgood.nc")  # never the output


def test_stale_temporary_files_are_removed_by_the_next_write(run, tmp_path):
    """What ``kill -9`` during a write leaves behind is cleaned by the next write to the target;
    the temporary files of live writers and of other targets are left alone."""
    dead = 2**22 + 12345  # above the usual pid_max: no such process
    stale = [f".run.nc.{dead}-0123456789abcdef.tmp", ".run.nc.ab_c1234.tmp"]
    kept = [f".run.nc.{os.getpid()}-0123456789abcdef.tmp", f".run.nc.x.{dead}-0123456789abcdef.tmp",
            f".other.nc.{dead}-0123456789abcdef.tmp"]
    for name in stale + kept:
        (tmp_path / name).write_bytes(b"half a file")
    io.write_dataset(run, tmp_path / "run.nc")
    assert sorted(os.listdir(tmp_path)) == sorted(["run.nc", *kept])


@pytest.mark.parametrize("error", [KeyboardInterrupt, SystemExit, MemoryError])
def test_temporary_file_is_removed_on_every_exit(run, tmp_path, monkeypatch, error):
    real = xr.Dataset.to_netcdf

    def interrupted(self, target, *args, **kwargs):
        real(self, target, *args, **kwargs)
        raise error()

    monkeypatch.setattr(xr.Dataset, "to_netcdf", interrupted)
    with pytest.raises(error):
        io.write_dataset(run, tmp_path / "run.nc")
    assert os.listdir(tmp_path) == []


def _checkpoint_file(run, tmp_path):
    st = State(0.1, np.ones((9, 6)), {"Phi": np.broadcast_to(np.eye(4), (9, 4, 4)).copy()}, {"nstep": 10})
    info = {"problem": {}, "run": {"integrator": "lie-verlet", "scheme": "lattice", "dt": 0.01, "dt_max": 0.03,
                                   "t_end": 0.1, "save_every": 2, "checkpoint_every": None},
            "counters": {"nstep": 10, "nforce": 11, "wall_time": 0.1}, "scene": None, "step": 10, "nsaves": 5,
            "nframes": 6, "e0": 0.5, "scale": 1.0, "scale_set": 1}
    return io.write_dataset(run, tmp_path / "run.nc", checkpoint=io.checkpoint_dataset(st, info))


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (lambda m: m.update(t=math.nan), "t must be a finite number, got nan"),
        (lambda m: m.pop("t"), "t is missing"),
        (lambda m: m["scalars"].update(nstep="ten"), "scalars must be a table of finite numbers"),
        (lambda m: m.update(arrays=["Phi", "Psi"]), "the variable 'array_Psi' is missing"),
        (lambda m: m.update(nframes=7), r"nframes must be an integer in 0\.\.6"),
        (lambda m: m.update(nframes=-1), "nframes must be an integer"),
        (lambda m: m.update(t=0.01), "the last saved time 0.1 is after the checkpoint time 0.01"),
        (lambda m: m["run"].pop("dt"), "run.dt is missing"),
        (lambda m: m["run"].update(dt=-0.01), "run.dt must be > 0"),
        (lambda m: m["run"].update(dt_max=math.nan), "run.dt_max must be a number"),
        (lambda m: m["run"].update(save_every=0), "run.save_every must be an integer ≥ 1"),
        (lambda m: m["run"].update(integrator=3), "run.integrator must be a name"),
        (lambda m: m.pop("counters"), "counters is missing"),
        (lambda m: m["counters"].update(nforce=1.5), "counters.nforce must be an integer"),
        (lambda m: m.update(step=-1), "step must be an integer ≥ 0"),
        (lambda m: m.update(e0=math.inf), "e0 must be a finite number"),
        (lambda m: m.update(problem=[]), "problem must be a table"),
        (lambda m: m.update(scene="x"), "scene must be a table"),
    ],
)
def test_checkpoints_are_checked_field_by_field(run, tmp_path, edit, expected):
    import netCDF4

    path = _checkpoint_file(run, tmp_path)
    state, info, records, attrs = io.read_checkpoint(path)
    io.check_run_info(info, path)  # the undamaged file passes
    with netCDF4.Dataset(path, "a") as nc:
        group = nc.groups[io.CHECKPOINT_GROUP]
        meta = json.loads(group.getncattr("cartan_checkpoint"))
        edit(meta)
        group.setncattr("cartan_checkpoint", json.dumps(meta))
    with pytest.raises(ValueError, match=f"damaged checkpoint: {expected}"):
        _, info, _, _ = io.read_checkpoint(path)
        io.check_run_info(info, path)


def test_damaged_checkpoint_arrays_and_times(run, tmp_path):
    import netCDF4

    for damage, expected in (("S", "S holds non-finite values"), ("time", "the saved times are not finite"),
                             ("json", "cartan_checkpoint is missing or not a JSON object")):
        path = _checkpoint_file(run, tmp_path)
        with netCDF4.Dataset(path, "a") as nc:
            if damage == "S":
                nc.groups[io.CHECKPOINT_GROUP].variables["S"][0, 0] = np.nan
            elif damage == "time":
                nc.variables["time"][2] = np.nan
            else:
                nc.groups[io.CHECKPOINT_GROUP].setncattr("cartan_checkpoint", "{")
        with pytest.raises(ValueError, match=expected):
            io.read_checkpoint(path)
