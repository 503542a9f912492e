"""The run Dataset of ``simulate`` assembled without xarray's general merge (``cartan.io``).

:func:`cartan.io.build_dataset` builds the variables and default indexes itself and hands them
to xarray's internal constructor; the result must be the one ``xr.Dataset(data_vars, coords,
attrs)`` gives — same variables in the same order, dimensions, indexes, dtypes, attributes —
and the written netCDF file must be the same, byte for byte.  Compared on every layout: d = 1
lattice (strains on edges), collocation (strains on nodes), a d = 2 sigma model (``axis``
coordinate of strings, the ``field`` variable, the medium's own output fields), a run
continued from a checkpoint (frames read back from the file) and a Dataset without frames.

The settings of ``simulate`` are checked before it runs: their types and ranges, the step
count and the frames kept in memory against their limits, the output file; a run that blows
up leaves its last good state beside the output, which stays as it was.
"""

from __future__ import annotations

import importlib
import json
import math
import os
import re
import warnings

import numpy as np
import pytest
import xarray as xr
from toys import arc_problem

import cartan
from cartan import io
from cartan.grid import Grid
from cartan.integrators import Kinematic
from cartan.problem import Clamped, Problem

simulate_module = importlib.import_module("cartan.simulate")  # the module, not the function


def _public(data_vars, coords, attrs):
    """The reference: xarray's public constructor on the same ``(dims, values, attrs)`` tuples."""
    return xr.Dataset(data_vars=data_vars, coords=coords, attrs=attrs)


def assert_same_dataset(a: xr.Dataset, b: xr.Dataset) -> None:
    """Identical in every respect the constructor fixes (not only ``identical``)."""
    assert a.identical(b)
    assert list(a.variables) == list(b.variables)
    assert list(a.sizes.items()) == list(b.sizes.items())
    assert set(a.coords) == set(b.coords) and set(a.data_vars) == set(b.data_vars)
    assert list(a.xindexes) == list(b.xindexes)
    for name, index in a.xindexes.items():
        assert type(index) is type(b.xindexes[name]) and index.equals(b.xindexes[name])
        assert index.to_pandas_index().dtype == b.xindexes[name].to_pandas_index().dtype
    for name, var in a.variables.items():
        other = b.variables[name]
        assert type(var) is type(other) and type(var._data) is type(other._data), name
        assert var.dtype == other.dtype and var.dims == other.dims and var.attrs == other.attrs, name
        assert np.array_equal(var.values, other.values), name
        assert var.encoding == other.encoding
    assert a.attrs == b.attrs


def _sigma_problem() -> Problem:
    sigma = cartan.medium("sigma-model", n=2, d=2)
    grid = Grid((6, 5), 1.0, periodic=(True, False))
    init = sigma.initial_state(grid, "random-smooth", amplitude=0.4, velocity_amplitude=0.3)
    return Problem(sigma, grid, init, {"v-start": Clamped()})


RUNS = {
    "lattice d=1": (lambda: arc_problem(15, velocity=0.1 * np.arange(6.0)), {"scheme": "lattice"}),
    "collocation": (lambda: arc_problem(15, velocity=0.1 * np.arange(6.0)),
                    {"scheme": "collocation", "scheme_options": {"derivative": "fd4"}}),
    "sigma d=2": (_sigma_problem, {"scheme": "lattice"}),
}


@pytest.mark.parametrize("label", [pytest.param(k, marks=[pytest.mark.slow] if k == "sigma d=2" else [])
                                   for k in sorted(RUNS)])  # d = 2: a loop of its own (≈ 25 s to compile)
def test_run_dataset_equals_the_constructor(label, tmp_path, monkeypatch):
    """``simulate``'s Dataset and file with the fast assembly equal those of ``xr.Dataset``."""
    make, options = RUNS[label]
    settings = dict(integrator="lie-verlet", dt=1e-3, t_end=7e-3, save_every=2, progress=False,
                    command="same history", **options)
    fast = simulate_module.simulate(make(), output=tmp_path / "fast.nc", **settings)
    monkeypatch.setattr(io, "_assemble", _public)
    ref = simulate_module.simulate(make(), output=tmp_path / "ref.nc", **settings)
    # the history line carries the time of the call (to the second) and cartan_config the
    # stepping wall time: take them from one run for the comparison
    ref.attrs["history"] = fast.attrs["history"]
    ref.attrs["cartan_config"] = fast.attrs["cartan_config"]
    assert fast.sizes["time"] == 5
    assert_same_dataset(fast, ref)
    # the written files: the same root group once the two volatile attributes agree
    for name in ("fast", "ref"):
        ds = cartan.open(tmp_path / f"{name}.nc")
        ds.attrs["history"] = fast.attrs["history"]
        ds.attrs["cartan_config"] = fast.attrs["cartan_config"]
        io.write_dataset(ds, tmp_path / f"{name}-root.nc")
    assert (tmp_path / "fast-root.nc").read_bytes() == (tmp_path / "ref-root.nc").read_bytes()


def test_written_file_is_byte_identical(tmp_path, monkeypatch):
    """One record set, both assemblies, the same bytes on disk (netCDF-4 writes are
    deterministic: the same Dataset written twice gives the same file)."""
    captured = {}
    real = io._assemble

    def capture(data_vars, coords, attrs):
        captured["args"] = (data_vars, coords, attrs)
        return real(data_vars, coords, attrs)

    monkeypatch.setattr(io, "_assemble", capture)
    cartan.simulate(_sigma_problem(), dt=1e-3, t_end=4e-3, save_every=1, progress=False, compiled=False)
    fast, ref = real(*captured["args"]), _public(*captured["args"])
    assert_same_dataset(fast, ref)
    paths = [io.write_dataset(ds, tmp_path / f"{k}.nc") for k, ds in (("fast", fast), ("ref", ref), ("again", ref))]
    assert paths[1].read_bytes() == paths[2].read_bytes()  # the premise
    assert paths[0].read_bytes() == paths[1].read_bytes()


def test_restarted_run_dataset_equals_the_constructor(tmp_path, monkeypatch):
    """Frames read back from a checkpoint (numpy scalars and arrays) assemble the same way, and a
    restart still reproduces the uninterrupted run bit for bit."""
    problem = arc_problem(15, velocity=0.1 * np.arange(6.0))
    kw = dict(dt=1e-3, save_every=2, progress=False)
    full = cartan.simulate(problem, t_end=1.2e-2, **kw)
    cartan.simulate(problem, t_end=6e-3, output=tmp_path / "part.nc", **kw)
    cont = cartan.simulate(problem, t_end=1.2e-2, restart=tmp_path / "part.nc", **kw)
    for name in full.variables:
        assert np.array_equal(full[name].values, cont[name].values), name
    assert full.drop_attrs(deep=False).identical(cont.drop_attrs(deep=False))
    monkeypatch.setattr(io, "_assemble", _public)
    cartan.simulate(problem, t_end=6e-3, output=tmp_path / "part-ref.nc", **kw)
    ref = cartan.simulate(problem, t_end=1.2e-2, restart=tmp_path / "part-ref.nc", **kw)
    ref.attrs["history"] = cont.attrs["history"]
    ref.attrs["cartan_config"] = cont.attrs["cartan_config"]
    assert_same_dataset(cont, ref)


def test_dataset_without_frames_equals_the_constructor(monkeypatch):
    scheme = cartan.registry("schemes")["lattice"](arc_problem(9))
    empty = {"time": [], "step": []}
    kw = dict(config={"run": {}}, history="h", title="t")
    fast = io.build_dataset(scheme, empty, **kw)
    monkeypatch.setattr(io, "_assemble", _public)
    ref = io.build_dataset(scheme, empty, **kw)
    assert fast.sizes["time"] == 0
    assert_same_dataset(fast, ref)


def test_conflicting_sizes_are_rejected():
    """A variable whose shape disagrees with the others is a ValueError naming the dimension, as
    with xarray's constructor."""
    data_vars = {"a": (("time", "node"), np.zeros((2, 3)), {}), "b": (("time", "node"), np.zeros((2, 4)), {})}
    with pytest.raises(ValueError, match="'node'"):
        _public(data_vars, {}, {})
    with pytest.raises(ValueError, match="conflicting sizes for dimension 'node'"):
        io._assemble(data_vars, {}, {})


@pytest.mark.parametrize("kind", ["float", "numpy", "0-d"])
def test_scalar_series_stack_like_numpy(kind):
    """Scalar series are converted in one call: the same float64 values as ``np.stack``."""
    rng = np.random.default_rng(3)
    x = rng.standard_normal(7) * 10.0 ** rng.integers(-300, 300, 7)
    values = {"float": [float(v) for v in x], "numpy": list(x), "0-d": [np.array(v) for v in x]}[kind]
    out = io._stack(values)
    ref = np.stack([np.asarray(v, dtype=float) for v in values])
    assert out.dtype == ref.dtype == np.float64 and out.shape == ref.shape == (7,)
    assert np.array_equal(out, ref)
    arrays = [rng.standard_normal((3, 2)) for _ in range(4)]
    assert np.array_equal(io._stack(arrays), np.stack(arrays))


# ---------------------------------------------------------------------------- hardening: settings and limits
# Every setting is checked before the run (nothing is written, no StabilityWarning); these runs
# use the reference path (compiled=False) on small problems.
KW = dict(dt=1e-3, t_end=4e-3, save_every=2, progress=False, compiled=False)


@pytest.mark.parametrize(
    ("override", "expected"),
    [
        ({"dt": "1e-3"}, "dt must be a real number, got '1e-3'"),
        ({"dt": True}, "dt must be a real number, got True"),
        ({"dt": -1e-3}, "dt must be finite and > 0"),
        ({"t_end": math.nan}, "t_end must be finite and > 0"),
        ({"t_end": "1"}, "t_end must be a real number"),
        ({"t_end": 10**400}, "t_end must be finite and > 0"),
        ({"max_energy_growth": -1}, "max_energy_growth must be finite and > 0, got -1"),
        ({"max_energy_growth": math.nan}, "max_energy_growth must be finite and > 0"),
        ({"max_energy_growth": "10"}, "max_energy_growth must be a real number"),
        ({"save_every": True}, "save_every must be an integer ≥ 1"),
        ({"save_every": 1.5}, "save_every must be an integer ≥ 1"),
        ({"save_every": math.inf}, "save_every must be an integer ≥ 1, got inf"),
        ({"checkpoint_every": math.nan}, "checkpoint_every must be an integer ≥ 1, got nan"),
        ({"checkpoint_every": "2"}, "checkpoint_every must be an integer ≥ 1"),
        ({"progress": "yes"}, "progress must be True, False or None"),
        ({"compiled": "no"}, "compiled must be True or False"),
        ({"output": 3}, "output must be a path"),
        ({"restart": b"x.nc"}, "restart must be a path"),
        ({"integrator_options": [("a", 1)]}, "integrator_options must be a dict"),
        ({"max_steps": 0}, "max_steps must be an integer ≥ 1"),
        ({"max_steps": True}, "max_steps must be an integer ≥ 1"),
        ({"command": 1}, "command must be a string"),
    ],
)
def test_simulate_arguments_are_checked(override, expected):
    with pytest.raises(ValueError, match=re.escape(expected)):
        cartan.simulate(arc_problem(7), **{**KW, **override})


@pytest.mark.parametrize(
    ("override", "expected"),
    [
        ({"dt": 5e-324}, "t_end/dt = 0.004/4.94066e-324 = inf steps, above the limit of 1000000000 steps"),
        ({"t_end": 1e308}, "= inf steps, above the limit of 1000000000 steps"),
        ({"t_end": 1e7}, "= 1e+10 steps, above the limit of 1000000000 steps"),
        ({"max_steps": 3}, "t_end/dt = 0.004/0.001 = 4 steps, above the limit of 3 steps"),
        ({"t_end": 1e-12}, "t_end = 1e-12 is too short for dt = 0.001: the run would take no step"),
    ],
)
def test_step_counts_are_bounded(override, expected, monkeypatch):
    monkeypatch.delenv("CARTAN_MAX_STEPS", raising=False)
    with pytest.raises(ValueError, match=re.escape(expected)):
        cartan.simulate(arc_problem(7), **{**KW, **override})


def test_step_limit_from_the_environment(monkeypatch):
    monkeypatch.setenv("CARTAN_MAX_STEPS", "3")
    with pytest.raises(ValueError, match="above the limit of 3 steps.*CARTAN_MAX_STEPS"):
        cartan.simulate(arc_problem(7), **KW)
    assert cartan.simulate(arc_problem(7), **KW, max_steps=4).sizes["time"] == 3  # the argument wins


def test_frames_kept_in_memory_are_bounded(monkeypatch):
    monkeypatch.setenv("CARTAN_MAX_MEMORY", "1M")
    with pytest.raises(ValueError, match=r"keeping 5002 frames of 7 nodes in memory needs ≈ .* above the limit of "
                                         r"1 MiB; save fewer frames \(a larger save_every than 1\), or raise"):
        cartan.simulate(arc_problem(7), **{**KW, "t_end": 5.0, "save_every": 1})
    assert cartan.simulate(arc_problem(7), **{**KW, "t_end": 5.0, "save_every": 1000}).sizes["time"] == 6


def test_restart_before_the_checkpoint_is_refused(tmp_path):
    cartan.simulate(arc_problem(7), output=tmp_path / "run.nc", **KW)
    with pytest.raises(ValueError, match=r"t_end = 0.002 is before the time t = 0.004 of the checkpoint"):
        cartan.simulate(arc_problem(7), restart=tmp_path / "run.nc", **{**KW, "t_end": 2e-3})


def test_settings_are_checked_before_the_stability_warning(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no StabilityWarning for a run that does not start
        with pytest.raises(ValueError, match="the output folder"):
            cartan.simulate(arc_problem(7), output=tmp_path / "missing" / "run.nc", **{**KW, "dt": 10.0})
        with pytest.raises(ValueError, match="no step"):
            cartan.simulate(arc_problem(7), **{**KW, "dt": 10.0, "t_end": 1e-12})
    assert os.listdir(tmp_path) == []


def test_output_is_checked_before_the_run(tmp_path, monkeypatch):
    def never(*args, **kwargs):  # pragma: no cover - the run must not start
        raise AssertionError("the run started")

    monkeypatch.setattr(simulate_module, "_advance", never)
    for output, expected in ((tmp_path / "missing" / "run.nc", "does not exist"), ("/dev/null", "is a device"),
                             (tmp_path, "is a directory")):
        with pytest.raises(ValueError, match=expected):
            cartan.simulate(arc_problem(7), output=output, **KW)


def test_blow_up_leaves_the_output_as_it_was(tmp_path):
    out = tmp_path / "run.nc"
    cartan.simulate(arc_problem(7), output=out, **KW)
    good = out.read_bytes()
    with pytest.warns(cartan.StabilityWarning), pytest.raises(cartan.InstabilityError) as info:
        cartan.simulate(arc_problem(7), output=out, **{**KW, "dt": 1.0, "t_end": 100.0})
    lastgood = tmp_path / "run.lastgood.nc"
    assert info.value.path == lastgood
    assert f"saved to {lastgood} ({out} is left as it was)" in str(info.value)
    assert out.read_bytes() == good
    kept = cartan.open(lastgood)
    assert kept.sizes["time"] >= 1 and np.all(np.isfinite(kept["S"].values))
    # the last good state is a checkpoint: it continues with a stable step
    cont = cartan.simulate(arc_problem(7), restart=lastgood, **{**KW, "t_end": float(kept.time[-1]) + 4e-3})
    assert cont.sizes["time"] > kept.sizes["time"]
    assert sorted(os.listdir(tmp_path)) == ["run.lastgood.nc", "run.nc"]


def test_no_output_of_a_fresh_run_is_written_on_blow_up(tmp_path):
    out = tmp_path / "new.nc"
    with pytest.warns(cartan.StabilityWarning), pytest.raises(cartan.InstabilityError, match="nothing was written"):
        cartan.simulate(arc_problem(7), output=out, **{**KW, "dt": 1.0, "t_end": 100.0})
    assert sorted(os.listdir(tmp_path)) == ["new.lastgood.nc"]


def test_problems_out_of_range_are_refused():
    rod = dict(E=1e4, poisson=0.5, density=5000.0)
    grid = Grid(5)
    massless = cartan.medium("cosserat-rod", radius=1e-200, **rod)  # every inertia underflows to 0
    problem = Problem(massless, grid, massless.initial_state(grid, "straight"))
    with pytest.raises(ValueError, match="has no inertia"):
        cartan.simulate(problem, **KW)
    short = Grid(5, length=1e-300)
    medium = cartan.medium("cosserat-rod", radius=0.25, **rod)
    with pytest.raises(ValueError, match="the CFL estimate of 'lie-verlet' on 'lattice' is not a number"):
        cartan.simulate(Problem(medium, short, medium.initial_state(short, "straight")), **KW)


def test_an_integrator_without_a_stability_limit_takes_the_inertial_time_scale(monkeypatch):
    """Without dt, implicit-midpoint (no stability limit) takes 1/ω_max, the step lie-verlet's
    default (half its CFL estimate 2/ω_max) also takes; kinematic, which has no time scale, asks for dt."""
    monkeypatch.setenv("CARTAN_COMPILED", "0")
    problem = arc_problem(7)
    cfg = {}
    for name in ("lie-verlet", "implicit-midpoint"):
        ds = cartan.simulate(problem, integrator=name, t_end=0.05, progress=False, compiled=False)
        cfg[name] = json.loads(ds.attrs["cartan_config"])["run"]
    assert math.isinf(cfg["implicit-midpoint"]["dt_max"])
    assert cfg["implicit-midpoint"]["dt"] == cfg["lie-verlet"]["dt"] > 0
    with pytest.raises(ValueError, match="dt is required: 'kinematic' has no stability limit"):
        cartan.simulate(problem, integrator=Kinematic(velocity=lambda t, u, X: np.zeros((*u.shape[:-1], 6))),
                        t_end=0.05, progress=False)
