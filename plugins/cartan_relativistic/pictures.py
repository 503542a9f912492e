"""Lab-frame pictures of a ``relativistic-rod`` run: snapshots of the string and worldlines.

``python -m cartan_relativistic.pictures RUN.nc OUT.png`` reads a run file written by
``cartan run`` (or any Dataset of the medium) and draws, side by side, the string at the saved
lab times in the x–y plane and the worldlines (lab time against the distance from the centre of
energy) of a few material points, with the light cone for reference.
"""

from __future__ import annotations

import sys
from typing import Any

import numpy as np

__all__ = ["draw", "main"]


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
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    x, y, z = (np.asarray(ds[k].values) for k in ("lab_x", "lab_y", "lab_z"))
    t = np.asarray(ds.coordinate_time.values)
    c = float(ds.attrs.get("c", 1.0)) if hasattr(ds, "attrs") else 1.0
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4.6))
    cmap = plt.get_cmap("viridis")
    nt = x.shape[0]
    for k in range(nt):
        col = cmap(k / max(nt - 1, 1))
        a1.plot(np.append(x[k], x[k, 0]), np.append(y[k], y[k, 0]), color=col, lw=1.0)
    a1.set_aspect("equal")
    a1.set_xlabel("x (lab)")
    a1.set_ylabel("y (lab)")
    a1.set_title("string at the saved lab times (dark: early)")
    centre = np.stack([x.mean(axis=1), y.mean(axis=1), z.mean(axis=1)], axis=-1)
    idx = np.linspace(0, x.shape[1] - 1, nodes).astype(int)
    for i in idx:
        d = np.linalg.norm(np.stack([x[:, i], y[:, i], z[:, i]], axis=-1) - centre, axis=-1)
        a2.plot(d, t[:, i], lw=1.0)
    r0 = float(np.max(np.linalg.norm(np.stack([x[0], y[0], z[0]], -1) - centre[0], axis=-1)))
    t0 = float(t.min())
    tt = np.linspace(t0, min(float(t.max()), t0 + r0 / c), 50)
    a2.plot(r0 - c * (tt - t0), tt, "k--", lw=0.8, label="inward light ray from the initial radius")
    a2.set_xlabel("distance from the centre (lab)")
    a2.set_ylabel("lab time t")
    a2.set_title("worldlines of material points")
    a2.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


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
