"""The figure of a sphere-rod run: start and end states on the sphere, potential energy vs time.

:func:`plot_sphere_rod` draws what the paper's figures of §VIII.A show — the rod's centreline
(black) with its directors e₂ (blue) on the sphere at the first and last saved frames, and the
potential energy against time.  matplotlib is used through its object API with the Agg
canvas, so no display is needed.
"""

from __future__ import annotations

import json
import os
import pathlib
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr
    from matplotlib.figure import Figure

__all__ = ["plot_sphere_rod"]

_ELEV, _AZIM = 25.0, -60.0


def _run_info(ds: xr.Dataset) -> tuple[float, bool]:
    """Sphere radius and whether the rod is closed, from the run's ``cartan_config``."""
    config = json.loads(ds.attrs.get("cartan_config", "{}"))
    problem = config.get("problem", {})
    radius = float(problem.get("parameters", {}).get("radius", 1.0))
    periodic = bool(problem.get("grid", {}).get("periodic", [False])[0])
    return radius, periodic


def _view_direction(elev: float, azim: float) -> np.ndarray:
    e, a = np.radians(elev), np.radians(azim)
    return np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])


def _draw_state(ax, frames: np.ndarray, radius: float, closed: bool, title: str, directors: int) -> None:
    """Sphere, centreline (solid in front, faint behind) and directors e₂ of one frame set."""
    view = _view_direction(_ELEV, _AZIM)
    # the sphere as a light wireframe of meridians and parallels
    s = np.linspace(0.0, 2.0 * np.pi, 121)
    for lat in np.radians(np.arange(-60, 61, 30)):
        ax.plot(radius * np.cos(lat) * np.cos(s), radius * np.cos(lat) * np.sin(s), radius * np.sin(lat) + 0 * s,
                color="0.82", lw=0.5)
    for lon in np.radians(np.arange(0, 180, 30)):
        ax.plot(radius * np.cos(lon) * np.cos(s), radius * np.sin(lon) * np.cos(s), radius * np.sin(s),
                color="0.82", lw=0.5)
    e2, e3 = frames[:, :, 1], frames[:, :, 2]
    x = radius * e3
    if closed:
        x = np.concatenate([x, x[:1]])
    # split the centreline into the parts facing the viewer and the parts behind the sphere
    front = (x @ view) >= 0.0
    for mask, style in ((front, {"color": "k", "lw": 2.0}), (~front, {"color": "k", "lw": 1.0, "alpha": 0.25})):
        seg = np.where(mask[:, None], x, np.nan)
        ax.plot(*seg.T, **style)
    step = max(1, len(e3) // directors)
    idx = np.arange(0, len(e3), step)
    tip = x[idx] + 0.18 * radius * e2[idx]
    for i, j in enumerate(idx):
        faint = float(x[j] @ view) < 0.0
        ax.plot(*np.stack([x[j], tip[i]]).T, color="tab:blue", lw=1.4 if not faint else 0.8,
                alpha=1.0 if not faint else 0.3)
    lim = 1.05 * radius
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.set_zlim(-lim, lim)
    ax.set_box_aspect((1.0, 1.0, 1.0), zoom=1.35)
    ax.view_init(elev=_ELEV, azim=_AZIM)
    ax.set_axis_off()
    ax.set_title(title)


def plot_sphere_rod(ds: xr.Dataset, path: str | os.PathLike | None = None, directors: int = 24) -> Figure:
    """Start and end states of a sphere-rod run on the sphere, and U against time.

    Parameters
    ----------
    ds : xarray.Dataset
        A run of the ``sphere-rod`` medium (from :func:`cartan.simulate` or :func:`cartan.open`);
        uses ``frame`` (the frames R = (e₁ e₂ e₃)), ``potential_energy`` and ``cartan_config``
        (radius, closed or open rod).
    path : path-like, optional
        Where to save the figure (format from the suffix).
    directors : int
        About how many directors e₂ to draw along the rod.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure

    radius, closed = _run_info(ds)
    R = np.asarray(ds["frame"].values, dtype=float)  # [time, node, 3, 3]
    t = np.asarray(ds["time"].values, dtype=float)
    U = np.asarray(ds["potential_energy"].values, dtype=float)

    fig = Figure(figsize=(14.0, 4.8), layout="constrained")
    gs = fig.add_gridspec(1, 3, width_ratios=[1.0, 1.0, 1.25])
    _draw_state(fig.add_subplot(gs[0], projection="3d"), R[0], radius, closed, f"initial state, t = {t[0]:g}",
                directors)
    _draw_state(fig.add_subplot(gs[1], projection="3d"), R[-1], radius, closed, f"final state, t = {t[-1]:g}",
                directors)
    ax = fig.add_subplot(gs[2])
    positive = U > 0
    if np.any(positive) and U[positive].max() > 100.0 * U[positive].min():
        ax.semilogy(t[positive], U[positive], color="k", lw=1.8)
    else:
        ax.plot(t, U, color="k", lw=1.8)
    ax.set_xlabel("time t")
    ax.set_ylabel("potential energy U")
    ax.set_title("potential energy of the rod")
    ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"Cosserat rod on a sphere (r = {radius:g}): centreline (black) and directors e₂ (blue)")
    if path is not None:
        fig.savefig(pathlib.Path(path), dpi=120)
    return fig
