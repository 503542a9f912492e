"""Proper time accumulated per node of a ``relativistic-rod`` run (docs/media/relativistic-rod.md §4).

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

from typing import Any

import numpy as np

__all__ = ["add_proper_time", "proper_time"]

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
        τ, zero in the first frame, in the units of ``coordinate_time``.

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
    t = np.asarray(ds["coordinate_time"].values, dtype=float)
    rate = 1.0 / np.asarray(ds["lorentz_factor"].values, dtype=float)
    tau = np.zeros_like(t)
    if t.shape[0] < 2:
        return tau
    if method == "simpson" and t.shape[0] >= 3:
        from scipy.integrate import cumulative_simpson

        tau[1:] = cumulative_simpson(rate, x=t, axis=0)
    else:
        tau[1:] = np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t, axis=0), axis=0)
    return tau


def add_proper_time(ds: Any, method: str = "simpson") -> Any:
    """``ds`` with the variable ``proper_time`` ``[time, *nodes]`` (:func:`proper_time`) added in place."""
    tau = proper_time(ds, method)
    dims = ds["lorentz_factor"].dims
    ds["proper_time"] = (dims, tau)
    ds["proper_time"].attrs.update({
        "long_name": f"proper time τ = ∫dt/γ of each node since the first frame ({method} rule over the frames)",
        "units": ds["coordinate_time"].attrs.get("units", "s"),
    })
    return ds
