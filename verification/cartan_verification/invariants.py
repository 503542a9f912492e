"""Invariant checks that apply to any run (VERIFICATION.md §1).

Each function takes the Dataset of :func:`cartan.simulate` and returns one float, the worst
value over the saved frames:

=========================  ==========================================================  =====================
function                   measured                                                    good
=========================  ==========================================================  =====================
temporal_integrability     ``integrability_residual``: stored X vs X of the            round-off (lattice)
                           reconstructed Φ (the space-time plaquette)
spatial_integrability      ``spatial_residual`` (d ≥ 2): ∂_βX_α − ∂_αX_β − [X_α, X_β]   round-off (lattice)
                           or the discrete plaquette holonomy
ring_closure               ``closure_residual``: holonomy around each periodic loop     round-off (lattice)
group_membership           ``group_defect``: ‖ΦᵀΦ − I‖ or the group's relation          round-off (geometric)
energy_balance             |E(t) + D(t) − W(t) − E(0)| / energy scale                   the integrator's order
momentum_drift             |J(t) − J(0)| / momentum scale (free media)                  round-off (symmetric)
dissipation_balance        |E(t) − E(0) + ∫₀ᵗ Σ wᵢNᵢ·ΓNᵢ dt − W(t)| / E(0), the rate      the integrator's order
                           recomputed from the saved velocities and the problem's        (frames saved every
                           dissipative loads (needs the Problem)                          step)
=========================  ==========================================================  =====================

A check that does not apply to the run (no periodic axis, d = 1 for the spatial residual)
returns 0.0.  :func:`check_invariants` applies them all with tolerances and reports pass/fail.

:func:`dissipation_balance` is the energy law of a gradient flow, dE/dt = −⟨N, ΓN⟩, checked
independently of the integrator's own ``dissipated_energy`` account: for the harmonic-map
flow of the sigma model (``harmonic_map_damping``, the ``overdamped`` integrator) it is
dE/dt = −∫|∂_t n|² du (Eells & Sampson 1964); it applies to any run with linear damping,
overdamped or inertial (then E = K + V).  The time integral is the trapezoidal rule over the
saved frames, so it measures the run only when every step (or a fine enough subset) is saved.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

__all__ = [
    "DEFAULT_TOLERANCES",
    "check_invariants",
    "dissipation_balance",
    "dissipation_rate",
    "energy_balance",
    "energy_scale",
    "group_membership",
    "momentum_drift",
    "ring_closure",
    "spatial_integrability",
    "temporal_integrability",
]


def _max_of(ds: xr.Dataset, name: str) -> float:
    if name not in ds:
        return 0.0
    values = np.asarray(ds[name].values, dtype=float)
    if values.size == 0:
        return 0.0
    if not np.all(np.isfinite(values)):
        return math.inf
    return float(np.max(np.abs(values)))


def temporal_integrability(ds: xr.Dataset) -> float:
    """Worst temporal integrability residual over the run (X stored vs X of Φ)."""
    return _max_of(ds, "integrability_residual")


def spatial_integrability(ds: xr.Dataset) -> float:
    """Worst spatial integrability residual (d ≥ 2; 0.0 for d = 1, where it is void)."""
    return _max_of(ds, "spatial_residual")


def ring_closure(ds: xr.Dataset) -> float:
    """Worst ring-closure residual: holonomy around every periodic loop vs the identity
    (0.0 without periodic axes)."""
    return _max_of(ds, "closure_residual")


def group_membership(ds: xr.Dataset) -> float:
    """Worst group defect of the frames (‖ΦᵀΦ − I‖, or the group's defining relation)."""
    return _max_of(ds, "group_defect")


def _energies(ds: xr.Dataset) -> tuple[np.ndarray, ...]:
    def get(name: str) -> np.ndarray:
        if name in ds:
            return np.asarray(ds[name].values, dtype=float)
        return np.zeros(ds.sizes["time"])

    return get("kinetic_energy"), get("potential_energy"), get("dissipated_energy"), get("external_work")


def energy_scale(ds: xr.Dataset) -> float:
    """The run's energy scale: the largest |K| + |V| + |D| + |W| over the frames."""
    K, V, D, W = _energies(ds)
    return float(np.max(np.abs(K) + np.abs(V) + np.abs(D) + np.abs(W)))


def energy_balance(ds: xr.Dataset, relative: bool = True) -> float:
    """max_t |E(t) + dissipated(t) − external_work(t) − E(0)|, E = K + V, divided by
    :func:`energy_scale` (``relative=True``; the absolute value when the scale is 0)."""
    K, V, D, W = _energies(ds)
    E = K + V
    err = np.abs(E + D - W - E[0])
    if not np.all(np.isfinite(err)):
        return math.inf
    worst = float(np.max(err))
    if not relative:
        return worst
    scale = energy_scale(ds)
    return worst / scale if scale > 0 else worst


def momentum_drift(ds: xr.Dataset, relative: bool = True) -> float:
    """max_t |J(t) − J(0)| of the total momentum (spatial frame) relative to max_t |J(t)|
    (absolute when the momentum is zero throughout).  Meaningful for free media only:
    loads and clamped ends exchange momentum with the outside."""
    if "total_momentum" not in ds:
        return 0.0
    J = np.asarray(ds["total_momentum"].values, dtype=float)
    J = J.reshape(J.shape[0], -1)
    if not np.all(np.isfinite(J)):
        return math.inf
    drift = float(np.max(np.linalg.norm(J - J[0], axis=-1)))
    scale = float(np.max(np.linalg.norm(J, axis=-1)))
    return drift / scale if relative and scale > 0 else drift


def dissipation_rate(ds: xr.Dataset, problem: Any) -> np.ndarray:
    """The dissipated power ``Σ_i w_i N_i·Γ N_i`` at every saved frame, ``(time,)``.

    Computed from the saved body velocities ``N`` and the problem's dissipative loads
    (velocity-dependent forces such as :class:`cartan.Damping`, whose power is −T·N), with the
    quadrature weights of the run's scheme.

    Parameters
    ----------
    ds : xarray.Dataset
        A run of :func:`cartan.simulate` (needs ``N`` and ``cartan_config``).
    problem : cartan.Problem
        The problem that was run.

    Returns
    -------
    ndarray, shape ``(time,)``
        −Σ_i w_i T_i·N_i summed over the dissipative loads (≥ 0).
    """
    import json

    from cartan.plugins import get_registry

    loads = [load for load in problem.loads if getattr(load, "dissipative", False)]
    N = np.asarray(ds["N"].values, dtype=float)
    if not loads:
        return np.zeros(N.shape[0])
    for load in loads:
        if getattr(load, "needs_structure_field", False):
            raise ValueError(f"dissipation_balance: the dissipative load {type(load).__name__} needs the structure "
                             "field; only velocity-dependent loads (e.g. cartan.Damping) are supported")
    run = json.loads(ds.attrs["cartan_config"])["run"]
    scheme = get_registry().get("schemes", run.get("scheme", "lattice"))
    weights = scheme(problem, **(run.get("scheme_options") or {})).weights
    t = np.asarray(ds["time"].values, dtype=float)
    rate = np.zeros(N.shape[0])
    for load in loads:
        for k in range(N.shape[0]):
            T = np.asarray(load.force(None, N[k], float(t[k])), dtype=float)
            rate[k] -= float(np.sum(weights * np.einsum("...i,...i->...", T, N[k])))
    return rate


def dissipation_balance(ds: xr.Dataset, problem: Any, relative: bool = True) -> float:
    """max_t |E(t) − E(0) + ∫₀ᵗ P dt − W(t)|, E = K + V, with the dissipated power P of
    :func:`dissipation_rate` integrated by the trapezoidal rule over the saved frames;
    divided by E(0) (``relative=True``, absolute when E(0) = 0).  0.0 without dissipative loads.

    For a gradient flow saved at every step this is the discrete defect of the energy law
    dE/dt = −⟨N, ΓN⟩: O(Δt^p) for an integrator of order p.
    """
    rate = dissipation_rate(ds, problem)
    if not np.any(rate):
        return 0.0
    K, V, _, W = _energies(ds)
    E = K + V
    t = np.asarray(ds["time"].values, dtype=float)
    dissipated = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t))])
    err = np.abs(E - E[0] + dissipated - W)
    if not np.all(np.isfinite(err)):
        return math.inf
    worst = float(np.max(err))
    return worst / abs(float(E[0])) if relative and E[0] != 0 else worst


#: Tolerances of :func:`check_invariants` for a lattice run with a geometric integrator: the
#: geometric residuals are round-off (a few hundred ulps of the O(1) group elements, after
#: thousands of steps); the energy balance is the integrator's O(Δt^p) error at a resolved Δt;
#: a check set to ``None`` is reported but not judged.
DEFAULT_TOLERANCES: dict[str, float | None] = {
    "temporal_integrability": 1e-10,
    "spatial_integrability": 1e-10,
    "ring_closure": 1e-10,
    "group_membership": 1e-10,
    "energy_balance": 1e-2,
    "momentum_drift": None,
    "dissipation_balance": None,
}

CHECKS = {
    "temporal_integrability": temporal_integrability,
    "spatial_integrability": spatial_integrability,
    "ring_closure": ring_closure,
    "group_membership": group_membership,
    "energy_balance": energy_balance,
    "momentum_drift": momentum_drift,
}


def check_invariants(ds: xr.Dataset, tolerances: Mapping[str, float | None] | None = None,
                     problem: Any = None) -> dict[str, Any]:
    """Apply every invariant check to ``ds``.

    Parameters
    ----------
    ds : xarray.Dataset
        A run of :func:`cartan.simulate`.
    tolerances : mapping, optional
        Overrides of :data:`DEFAULT_TOLERANCES` (``None`` reports a check without judging it).
    problem : cartan.Problem, optional
        The problem that was run: adds :func:`dissipation_balance` (reported, judged when a
        tolerance is given).

    Returns
    -------
    dict
        ``{check: {"value": float, "tolerance": float | None, "passed": bool | None}}`` and
        ``"passed"``: True when every judged check passed.
    """
    tol = {**DEFAULT_TOLERANCES, **dict(tolerances or {})}
    checks: dict[str, Any] = dict(CHECKS)
    checks["dissipation_balance"] = None if problem is None else (lambda d: dissipation_balance(d, problem))
    unknown = sorted(set(tol) - set(checks))
    if unknown:
        raise ValueError(f"unknown invariant checks {unknown}; choose from {sorted(checks)}")
    report: dict[str, Any] = {}
    ok = True
    for name, fn in checks.items():
        if fn is None:
            continue
        value = fn(ds)
        limit = tol[name]
        passed = None if limit is None else bool(value <= limit)
        ok = ok and passed is not False
        report[name] = {"value": value, "tolerance": limit, "passed": passed}
    report["passed"] = ok
    return report
