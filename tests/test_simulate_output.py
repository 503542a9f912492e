"""The run Dataset of ``simulate`` assembled without xarray's general merge (``cartan.io``).

:func:`cartan.io.build_dataset` builds the variables and default indexes itself and hands them
to xarray's internal constructor; the result must be the one ``xr.Dataset(data_vars, coords,
attrs)`` gives — same variables in the same order, dimensions, indexes, dtypes, attributes —
and the written netCDF file must be the same, byte for byte.  Compared on every layout: d = 1
lattice (strains on edges), collocation (strains on nodes), a d = 2 sigma model (``axis``
coordinate of strings, the ``field`` variable, the medium's own output fields), a run
continued from a checkpoint (frames read back from the file) and a Dataset without frames.
"""

from __future__ import annotations

import importlib

import numpy as np
import pytest
import xarray as xr
from toys import arc_problem

import cartan
from cartan import io
from cartan.grid import Grid
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


@pytest.mark.parametrize("label", sorted(RUNS))
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
    cartan.simulate(_sigma_problem(), dt=1e-3, t_end=4e-3, save_every=1, progress=False)
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
