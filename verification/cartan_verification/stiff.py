"""Stability map of a stiff rod: largest stable Δt against dx, explicit against implicit.

The problem (:func:`stiff_rod`) is a thin cantilever — a ``cosserat-rod`` whose radius is much
smaller than the node spacing — set into a bending motion.  Its fastest semi-discrete modes
are the stretch and shear modes (ω_max ≈ 2√(α_cGA/ρI) for the shear–rotation mode when
radius ≪ dx), orders of magnitude faster than the bending motion, so an explicit integrator
must resolve them: ``lie-verlet`` is stable only up to Δt ≈ 2/ω_max (the CFL estimate of
:meth:`cartan.integrators.base.Integrator.dt_max`).  ``implicit-midpoint`` is A-stable for the
linearised system; for this large-amplitude bending motion its Δt is limited by the nonlinear
coupling of the unresolved stiff modes (and by Newton's method), far above the explicit limit.

:func:`stability_map` bisects the largest stable Δt of both integrators at several dx with
:func:`cartan.study.stability` and returns one Dataset; :func:`plot_stability_map` charts it.
At the default settings (dx = 0.1, 0.05, 0.025; 100 steps per trial for implicit-midpoint, 400
for lie-verlet) the map takes about 20–40 s on one core.
"""

from __future__ import annotations

import functools
import math
import os
import pathlib
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

import cartan

from .case import Case

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

    from cartan.problem import Problem

__all__ = ["STIFF_ROD", "StiffRodStability", "plot_stability_map", "stability_map", "step_cost", "stiff_rod"]

#: material of the stiff rod: radius ≪ dx, so stretch and shear are far stiffer than bending
STIFF_ROD = {"E": 1e6, "poisson": 0.5, "radius": 1e-3, "density": 1000.0}


def stiff_rod(n: int, length: float = 1.0, tip_speed: float = 0.1, **material: float) -> Problem:
    """A straight cantilever (clamped at u = 0, free at u = L) in a bending motion.

    Parameters
    ----------
    n : int
        Number of nodes (≥ 3); dx = L/(n − 1).
    length : float
        L > 0.
    tip_speed : float
        Initial transverse velocity V₂ = tip_speed·(u/L)² with the matching rotation rate
        Ω₃ = ∂V₂/∂u (no initial shear rate), so the motion starts as pure bending.
    **material
        ``cosserat-rod`` parameters overriding :data:`STIFF_ROD`.

    Returns
    -------
    cartan.Problem
    """
    if isinstance(n, bool) or int(n) != n or n < 3:
        raise ValueError(f"n must be an integer ≥ 3, got {n!r}")
    if not (math.isfinite(length) and length > 0):
        raise ValueError(f"length must be finite and > 0, got {length!r}")
    if not math.isfinite(tip_speed):
        raise ValueError(f"tip_speed must be finite, got {tip_speed!r}")
    rod = cartan.medium("cosserat-rod", **{**STIFF_ROD, **material})
    grid = cartan.Grid(int(n), length=length)
    u = grid.coordinates(0)
    N = np.zeros((int(n), 6))
    N[:, 1] = tip_speed * (u / length) ** 2
    N[:, 5] = 2.0 * tip_speed * u / length**2
    initial = rod.initial_state(grid, "straight", velocity=N)
    return cartan.Problem(rod, grid, initial, {"start": cartan.Clamped()}, name="stiff-cantilever")


def stability_map(n_values: Sequence[int] = (11, 21, 41), *, steps_implicit: int = 100, steps_explicit: int = 400,
                  rtol: float = 0.05, implicit_bracket: tuple[float, float] = (1.0, 4096.0),
                  explicit_bracket: tuple[float, float] = (1 / 8, 8.0), client: Any = None,
                  **problem: Any) -> xr.Dataset:
    """Largest stable Δt against dx for ``lie-verlet`` and ``implicit-midpoint`` on :func:`stiff_rod`.

    Each Δt_max is bisected by :func:`cartan.study.stability` (a trial Δt is stable when
    ``steps`` steps run without blow-up — for the implicit integrator also without a Newton
    failure, which :func:`cartan.simulate` reports as an instability — and the energy-balance
    error stays below 10 × the initial energy over the trial's fixed physical time), in
    ``bracket`` × the explicit CFL estimate 2/ω_max of the grid, to relative ``rtol``.

    Parameters
    ----------
    n_values : sequence of int
        Grid sizes (dx = L/(n − 1)).
    steps_implicit, steps_explicit : int
        Steps per trial run.
    rtol : float
        Relative width of the final bisection bracket.
    implicit_bracket, explicit_bracket : (float, float)
        Bisection brackets in units of the CFL estimate.
    client
        Passed to :func:`cartan.study.stability` (None: in this process).
    **problem
        Keywords of :func:`stiff_rod` (``length``, ``tip_speed``, material parameters).

    Returns
    -------
    xarray.Dataset
        dims ``(integrator, n)`` = ``(["lie-verlet", "implicit-midpoint"], n_values)``:
        ``dt_max``, ``dt_cfl``, ``dt_reference`` (the explicit estimate, for both), ``h``,
        ``ratio`` = dt_max/dt_reference, ``runs``, ``bracketed`` (0: stable at the top of the
        bracket, so dt_max is a lower bound).
    """
    import xarray as xr

    from cartan.study import stability

    factory = functools.partial(stiff_rod, **problem)
    parts = [
        stability(factory, "lie-verlet", n_values, steps=steps_explicit, rtol=rtol, bracket=explicit_bracket,
                  client=client),
        stability(factory, "implicit-midpoint", n_values, steps=steps_implicit, rtol=rtol,
                  bracket=implicit_bracket, client=client),
    ]
    ds = xr.concat(parts, dim="integrator", data_vars="all", coords="different", compat="equals",
                   combine_attrs="drop_conflicts")
    ds.attrs.update({
        "title": "stiff cantilever: largest stable Δt against dx",
        "steps_implicit": int(steps_implicit),
        "steps_explicit": int(steps_explicit),
        "implicit_bracket": list(implicit_bracket),
        "explicit_bracket": list(explicit_bracket),
        "problem": repr({**STIFF_ROD, **problem}),
    })
    return ds


def step_cost(n: int, factor: float, steps: int = 100, integrator_options: dict[str, Any] | None = None,
              **problem: Any) -> dict[str, float]:
    """Cost and accuracy of ``implicit-midpoint`` on :func:`stiff_rod` at ``factor`` × the CFL estimate.

    Runs ``steps`` steps (no output, no guard) and returns the CFL estimate ``dt_cfl`` and
    ``dt``, the wall time per step ``ms_per_step`` (the integrator's own clock, energies
    excluded), ``newton_per_step`` (Newton iterations per step), ``forces_per_step`` (force
    evaluations per step, finite-difference Jacobians included), ``jacobians``, the largest
    relative energy error ``energy_error`` = max_k |E_k − E_0|/E_0 over the steps and the
    largest group defect of the frames at the end, ``defect``.
    """
    from cartan.integrators.explicit import LieVerlet
    from cartan.integrators.implicit import ImplicitMidpoint
    from cartan.schemes.lattice import Lattice

    if not (math.isfinite(factor) and factor > 0):
        raise ValueError(f"factor must be finite and > 0, got {factor!r}")
    if isinstance(steps, bool) or int(steps) != steps or steps < 1:
        raise ValueError(f"steps must be an integer ≥ 1, got {steps!r}")
    prob = stiff_rod(n, **problem)
    scheme = Lattice(prob)
    state = scheme.initial_state()
    dt_cfl = float(LieVerlet().dt_max(scheme, state))
    dt = factor * dt_cfl
    integ = ImplicitMidpoint(**(integrator_options or {}))
    e0 = scheme.kinetic_energy(state) + scheme.potential_energy(state)
    err = 0.0
    for _ in range(int(steps)):
        integ.step(scheme, state, dt)
        err = max(err, abs(scheme.kinetic_energy(state) + scheme.potential_energy(state) - e0) / abs(e0))
    defect = float(np.max(scheme.group.defect(scheme.frames(state))))
    return {"n": int(n), "dt_cfl": dt_cfl, "dt": dt, "ms_per_step": 1e3 * integ.wall_time / integ.nstep,
            "newton_per_step": integ.newton_iterations / integ.nstep, "forces_per_step": integ.nforce / integ.nstep,
            "jacobians": integ.jacobians, "energy_error": err, "defect": defect}


def plot_stability_map(ds: xr.Dataset, path: str | os.PathLike) -> pathlib.Path:
    """Chart a :func:`stability_map` Dataset: Δt_max against dx (log–log) per integrator, the
    explicit CFL estimate dashed; open triangles mark lower bounds (stable at the top of the
    bracket), and the implicit/explicit ratio is annotated at each dx.  Writes a PNG."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.8), constrained_layout=True)
    h = np.asarray(ds["h"].isel(integrator=0).values, float)
    ref = np.asarray(ds["dt_reference"].isel(integrator=0).values, float)
    ax.loglog(h, ref, "k--", lw=1, label="explicit CFL estimate 2/ω_max")
    values = {}
    for integ in ds["integrator"].values:
        sel = ds.sel(integrator=integ)
        dtm = np.asarray(sel["dt_max"].values, float)
        exact = np.asarray(sel["bracketed"].values, float) > 0
        ok = np.isfinite(dtm) & (dtm > 0)
        values[str(integ)] = np.where(ok, dtm, np.nan)
        line = ax.loglog(h[ok], dtm[ok], "o-", label=f"{integ}: largest stable Δt")[0]
        low = ok & ~exact
        if low.any():
            ax.loglog(h[low], dtm[low], "^", mfc="none", ms=10, color=line.get_color(),
                      label=f"{integ}: stable at the top of the bracket (lower bound)")
    if "lie-verlet" in values and "implicit-midpoint" in values:
        for x, a, b in zip(h, values["lie-verlet"], values["implicit-midpoint"], strict=True):
            if np.isfinite(a) and np.isfinite(b):
                ax.annotate(f"×{b / a:.0f}", (x, b), textcoords="offset points", xytext=(4, 6), fontsize=8)
    ax.set_xlabel("dx")
    ax.set_ylabel("Δt")
    return cartan.study.finish_chart(fig, ax, path, ds.attrs.get("title", "stability map"))


class StiffRodStability(Case):
    """The stiff cantilever's stability map as a report section (``kind = "stability"``).

    Checks, at every dx of the map: ``implicit-midpoint`` is stable at ≥ 10× the explicit CFL
    estimate (its whole point), and ``lie-verlet``'s bisected limit lies within a factor 2 of
    that estimate (the estimate, 2/ω_max of the linearised lattice force, predicts the explicit
    limit: a leapfrog-type method is stable up to ωΔt = 2 for the fastest mode).
    """

    name = "rod-stiff-stability"
    medium = "cosserat-rod"
    kind = "stability"
    description = "thin cantilever (radius 1e-3 ≪ dx) in bending: largest stable Δt against dx, explicit vs implicit"
    reference = "the explicit CFL estimate 2/ω_max (power iteration on the linearised lattice force)"
    quantity = "largest stable Δt (bisected) relative to the explicit estimate"
    norm = "ratio dt_max / dt_cfl(lie-verlet)"
    tolerance = 10.0
    tolerance_reason = ("implicit-midpoint stable at ≥ 10× the explicit limit at every dx; lie-verlet's limit "
                        "within [1/2, 2] of its CFL estimate")
    default_integrators = ("lie-verlet", "implicit-midpoint")
    levels = (0, 1, 2)
    #: grid sizes of the quick map (dx = 0.1, 0.05, 0.025); the full run adds dx = 0.0125
    n_values = (11, 21, 41)

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        """The stiff cantilever at ``n_values[level]`` and a run of 100 steps at 10× the explicit limit."""
        n = self.n_values[int(level)] if int(level) < len(self.n_values) else 2 * self.n_values[-1] - 1
        return stiff_rod(n, tip_speed=0.01), {"dt": 5e-4, "t_end": 5e-2, "save_every": 10}

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        """Not a convergence case: no reference solution (NaN)."""
        return math.nan

    def report_section(self, out_dir: Any, quick: bool, client: Any = None) -> tuple[str, list, int, int]:
        n_values = self.n_values if quick else (*self.n_values, 2 * self.n_values[-1] - 1)
        ds = stability_map(n_values, client=client)
        chart = plot_stability_map(ds, pathlib.Path(out_dir) / f"{self.name}.png")
        ref = np.asarray(ds["dt_reference"].isel(integrator=0).values, float)
        h = np.asarray(ds["h"].isel(integrator=0).values, float)
        explicit = np.asarray(ds["dt_max"].sel(integrator="lie-verlet").values, float) / ref
        implicit = np.asarray(ds["dt_max"].sel(integrator="implicit-midpoint").values, float) / ref
        lower = np.asarray(ds["bracketed"].sel(integrator="implicit-midpoint").values, float) == 0
        rows, failed = [], 0
        for k in range(len(h)):
            ok_e = bool(0.5 <= explicit[k] <= 2.0)
            ok_i = bool(implicit[k] >= 10.0)
            failed += (not ok_e) + (not ok_i)
            bound = " (lower bound: stable at the top of the bracket)" if lower[k] else ""
            rows.append(f"| {h[k]:.4g} | {ref[k]:.3g} | {explicit[k]:.2f} | {'pass' if ok_e else '**FAIL**'} "
                        f"| {implicit[k]:.0f}{bound} | {'pass' if ok_i else '**FAIL**'} |")
        text = (f"\n## Stability: `{self.name}`\n\n{self.description}.  Each largest stable Δt is bisected by "
                "`cartan.study.stability` (a trial is stable when it neither blows up nor lets the energy-balance "
                "error exceed 10× the initial energy over a fixed physical time; for implicit-midpoint a Newton "
                f"failure counts as unstable).  Checks: {self.tolerance_reason}.  Chart: [stability map]({chart.name})."
                "\n\n| dx | explicit CFL estimate [s] | lie-verlet Δt_max / estimate | result "
                "| implicit-midpoint Δt_max / estimate | result |\n|---|---|---|---|---|---|\n"
                + "\n".join(rows) + "\n")
        return text, [ds], 2 * len(h), failed
