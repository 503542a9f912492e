"""Lab-frame pictures of a ``relativistic-rod`` run: snapshots of the string and worldlines.

``cartan plot RUN.nc`` draws them through :meth:`RelativisticRod.draw
<cartan_relativistic.string.RelativisticRod.draw>` (the medium's picture hook,
:meth:`cartan.medium.Medium.draw`), and so does ``python -m cartan_relativistic.pictures RUN.nc
OUT.png``: side by side, the string at the saved lab times in the x–y plane and the worldlines
(lab time against the distance from the centre of energy) of a few material points, with the
light cone for reference.
"""

from __future__ import annotations

import json
import sys
from typing import Any

import numpy as np

__all__ = ["REQUIRED", "draw", "draw_figure", "main"]

#: the per-node outputs of the medium the pictures are drawn from
REQUIRED: tuple[str, ...] = ("lab_x", "lab_y", "lab_z", "coordinate_time")


def _config(ds: Any) -> dict[str, Any]:
    try:
        config = json.loads(str(ds.attrs.get("cartan_config", "")))
    except ValueError:
        return {}
    return config.get("problem", {}) if isinstance(config, dict) else {}


def draw_figure(ds: Any, fig: Any, nodes: int = 8) -> bool:
    """Draw snapshots and worldlines of a Dataset of the medium into a matplotlib figure.

    Parameters
    ----------
    ds : xarray.Dataset
        Frames with ``lab_x``, ``lab_y``, ``lab_z`` and ``coordinate_time`` ``[time, node]``
        (the medium's outputs); ``c`` and whether the string is closed are read from the
        ``cartan_config`` attribute (default c = 1, closed).
    fig : matplotlib.figure.Figure
        An empty figure; two axes are added.
    nodes : int
        Number of worldlines drawn (evenly spaced nodes), ≥ 1.

    Returns
    -------
    bool
        False (nothing drawn) when ``ds`` lacks the outputs or holds fewer than two frames
        (a static result, say); True otherwise.
    """
    from matplotlib import cm, colors

    if nodes < 1:
        raise ValueError(f"nodes must be ≥ 1, got {nodes}")
    if any(k not in ds or ds[k].ndim != 2 for k in REQUIRED) or ds["lab_x"].shape[0] < 2:
        return False
    problem = _config(ds)
    c = float(problem.get("parameters", {}).get("c", ds.attrs.get("c", 1.0)))
    closed = bool(np.all(problem.get("grid", {}).get("periodic", [True])))
    x, y, z = (np.asarray(ds[k].values, dtype=float) for k in ("lab_x", "lab_y", "lab_z"))
    t = np.asarray(ds["coordinate_time"].values, dtype=float)
    frame_t = t.mean(axis=1)
    a1, a2 = fig.subplots(1, 2)
    cmap = cm.viridis
    norm = colors.Normalize(vmin=float(frame_t[0]), vmax=float(max(frame_t[-1], frame_t[0] + 1e-12)))
    for k in range(x.shape[0]):
        xs, ys = (np.append(x[k], x[k, 0]), np.append(y[k], y[k, 0])) if closed else (x[k], y[k])
        a1.plot(xs, ys, color=cmap(norm(frame_t[k])), lw=1.0)
    a1.set_aspect("equal", adjustable="datalim")
    a1.set_xlabel("x (lab)")
    a1.set_ylabel("y (lab)")
    a1.set_title("string at the saved lab times")
    a1.grid(True, alpha=0.3)
    sm = cm.ScalarMappable(norm=norm, cmap=cmap)
    sm.set_array([])
    fig.colorbar(sm, ax=a1, shrink=0.8, label="lab time t")
    centre = np.stack([x.mean(axis=1), y.mean(axis=1), z.mean(axis=1)], axis=-1)
    idx = np.unique(np.linspace(0, x.shape[1] - 1, nodes).round().astype(int))
    for i in idx:
        d = np.linalg.norm(np.stack([x[:, i], y[:, i], z[:, i]], axis=-1) - centre, axis=-1)
        a2.plot(d, t[:, i], lw=1.0)
    r0 = float(np.max(np.linalg.norm(np.stack([x[0], y[0], z[0]], -1) - centre[0], axis=-1)))
    t0 = float(t.min())
    tt = np.linspace(t0, min(float(t.max()), t0 + r0 / c), 50)
    a2.plot(r0 - c * (tt - t0), tt, "k--", lw=0.8, label="inward light ray from the initial radius")
    a2.set_xlabel("distance from the centre of the string (lab)")
    a2.set_ylabel("lab time t")
    a2.set_title(f"worldlines of {idx.size} material points")
    a2.legend(loc="upper right", fontsize=8)
    a2.grid(True, alpha=0.3)
    return True


def draw(ds: Any, path: str, nodes: int = 8) -> None:
    """Draw snapshots and worldlines of a Dataset of the medium into ``path``.

    Parameters
    ----------
    ds : xarray.Dataset
        Frames with ``lab_x``, ``lab_y``, ``lab_z`` ``[time, node]`` and ``coordinate_time``.
    path : str
        Output image file.
    nodes : int
        Number of worldlines drawn (evenly spaced nodes).

    Raises
    ------
    ValueError
        If ``ds`` lacks the medium's lab-frame outputs or has fewer than two frames.
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10.0, 4.6), layout="constrained")
    if not draw_figure(ds, fig, nodes=nodes):
        raise ValueError(f"ds: needs {', '.join(REQUIRED)} [time, node] over at least two frames")
    fig.suptitle(str(ds.attrs.get("title", "")) if hasattr(ds, "attrs") else "")
    fig.savefig(path, dpi=110)


def main(argv: list[str] | None = None) -> int:
    """Command line: ``python -m cartan_relativistic.pictures RUN.nc OUT.png``."""
    import xarray as xr

    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 2:
        print("usage: python -m cartan_relativistic.pictures RUN.nc OUT.png", file=sys.stderr)
        return 2
    with xr.open_dataset(argv[0]) as ds:
        draw(ds.load(), argv[1])
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
