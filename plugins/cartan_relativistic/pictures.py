"""Lab-frame pictures of a ``relativistic-rod`` run: snapshots of the string and worldlines.

``cartan plot RUN.nc`` draws them through :meth:`RelativisticRod.draw
<cartan_relativistic.string.RelativisticRod.draw>` (the medium's picture hook,
:meth:`cartan.medium.Medium.draw`), and so does ``python -m cartan_relativistic.pictures RUN.nc
OUT.png``: side by side, the string at equal lab times in the x–y plane (a closed string with a
dot on its material point u = 0, an open one with squares on its ends held in space) and the worldlines of
a few material points.  For a closed string the worldlines are drawn as lab time against the
distance from the centre of the string, with the inward light ray for reference; for an open
string as the Minkowski diagram (lab time against lab x), with the saved frames — the slices of
constant run time, simultaneous in the string's own frame when the run is in proper time — and
the light cone.  When the nodes of a saved frame carry different lab times (a run in proper
time, the ``kinematic`` integrator), the snapshots are interpolated along each worldline to
common lab times, so that what is drawn is the string as the lab sees it (Lorentz-contracted).
"""

from __future__ import annotations

import json
import sys
from typing import Any

import numpy as np

__all__ = ["REQUIRED", "draw", "draw_figure", "lab_snapshots", "main"]

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
    snap_t, sx, sy = lab_snapshots(t, x, y)
    a1, a2 = fig.subplots(1, 2)
    cmap = cm.viridis
    norm = colors.Normalize(vmin=float(snap_t[0]), vmax=float(max(snap_t[-1], snap_t[0] + 1e-12)))
    # a straight string moving along its own line would draw every snapshot on one line: stack them by lab time
    stacked = not closed and float(np.ptp(sy)) <= 1e-9 * max(float(np.ptp(sx)), 1e-300)
    for k in range(sx.shape[0]):
        xs, ys = (np.append(sx[k], sx[k, 0]), np.append(sy[k], sy[k, 0])) if closed else (sx[k], sy[k])
        if stacked:
            ys = np.full_like(xs, snap_t[k])
        a1.plot(xs, ys, color=cmap(norm(snap_t[k])), lw=1.0 if closed else 2.0,
                marker=None if closed or sx.shape[1] > 40 else "|")
        if closed:  # the material point u = 0: a rotation shows
            a1.plot(sx[k, 0], sy[k, 0], "o", ms=3.5, color=cmap(norm(snap_t[k])), mec="k", mew=0.4)
    held = [i for key, i in (("start", 0), ("end", -1))
            if (problem.get("boundaries", {}).get(key) or {}).get("kind") in ("held", "clamped")]
    if held and not closed and not stacked:  # the ends held in space (cartan.Held, cartan.Clamped)
        a1.plot(sx[0, held], sy[0, held], "ks", ms=5, label="fixed end")
        a1.legend(loc="upper right", fontsize=8)
    if stacked:
        a1.set_ylabel("lab time t (the string lies along x)")
    else:
        a1.set_aspect("equal", adjustable="datalim")
        a1.set_ylabel("y (lab)")
    a1.set_xlabel("x (lab)")
    a1.set_title("string at equal lab times")
    a1.grid(True, alpha=0.3)
    sm = cm.ScalarMappable(norm=norm, cmap=cmap)
    sm.set_array([])
    fig.colorbar(sm, ax=a1, shrink=0.8, label="lab time t")
    idx = np.unique(np.linspace(0, x.shape[1] - 1, nodes).round().astype(int))
    if not closed:
        _minkowski(a2, t, x, idx, c)
        return True
    centre = np.stack([x.mean(axis=1), y.mean(axis=1), z.mean(axis=1)], axis=-1)
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


def lab_snapshots(t: np.ndarray, x: np.ndarray, y: np.ndarray,
                  frames: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The string at common lab times, interpolated linearly along each node's worldline.

    Parameters
    ----------
    t, x, y : arrays, shape ``(frames, nodes)``
        Lab time and lab positions of every node at every saved frame.
    frames : int, optional
        Number of lab times (default: as many as saved frames).

    Returns
    -------
    (times, xs, ys) : arrays of shapes ``(k,)``, ``(k, nodes)``, ``(k, nodes)``
        Lab times spread over the interval every worldline covers, and the positions there.
        When the nodes of each frame share its lab time (temporal gauge) these are the saved
        frames themselves; when no lab time is covered by every worldline, the saved frames.
    """
    frames = t.shape[0] if frames is None else int(frames)
    if np.allclose(t, t[:, :1], rtol=0.0, atol=1e-12 * max(1.0, float(np.max(np.abs(t))))):
        return t[:, 0], x, y
    lo, hi = float(np.max(t[0])), float(np.min(t[-1]))
    if not hi > lo or np.any(np.diff(t, axis=0) <= 0):
        return t.mean(axis=1), x, y
    times = np.linspace(lo, hi, frames)
    xs = np.stack([np.interp(times, t[:, i], x[:, i]) for i in range(t.shape[1])], axis=-1)
    ys = np.stack([np.interp(times, t[:, i], y[:, i]) for i in range(t.shape[1])], axis=-1)
    return times, xs, ys


def _minkowski(ax: Any, t: np.ndarray, x: np.ndarray, idx: np.ndarray, c: float) -> None:
    """Worldlines (lab time against lab x) of the nodes ``idx``, the saved frames and the light cone."""
    for k in range(t.shape[0]):
        ax.plot(x[k], t[k], color="0.6", lw=0.8, label="saved frames (constant run time)" if k == 0 else None)
    for i in idx:
        ax.plot(x[:, i], t[:, i], lw=1.2)
    t0, x0 = float(t[0, 0]), float(x[0, 0])
    span = float(t.max() - t0)
    ax.plot([x0, x0 + c * span], [t0, t0 + span], "k--", lw=0.8, label="light ray")
    ax.set_xlabel("x (lab)")
    ax.set_ylabel("lab time t")
    ax.set_title(f"worldlines of {idx.size} material points (Minkowski diagram)")
    ax.legend(loc="upper left", fontsize=8)
    ax.grid(True, alpha=0.3)


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
