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
