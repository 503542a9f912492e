"""Quick-look figures of a run (``cartan plot``).

:func:`plot_run` draws, side by side, snapshots of the configuration coloured by time
(the centreline ``position`` for affine groups, in 3-D or 2-D; the ``field`` when it is a
point of R² or R³; nothing otherwise) and the energies against time: kinetic, potential,
total ``E = K + V``, and ``E + D − W`` (total plus dissipated energy minus external work,
constant when the energy balance closes).  matplotlib is used through its object API with
the Agg canvas, so no display is needed.
"""

from __future__ import annotations

import os
import pathlib
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr
    from matplotlib.figure import Figure

__all__ = ["plot_run"]


def _points(ds: xr.Dataset) -> np.ndarray | None:
    """Configuration points ``[time, nodes..., k]`` (k = 2 or 3), or None."""
    for name in ("position", "field"):
        if name in ds:
            arr = np.asarray(ds[name].values)
            if arr.ndim >= 3 and arr.shape[-1] in (2, 3):
                return arr
    return None


def _snapshot_indices(nt: int, snapshots: int) -> np.ndarray:
    if nt <= snapshots:
        return np.arange(nt)
    return np.unique(np.linspace(0, nt - 1, snapshots).round().astype(int))


def _draw_configuration(fig: Figure, ax_slot: int, ds: xr.Dataset, pts: np.ndarray, snapshots: int) -> None:
    from matplotlib import cm, colors

    t = np.asarray(ds["time"].values, dtype=float)
    k = pts.shape[-1]
    norm = colors.Normalize(vmin=float(t[0]), vmax=float(t[-1]) if t[-1] > t[0] else float(t[0]) + 1.0)
    cmap = cm.viridis
    ax = fig.add_subplot(1, 2, ax_slot, projection="3d" if k == 3 else None)
    curve = pts.ndim == 3  # d = 1: [time, node, k]
    for i in _snapshot_indices(len(t), snapshots):
        p = pts[i].reshape(-1, k)
        c = cmap(norm(t[i]))
        if curve:
            ax.plot(*p.T, color=c, lw=1.5)
        else:
            ax.scatter(*p.T, color=c, s=4)
    flat = pts.reshape(-1, k)
    lo, hi = np.nanmin(flat, axis=0), np.nanmax(flat, axis=0)
    if k == 3:  # equal scales: a cube around the data
        centre = 0.5 * (lo + hi)
        half = 0.55 * max(float(np.max(hi - lo)), 1e-12)
        ax.set_xlim(centre[0] - half, centre[0] + half)
        ax.set_ylim(centre[1] - half, centre[1] + half)
        ax.set_zlim(centre[2] - half, centre[2] + half)
        ax.set_box_aspect((1.0, 1.0, 1.0))
        ax.set_xlabel("x")
        ax.set_ylabel("y")
        ax.set_zlabel("z")
    else:
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x")
        ax.set_ylabel("y")
    ax.set_title("configuration" + (" (centreline)" if curve else ""))
    sm = cm.ScalarMappable(norm=norm, cmap=cmap)
    sm.set_array([])
    fig.colorbar(sm, ax=ax, shrink=0.7, pad=0.1, label="time")


def _draw_energies(fig: Figure, ax_slot: int, ncols: int, ds: xr.Dataset) -> None:
    ax = fig.add_subplot(1, ncols, ax_slot)
    t = np.asarray(ds["time"].values, dtype=float)
    K = np.asarray(ds["kinetic_energy"].values)
    V = np.asarray(ds["potential_energy"].values)
    D = np.asarray(ds["dissipated_energy"].values) if "dissipated_energy" in ds else np.zeros_like(K)
    W = np.asarray(ds["external_work"].values) if "external_work" in ds else np.zeros_like(K)
    E = K + V
    ax.plot(t, K, label="kinetic K")
    ax.plot(t, V, label="potential V")
    ax.plot(t, E, label="total E = K + V", lw=2)
    label = "E + D − W (balance)" if np.any(W) else "E + D (dissipated + total)"
    ax.plot(t, E + D - W, "--", label=label, color="k")
    ax.set_xlabel("time")
    ax.set_ylabel("energy")
    ax.set_title("energies")
    ax.legend(fontsize="small")
    ax.grid(True, alpha=0.3)


def plot_run(
    ds: xr.Dataset, path: str | os.PathLike | None = None, snapshots: int = 8, title: str | None = None
) -> Figure:
    """Quick-look figure of a run: configuration snapshots and energies against time.

    Parameters
    ----------
    ds : xarray.Dataset
        A run Dataset (from :func:`cartan.simulate` or :func:`cartan.open`).
    path : path-like, optional
        Where to save the figure (format from the suffix, e.g. ``.png``, ``.pdf``).
    snapshots : int
        Number of configurations drawn, evenly spaced in time.
    title : str, optional
        Figure title (default: the Dataset's ``title`` attribute).

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure

    pts = _points(ds)
    ncols = 2 if pts is not None and ds.sizes.get("time", 0) > 0 else 1
    fig = Figure(figsize=(6.0 * ncols, 4.8), layout="constrained")
    if ncols == 2:
        _draw_configuration(fig, 1, ds, pts, snapshots)
    _draw_energies(fig, ncols, ncols, ds)
    fig.suptitle(title if title is not None else str(ds.attrs.get("title", "")))
    if path is not None:
        fig.savefig(pathlib.Path(path), dpi=120)
    return fig
