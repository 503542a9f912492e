"""The ``kirchhoff-love`` medium: a Koiter shell adapted to its Gauss map (paper §VII.B).

(M, X, G) = (a 2D chart (u, v), E³, SE(3)), d = 2.  The structure field Φ = (r, R) carries the
mid-surface point r and a frame R = (e₁ e₂ e₃); the strains X_α = Φ⁻¹∂_αΦ = {θ_α; π_α}
(α = u, v; translations first) are those of the Cosserat surface (paper §VI.B,
:mod:`cartan_cosserat_surface.surface`).  The Kirchhoff–Love surface is the Cosserat surface
*adapted* to its Gauss map (§VII.B): e₃ is the unit normal, i.e.

    θ_u,3 = θ_v,3 = 0        (∂_α r = θ_α,1 e₁ + θ_α,2 e₂),

declared by :meth:`KirchhoffLove.constrained_strains` (component 2 of X on both axes) and held
by the statics' Lagrange multipliers on every lattice edge (:func:`cartan.solve_static`,
:func:`cartan.continuation`).  The multiplier of θ_α,3 is the stress conjugate to the normal
component of ∂_α r: the transverse shear force, a reaction (the fictitious stress of §IV.E),
returned as ``constraint_force``.

Strain measures (invariant under a rotation of the frame about e₃)
    * metric a_αβ = θ_α,1 θ_β,1 + θ_α,2 θ_β,2 (the first fundamental form; components 1, 2 only:
      on the constraint it is θ_α·θ_β), membrane strain ε_αβ = ½(a_αβ − a⁰_αβ);
    * second fundamental form b_αβ = ∂_α r·∂_β e₃ = θ_α,1 π_β,2 − θ_α,2 π_β,1 (∂_β e₃ =
      R(π_β × e₃) = R(π_β,2, −π_β,1, 0)), symmetrised, and the change of curvature
      κ_αβ = sym(b)_αβ − sym(b⁰)_αβ.

Energy per unit chart area (Koiter; St Venant–Kirchhoff, plane stress, thickness h)
    U = √a⁰ [ ½ h 𝒞(ε, ε) + ½ (h³/12) 𝒞(κ, κ) ],  𝒞^{αβγδ} = E/(1−ν²) [ν A^αβ A^γδ +
    ½(1−ν)(A^αγ A^βδ + A^αδ A^βγ)], A = (a⁰)⁻¹,

with no transverse-shear term: the stress does not depend on θ_α,3 (the constrained
components) nor on π_α,3.  With n = h𝒞ε and m = (h³/12)𝒞κ,

    ∂U/∂θ_α = √a⁰ [ n^αβ (θ_β,1, θ_β,2, 0) + m^αβ (π_β,2, −π_β,1, 0) ],
    ∂U/∂π_β = √a⁰ m^αβ (−θ_α,2, θ_α,1, 0).

Conventions
    * Mean curvature H = ½ tr(a⁻¹b) = ½(κ₁ + κ₂) with b_αβ = ∂_α r·∂_β e₃: H > 0 where the
      surface bends away from e₃ (a sphere with the outward normal has H = +1/R, a cylinder of
      radius R with the outward normal H = +1/(2R)); Gauss curvature K = det b / det a.
    * Bending energy: for a plate (flat rest state, Cartesian chart) and small strains the
      bending part is ½D[(tr κ)² − 2(1 − ν) det κ] = ½D(2H)² − D(1 − ν)K, D = Eh³/(12(1 − ν²)):
      the factor ½ in front of (2H)², i.e. Helfrich's κ_b = D and κ_G = −D(1 − ν).
    * Drill: π_α,3 (in an adapted frame the Levi-Civita connection form, §VII.B) enters neither
      the energy nor an output; the rotation Ω₃ about e₃ is a gauge (zero inertia), so the
      statics hold it at zero: the frame is transported without spin about the normal, from
      the initial state's e₁.
    * Gauge (the parameter ``gauge``): the initial-state builders give the *coordinate* gauge
      e₁ ∥ ∂_u r (default) or the *principal* gauge (§VII.B): e₁, e₂ along the principal
      directions, diagonalising the shape operator, e₁ along the larger principal curvature
      κ₁ ≥ κ₂ (with the sign above: the circumference of a cylinder with the outward normal)
      and turned from the coordinate e₁ by φ ∈ (−π/2, π/2].  In the frame basis the second
      fundamental form is B = T⁻¹ b T⁻ᵀ, T_αr = ∂_α r·e_r (on the lattice T_αr = θ_α,r), and
      φ = ½ atan2(2B₁₂, B₁₁ − B₂₂) (:func:`principal_angle`).  At an umbilic (κ₁ = κ₂: every
      point of a flat plate or a sphere) the principal frame is undefined: the builders raise a
      ``ValueError`` naming the node and its material coordinates, or, with
      ``umbilic="keep"``, leave the frame there unturned (the paper's Ω₃ = 0 at umbilics).  The
      gauge changes neither the energy density at a point nor the motion of the surface (the
      lattice's edge strains mix frames turned by O(Δ∂φ), an O(Δ²) difference); in a run the
      frame is then transported without spin about e₃ (Ω₃ = 0), so the principal gauge is that
      of the initial state, and :func:`principal_angle` of a later strain gives the turn back
      to it.

Kinetic data are those of :class:`~cartan_cosserat_surface.surface.CosseratSurface` (ρh, ρh³/12,
0 about e₃).  :func:`cartan.simulate` runs it with the ``rattle`` integrator, which holds
θ_α,3 = 0 by multipliers at every step (:mod:`cartan.integrators.constrained`).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from cartan_cosserat_surface.surface import CosseratSurface, _constitutive, shell_point
from numba import njit

from cartan.medium import MediumKernels

__all__ = ["GAUGES", "UMBILIC_TOLERANCE", "KirchhoffLove", "koiter_energy", "koiter_stress", "principal_angle",
           "principal_curvatures", "torus_surface"]

#: the frame gauges of the initial-state builders
GAUGES = ("coordinate", "principal")
#: |κ₁ − κ₂| at or below this fraction of the curvature scale marks an umbilic (see :func:`principal_angle`)
UMBILIC_TOLERANCE = 1e-6


# ====================================================================== point kernels
@njit(cache=True)
def _koiter(X, X0, p, Q, want):  # pragma: no cover - compiled
    """Energy density at one point; writes Q = ∂U/∂X when ``want`` (see the module docstring):
    the shell energy of :func:`~cartan_cosserat_surface.surface.shell_point` with the metric
    of the tangent components and no transverse shear (θ_a,3 is held at zero; neither it nor
    the drill π_a,3 carries a constitutive stress)."""
    return shell_point(X, X0, p, Q, want, 2, 0.0)


@njit(cache=True)
def koiter_energy(X, X0, p):  # pragma: no cover - compiled
    """Koiter energy density U(X; X₀) per unit chart area; ``p = (E, ν, h)``; X, X₀ ``(2, 6)``."""
    Q = np.empty((1, 1))
    return _koiter(X, X0, p, Q, False)


@njit(cache=True)
def koiter_stress(X, X0, p, Q):  # pragma: no cover - compiled
    """Writes Q = ∂U/∂X ``(2, 6)`` (see :func:`koiter_energy`)."""
    _koiter(X, X0, p, Q, True)


@njit(cache=True)
def _fields(X, X0, p, out):  # pragma: no cover - compiled
    """(n^uu, n^uv, n^vv, m^uu, m^uv, m^vv, K, H, U_bending, U_membrane) at one point, ``out`` (10,)."""
    E, nu, h = p[0], p[1], p[2]
    cs = E / (1.0 - nu * nu)
    a0 = np.zeros(3)
    a = np.zeros(3)
    for i in range(2):
        a0[0] += X0[0, i] * X0[0, i]
        a0[1] += X0[0, i] * X0[1, i]
        a0[2] += X0[1, i] * X0[1, i]
        a[0] += X[0, i] * X[0, i]
        a[1] += X[0, i] * X[1, i]
        a[2] += X[1, i] * X[1, i]
    det0 = a0[0] * a0[2] - a0[1] * a0[1]
    J = np.sqrt(det0)
    Auu, Auv, Avv = a0[2] / det0, -a0[1] / det0, a0[0] / det0
    b = np.empty((2, 2))
    b0 = np.empty((2, 2))
    for i in range(2):
        for j in range(2):
            b[i, j] = X[i, 0] * X[j, 4] - X[i, 1] * X[j, 3]
            b0[i, j] = X0[i, 0] * X0[j, 4] - X0[i, 1] * X0[j, 3]
    euu, euv, evv = 0.5 * (a[0] - a0[0]), 0.5 * (a[1] - a0[1]), 0.5 * (a[2] - a0[2])
    kuu, kuv, kvv = b[0, 0] - b0[0, 0], 0.5 * (b[0, 1] + b[1, 0] - b0[0, 1] - b0[1, 0]), b[1, 1] - b0[1, 1]
    n = _constitutive(euu, euv, evv, Auu, Auv, Avv, nu, cs * h)
    m = _constitutive(kuu, kuv, kvv, Auu, Auv, Avv, nu, cs * h ** 3 / 12.0)
    out[0], out[1], out[2] = n
    out[3], out[4], out[5] = m
    det = a[0] * a[2] - a[1] * a[1]
    bs = 0.5 * (b[0, 1] + b[1, 0])
    out[6] = (b[0, 0] * b[1, 1] - bs * bs) / det
    out[7] = 0.5 * (a[2] * b[0, 0] - 2.0 * a[1] * bs + a[0] * b[1, 1]) / det
    out[8] = 0.5 * J * (m[0] * kuu + 2.0 * m[1] * kuv + m[2] * kvv)
    out[9] = 0.5 * J * (n[0] * euu + 2.0 * n[1] * euv + n[2] * evv)


@njit(cache=True)
def _fields_batch(X, X0, p, out):  # pragma: no cover - compiled
    for i in range(X.shape[0]):
        _fields(X[i], X0[i], p, out[i])


# ====================================================================== principal gauge
def checked_gauge(gauge: Any, umbilic: Any) -> tuple[str, str]:
    """``(gauge, umbilic)`` validated: ``ValueError`` naming the parameter and the allowed values."""
    if gauge not in GAUGES:
        raise ValueError(f"gauge must be one of {', '.join(GAUGES)}, got {gauge!r}")
    if umbilic not in ("error", "keep"):
        raise ValueError(f"umbilic must be 'error' or 'keep', got {umbilic!r}")
    return gauge, umbilic


def _frame_form(T: np.ndarray, b: np.ndarray) -> np.ndarray:
    """B = T⁻¹ sym(b) T⁻ᵀ ``[..., 2, 2]``: the second fundamental form in the frame basis, from
    T_αr = ∂_α r·e_r and b_αβ = ∂_α r·∂_β e₃ ``[..., 2, 2]``."""
    Ti = np.linalg.inv(T)
    bs = 0.5 * (b + np.swapaxes(b, -1, -2))
    return Ti @ bs @ np.swapaxes(Ti, -1, -2)


def principal_curvatures(X: np.ndarray) -> np.ndarray:
    """(κ₁, κ₂) ``[..., 2]``, κ₁ ≥ κ₂, of strains X ``[..., 2, 6]`` of an adapted frame
    (T_αr = θ_α,r, b_αβ = θ_α,1 π_β,2 − θ_α,2 π_β,1): the eigenvalues of B = T⁻¹bT⁻ᵀ."""
    X = np.asarray(X, dtype=float)
    T = X[..., :, :2]
    b = X[..., :, None, 0] * X[..., None, :, 4] - X[..., :, None, 1] * X[..., None, :, 3]
    return np.linalg.eigvalsh(_frame_form(T, b))[..., ::-1]


def principal_angle(T: np.ndarray, b: np.ndarray, *, scale: float | None = None,
                    tolerance: float = UMBILIC_TOLERANCE, umbilic: str = "error",
                    where: Any = None) -> np.ndarray:
    """The angle φ ``[...]`` by which a frame (e₁, e₂) must turn about e₃ to be principal.

    Parameters
    ----------
    T : array_like, shape ``[..., 2, 2]``
        T_αr = ∂_α r·e_r, the tangents in the frame (θ_α,r on the lattice).
    b : array_like, shape ``[..., 2, 2]``
        b_αβ = ∂_α r·∂_β e₃ (symmetrised here).
    scale : float, optional
        The curvature scale of the umbilic test (default: the largest |κ| over the points; 0,
        a flat surface, makes every point an umbilic).
    tolerance : float
        A point is an umbilic where κ₁ − κ₂ ≤ ``tolerance``·scale.
    umbilic : {"error", "keep"}
        At an umbilic: raise ``ValueError`` or return φ = 0 (the frame left unturned).
    where : callable, optional
        ``where(index) -> str`` describing a point for the error message (default: the index).

    Returns
    -------
    numpy.ndarray ``[...]``
        φ = ½ atan2(2B₁₂, B₁₁ − B₂₂) ∈ (−π/2, π/2]: e₁' = cos φ e₁ + sin φ e₂ is the principal
        direction of κ₁ ≥ κ₂ (B = T⁻¹bT⁻ᵀ, the second fundamental form in the frame basis).
    """
    if umbilic not in ("error", "keep"):
        raise ValueError(f"umbilic must be 'error' or 'keep', got {umbilic!r}")
    B = _frame_form(np.asarray(T, dtype=float), np.asarray(b, dtype=float))
    d, o = B[..., 0, 0] - B[..., 1, 1], B[..., 0, 1]
    gap = np.sqrt(d * d + 4.0 * o * o)                      # κ₁ − κ₂
    mean = 0.5 * (B[..., 0, 0] + B[..., 1, 1])
    if scale is None:
        scale = float(np.max(np.abs(mean) + 0.5 * gap, initial=0.0))
    flat = gap <= tolerance * scale
    if umbilic == "error" and np.any(flat):
        idx = tuple(int(i) for i in np.argwhere(flat)[0])
        at = where(idx) if where is not None else f"point {idx}"
        detail = (f"κ₁ = κ₂ = {float(mean[idx]):.6g} there, to {tolerance:g} of the largest |κ| = {scale:.6g}"
                  if scale > 0.0 else "κ₁ = κ₂ = 0 everywhere: a flat surface")
        raise ValueError(f"gauge='principal': the principal frame is undefined at an umbilic (κ₁ = κ₂), "
                         f"{int(flat.sum())} point(s), the first at {at} ({detail}); use gauge='coordinate', "
                         f"or umbilic='keep' to leave the frames unturned there")
    return np.where(flat, 0.0, 0.5 * np.arctan2(2.0 * o, d))


# ====================================================================== closed surfaces
def torus_surface(grid: Any, major_radius: float | None = None, minor_radius: float | None = None
                  ) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray], tuple[np.ndarray, ...]]:
    """The torus of revolution about z on a doubly periodic chart, by arc length.

    r(u, v) = ((R + r cos ψ) cos φ, (R + r cos ψ) sin φ, r sin ψ), φ = u/R, ψ = v/r: u runs
    along the centre circle (period 2πR), v around the tube (period 2πr).  Frames in the
    coordinate gauge: e₁ = ∂_u r/|∂_u r| (the parallel), e₂ = ∂_v r/|∂_v r| (the meridian),
    e₃ = e₁ × e₂ the outward normal.  Every parallel and every meridian is a circle whose
    frames turn uniformly — an orbit of a one-parameter subgroup of SE(3) —, so the lattice's
    edge strains are the continuum strains and the torus is closed with identity holonomies.
    With the outward normal H = (R + 2r cos ψ)/(2r(R + r cos ψ)), K = cos ψ/(r(R + r cos ψ)),
    κ₁ = 1/r along the meridian, κ₂ = cos ψ/(R + r cos ψ) along the parallel (no umbilic).

    Parameters
    ----------
    grid : cartan.grid.Grid
        d = 2, both axes periodic, lengths (2πR, 2πr).
    major_radius, minor_radius : float, optional
        R > r > 0 (defaults: L_u/(2π), L_v/(2π)); given, they must close the chart's periods.

    Returns
    -------
    pos : numpy.ndarray ``[nu, nv, 3]``
    frames : numpy.ndarray ``[nu, nv, 3, 3]`` (columns e₁ e₂ e₃)
    tangents : tuple of 2 arrays ``[nu, nv, 3]`` (r_u, r_v)
    second : tuple of 3 arrays ``[nu, nv, 3]`` (r_uu, r_uv, r_vv)
    """
    if grid.d != 2 or not all(grid.periodic):
        raise ValueError(f"grid: a torus needs a d = 2 grid with both axes periodic, got d = {grid.d}, "
                         f"periodic = {tuple(grid.periodic)}")
    radii = []
    for name, value, L in (("major_radius", major_radius, grid.length[0]),
                           ("minor_radius", minor_radius, grid.length[1])):
        rad = L / (2.0 * np.pi) if value is None else float(np.asarray(value, dtype=float))
        if not np.isfinite(rad) or rad <= 0.0:
            raise ValueError(f"{name} must be > 0, got {value!r}")
        if abs(L - 2.0 * np.pi * rad) > 1e-9 * rad:
            raise ValueError(f"{name}: the periodic axis closes only for length 2π·{name} = {2 * np.pi * rad}, "
                             f"got length {L}")
        radii.append(rad)
    R, r = radii
    if not r < R:
        raise ValueError(f"minor_radius must be < major_radius = {R} (a ring torus), got {r}")
    u, v = np.meshgrid(grid.coordinates(0), grid.coordinates(1), indexing="ij")
    cp, sp, cq, sq = np.cos(u / R), np.sin(u / R), np.cos(v / r), np.sin(v / r)
    rho = R + r * cq
    z = np.zeros_like(u)
    pos = np.stack([rho * cp, rho * sp, r * sq], axis=-1)
    e1 = np.stack([-sp, cp, z], axis=-1)
    e2 = np.stack([-sq * cp, -sq * sp, cq], axis=-1)
    e3 = np.stack([cq * cp, cq * sp, sq], axis=-1)
    ru, rv = (rho / R)[..., None] * e1, e2
    radial = np.stack([cp, sp, z], axis=-1)
    ruu = -(rho / R ** 2)[..., None] * radial
    ruv = -(sq / R)[..., None] * e1
    rvv = -e3 / r
    return pos, np.stack([e1, e2, e3], axis=-1), (ru, rv), (ruu, ruv, rvv)


# ====================================================================== medium
class KirchhoffLove(CosseratSurface):
    """Kirchhoff–Love (Koiter) plate and shell on SE(3), d = 2, adapted to its Gauss map
    (paper §VII.B): the transverse shear strains θ_α,3 are held at zero.

    Parameters
    ----------
    E : float
        Young's modulus (> 0), default 1.
    poisson : float
        Poisson ratio ν, in (−1, 0.5), default 0.3.
    thickness : float
        Shell thickness h (> 0), default 0.1.
    density : float
        Mass density ρ (> 0), default 1 (the kinetic metric; unused by the statics).
    rest_curvature : sequence of 2 floats
        Constant rest curvatures (k_u, k_v) of the chart axes (a cylinder of radius 1/k): at most
        one may be non-zero.  Other stress-free shapes are given as ``Problem(reference=Φ_ref)``
        with frames adapted to the reference surface (e₃ its normal).
    gauge : {"coordinate", "principal"}
        The in-plane frames the initial-state builders give (module docstring): e₁ ∥ ∂_u r
        (default) or e₁, e₂ along the principal directions (κ₁ ≥ κ₂).
    umbilic : {"error", "keep"}
        With ``gauge="principal"``, at an umbilic (κ₁ = κ₂ to ``UMBILIC_TOLERANCE`` of the
        largest |κ| of the surface, e.g. every node of a plate or a sphere): raise a
        ``ValueError`` naming the node and its (u, v) (default), or keep the coordinate frame
        there (the paper's Ω₃ = 0 at umbilics).

    Notes
    -----
    ``X``, ``Q`` have shape ``[..., 2, 6]``, components ``(θ_α; π_α)``.  Energy, stress and
    conventions: see the module docstring.  Initial states (``flat``, ``cylinder``,
    ``surface``, and the closed ``torus`` of :func:`torus_surface`) and loads (``gravity``,
    ``dead-load``, ``director-pressure`` — here a pressure along the normal —,
    ``simple-support``) are those of ``cosserat-surface`` (the torus is this medium's); a ``surface``
    with given ``frames`` must have e₃ along the normal.
    """

    name: ClassVar[str] = "kirchhoff-love"
    #: the initial-state builders' frame gauge and umbilic rule (defaults of subclasses that do not set them)
    gauge: str = "coordinate"
    umbilic: str = "error"
    #: :meth:`outputs` measures the resultants from the problem's reference (its nodal rest strains)
    outputs_read_reference: ClassVar[bool] = True
    output_fields: ClassVar[dict[str, tuple[str, str]]] = {
        "normal_x": ("unit normal e3 (Gauss map), x component", "1"),
        "normal_y": ("unit normal e3 (Gauss map), y component", "1"),
        "normal_z": ("unit normal e3 (Gauss map), z component", "1"),
        "membrane_force_uu": ("membrane force N^uu (thickness-integrated, physical component)", "N m-1"),
        "membrane_force_uv": ("membrane force N^uv (thickness-integrated, physical component)", "N m-1"),
        "membrane_force_vv": ("membrane force N^vv (thickness-integrated, physical component)", "N m-1"),
        "bending_moment_uu": ("bending moment M^uu (thickness-integrated, physical component)", "N"),
        "bending_moment_uv": ("bending moment M^uv (thickness-integrated, physical component)", "N"),
        "bending_moment_vv": ("bending moment M^vv (thickness-integrated, physical component)", "N"),
        "gauss_curvature": ("Gauss curvature K = det b / det a", "m-2"),
        "mean_curvature": ("mean curvature H = tr(a^-1 b)/2, positive where the surface bends away from e3",
                           "m-1"),
        "bending_energy_density": ("Koiter bending energy per unit chart area", "J m-2"),
        "membrane_energy_density": ("Koiter membrane energy per unit chart area", "J m-2"),
    }

    def __init__(self, E: float = 1.0, poisson: float = 0.3, thickness: float = 0.1, density: float = 1.0,
                 rest_curvature: Any = (0.0, 0.0), gauge: str = "coordinate", umbilic: str = "error"):
        super().__init__(E=E, poisson=poisson, thickness=thickness, density=density, shear_correction=1.0,
                         rest_curvature=rest_curvature)
        self.gauge, self.umbilic = checked_gauge(gauge, umbilic)

    # ------------------------------------------------------------------ contract
    def parameters(self) -> dict[str, Any]:
        """Constructor keywords (JSON-serialisable); ``KirchhoffLove(**parameters())`` rebuilds it."""
        return {"E": self.E, "poisson": self.nu, "thickness": self.h, "density": self.rho,
                "rest_curvature": self.k0.tolist(), "gauge": self.gauge, "umbilic": self.umbilic}

    def constrained_strains(self) -> tuple[np.ndarray, np.ndarray]:
        """θ_u,3 = θ_v,3 = 0: component 2 of X (the e₃ component of θ_α) held at 0 on every edge
        of both axes — e₃ is the Gauss map (paper §VII.B); the multipliers are the transverse
        shear forces."""
        return np.array([2]), np.array([0.0])

    def point_kernels(self) -> MediumKernels:
        return MediumKernels(koiter_energy, koiter_stress, np.array([self.E, self.nu, self.h]))

    def planar_reduction(self) -> None:
        """None: a shell has no planar twin."""
        return None

    # ------------------------------------------------------------------ initial states
    initial_kinds: ClassVar[tuple[str, ...]] = (*CosseratSurface.initial_kinds, "torus")

    def initial_state(self, grid, kind: str, **params: Any):
        """The initial states of ``cosserat-surface`` (``flat``, ``cylinder``, ``surface``) and
        the closed ``"torus"`` of :func:`torus_surface` (``major_radius`` R, ``minor_radius`` r;
        both axes periodic, identity holonomies), in the medium's gauge."""
        if kind != "torus":
            return super().initial_state(grid, kind, **params)
        from cartan.medium import check_keywords
        from cartan.problem import InitialState

        check_keywords(kind, self._torus, params)
        pos, E = self._torus(grid, **params)
        return InitialState(Phi=self._assemble(pos, E))

    def _torus(self, grid, major_radius=None, minor_radius=None):
        pos, E, tangents, second = torus_surface(grid, major_radius, minor_radius)
        if self.gauge == "principal":  # κ₁ = 1/r along the meridian: e₁ turned onto e₂ (φ = π/2)
            E = self._principal(grid, E, tangents, second)
        return pos, E

    def _principal(self, grid, E: np.ndarray, tangents: tuple, second: tuple) -> np.ndarray:
        """The frames ``E`` ``[*shape, 3, 3]`` turned about e₃ into the principal gauge, from the
        tangents (r_u, r_v) and second derivatives (r_uu, r_uv, r_vv) ``[*shape, 3]`` at the nodes."""
        e = E[..., :, :2]
        T = np.stack([np.einsum("...i,...ir->...r", t, e) for t in tangents], axis=-2)
        e3 = E[..., :, 2]
        ruu, ruv, rvv = (np.sum(r * e3, axis=-1) for r in second)
        b = -np.stack([np.stack([ruu, ruv], axis=-1), np.stack([ruv, rvv], axis=-1)], axis=-2)  # r_α·∂_βe₃
        u, v = self._mesh(grid)

        def where(idx):
            return f"node {idx}, (u, v) = ({u[idx]:.6g}, {v[idx]:.6g})"

        phi = principal_angle(T, b, umbilic=self.umbilic, where=where)
        c, s = np.cos(phi)[..., None], np.sin(phi)[..., None]
        out = E.copy()
        out[..., :, 0] = c * E[..., :, 0] + s * E[..., :, 1]
        out[..., :, 1] = -s * E[..., :, 0] + c * E[..., :, 1]
        return out

    def _flat(self, grid, origin=None, rotation=None):
        pos, E = super()._flat(grid, origin=origin, rotation=rotation)
        if self.gauge == "principal":  # every node an umbilic
            z = np.zeros_like(pos)
            return pos, self._principal(grid, E, (E[..., :, 0], E[..., :, 1]), (z, z, z))
        return pos, E

    def _cylinder(self, grid, radius=None):
        pos, E = super()._cylinder(grid, radius=radius)
        if self.gauge == "principal":  # κ₁ = 1/R along the circumference: the coordinate frame, φ = 0
            R = float(radius) if radius is not None else grid.length[0] / (2.0 * np.pi)
            e1, e2, e3 = E[..., :, 0], E[..., :, 1], E[..., :, 2]
            return pos, self._principal(grid, E, (e1, e2), (-e3 / R, np.zeros_like(e3), np.zeros_like(e3)))
        return pos, E

    def _surface(self, grid, position=None, frames=None):
        pos, E = super()._surface(grid, position=position, frames=frames)
        if frames is None and self.gauge == "principal":
            u, v = self._mesh(grid)
            eps = 1e-6 * max(grid.length)
            ru = (np.asarray(position(u + eps, v)) - np.asarray(position(u - eps, v))) / (2 * eps)
            rv = (np.asarray(position(u, v + eps)) - np.asarray(position(u, v - eps))) / (2 * eps)
            big = 1e-4 * max(grid.length)   # second differences: O(big²) truncation, O(1e-16/big²) round-off
            r = np.asarray(position(u, v))
            ruu = (np.asarray(position(u + big, v)) - 2.0 * r + np.asarray(position(u - big, v))) / big ** 2
            rvv = (np.asarray(position(u, v + big)) - 2.0 * r + np.asarray(position(u, v - big))) / big ** 2
            ruv = (np.asarray(position(u + big, v + big)) - np.asarray(position(u + big, v - big))
                   - np.asarray(position(u - big, v + big)) + np.asarray(position(u - big, v - big))) / (4 * big ** 2)
            E = self._principal(grid, E, (ru, rv), (ruu, ruv, rvv))
        if frames is not None:  # the frames must be adapted: e₃ normal to the surface
            u, v = self._mesh(grid)
            eps = 1e-6 * max(grid.length)
            ru = (np.asarray(position(u + eps, v)) - np.asarray(position(u - eps, v))) / (2 * eps)
            rv = (np.asarray(position(u, v + eps)) - np.asarray(position(u, v - eps))) / (2 * eps)
            e3 = E[..., :, 2]
            tilt = np.maximum(np.abs(np.sum(e3 * ru, axis=-1)) / np.linalg.norm(ru, axis=-1),
                              np.abs(np.sum(e3 * rv, axis=-1)) / np.linalg.norm(rv, axis=-1))
            if np.max(tilt) > 1e-6:
                raise ValueError(f"frames: e3 must be the unit normal of the surface (Kirchhoff–Love adaptation), "
                                 f"but |e3·r_α|/|r_α| reaches {np.max(tilt):.3e}")
        return pos, E

    # ------------------------------------------------------------------ picture
    @classmethod
    def draw(cls, ds: Any, fig: Any) -> bool:
        """The last configuration of a result (run, equilibrium or continuation path) twice in
        3D, coloured by the mean curvature H and by the Gauss curvature K (the first
        configuration as a grey wireframe); False (the generic picture) when the file holds no
        surface or no curvature fields."""
        from cartan.plotting import _draw_surface_panel, _is_surface, _points

        pts = _points(ds)
        if not _is_surface(pts) or "mean_curvature" not in ds or "gauss_curvature" not in ds:
            return False
        _draw_surface_panel(fig, (1, 2, 1), ds, pts, "mean_curvature", "mean curvature H")
        _draw_surface_panel(fig, (1, 2, 2), ds, pts, "gauss_curvature", "Gauss curvature K")
        return True

    # ------------------------------------------------------------------ outputs
    def fields(self, X: np.ndarray, X0: np.ndarray | None = None) -> np.ndarray:
        """Resultants, curvatures and energy densities at strains X ``[..., 2, 6]`` (rest strain
        X0, default the medium's): ``[..., 10]`` = (n^uu, n^uv, n^vv, m^uu, m^uv, m^vv, K, H,
        bending energy density, membrane energy density)."""
        X = np.asarray(X, dtype=float)
        X0 = self.rest_strain() if X0 is None else np.asarray(X0, dtype=float)
        lead = X.shape[:-2]
        Xf = np.ascontiguousarray(X.reshape(-1, 2, 6))
        X0f = np.ascontiguousarray(np.broadcast_to(X0, X.shape).reshape(-1, 2, 6))
        out = np.empty((Xf.shape[0], 10))
        _fields_batch(Xf, X0f, np.array([self.E, self.nu, self.h]), out)
        return out.reshape(*lead, 10)

    def resultants(self, X: np.ndarray, X0: np.ndarray | None = None) -> np.ndarray:
        """(n^uu, n^uv, n^vv, 0, 0, m^uu, m^uv, m^vv, K, H) ``[..., 10]``, the layout of
        :meth:`CosseratSurface.resultants`; the transverse shear force is a reaction (the
        statics' ``constraint_force``), shown here as 0."""
        f = self.fields(X, X0)
        z = np.zeros(f.shape[:-1] + (2,))
        return np.concatenate([f[..., :3], z, f[..., 3:8]], axis=-1)

    def outputs(self, q: np.ndarray, X: np.ndarray, N: np.ndarray, grid: Any,
                reference: dict[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
        """Normal, resultants, curvatures and energy densities at the nodes ``[*shape]`` each.

        The strains are measured from the problem's stress-free reference (``reference["X0"]``
        ``[*shape, 2, 6]``, the nodal rest strains, :attr:`outputs_read_reference`), else from the
        medium's constant :meth:`rest_strain`, as the energy measures them (the energy densities
        per unit chart area carry the reference's √a⁰).  The resultants are reported in physical
        components on the reference chart's unit tangents t_α = θ⁰_α/|θ⁰_α|, |θ⁰_α| = √a⁰_αα
        (the tangential components, as the metric): N^αβ = n^αβ|θ⁰_α||θ⁰_β|,
        M^αβ = m^αβ|θ⁰_α||θ⁰_β| (force and moment per unit reference length; the contravariant
        chart components themselves, to the bit, on plates and cylinders by arclength, |θ⁰_α| = 1).
        On the sphere by longitude and colatitude, |θ⁰_u| = R sin θ: the contravariant
        n^uu ~ N/(R² sin² θ) would grow without bound towards the poles."""
        X0 = self.rest_strain() if reference is None else np.asarray(reference["X0"], dtype=float)
        f = self.fields(X, X0)
        X0 = np.broadcast_to(X0, np.shape(X))
        s = np.sqrt(X0[..., 0] ** 2 + X0[..., 1] ** 2)           # |θ⁰_α| = √a⁰_αα [*shape, 2]
        scale = np.stack([s[..., 0] ** 2, s[..., 0] * s[..., 1], s[..., 1] ** 2], axis=-1)
        f[..., 0:3] *= scale
        f[..., 3:6] *= scale
        names = ["membrane_force_uu", "membrane_force_uv", "membrane_force_vv", "bending_moment_uu",
                 "bending_moment_uv", "bending_moment_vv", "gauss_curvature", "mean_curvature",
                 "bending_energy_density", "membrane_energy_density"]
        out = {name: f[..., i] for i, name in enumerate(names)}
        out["normal_x"], out["normal_y"], out["normal_z"] = q[..., 1, 3], q[..., 2, 3], q[..., 3, 3]
        return out
