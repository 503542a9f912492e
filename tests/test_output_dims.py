"""Medium outputs with extra named dimensions (``output_fields`` entries ``(long_name, units,
dims)``, labels from ``output_coords``): the run and equilibrium Datasets, the netCDF files and
their restart, the checks of the declarations and of the returned shapes, and the component
selection of ``cartan plot --field``.

The medium is the O(3) sigma model on a 6 × 5 grid (d = 2, a surface in R³ for the plots) with two
tensor outputs per node whose values are known exactly from recorded core variables: the
nematic tensor n ⊗ n (dimensions ``row``, ``col``, labelled by the medium) and a copy of the
nodal strain X (dimensions ``axis``, ``component``, the core's own, with the core's labels).
Comparisons are exact or to round-off (1e-14: |n| = 1 up to the group defect of the frames).
The steps run in the numpy reference path (``compiled=False``): no loop is compiled.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from cartan_sigma.model import SigmaModel
from click.testing import CliRunner

import cartan
from cartan.cli import main
from cartan.io import write_dataset
from cartan.plotting import _node_values, plot_run
from cartan.rigid_modes import UnsupportedRigidMotion

GRID = cartan.Grid((6, 5), length=(1.0, 0.8))
LABELS = ["x", "y", "z"]


class TensorSigma(SigmaModel):
    """The sigma model on S² (d = 2) recording the nematic tensor n ⊗ n and the nodal strain
    as tensors per node; ``bad`` returns a value of the wrong trailing shape for one field."""

    name = "tensor-sigma"
    output_coords = {"row": LABELS, "col": ("second spatial index", LABELS)}

    def __init__(self, bad: str | None = None, extra: dict[str, Any] | None = None, **kw: Any):
        super().__init__(n=2, d=2, **kw)
        self.bad = bad
        self.output_fields = {
            **self.output_fields,
            "nematic_tensor": ("nematic tensor n ⊗ n", "1", ("row", "col")),
            "strain_copy": ("nodal strain X", "mixed", ("axis", "component")),
            **(extra or {}),
        }

    def outputs(self, q, X, N, grid) -> dict[str, np.ndarray]:
        out = super().outputs(q, X, N, grid)
        out["nematic_tensor"] = q[..., :, None] * q[..., None, :]
        out["strain_copy"] = np.array(X)
        if self.bad == "trailing":          # a 3 × 2 tensor where the labels say 3 × 3
            out["nematic_tensor"] = out["nematic_tensor"][..., :2]
        elif self.bad == "missing-dim":     # one value per node and row, no col dimension
            out["nematic_tensor"] = q
        elif self.bad == "core-size":       # 'component' with 2 entries where the group has 3
            out["strain_copy"] = out["strain_copy"][..., :2]
        return out


def problem(medium: SigmaModel | None = None) -> cartan.Problem:
    medium = medium if medium is not None else TensorSigma()
    init = medium.initial_state(GRID, "great-circle", angle=lambda u, v: 0.9 * u + 0.6 * v * v,
                                velocity=lambda u, v: np.stack([0.0 * u, 0.2 * np.ones_like(u), 0.0 * u], -1))
    return cartan.Problem(medium, GRID, init)


def run(medium: SigmaModel | None = None, **kw: Any):
    return cartan.simulate(problem(medium), dt=0.01, t_end=kw.pop("t_end", 0.04), save_every=1, progress=False,
                           compiled=False, **kw)


@pytest.fixture(scope="module")
def ds():
    return run()


def check_values(ds) -> None:
    """The recorded tensors are those of the recorded field and strains, in every frame."""
    n = ds["field"].values
    np.testing.assert_array_equal(ds["nematic_tensor"].values, n[..., :, None] * n[..., None, :])
    np.testing.assert_array_equal(ds["strain_copy"].values, ds["X"].values)
    trace = np.trace(ds["nematic_tensor"].values, axis1=-2, axis2=-1)
    np.testing.assert_allclose(trace, 1.0, rtol=0, atol=1e-14)  # |n| = 1


# ---------------------------------------------------------------- the Dataset
def test_run_dataset_has_the_extra_dimensions(ds):
    nem = ds["nematic_tensor"]
    assert nem.dims == ("time", "u", "v", "row", "col") and nem.shape == (5, 6, 5, 3, 3)
    assert nem.attrs == {"long_name": "nematic tensor n ⊗ n", "units": "1"}
    assert list(ds["row"].values) == LABELS and list(ds["col"].values) == LABELS
    assert ds["col"].attrs["long_name"] == "second spatial index"
    assert ds["row"].attrs["long_name"] == "row of the medium's output fields"
    # dimensions shared with the core's variables keep the core's labels
    strain = ds["strain_copy"]
    assert strain.dims == ds["X"].dims == ("time", "u", "v", "axis", "component")
    assert strain.attrs == {"long_name": "nodal strain X", "units": "mixed"}
    assert list(ds["axis"].values) == ["u", "v"] and list(ds["component"].values) == [0, 1, 2]
    # the scalar outputs are as before: a node field and a series
    assert ds["energy_density"].dims == ("time", "u", "v") and ds["topological_charge"].dims == ("time",)
    check_values(ds)
    # the field moves: the tensors are not the same in every frame
    assert np.max(np.abs(nem.values[-1] - nem.values[0])) > 1e-3


def test_netcdf_round_trip_and_restart(ds, tmp_path):
    path = write_dataset(ds, tmp_path / "copy.nc")
    back = cartan.open(path)
    for name in ("nematic_tensor", "strain_copy", "energy_density"):
        assert back[name].dims == ds[name].dims and back[name].attrs == ds[name].attrs
        np.testing.assert_array_equal(back[name].values, ds[name].values)
    for dim in ("row", "col", "axis"):
        assert list(back[dim].values) == list(ds[dim].values) and back[dim].attrs == ds[dim].attrs
    # a run written with its checkpoint and continued from it has the same tensors in every frame
    part = tmp_path / "part.nc"
    run(t_end=0.02, output=part)
    assert cartan.open(part)["nematic_tensor"].sizes["time"] == 3
    whole = cartan.simulate(problem(), restart=part, t_end=0.04, progress=False, compiled=False)
    assert whole["nematic_tensor"].dims == ds["nematic_tensor"].dims
    np.testing.assert_allclose(whole["nematic_tensor"].values, ds["nematic_tensor"].values, rtol=0, atol=1e-14)
    check_values(cartan.open(part))


def test_static_equilibrium_records_the_tensors():
    """A geodesic field n(u) on a great circle (angle linear in u) is a harmonic map: Newton
    stops at it, and the equilibrium Dataset carries the tensors of the one frame."""
    medium = TensorSigma()
    init = medium.initial_state(GRID, "great-circle", angle=lambda u, v: 0.7 * u)
    # no support: the global rotation about the circle's axis is free (cartan.rigid_modes)
    with pytest.warns(UnsupportedRigidMotion, match=r"rotation about \(0, 1, 0\)"):
        eq = cartan.solve_static(cartan.Problem(medium, GRID, init))
    assert eq["nematic_tensor"].dims == ("time", "u", "v", "row", "col") and eq.sizes["time"] == 1
    assert list(eq["col"].values) == LABELS and eq["col"].attrs["long_name"] == "second spatial index"
    assert eq["strain_copy"].dims == ("time", "u", "v", "axis", "component")
    check_values(eq)


# ---------------------------------------------------------------- bad declarations and values
@pytest.mark.parametrize("bad, match", [
    ("trailing", r"medium 'tensor-sigma': output 'nematic_tensor': its dimension 'col' has 2 entries but "
                 r"output_coords\['col'\] has 3 labels"),
    ("missing-dim", r"medium 'tensor-sigma': output 'nematic_tensor' declares the extra dimensions "
                    r"\('row', 'col'\): it must have shape"),
    ("core-size", r"medium 'tensor-sigma': output 'strain_copy': its dimension 'component' has 2 entries, but "
                  r"the core's variables give 'component' 3"),
])
def test_wrong_shapes_are_refused(bad, match):
    with pytest.raises(ValueError, match=match):
        run(TensorSigma(bad=bad), t_end=0.01)


@pytest.mark.parametrize("extra, coords, match", [
    ({"t": ("a", "1", "row")}, None, r"output_fields\['t'\]: dims must be a tuple of dimension names"),
    ({"t": ("a", "1", ("row", "row"))}, None, r"output_fields\['t'\]: dims must be distinct"),
    ({"t": ("a", "1", ("u",))}, None, r"output_fields\['t'\]: dims \['u'\] are the core's time and node"),
    ({"t": ("a",)}, None, r"output_fields\['t'\] must be \(long_name, units\) or \(long_name, units, dims\)"),
    ({}, {"row": ["x", "x", "z"]}, r"output_coords\['row'\] must be a non-empty list of distinct strings"),
    ({}, {"axis": ["a", "b"]}, r"output_coords\['axis'\] = \['a', 'b'\] differs from the labels \['u', 'v'\]"),
    ({"t": ("a", "1", ("field",))}, None, r"dimensions named like variables of the Dataset: \['field'\]"),
])
def test_bad_declarations_are_refused(extra, coords, match):
    medium = TensorSigma(extra=extra)
    if coords is not None:
        medium.output_coords = {**TensorSigma.output_coords, **coords}
    if "t" in extra:  # the extra field's value: one 3-vector per node
        medium.outputs = lambda q, X, N, grid: {**TensorSigma.outputs(medium, q, X, N, grid), "t": q}
    with pytest.raises(ValueError, match=r"medium 'tensor-sigma'.*" + match):
        run(medium, t_end=0.01)


# ---------------------------------------------------------------- cartan plot --field NAME[...]
def test_plot_component_selection(ds, tmp_path):
    pts = ds["field"].values
    values, label = _node_values(ds, pts, "nematic_tensor[x,z]", -1)
    np.testing.assert_array_equal(values, ds["nematic_tensor"].values[-1, :, :, 0, 2])
    assert label == "nematic_tensor[x,z]"
    keyed, _ = _node_values(ds, pts, "nematic_tensor[col=x, row=z]", -1)
    np.testing.assert_array_equal(keyed, ds["nematic_tensor"].values[-1, :, :, 2, 0])
    strain, label = _node_values(ds, pts, "strain_copy[v,1]", 0)   # core labels: axis v, component 1
    np.testing.assert_array_equal(strain, ds["X"].values[0, :, :, 1, 1])
    assert label == "strain_copy[v,1] [mixed]"
    fig = plot_run(ds, tmp_path / "nematic.png", field="nematic_tensor[x,z]")
    assert (tmp_path / "nematic.png").stat().st_size > 0
    assert "nematic_tensor[x,z]" in [ax.get_ylabel() for ax in fig.axes]   # the colour bar
    for field, match in [
        ("nematic_tensor", r"field 'nematic_tensor' has the dimensions row, col beyond the nodes "
                           r"\(row: x, y, z; col: x, y, z\): choose a component, e.g. nematic_tensor\[x,x\]"),
        ("nematic_tensor[x]", r"give 2 label\(s\), one per dimension row, col"),
        ("nematic_tensor[x,w]", r"'w' is not a label of 'col' \(x, y, z\)"),
        ("energy_density[x]", r"field 'energy_density' has no dimension beyond the nodes"),
        ("stress", r"node fields: .*nematic_tensor\[row,col\]"),
    ]:
        with pytest.raises(ValueError, match=match):
            _node_values(ds, pts, field, -1)


def test_cli_plot_names_the_dimensions(ds, tmp_path):
    path = write_dataset(ds, tmp_path / "run.nc")
    res = CliRunner().invoke(main, ["plot", str(path), "--field", "nematic_tensor"])
    assert res.exit_code == 2 and res.stdout == ""
    lines = res.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"cartan: error: {path}: field 'nematic_tensor' has the "
                                                   "dimensions row, col beyond the nodes (row: x, y, z; col: x, y, z)")
    res = CliRunner().invoke(main, ["plot", str(path), "--field", "nematic_tensor[y,y]", "-o",
                                    str(tmp_path / "yy.png")])
    assert res.exit_code == 0, res.stderr
    assert (tmp_path / "yy.png").stat().st_size > 0
