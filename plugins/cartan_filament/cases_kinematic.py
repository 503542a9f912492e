"""Verification cases of the filament's kinematics (paper §III.E, §VII.A): the two adapted
gauges along a helix, and the binormal (local induction) flow of a vortex ring through the
``kinematic`` integrator.

The binormal flow is run on the ``cosserat-rod`` medium (on SE(3), the same structure field
and strains as the filament): a prescribed-velocity run uses nothing of the medium but its
group, and the ``kinematic`` integrator does not hold constrained strains (``rattle`` does,
for dynamics).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from cartan_verification.case import Case, StaticCase

import cartan

from .binormal import binormal_velocity
from .gauges import AdaptedFrames, bishop_frames, frenet_frames, relative_angle

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

    from cartan.problem import Problem

__all__ = ["BishopFrenetHelix", "VortexRing", "all_cases", "kinematic_medium", "ring_positions", "run_binormal",
           "vortex_ring_problem"]


def kinematic_medium():
    """The SE(3) medium that carries prescribed-velocity runs of a filament: ``cosserat-rod``
    (its stiffnesses and inertia are not used by the ``kinematic`` integrator)."""
    return cartan.medium("cosserat-rod", stretch_shear=[1.0, 1.0, 1.0], bend_twist=[1.0, 1.0, 1.0], mass=1.0,
                         rotational_inertia=[0.01, 0.01, 0.01])


# ---------------------------------------------------------------------------- gauges along a helix
class BishopFrenetHelix(StaticCase):
    """Bishop against Frenet along a helix of radius a = 1 and pitch 2πb, b = 0.5: curvature
    κ = a/(a² + b²) = 0.8, torsion τ = b/(a² + b²) = 0.4, two turns (L = 4π√(a² + b²)),
    sampled at n = 20·2^level + 1 equally spaced arclengths.

    The Bishop frame is the Frenet frame turned about e₁ by φ(s) = φ(0) − ∫₀ˢτ ds (from
    π_B = Rot(−φ)π_F + φ′e₁ with π_F = (τ, 0, κ) and the Bishop condition π_B,1 = 0; the angle
    is right-handed about the tangent, from Frenet to Bishop).  Both frames are built from the
    samples by second-order finite differences (:mod:`cartan_filament.gauges`), so the angle
    is O(h²).  The discrete Bishop frame has π₁ = 0 on every lattice edge to round-off (the
    minimal rotation between consecutive tangents has its axis normal to both), which the
    case records beside the angle.
    """

    name = "filament-bishop-frenet-helix"
    medium = "filament"
    description = "Bishop frame against Frenet frame along a helix: relative angle −∫τ ds"
    reference = ("φ(s) − φ(0) = −τ s for the rotation about e₁ from the Frenet to the Bishop frame, τ = b/(a² + b²) "
                 "(Bishop 1975; paper §III.E, §VII.A: π = (τ, 0, κ) in the Frenet gauge, π₁ = 0 in the Bishop gauge)")
    quantity = "relative frame angle φ_i at every node, unwrapped, against −τ s_i"
    norm = "max_i |φ_i − φ_0 + τ s_i| / (τ L)"
    space_order = 2.0
    levels = (0, 1, 2, 3)
    tolerance = 2e-3
    tolerance_reason = ("n = 20·2^level + 1; the O(h²) error is 6.1e-2, 1.7e-2, 4.5e-3, 1.2e-3 at n = 21, 41, 81, 161 "
                        "(measured; observed orders 1.87, 1.89, 1.94): 2e-3 holds at n = 161")

    a, b, turns = 1.0, 0.5, 2.0

    @property
    def pitch_length(self) -> float:
        return math.hypot(self.a, self.b)

    def curvature_torsion(self) -> tuple[float, float]:
        c2 = self.a**2 + self.b**2
        return self.a / c2, self.b / c2

    def helix(self, n: int) -> tuple[np.ndarray, float, float]:
        """Samples ``[n, 3]``, spacing h and length L of the helix."""
        L = 2 * math.pi * self.turns * self.pitch_length
        s = np.linspace(0.0, L, n)
        t = s / self.pitch_length
        return np.stack([self.a * np.cos(t), self.a * np.sin(t), self.b * t], axis=-1), float(s[1]), L

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        n = 20 * 2**level + 1
        r, h, L = self.helix(n)
        grid = cartan.Grid(n, length=L)
        return cartan.Problem(cartan.medium("filament"), grid, frenet_frames(r, h).initial_state(),
                              name=self.name), {}

    def solve(self, problem: Problem, settings: Mapping[str, Any]) -> xr.Dataset:
        import xarray as xr

        r = np.asarray(problem.initial.Phi)[:, 1:, 0]
        h = problem.grid.spacing[0]
        frenet, bishop = frenet_frames(r, h), bishop_frames(r, h)
        phi = np.unwrap(relative_angle(frenet, bishop))
        s = problem.grid.coordinates(0)
        kappa, tau = self.curvature_torsion()
        XF, XB = frenet.edge_strains(), bishop.edge_strains()
        return xr.Dataset(
            {"angle": ("node", phi - phi[0], {"long_name": "angle from the Frenet to the Bishop frame about e1"}),
             "angle_exact": ("node", -tau * s, {"long_name": "-integral of the torsion"}),
             "curvature": ("node", frenet.curvature, {"long_name": "curvature (finite differences)"}),
             "bishop_twist": ("edge", XB[:, 3], {"long_name": "pi_1 of the Bishop frame on the lattice edges"}),
             "frenet_pi2": ("edge", XF[:, 4], {"long_name": "pi_2 of the Frenet frame on the lattice edges"})},
            coords={"u": ("node", s)},
            attrs={"kappa": kappa, "tau": tau, "length": float(problem.grid.length[0])})

    def parts(self, ds: xr.Dataset) -> dict[str, float]:
        tau, L = float(ds.attrs["tau"]), float(ds.attrs["length"])
        return {"angle": float(np.max(np.abs(ds["angle"].values - ds["angle_exact"].values))) / (tau * L),
                "curvature": float(np.max(np.abs(ds["curvature"].values - ds.attrs["kappa"]))) / ds.attrs["kappa"],
                "bishop twist": float(np.max(np.abs(ds["bishop_twist"].values))),
                "frenet pi2": float(np.max(np.abs(ds["frenet_pi2"].values)))}

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        return self.parts(ds)["angle"]


# ---------------------------------------------------------------------------- vortex ring
def ring_positions(n: int, radius: float = 1.0, normal: Any = (0.0, 0.0, 1.0), amplitude: float = 0.0,
                   mode: int = 3) -> np.ndarray:
    """A circle of ``radius`` in the plane through the origin with unit ``normal``, sampled at n
    equal angles, counter-clockwise about the normal (its binormal is +normal), optionally
    perturbed by ``amplitude``·radius in the radial (cos mφ) and normal (sin mφ) directions.

    Returns
    -------
    ndarray ``[n, 3]``
    """
    nz = np.asarray(normal, dtype=float)
    nz = nz / np.linalg.norm(nz)
    ex = np.cross(nz, [1.0, 0.0, 0.0] if abs(nz[0]) < 0.9 else [0.0, 1.0, 0.0])
    ex /= np.linalg.norm(ex)
    ey = np.cross(nz, ex)
    phi = 2 * np.pi * np.arange(n) / n
    rho = radius * (1.0 + amplitude * np.cos(mode * phi))
    z = radius * amplitude * np.sin(mode * phi)
    return rho[:, None] * (np.cos(phi)[:, None] * ex + np.sin(phi)[:, None] * ey) + z[:, None] * nz


def vortex_ring_problem(n: int, radius: float = 1.0, normal: Any = (0.0, 0.0, 1.0), amplitude: float = 0.0,
                        mode: int = 3, gauge: str = "bishop") -> tuple[Problem, AdaptedFrames]:
    """A closed filament (periodic grid of n nodes, length 2πR) on the ring of
    :func:`ring_positions`, in the Bishop (default) or Frenet gauge, as a ``cosserat-rod``
    problem for the ``kinematic`` integrator.

    Returns
    -------
    (Problem, AdaptedFrames)
    """
    grid = cartan.Grid(n, length=2 * math.pi * radius, periodic=True)
    r = ring_positions(n, radius, normal, amplitude, mode)
    build = {"bishop": bishop_frames, "frenet": frenet_frames}.get(gauge)
    if build is None:
        raise ValueError(f"gauge must be 'bishop' or 'frenet', got {gauge!r}")
    frames = build(r, grid.spacing[0], closed=True)
    return cartan.Problem(kinematic_medium(), grid, frames.initial_state(), name="filament-vortex-ring"), frames


def run_binormal(problem: Problem, dt: float, t_end: float, order: int = 4, save_every: int | None = None,
                 compiled: bool = False, **velocity_options: Any) -> xr.Dataset:
    """Run the binormal flow (:func:`~cartan_filament.binormal.binormal_velocity`) on a closed
    filament ``problem`` with the ``kinematic`` integrator of ``order``.

    Returns
    -------
    xarray.Dataset
        The run, frames tracked (``position``, ``frame``, edge strains ``X``).
    """
    from cartan.integrators import Kinematic

    velocity = binormal_velocity(None, periodic=problem.grid.periodic[0], compiled=compiled, **velocity_options)
    return cartan.simulate(problem, integrator=Kinematic(velocity=velocity, order=order), dt=dt, t_end=t_end,
                           save_every=save_every, progress=False, compiled=compiled, reduce=False,
                           scheme_options={"track_frames": True})


def ring_errors(ds: xr.Dataset, radius: float, normal: Any, coefficient: float = 1.0) -> dict[str, float]:
    """Departures of a run from the translating ring: centroid against c₀ + (c t/R)·normal,
    relative to the distance travelled; radius (max over nodes and frames) relative to R;
    lattice constraint residual max|θ − (1, 0, 0)|; relative change of the polygon length."""
    nz = np.asarray(normal, dtype=float)
    nz = nz / np.linalg.norm(nz)
    t = np.asarray(ds["time"].values)
    P = np.asarray(ds["position"].values)  # [time, node, 3]
    c = P.mean(axis=1)
    exact = c[0] + (coefficient * t / radius)[:, None] * nz
    travel = max(abs(coefficient) * float(t[-1]) / radius, 1e-300)
    rad = np.linalg.norm(P - c[:, None, :], axis=-1)
    X = np.asarray(ds["X"].values)
    length = np.linalg.norm(np.roll(P, -1, axis=1) - P, axis=-1).sum(axis=1)
    return {"translation": float(np.max(np.linalg.norm(c - exact, axis=-1))) / travel,
            "radius": float(np.max(np.abs(rad - radius))) / radius,
            "constraint": float(np.max(np.abs(X[..., :3] - np.array([1.0, 0.0, 0.0])))),
            "length": float(np.max(np.abs(length / length[0] - 1.0)))}


#: the ring's settings shared by the case, the scene and the tests
RING_NORMAL = (0.0, 0.6, 0.8)


class VortexRing(Case):
    """A circular vortex ring of radius R = 1 (n = 16 nodes, a tilted plane with unit normal
    (0, 0.6, 0.8), so that no planar reduction applies) under the binormal flow ∂_t r = κb,
    run by ``kinematic`` (RKMK4) with the velocity of
    :func:`~cartan_filament.binormal.binormal_velocity` in the Bishop gauge (Ω₁ = −½κ²).

    The ring translates along its normal at speed 1/R without changing shape (the local
    induction approximation with unit coefficient).  On the lattice the sampled Bishop
    frames are an orbit of a one-parameter subgroup, so the edge strains are exactly
    (1, 0, 0; 0, π₂, π₃) with |π| = 1/R and, by symmetry, every node moves alike: the
    semi-discrete flow is the exact translation and the error is the time integration's
    alone, O(Δt⁴) (the frames turn about their tangents at Ω₁ = −½κ² while translating).
    Δt = 0.2/2^level over t ∈ [0, 2]: Δt·c/dx² = 1.3/2^level, inside the dispersive limit
    2√2 of :func:`~cartan_filament.binormal.binormal_dt_limit`.
    """

    name = "filament-vortex-ring"
    medium = "filament"  # the filament's case; the run carries it on cosserat-rod (kinematic_medium)
    description = "vortex ring under the binormal flow: translates at speed 1/R along its normal, shape kept"
    reference = ("r(t) = r(0) + (t/R)·n for the circle of radius R under ∂_t r = κb (local induction approximation, "
                 "Hasimoto 1972; unit circulation coefficient: speed κ = 1/R)")
    quantity = "centroid against c₀ + (t/R)n, radius of every node, over all saved frames"
    norm = ("max of |c − c_exact|/(t_end/R) and max|ρ_i − R|/R; the lattice constraint residual max|θ − (1,0,0)| "
            "and the length change are recorded beside it")
    space_order = None
    time_order_of = {"kinematic": 4.0}
    refine = "time"
    default_integrators = ("kinematic",)
    default_schemes = ("lattice",)
    levels = (0, 1, 2, 3)
    tolerance = 1e-8
    tolerance_reason = ("Δt = 0.2/2^level, O(Δt⁴): 8.2e-6, 5.2e-7, 3.3e-8, 2.1e-9 at levels 0–3 (measured; observed "
                        "orders 3.97, 3.99, 3.99); 1e-8 holds at level 3")

    n, radius, t_end = 16, 1.0, 2.0

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        prob, _ = vortex_ring_problem(self.n, self.radius, RING_NORMAL)
        steps = 10 * 2**level
        return prob, {"dt": self.t_end / steps, "t_end": self.t_end, "save_every": steps // 10,
                      "integrator_options": {"velocity": binormal_velocity(None), "order": 4},
                      "scheme_options": {"track_frames": True}}

    def run(self, problem: Problem, settings: Mapping[str, Any], integrator: str, scheme: str = "lattice",
            compiled: bool = True) -> xr.Dataset:
        """:func:`cartan.simulate` without the planar reduction (the velocity is an SE(3) one)."""
        return cartan.simulate(problem, integrator=integrator, scheme=scheme, compiled=compiled, progress=False,
                               reduce=False, **dict(settings))

    def parts(self, ds: xr.Dataset) -> dict[str, float]:
        return ring_errors(ds, self.radius, RING_NORMAL)

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        p = self.parts(ds)
        return max(p["translation"], p["radius"])


def all_cases() -> list[Case]:
    return [BishopFrenetHelix(), VortexRing()]
