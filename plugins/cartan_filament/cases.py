"""Verification cases of the Kirchhoff filament (paper §VII.A): static equilibria with the
strain constraint θ = (1, 0, 0) held by Lagrange multipliers (:func:`cartan.solve_static`,
:func:`cartan.continuation`), refined in space on the lattice; Michell's instability of the
twisted closed ring on a periodic lattice (:func:`michell_ring`); Greenhill's twist buckling of
the clamped–clamped column (:class:`FilamentGreenhill`); and the cross-medium limit of
the Cosserat rod (:func:`cosserat_limit`).

The references are those of the ``cosserat-rod`` cases
(:mod:`cartan_verification.references`); the elastica and Euler cases reuse their classes with
the filament in place of the stiff planar rod.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from cartan_verification.case import StaticCase
from cartan_verification.cases_static import CantileverElastica, EulerBuckling
from cartan_verification.references import euler_critical_load

import cartan

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

    from cartan.problem import Problem

__all__ = ["FilamentCantileverElastica", "FilamentEulerBuckling", "FilamentGreenhill", "KirchhoffAnalogy",
           "MichellRing", "all_cases", "cosserat_limit", "greenhill_clamped", "kirchhoff_drifts", "michell_ring"]


def _filament(**params: Any):
    return cartan.medium("filament", **params)


def _constraint_residual(ds: xr.Dataset) -> float:
    """The largest strain-constraint residual max|θ − (1, 0, 0)| recorded in ``ds``."""
    return float(np.max(np.asarray(ds["constraint_residual"].values)))


# ---------------------------------------------------------------------------- cantilever elastica
class FilamentCantileverElastica(CantileverElastica):
    """The inextensible cantilever elastica with the filament (B = C = 1, L = 1): clamped at
    s = 0, dead tip force α·B/L² along −y, continuation from 0 to α = 10 through α = 1 and 2.

    The constraint θ = (1, 0, 0) holds to round-off at every path point (an inextensible rod,
    not the stiff limit of ``rod-cantilever-elastica``): the error is the discretisation's
    alone, O(h²); n = 10·2^level + 1.
    """

    name = "filament-cantilever-elastica"
    medium = "filament"
    description = "inextensible filament: cantilever elastica under a tip dead load, PL²/B = 1, 2, 10"
    tolerance = 2e-4
    tolerance_reason = ("n = 10·2^level + 1; the O(h²) error is 2.6e-5 at n = 81 (α = 10, tip vertical; "
                        "measured) and 1.05e-4 at n = 41: 2e-4 holds from n = 41 on")

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        rod = _filament()
        grid = cartan.Grid(10 * 2**level + 1, length=1.0)
        prob = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                              {"start": cartan.Clamped(), "end": cartan.Free(load=[0.0, -1.0, 0.0, 0.0, 0.0, 0.0])},
                              name=self.name)
        return prob, {"lam_max": max(self.loads), "ds0": self.ds0, "stops": list(self.loads[:-1]), "detect": False}

    def parts(self, ds: xr.Dataset) -> dict[str, float]:
        out = super().parts(ds)
        out["constraint residual"] = _constraint_residual(ds)
        return out


# ---------------------------------------------------------------------------- Euler buckling
class FilamentEulerBuckling(EulerBuckling):
    """Euler buckling of a pinned–pinned inextensible filament (B₃ = 1 for bending in x–y,
    B₂ = 2 so that the first mode is simple, C = 1, L = 1) under an axial dead load λ at the
    end, followed by continuation to 1.5 π²B₃/L² with branch switching at the located
    bifurcation.  The pins are the continuation's multipliers: start x, y, z and the rotation
    about the axis x (a three-dimensional column held by position pins alone keeps its rigid
    spin about the axis), end y and z (it slides along x).

    References and error as for ``rod-euler-buckling``: P_cr = π²B/L² (Euler) and the
    pinned–pinned elastica at P/P_cr = 1.5 (Love §263: w/L = 0.394288, Δ/L = 0.636412), the
    largest of the three relative errors, O(h²); n = 10·2^level + 1.
    """

    name = "filament-euler-buckling"
    medium = "filament"
    description = ("inextensible filament, pinned–pinned Euler buckling: P_cr = π²B/L² and the post-buckled "
                   "elastica at P = 1.5 P_cr")
    tolerance = 1e-3
    tolerance_reason = ("n = 10·2^level + 1; O(h²) errors, the largest 2.6e-4 at n = 81 and 1.0e-3 at n = 41 "
                        "(measured); asked within 1e-3 at n = 81")

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        rod = _filament(bending=[2.0, 1.0])
        n = 10 * 2**level + 1
        grid = cartan.Grid(n, length=1.0)
        prob = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                              {"start": cartan.Free(), "end": cartan.Free(load=[-1.0, 0.0, 0.0, 0.0, 0.0, 0.0])},
                              name=self.name)
        return prob, {"lam_max": self.load_ratio * euler_critical_load(1.0, 1.0), "ds0": self.ds0,
                      "pins": {"start": (0, 1, 2, 3), "end": (1, 2)}}

    def parts(self, ds: xr.Dataset) -> dict[str, float]:
        out = super().parts(ds)
        out["constraint residual"] = _constraint_residual(ds)
        return out


# ---------------------------------------------------------------------------- Kirchhoff analogy
def kirchhoff_drifts(ds: xr.Dataset, medium: Any, scales: Mapping[str, float] | None = None) -> dict[str, float]:
    """Drift (max − min over the edges) of the Kirchhoff invariants of a static solution.

    Parameters
    ----------
    ds : xarray.Dataset
        A :func:`cartan.solve_static` result of a filament (``X``, ``constraint_force``).
    medium : Filament
        The filament solved (𝔹, π⁰).
    scales : mapping, optional
        Divide each drift by ``scales[name]`` (default 1).

    Returns
    -------
    dict ``{"n_norm", "m_dot_n", "twist_moment", "hamiltonian"}`` of floats.
    """
    X = np.asarray(ds["X"].isel(time=0).values).reshape(-1, 6)
    n = np.asarray(ds["constraint_force"].isel(time=0).values)
    inv = medium.kirchhoff_invariants(X, n)
    scales = scales or {}
    return {k: float(np.ptp(v)) / float(scales.get(k, 1.0)) for k, v in inv.items()}


class KirchhoffAnalogy(StaticCase):
    """Kirchhoff's kinetic analogy along a three-dimensional static solution (paper §VII.A):
    a filament (B₂ = B₃ = 1, C = 0.7, no natural curvature, L = 1) clamped at s = 0 under a dead
    tip wrench F = (0.5, −1.5, 1.0), M = (0.4, 0.3, −0.5).  With no distributed load the
    spatial force is constant, so |n|, m·n, the twist moment m₁ (isotropic bending) and
    H = ½ m·𝔹⁻¹m + n·d₁ are first integrals in s.

    On the lattice the edge quantities m_e = 𝔹(π_e − π⁰), n_e (the constraint multipliers)
    conserve them to O(h²): the error is the largest drift (max − min over the edges), each
    divided by its scale (|F|, |F|·|M|, |M|, ½|M|²/B + |F|).  n = 10·2^level + 1.
    """

    name = "filament-kirchhoff-analogy"
    medium = "filament"
    description = "Kirchhoff analogy: |n|, m·n, m₃ and H constant along a 3-D static filament"
    reference = "first integrals of the Kirchhoff equilibrium (Kirchhoff 1859; paper §VII.A): zero drift in s"
    quantity = "drift (max − min over the edges) of |n|, m·n, the twist moment and H"
    norm = "max of the four drifts, each relative to its scale"
    space_order = 2.0
    levels = (0, 1, 2, 3)
    tolerance = 1e-3
    tolerance_reason = ("n = 10·2^level + 1; O(h²) drift, 1.3e-5 at n = 81 and 1.9e-4 at n = 21 (measured: "
                        "|n|); 1e-3 is the bound asked")

    force = (0.5, -1.5, 1.0)
    moment = (0.4, 0.3, -0.5)
    twist = 0.7

    def medium_obj(self):
        return _filament(bending=1.0, twist=self.twist)

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        rod = self.medium_obj()
        grid = cartan.Grid(10 * 2**level + 1, length=1.0)
        prob = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                              {"start": cartan.Clamped(),
                               "end": cartan.Free(load=[*self.force, *self.moment])}, name=self.name)
        return prob, {"load_steps": 4, "max_iter": 30}

    def scales(self) -> dict[str, float]:
        f, m = float(np.linalg.norm(self.force)), float(np.linalg.norm(self.moment))
        return {"n_norm": f, "m_dot_n": f * m, "twist_moment": m, "hamiltonian": 0.5 * m * m + f}

    def parts(self, ds: xr.Dataset, problem: Problem) -> dict[str, float]:
        out = kirchhoff_drifts(ds, problem.medium, self.scales())
        out["constraint residual"] = _constraint_residual(ds)
        return out

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        return float(max(self.parts(ds, problem).values()))


# ---------------------------------------------------------------------------- closed filaments: Michell
def _ring_problem(n: int, bending: float, twist: float, rest_twist: float, radius: float) -> Problem:
    rod = _filament(bending=bending, twist=twist, rest_twist=rest_twist)
    grid = cartan.Grid(n, length=2.0 * np.pi * radius, periodic=True)
    return cartan.Problem(rod, grid, rod.initial_state(grid, "ring"), {}, name="filament-michell-ring")


def _symmetry_generators(Phi: np.ndarray) -> np.ndarray:
    """The 7 null directions of a closed isotropic ring ``[7, 6n]`` (body components, translation
    first): the six rigid motions, V = Rᵀ(v + ω × x), Ω = Rᵀω, and the material rotation about
    the tangents, Ω = (1, 0, 0) at every node (the energy of B₂ = B₃ does not see it)."""
    x, R = Phi[:, 1:, 0], Phi[:, 1:, 1:]
    RT = np.swapaxes(R, -1, -2)
    rows = []
    for k in range(3):
        e = np.eye(3)[k]
        rows.append(np.concatenate([RT @ e, np.zeros_like(x)], axis=-1).ravel())
        rows.append(np.concatenate([np.einsum("nij,nj->ni", RT, np.cross(e, x)), RT @ e], axis=-1).ravel())
    rows.append(np.concatenate([np.zeros_like(x), np.broadcast_to([1.0, 0.0, 0.0], x.shape)], axis=-1).ravel())
    return np.array(rows)


def michell_ring(n: int, twist: float = 1.0, bending: float = 1.0, radius: float = 1.0) -> dict[str, Any]:
    """The critical twist moment of a closed circular filament on the lattice (Michell 1889).

    A naturally straight, isotropic filament (B₂ = B₃ = B, twist stiffness C) closed into the
    circle of radius R with the material frame untwisted (π₁ = 0) and the natural twist π₁⁰ = −t
    carries the twist moment m₁ = C(π₁ − π₁⁰) = Ct: the energy depends on π₁ − π₁⁰ only, so this
    is Michell's twisted ring (twist density t, total twist Tw = tR) without the integer
    closure of a twisted frame.  The circle is an equilibrium for every t (the multipliers
    carry the binormal force n₃ = m₁/R); it is stable until

        m₁R/B = √3        (Michell 1889; Tw = √3 B/C),

    where mode-2 out-of-plane perturbations cost no energy.

    On the lattice the configuration does not change with t and the multipliers are linear in
    t, so the static Jacobian (:class:`cartan.statics._Equilibrium`, the saddle point matrix of
    §IV.E) is affine in t: K(t) = K₀ + tK₁ exactly.  Its symmetric force block restricted to
    the kernel of the constraint rows and of the seven symmetry directions
    (:func:`_symmetry_generators`) is negative definite at t = 0, and the critical t is the
    smallest positive t at which it is singular: 1/t_c is the largest eigenvalue of the
    symmetric-definite pencil (Z ᵀK₁Z, −ZᵀK₀Z) (linear buckling, exact here).

    Parameters
    ----------
    n : int
        Nodes of the periodic grid (≥ 8).
    twist, bending, radius : float
        C, B, R > 0.

    Returns
    -------
    dict
        ``"critical"`` (m₁R/B at the instability on the lattice), ``"reference"`` (√3),
        ``"equilibrium_residual"`` (max |F_int + B_cᵀν| at t = t_c, relative to m₁/R),
        ``"constraint_residual"`` (max |θ − (1, 0, 0)| of the ring), ``"eig_at_critical"``
        (the largest eigenvalue of the restricted block at t_c, relative to its scale: zero
        when K is affine in t), ``"binormal_force"`` (the multiplier n₃ R/m₁ at t_c, 1 in the
        continuum), ``"wall_time"``.
    """
    import time

    import scipy.linalg as sl

    from cartan.statics import _Equilibrium

    if int(n) != n or n < 8:
        raise ValueError(f"n must be an integer ≥ 8, got {n!r}")
    for name, v in (("twist", twist), ("bending", bending), ("radius", radius)):
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
    start = time.perf_counter()

    def block(t: float):
        eq = _Equilibrium(_ring_problem(int(n), bending, twist, -t, radius), probe_lam=0.0)
        state = eq.state0
        F = eq.residual(state, np.zeros(eq.nmult), 0.0)[: eq.nunk]
        Bc = eq._constraint_matrix(state).toarray()
        mu = np.linalg.lstsq(Bc.T, -F, rcond=None)[0]  # the multipliers that balance the ring
        res = eq.residual(state, mu, 0.0)
        K = eq.jacobian(state, mu, 0.0).toarray()
        H = 0.5 * (K[: eq.nunk, : eq.nunk] + K[: eq.nunk, : eq.nunk].T)
        Phi = eq.sch.frames(state).reshape(-1, 4, 4)
        return eq, state, H, Bc, Phi, res, eq.edge_multipliers(mu)

    eq, state, H0, Bc, Phi, _, _ = block(0.0)
    _, _, H1, _, _, _, _ = block(1.0)
    Z = sl.null_space(np.vstack([Bc, _symmetry_generators(Phi)]))
    A0, A1 = Z.T @ H0 @ Z, Z.T @ (H1 - H0) @ Z
    mu_inv = sl.eigh(A1, -A0, eigvals_only=True)
    t_c = 1.0 / float(np.max(mu_inv))
    _, _, Hc, _, _, res_c, n_e = block(t_c)
    ev = np.linalg.eigvalsh(Z.T @ Hc @ Z)
    m1 = twist * t_c
    out = {"critical": m1 * radius / bending, "reference": math.sqrt(3.0),
           "equilibrium_residual": float(np.max(np.abs(res_c))) * radius / m1,
           "constraint_residual": float(np.max(np.abs(eq.constraint_values(state)))),
           "eig_at_critical": float(np.max(ev)) / float(np.max(np.abs(ev))),
           "binormal_force": float(np.mean(n_e[:, 2])) * radius / m1,
           "wall_time": time.perf_counter() - start}
    return out


class MichellRing(StaticCase):
    """Michell's instability of a twisted closed filament (Michell 1889; paper §VII.A): a
    naturally straight isotropic filament (B = 1, C = 1) closed into the circle R = 1 on a
    periodic grid, twist moment m₁ carried through the natural twist (:func:`michell_ring`).
    The circle is an equilibrium for every m₁ (force residual and constraint rows at
    round-off) and loses stability at m₁R/B = √3 (C-independent; Tw = √3B/C for a twisted
    frame).  The error is the relative error of the lattice's critical m₁R/B, from the exact
    linear buckling problem of the static Jacobian restricted to the constraints' kernel;
    n = 16·2^level."""

    name = "filament-michell-ring"
    medium = "filament"
    description = ("closed twisted ring: Michell's instability at m₁R/B = √3 (smallest eigenvalue of the static "
                   "Jacobian)")
    reference = "Michell 1889 (Goriely, J. Elasticity 84, 2006): a twisted ring is stable iff m₁R/B < √3"
    quantity = "critical twist moment m₁R/B on the lattice"
    norm = "relative error"
    space_order = 2.0
    levels = (0, 1, 2, 3)
    quick_levels = (0, 1, 2)
    tolerance = 5e-3
    tolerance_reason = ("n = 16·2^level; O(h²): 4.7e-2, 1.1e-2, 2.8e-3 at n = 16, 32, 64 (measured); 5e-3 holds "
                        "from n = 64 on")
    twist = 1.0

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        # no solver settings: the critical twist is an eigenvalue problem (:func:`michell_ring`)
        return _ring_problem(16 * 2**level, 1.0, self.twist, 0.0, 1.0), {}

    def solve(self, problem: Problem, settings: Mapping[str, Any]) -> xr.Dataset:
        import xarray as xr

        out = michell_ring(n=problem.grid.shape[0], twist=self.twist, bending=1.0, radius=1.0)
        ds = xr.Dataset({k: ((), float(v)) for k, v in out.items() if k != "wall_time"})
        ds.attrs["wall_time"] = out["wall_time"]
        ds.attrs["newton_iterations"] = 0
        return ds

    def parts(self, ds: xr.Dataset) -> dict[str, float]:
        return {k: float(ds[k]) for k in ("critical", "equilibrium_residual", "constraint_residual",
                                          "eig_at_critical", "binormal_force")}

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        return abs(float(ds["critical"]) - math.sqrt(3.0)) / math.sqrt(3.0)


# ---------------------------------------------------------------------------- Greenhill
def greenhill_clamped() -> float:
    """Greenhill's critical twisting moment of the clamped–clamped column, M_c L/B = 2x₁ with
    x₁ = 4.49341 the first positive root of tan x = x (M_c L/B = 8.98682)."""
    from scipy.optimize import brentq

    return 2.0 * brentq(lambda x: math.tan(x) - x, 4.4, 4.5, xtol=1e-14)


class FilamentGreenhill(StaticCase):
    """Greenhill's twist buckling of a straight clamped–clamped filament (L = 1, C = 1): the end
    at s = L keeps its tangent and its lateral position (continuation pins: y, z and the rotations
    about y and z) but slides along the axis and turns about it under the dead axial moment λ.

    For isotropic bending the critical eigenvalue is double (a mode and its turn about the axis):
    det K keeps its sign and the continuation sees nothing.  With B₂, B₃ = 1 ∓ δ the pair splits
    into two simple bifurcations at M₋ < M_c < M₊ (8.90, 9.07 at δ = 0.01), both located when the
    arclength step (0.08) is below their distance; M(δ) = (M₋ + M₊)/2 is even in δ (δ → −δ swaps
    the axes), so M(δ) = M_c + O(δ²): measured −1.3e-5 relative at δ = 0.01 (from δ = 0.005),
    below the O(h²) error.  The error is |M(δ)/M_c − 1| with M_c L/B = 8.98682 (Greenhill 1883;
    tan x = x);
    n = 10·2^level + 1.
    """

    name = "filament-greenhill"
    medium = "filament"
    description = ("clamped–clamped filament under an axial twisting moment: Greenhill's critical moment "
                   "M_c L/B = 8.98682")
    reference = ("Greenhill (1883); Timoshenko & Gere, Theory of Elastic Stability §2.19: a clamped–clamped shaft "
                 "buckles at M L/B = 2x₁, tan x₁ = x₁ (8.98682)")
    quantity = "mean of the two bifurcation moments of the split pair (B₂, B₃ = 1 ∓ 0.01), times L/B"
    norm = "relative error"
    space_order = 2.0
    levels = (1, 2)  # n = 21, 41: 75 path points each (≈ 3 s + 4 s); n = 81 measured, 4× the cost
    tolerance = 5e-4
    tolerance_reason = ("n = 10·2^level + 1; O(h²): 8.25e-4, 1.95e-4, 3.8e-5 at n = 21, 41, 81 (measured; orders "
                        "2.08, 2.36, the last pair shifted by the O(δ²) bias); 5e-4 holds from n = 41 on (margin 2.6)")
    split, ds0 = 0.01, 0.08

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        rod = _filament(bending=[1.0 - self.split, 1.0 + self.split], twist=1.0)
        grid = cartan.Grid(10 * 2**level + 1, length=1.0)
        prob = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                              {"start": cartan.Clamped(), "end": cartan.Free(load=[0.0, 0.0, 0.0, 1.0, 0.0, 0.0])},
                              name=self.name)
        return prob, {"lam_max": 10.0, "ds0": self.ds0, "ds_max": self.ds0, "max_points": 300,
                      "pins": {"end": (1, 2, 4, 5)}, "branch_switch": False}

    def solve(self, problem: Problem, settings: Mapping[str, Any]) -> xr.Dataset:
        return cartan.continuation(problem, **dict(settings))

    def parts(self, ds: xr.Dataset) -> dict[str, float]:
        """The mean critical moment's relative error and the splitting (M₊ − M₋)/M_c (``inf``
        unless exactly two bifurcations were located)."""
        kinds = [str(k) for k in ds["critical_kind"].values]
        if kinds != ["bifurcation", "bifurcation"]:
            return {"critical_moment": math.inf, "splitting": math.inf}
        lo, hi = (float(v) for v in ds["critical_load"].values)
        ref = greenhill_clamped()
        return {"critical_moment": abs(0.5 * (lo + hi) / ref - 1.0), "splitting": (hi - lo) / ref}

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        return self.parts(ds)["critical_moment"]


# ---------------------------------------------------------------------------- cross-medium limit
def cosserat_limit(ratios=(1e2, 1e3, 1e4, 1e5, 1e6), n: int = 21, alpha: float = 2.0) -> dict[str, Any]:
    """The cosserat-rod with stretch and shear stiffness EA = GA = ratio·B/L² against the
    filament on the same lattice: the cantilever under the tip force α·B/L² along −y.

    Both are solved by :func:`cartan.solve_static` (the filament with its constraints); the
    difference of the tip positions is O(1/ratio) (the axial and shear strains are P/EA).

    Parameters
    ----------
    ratios : sequence of float
        EA·L²/B = GA·L²/B.
    n : int
        Nodes of the common grid.
    alpha : float
        PL²/B.

    Returns
    -------
    dict with ``"ratios"``, ``"errors"`` (|x_tip,rod − x_tip,filament| / L) and ``"slope"``
    (least-squares slope of log error against log ratio).
    """
    grid = cartan.Grid(n, length=1.0)
    load = [0.0, -alpha, 0.0, 0.0, 0.0, 0.0]

    def tip(rod) -> np.ndarray:
        prob = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                              {"start": cartan.Clamped(), "end": cartan.Free(load=load)})
        ds = cartan.solve_static(prob, load_steps=2, max_iter=40)
        return np.asarray(ds["position"].isel(time=0, node=-1).values)

    ref = tip(_filament())
    errors = []
    for s in ratios:
        rod = cartan.medium("cosserat-rod", stretch_shear=[s, s, s], bend_twist=[1.0, 1.0, 1.0], mass=1.0,
                            rotational_inertia=[0.01, 0.01, 0.01])
        errors.append(float(np.linalg.norm(tip(rod) - ref)))
    slope = float(np.polyfit(np.log(ratios), np.log(errors), 1)[0])
    return {"ratios": list(map(float, ratios)), "errors": errors, "slope": slope}


def all_cases() -> list[StaticCase]:
    return [FilamentCantileverElastica(), FilamentEulerBuckling(), KirchhoffAnalogy(), MichellRing(),
            FilamentGreenhill()]

