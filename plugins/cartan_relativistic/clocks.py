"""Proper time per node of a ``relativistic-rod`` run from its saved frames (docs/media/relativistic-rod.md §4).

A run with ``clocks=True`` (the elastic string's default) accumulates τ during the run, step by
step (the output ``proper_time``, :meth:`cartan_relativistic.string.RelativisticRod.accumulator_rates`);
this module rebuilds it afterwards from the frames of any run.

A node's clock runs at ``dτ = dt/γ``, ``t`` its lab (coordinate) time r⁰/c and γ its Lorentz
factor: both are outputs of every saved frame (``coordinate_time``, ``lorentz_factor``, paper
§VIII.C).  The proper time elapsed since the first frame is their integral over the saved
frames,

    τ_i(t_k) = ∫_{t_i(0)}^{t_i(t_k)} dt/γ_i,

by the cumulative Simpson rule (error O(Δt_s⁴) for a smooth γ, Δt_s the save interval; exact
for constant and linear 1/γ) or, with ``method="trapezoid"``, the cumulative trapezoidal rule
(O(Δt_s²)).  The integral is taken in the node's own coordinate time, so it holds for every
gauge the medium runs: the temporal gauge of the elastic string (t_i = t), the conformal–temporal
gauge of the Nambu–Goto string, and the ``kinematic`` runs in proper time (where it returns the
run's own time back).
"""

from __future__ import annotations

import sys
from typing import Any

import numpy as np

__all__ = ["add_proper_time", "draw_clocks", "main", "proper_time"]

#: the integration rules of :func:`proper_time`
METHODS = ("simpson", "trapezoid")


def proper_time(ds: Any, method: str = "simpson") -> np.ndarray:
    """The proper time τ accumulated by every node since the first saved frame.

    Parameters
    ----------
    ds : xarray.Dataset
        A run of ``relativistic-rod`` (any energy) with the outputs ``coordinate_time`` and
        ``lorentz_factor`` ``[time, *nodes]``.
    method : {"simpson", "trapezoid"}
        The cumulative quadrature over the saved frames (module docstring).

    Returns
    -------
    numpy.ndarray ``[time, *nodes]``
        τ, zero in the first frame, in the units of ``coordinate_time``; NaN after the first
        frame at a node whose coordinate time does not increase from frame to frame (no
        worldline to integrate along: a clamped end of the elastic string in files written
        before its ``coordinate_time`` advanced with the lab time; a clamped end of the
        Nambu–Goto string, whose event the core holds, in files written before the medium
        refused it).

    Raises
    ------
    ValueError
        When ``method`` is not one of :data:`METHODS`, or ``ds`` lacks the two outputs.
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    missing = [k for k in ("coordinate_time", "lorentz_factor") if k not in ds]
    if missing:
        raise ValueError(f"ds must be a relativistic-rod run with the outputs coordinate_time and lorentz_factor; "
                         f"missing {missing}")
    t_all = np.asarray(ds["coordinate_time"].values, dtype=float)
    rate_all = 1.0 / np.asarray(ds["lorentz_factor"].values, dtype=float)
    tau = np.zeros_like(t_all)
    if t_all.shape[0] < 2:
        return tau
    shape = t_all.shape
    t, rate, out = t_all.reshape(shape[0], -1), rate_all.reshape(shape[0], -1), tau.reshape(shape[0], -1)
    # a node whose coordinate time does not advance has no worldline to integrate along: NaN (a
    # clamped end in files written before its coordinate_time advanced with the lab time)
    moving = np.all(np.diff(t, axis=0) > 0, axis=0)
    out[1:, ~moving] = np.nan
    t, rate = t[:, moving], rate[:, moving]
    if method == "simpson" and t.shape[0] >= 3:
        from scipy.integrate import cumulative_simpson

        out[1:, moving] = cumulative_simpson(rate, x=t, axis=0)
    else:
        out[1:, moving] = np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t, axis=0), axis=0)
    return tau


def add_proper_time(ds: Any, method: str = "simpson") -> Any:
    """``ds`` with the variable ``proper_time`` ``[time, *nodes]`` (:func:`proper_time`) added in place
    (replacing the one a run with ``clocks`` accumulated)."""
    tau = proper_time(ds, method)
    dims = ds["lorentz_factor"].dims
    ds["proper_time"] = (dims, tau)
    ds["proper_time"].attrs.update({
        "long_name": f"proper time τ = ∫dt/γ of each node since the first frame ({method} rule over the frames)",
        "units": ds["coordinate_time"].attrs.get("units", "s"),
    })
    return ds


def draw_clocks(ds: Any, fig: Any, nodes: int = 6) -> None:
    """The clocks of a run with ``clocks``: the worldlines of ``nodes`` material points in the lab
    (x against t, left) and each one's lag t − τ behind the lab time (right: the accumulated
    ``proper_time`` as lines, the quadrature over the saved frames, :func:`proper_time`, as dots
    where it exists).

    Raises
    ------
    ValueError
        When ``ds`` has no ``proper_time`` (a run without ``clocks``).
    """
    if "proper_time" not in ds:
        raise ValueError("ds must be a relativistic-rod run with clocks=True (the output proper_time)")
    import matplotlib as mpl

    t = np.asarray(ds["time"].values, dtype=float)
    tau = np.asarray(ds["proper_time"].values, dtype=float)
    x = np.asarray(ds["lab_x"].values, dtype=float)
    framed = proper_time(ds, "trapezoid") if "coordinate_time" in ds else None
    n = tau.shape[1]
    pick = np.unique(np.linspace(0, n - 1, min(nodes, n)).round().astype(int))
    colors = mpl.colormaps["viridis"](np.linspace(0.0, 0.9, len(pick)))
    left, right = fig.subplots(1, 2)
    u = np.asarray(ds["node"].values) if "node" in ds.coords else np.arange(n)
    for c, i in zip(colors, pick, strict=True):
        label = f"node {i}" + (f" (u = {float(u[i]):.3g})" if "node" in ds.coords else "")
        left.plot(x[:, i], t, color=c, lw=1.2, label=label)
        right.plot(t, t - tau[:, i], color=c, lw=1.4, label=label)
        if framed is not None and np.all(np.isfinite(framed[:, i])):
            right.plot(t[::4], (t - framed[:, i])[::4], "o", color=c, ms=3)
    left.set_xlabel("lab x")
    left.set_ylabel("lab time t")
    left.set_title("worldlines")
    right.set_xlabel("lab time t")
    right.set_ylabel("t − τ")
    right.set_title("clock lag t − τ (lines: in the run; dots: from the frames)")
    right.legend(fontsize=7, loc="upper left")


def main(argv: list[str] | None = None) -> int:
    """``python -m cartan_relativistic.clocks RUN.nc OUT.png``: the clock chart of a run (:func:`draw_clocks`)."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 2:
        print("usage: python -m cartan_relativistic.clocks RUN.nc OUT.png")
        return 2
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    import cartan

    ds = cartan.open(args[0])
    fig = Figure(figsize=(11, 4), layout="constrained")
    draw_clocks(ds, fig)
    fig.savefig(args[1], dpi=110)
    t = float(ds["time"].values[-1])
    lag = t - np.asarray(ds["proper_time"].values[-1], dtype=float)
    print(f"t = {t:g}: lag t − τ from {lag.min():.4g} to {lag.max():.4g} over the nodes")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
