"""Vesicles of sphere topology: the Helfrich flow on the sphere's chart (paper §VII.B).

A closed vesicle of genus 0 lives on the sphere's chart, longitude u (periodic, N nodes, N even)
× colatitude v glued across the poles (``Grid((N, N/2), (2π, π), periodic=(True, False),
glued=(None, 0))``, the ``"sphere"`` initial kind of ``cosserat-surface``; staggered colatitude
nodes θ_k = (k + ½)π/n, none on a pole).  The core's strain constraints hold θ_α,3 = 0 on every
edge of this chart, those across the poles included (:mod:`cartan.constraints`, "Glued axes"), so
``helfrich-membrane`` runs here as on the torus (:func:`ellipsoid_problem`, the flow
:func:`cartan_kirchhoff_love.vesicle.helfrich_flow`).  The adaptation can instead be held by a
**penalty**: :class:`PenalisedHelfrichMembrane` is ``helfrich-membrane`` without constrained
strains and with the energy

    U = U_Helfrich(X; X₀) + ½ k_n J₀ (θ_u,3² + θ_v,3²)        (per unit chart area),

k_n = ``normal_stiffness`` (the transverse-shear stiffness of the Cosserat surface, the penalty
form of the constraint: the cross-medium limit of ``kirchhoff-love`` converges as 1/k_n,
docs/media/kirchhoff-love.md).  The Helfrich part reads only the tangential components
(θ_α,1, θ_α,2) and the bending strains, so on the adaptation θ_α,3 = 0 the energy is exactly the
Helfrich energy; at equilibrium θ_α,3 is the transverse shear force over k_n.

:func:`ellipsoid_problem` builds the flow's start, a spheroid (a = b, c along z) at a given
reduced volume v = 3V/(4πR₀³), R₀ = √(A/4π), with R₀ = 1; :func:`vesicle_shape` measures a
configuration (A, V, v, E_H/8πκ_b, the principal axes of the surface's inertia tensor, the
poles' distance and the equatorial diameter); the reference is
:mod:`cartan_kirchhoff_love.vesicle_axisym`.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
from numba import njit

import cartan
from cartan.medium import MediumKernels, check_positive
from cartan.problem import InitialState, Problem

from .helfrich import HelfrichMembrane, _helfrich

__all__ = ["PenalisedHelfrichMembrane", "ellipsoid_problem", "plot_vesicles", "revolved_problem", "spheroid_aspect",
           "spheroid_energy", "spheroid_measures", "vesicle_shape"]


# ====================================================================== point kernels
@njit(cache=True)
def penalised_energy(X, X0, p):  # pragma: no cover - compiled
    """Helfrich energy density plus ½k_n J₀(θ_u,3² + θ_v,3²); ``p = (κ_b, κ_G, c₀, σ, K_a, μ, k_n)``;
    X, X₀ ``(2, 6)``."""
    Q = np.empty((1, 1))
    J0 = np.sqrt((X0[0, 0] * X0[0, 0] + X0[0, 1] * X0[0, 1]) * (X0[1, 0] * X0[1, 0] + X0[1, 1] * X0[1, 1])
                 - (X0[0, 0] * X0[1, 0] + X0[0, 1] * X0[1, 1]) ** 2)
    return _helfrich(X, X0, p, Q, False) + 0.5 * p[6] * J0 * (X[0, 2] * X[0, 2] + X[1, 2] * X[1, 2])


@njit(cache=True)
def penalised_stress(X, X0, p, Q):  # pragma: no cover - compiled
    """Writes Q = ∂U/∂X ``(2, 6)`` of :func:`penalised_energy`."""
    _helfrich(X, X0, p, Q, True)
    J0 = np.sqrt((X0[0, 0] * X0[0, 0] + X0[0, 1] * X0[0, 1]) * (X0[1, 0] * X0[1, 0] + X0[1, 1] * X0[1, 1])
                 - (X0[0, 0] * X0[1, 0] + X0[0, 1] * X0[1, 1]) ** 2)
    Q[0, 2] = p[6] * J0 * X[0, 2]
    Q[1, 2] = p[6] * J0 * X[1, 2]


# ====================================================================== medium
class PenalisedHelfrichMembrane(HelfrichMembrane):
    """``helfrich-membrane`` whose adaptation θ_α,3 = 0 is held by the penalty ½k_n J₀ θ_α,3²
    instead of multipliers (module docstring): the cross-medium limit of the constrained medium,
    biased by O(1/k_n) (the multipliers hold the adaptation exactly on the sphere's chart too).

    Parameters
    ----------
    normal_stiffness : float
        k_n > 0 (default 1e5, in units of κ_b/ℓ² for a body of size ℓ); the energy's bias is
        O(1/k_n).  Other parameters: :class:`~cartan_kirchhoff_love.helfrich.HelfrichMembrane`.
    """

    name: ClassVar[str] = "helfrich-membrane-penalised"

    def __init__(self, *args: Any, normal_stiffness: float = 1e5, **kwargs: Any):
        super().__init__(*args, **kwargs)
        self.kn = float(check_positive("normal_stiffness", normal_stiffness, shape=()))

    def parameters(self) -> dict[str, Any]:
        return {**super().parameters(), "normal_stiffness": self.kn}

    def constrained_strains(self) -> None:
        """None: the adaptation is the penalty's."""
        return None

    @property
    def kernel_params(self) -> np.ndarray:
        """p = (κ_b, κ_G, c₀, σ, K_a, μ, k_n)."""
        return np.array([self.kb, self.kg, self.c0, self.sigma, self.ka, self.mu, self.kn])

    def point_kernels(self) -> MediumKernels:
        return MediumKernels(penalised_energy, penalised_stress, self.kernel_params)

    def fields(self, X: np.ndarray, X0: np.ndarray | None = None) -> np.ndarray:
        """As ``helfrich-membrane`` (the penalty is not part of the fields)."""
        return HelfrichMembrane.fields(self._helfrich_only(), X, X0)

    def _helfrich_only(self) -> HelfrichMembrane:
        p = super().parameters()
        out = HelfrichMembrane(**{**p, "tension": 0.0})
        out.sigma = self.sigma
        return out


# ====================================================================== spheroids
def spheroid_measures(a: float, c: float) -> tuple[float, float]:
    """(A, V) of the spheroid with equatorial radius a and polar semi-axis c (> 0)."""
    a, c = float(a), float(c)
    V = 4.0 / 3.0 * math.pi * a * a * c
    if abs(c - a) < 1e-12 * a:
        return 4.0 * math.pi * a * a, V
    if c > a:   # prolate
        e = math.sqrt(1.0 - a * a / (c * c))
        return 2.0 * math.pi * a * a * (1.0 + c / (a * e) * math.asin(e)), V
    e = math.sqrt(1.0 - c * c / (a * a))   # oblate
    return 2.0 * math.pi * a * a * (1.0 + (1.0 - e * e) / e * math.atanh(e)), V


def spheroid_aspect(reduced_volume: float, shape: str = "prolate") -> float:
    """The aspect ratio c/a of the spheroid with the reduced volume v = 3V/(4πR₀³) ∈ (0, 1)
    (> 1 prolate, < 1 oblate)."""
    from scipy.optimize import brentq

    v = float(reduced_volume)
    if not 0.0 < v < 1.0:
        raise ValueError(f"reduced_volume must be in (0, 1), got {reduced_volume!r}")
    if shape not in ("prolate", "oblate"):
        raise ValueError(f"shape must be 'prolate' or 'oblate', got {shape!r}")

    def rv(q: float) -> float:
        A, V = spheroid_measures(1.0, q)
        return 3.0 * V / (4.0 * math.pi * (A / (4.0 * math.pi)) ** 1.5) - v

    return brentq(rv, 1.0 + 1e-9, 1e3, xtol=1e-15) if shape == "prolate" else brentq(rv, 1e-3, 1.0 - 1e-9, xtol=1e-15)


def spheroid_energy(a: float, c: float, points: int = 20001) -> float:
    """E/(8πκ_b) = (1/16π)∮(κ₁ + κ₂)² dA of the spheroid (a, a, c), by Simpson's rule in the
    colatitude θ (κ₁ = ac/g³ along the meridian, κ₂ = c/(a g) along the parallel,
    g = √(a² cos²θ + c² sin²θ), dA = 2πa sin θ g dθ): an admissible shape, so its energy bounds the
    stationary shape's from above at the same reduced volume."""
    from scipy.integrate import simpson

    a, c = float(a), float(c)
    th = np.linspace(0.0, math.pi, int(points) | 1)
    g = np.sqrt(a * a * np.cos(th) ** 2 + c * c * np.sin(th) ** 2)
    f = (a * c / g ** 3 + c / (a * g)) ** 2 * 2.0 * math.pi * a * np.sin(th) * g
    return float(simpson(f, x=th) / (16.0 * math.pi))


def spheroid_frames(grid: Any, Phi: np.ndarray, reduced_volume: float = 0.9, shape: str = "prolate",
                    aspect: float | None = None, spacing: str = "angle") -> np.ndarray:
    """The frames ``[N, n, 4, 4]`` of a spheroid of area 4π (R₀ = 1) on the sphere's chart: ``Phi``
    (the unit sphere's frames on ``grid``, whose layout is kept) with r = (a sin θ cos φ,
    a sin θ sin φ, c cos θ) at the nodes' longitude φ and colatitude θ, e₁ along the parallel, e₃
    the outward normal; c/a = ``aspect`` or, by default, the spheroid of reduced volume v
    (:func:`spheroid_aspect`, ``shape`` ``"prolate"`` or ``"oblate"``).  ``spacing``: the
    colatitude nodes at the parameter θ_k = (k + ½)π/n (``"angle"``) or at equal arc length of the
    meridian, s_k = (k + ½)L/n (``"arc"``, the law of :func:`revolved_problem`'s lattice)."""
    if spacing not in ("angle", "arc"):
        raise ValueError(f"spacing must be 'angle' or 'arc', got {spacing!r}")
    if aspect is not None and not (np.isfinite(aspect) and 1e-3 <= aspect <= 1e3):
        raise ValueError(f"aspect must be in [1e-3, 1e3] (c/a), got {aspect!r}")
    q = spheroid_aspect(reduced_volume, shape) if aspect is None else float(aspect)
    A, _ = spheroid_measures(1.0, q)
    a = 1.0 / math.sqrt(A / (4.0 * math.pi))
    c = q * a
    theta = grid.coordinates(1) * (math.pi / grid.length[1])
    if spacing == "arc":  # the parameter θ at equal meridian arc length ds = √(a² cos²θ + c² sin²θ) dθ
        fine = np.linspace(0.0, math.pi, 20001)
        ds = np.sqrt(a * a * np.cos(fine) ** 2 + c * c * np.sin(fine) ** 2)
        s_fine = np.concatenate([[0.0], np.cumsum(0.5 * (ds[1:] + ds[:-1]) * np.diff(fine))])
        theta = np.interp(theta / math.pi * s_fine[-1], s_fine, fine)
    ph, th = np.meshgrid(grid.coordinates(0) * (2.0 * math.pi / grid.length[0]), theta, indexing="ij")
    pos = np.stack([a * np.sin(th) * np.cos(ph), a * np.sin(th) * np.sin(ph), c * np.cos(th)], axis=-1)
    nrm = np.stack([np.sin(th) * np.cos(ph) / a, np.sin(th) * np.sin(ph) / a, np.cos(th) / c], axis=-1)
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    e1 = np.stack([-np.sin(ph), np.cos(ph), 0.0 * ph], axis=-1)
    out = np.array(Phi, dtype=float)
    out[..., 1:, 0], out[..., 1:, 1], out[..., 1:, 2], out[..., 1:, 3] = pos, e1, np.cross(nrm, e1), nrm
    return out


def _vesicle_medium(normal_stiffness: float | None, area_modulus: float, shear_modulus: float) -> HelfrichMembrane:
    """``helfrich-membrane`` (the adaptation held by the strain constraints) for ``normal_stiffness``
    None, else :class:`PenalisedHelfrichMembrane` with k_n = ``normal_stiffness`` (> 0)."""
    if normal_stiffness is None:
        return HelfrichMembrane(area_modulus=area_modulus, shear_modulus=shear_modulus)
    if not (np.isfinite(normal_stiffness) and normal_stiffness > 0.0):
        raise ValueError(f"normal_stiffness must be None (multipliers) or > 0 (the penalty), got {normal_stiffness!r}")
    return PenalisedHelfrichMembrane(normal_stiffness=normal_stiffness, area_modulus=area_modulus,
                                     shear_modulus=shear_modulus)


def ellipsoid_problem(n: int, reduced_volume: float = 0.9, *, shape: str = "prolate", aspect: float | None = None,
                      normal_stiffness: float | None = None, area_modulus: float = 0.0, shear_modulus: float = 0.0,
                      spacing: str = "angle") -> Problem:
    """A spheroid vesicle (κ_b = 1, c₀ = κ_G = 0) on the sphere's chart with 2n × n nodes
    (:func:`spheroid_frames`; the ``"spheroid"`` initial state of ``helfrich-membrane``).  The glue is
    the sphere's (the half-turn about e₃).  The medium is ``helfrich-membrane`` (default: the
    adaptation θ_α,3 = 0 held by the core's strain constraints, the edges across the poles
    included) or, given a ``normal_stiffness`` k_n > 0, :class:`PenalisedHelfrichMembrane` (held by
    the penalty ½k_n J₀ θ_α,3²)."""
    if isinstance(n, bool) or int(n) != n or n < 4 or n % 2:
        raise ValueError(f"n must be an even integer ≥ 4 (colatitude nodes; 2n longitudes), got {n!r}")
    grid = cartan.Grid((2 * int(n), int(n)), (2.0 * math.pi, math.pi), periodic=(True, False), glued=(None, 0))
    med = _vesicle_medium(normal_stiffness, area_modulus, shear_modulus)
    st = med.initial_state(grid, "sphere")
    Phi = spheroid_frames(grid, st.Phi, reduced_volume, shape, aspect, spacing)
    return Problem(med, grid, InitialState(Phi=Phi, glue=st.glue), name=f"helfrich-vesicle-{shape}")


def _chart_problem(n: int, pos: np.ndarray, nrm: np.ndarray, ph: np.ndarray, grid: Any, name: str,
                   normal_stiffness: float | None, area_modulus: float = 0.0, shear_modulus: float = 0.0) -> Problem:
    med = _vesicle_medium(normal_stiffness, area_modulus, shear_modulus)
    st = med.initial_state(grid, "sphere")
    e1 = np.stack([-np.sin(ph), np.cos(ph), 0.0 * ph], axis=-1)
    Phi = np.array(st.Phi, dtype=float)
    Phi[..., 1:, 0], Phi[..., 1:, 1], Phi[..., 1:, 2], Phi[..., 1:, 3] = pos, e1, np.cross(nrm, e1), nrm
    return Problem(med, grid, InitialState(Phi=Phi, glue=st.glue), name=name)


def revolved_problem(shape: Any, n: int, *, normal_stiffness: float | None = 1e5, area_modulus: float = 0.0,
                     shear_modulus: float = 0.0) -> Problem:
    """An axisymmetric meridian (an :class:`~cartan_kirchhoff_love.vesicle_axisym.AxisymmetricVesicle`,
    the reference) revolved about z on the sphere's chart with 2n × n nodes: the colatitude node
    θ_k = (k + ½)π/n sits at the meridian's arc length s = Lθ_k/π (equal arc length), at
    (r cos φ, r sin φ, z − z̄) with e₃ = (sin ψ cos φ, sin ψ sin φ, cos ψ) the outward normal and
    e₁ along the parallel: the lattice of the reference shape, whose E_H, A and V measure the
    lattice's quadrature error on it (O(h²)).  The medium as :func:`ellipsoid_problem`'s:
    :class:`PenalisedHelfrichMembrane` with k_n = ``normal_stiffness``, ``helfrich-membrane`` for None
    (the start of a flow held by multipliers)."""
    if isinstance(n, bool) or int(n) != n or n < 4 or n % 2:
        raise ValueError(f"n must be an even integer ≥ 4 (colatitude nodes; 2n longitudes), got {n!r}")
    grid = cartan.Grid((2 * int(n), int(n)), (2.0 * math.pi, math.pi), periodic=(True, False), glued=(None, 0))
    ph, th = np.meshgrid(grid.coordinates(0), grid.coordinates(1), indexing="ij")
    y = shape.sol.sol(th[0] / math.pi)
    zbar = shape.sol.y[8, -1] / shape.sol.y[4, -1]
    psi, r, z = y[0][None, :], y[2][None, :], y[7][None, :] - zbar
    pos = np.stack([r * np.cos(ph), r * np.sin(ph), z + 0.0 * ph], axis=-1)
    nrm = np.stack([np.sin(psi) * np.cos(ph), np.sin(psi) * np.sin(ph), np.cos(psi) + 0.0 * ph], axis=-1)
    return _chart_problem(n, pos, nrm, ph, grid, "helfrich-vesicle-reference", normal_stiffness, area_modulus,
                          shear_modulus)


def vesicle_shape(problem: Problem, Phi: np.ndarray, pole: str = "corners") -> dict[str, float]:
    """Measures of a closed vesicle Φ ``[nu, nv, 4, 4]`` on its lattice: ``area`` A, ``volume`` V,
    ``reduced_volume`` v = 3V/(4πR₀³), ``energy`` E_H/(8πκ_b), ``axis_ratio`` the ratio of the
    principal semi-axes of the surface's second-moment tensor (the nodes weighted by their lattice
    area: √(λ_max/λ_mid) for a prolate shape, √(λ_min/λ_mid) for an oblate one, λ the eigenvalues of
    Σ w J (r − r̄)(r − r̄)ᵀ), ``length`` the extent along the principal axis of the largest (prolate)
    or smallest (oblate) eigenvalue over the extent across it, ``length`` and ``width`` themselves.
    With ``pole="cap"`` the area, v and E_H are those of the lattice with the pole cells
    (:func:`cartan_kirchhoff_love.vesicle.surface_measures`); the second moments keep the corners'
    node areas."""
    from .vesicle import _corner_data, bending_energy, surface_measures

    m = surface_measures(problem, Phi, pole)
    E = bending_energy(problem, Phi, pole) / (8.0 * math.pi * problem.medium.kb)
    c, _, J = _corner_data(problem, Phi)
    x = Phi.reshape(-1, 4, 4)[:, 1:, 0]
    w = np.bincount(c["node"], weights=c["weight"] * J, minlength=x.shape[0])
    xbar = (w[:, None] * x).sum(axis=0) / w.sum()
    d = x - xbar
    lam, vec = np.linalg.eigh(np.einsum("n,ni,nj->ij", w, d, d))
    prolate = (lam[2] - lam[1]) > (lam[1] - lam[0])
    axis = vec[:, 2] if prolate else vec[:, 0]
    along = d @ axis
    across = np.linalg.norm(d - along[:, None] * axis, axis=1)
    length = float(along.max() - along.min())
    width = 2.0 * float(across.max())
    R0 = math.sqrt(m["area"] / (4.0 * math.pi))
    V = abs(m["volume"])   # the sphere's chart (φ, θ) is negatively oriented against e₃: its lattice V is −V
    return {"area": m["area"], "volume": V,
            "reduced_volume": 3.0 * V / (4.0 * math.pi * R0 ** 3), "energy": E,
            "axis_ratio": float(math.sqrt(lam[2] / lam[1]) if prolate else math.sqrt(lam[0] / lam[1])),
            "length": length, "width": width, "extent_ratio": length / width}


def plot_vesicles(shapes: Any, n: int = 16, path: str | None = None) -> Any:
    """A figure of axisymmetric vesicles (reference solutions, :mod:`~cartan_kirchhoff_love.vesicle_axisym`):
    per shape, its lattice on the sphere's chart (:func:`revolved_problem`, 2n × n nodes, the poles
    closed by the reference's pole points) as a 3D surface coloured by the lattice's mean curvature H at
    the nodes, with the reference meridian (the 1D solution, in the plane y = 0) and the starting spheroid's
    meridian of the same v (dashed) overlaid.  Saved to ``path`` when given; returns the figure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import cm, colors

    from .vesicle import _lattice

    shapes = list(shapes)
    fig = plt.figure(figsize=(6.0 * len(shapes), 6.0))
    for k, shape in enumerate(shapes):
        ax = fig.add_subplot(1, len(shapes), k + 1, projection="3d", computed_zorder=False)
        pb = revolved_problem(shape, n)
        Phi = np.asarray(pb.initial.Phi)
        scheme, state = _lattice(pb, Phi)
        X = [x.reshape(-1, x.shape[-1]) for x in scheme.edge_strains(state)]
        c = scheme.corners()
        H = pb.medium.fields(np.stack([X[a][c["edge"][:, a]] for a in range(2)], axis=1))[:, 0]
        Hn = np.bincount(c["node"], weights=H, minlength=Phi[..., 0, 0].size) / np.bincount(
            c["node"], minlength=Phi[..., 0, 0].size)
        Hn = Hn.reshape(Phi.shape[:2])
        x = Phi[..., 1:, 0]
        r_pole, z_pole = shape.meridian(2)
        top, bottom = np.array([0.0, 0.0, z_pole[0]]), np.array([0.0, 0.0, z_pole[-1]])
        # close the seam (periodic u) and the poles
        xs = np.concatenate([x, x[:1]], axis=0)
        xs = np.concatenate([np.broadcast_to(top, (xs.shape[0], 1, 3)), xs,
                             np.broadcast_to(bottom, (xs.shape[0], 1, 3))], axis=1)
        Hs = np.concatenate([Hn, Hn[:1]], axis=0)
        Hs = np.concatenate([Hs[:, :1], Hs, Hs[:, -1:]], axis=1)
        norm = colors.Normalize(vmin=float(Hs.min()), vmax=float(Hs.max()))
        face = 0.25 * (Hs[:-1, :-1] + Hs[1:, :-1] + Hs[:-1, 1:] + Hs[1:, 1:])
        ax.plot_surface(xs[..., 0], xs[..., 1], xs[..., 2], facecolors=cm.viridis(norm(face)), shade=False,
                        edgecolor="0.35", linewidth=0.3, alpha=0.45, zorder=1)
        rm, zm = shape.meridian(400)
        ax.plot(rm, 0.0 * rm - 1e-3, zm, color="crimson", lw=2.0, zorder=3,
                label="reference meridian (shape equations)")
        ax.plot(-rm, 0.0 * rm - 1e-3, zm, color="crimson", lw=2.0, zorder=3)
        q = spheroid_aspect(shape.reduced_volume, "prolate" if shape.axis_ratio > 1.0 else "oblate")
        A, _ = spheroid_measures(1.0, q)
        a = 1.0 / math.sqrt(A / (4.0 * math.pi))
        th = np.linspace(0.0, 2.0 * math.pi, 200)
        ax.plot(a * np.sin(th), 0.0 * th - 1e-3, q * a * np.cos(th), color="k", lw=1.0, ls="--",
                zorder=2, label="spheroid of the same v")
        m = fig.colorbar(cm.ScalarMappable(norm=norm, cmap="viridis"), ax=ax, shrink=0.55, pad=0.02)
        m.set_label("lattice mean curvature H (nodes)")
        kind = "prolate" if shape.axis_ratio > 1.0 else "oblate"
        ax.set_title(f"{kind}, v = {shape.reduced_volume:g}: E/8πκ = {shape.energy:.6f}\n"
                     f"σ = {shape.tension:.4f}, p = {shape.pressure:.4f} (R₀ = 1); {2 * n} × {n} nodes", fontsize=10)
        lim = 1.05 * max(float(np.abs(xs).max()), 1.0)
        ax.set_xlim(-lim, lim), ax.set_ylim(-lim, lim), ax.set_zlim(-lim, lim)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(elev=10, azim=-75)
        ax.set_xlabel("x"), ax.set_ylabel("y"), ax.set_zlabel("z")
        ax.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    if path is not None:
        fig.savefig(path, dpi=110)
    return fig
