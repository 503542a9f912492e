"""Free vibration of a simply supported square Kirchhoff–Love plate, run with ``rattle``.

The reference
-------------
A square plate of side a, simply supported on its four edges (w = 0, free to turn about the
edge, M_n = 0), has the modes w = sin(mπx/a) sin(nπy/a) of the Kirchhoff plate with the
frequency parameters (Leissa, *Vibration of Plates*, NASA SP-160, 1969, §4.1)

    λ_mn = ω a² √(ρh/D) = π²(m² + n²):    19.7392, 49.3480, 78.9568   for (1, 1), (1, 2), (2, 2),

D = Eh³/(12(1 − ν²)).  These omit the rotary inertia.  The medium's kinetic metric has it
(ρh³/12 about e₁, e₂; :meth:`~cartan_cosserat_surface.surface.CosseratSurface.inertia`), and it
cannot be set to zero: the rotations are velocities of the frame, held to the slopes by the
constraints θ_α,3 = 0, and a zero entry would be a gauge.  Its linearised Lagrangian,
½ρh ẇ² + ½(ρh³/12)|∇ẇ|² − ½D[(Δw)² − 2(1 − ν)(w_xx w_yy − w_xy²)], has the same modes (the
Gauss term integrates to zero on simply supported edges) with Rayleigh's frequency

    ω² = D k⁴ / (ρh (1 + k²h²/12)),    k² = π²(m² + n²)/a²,

i.e. λ_model = π²(m² + n²)/√(1 + π²(m² + n²)h²/(12a²)) (:func:`plate_frequency`), which tends to
the listed λ as h/a → 0: at h/a = 0.1 it is 19.5788, 48.3636, 76.4808 (0.81 %, 2.00 %, 3.14 %
below).  The case compares the run with λ_model; :func:`plate_frequency` with
``rotary=False`` gives the listed values.

Simple supports on the lattice: the odd-periodic plate
------------------------------------------------------
A simply supported mode is exactly a mode of the plate of side 2a periodic in x and y (the odd
continuation w(−x, y) = −w(x, y), w(x, −y) = −w(x, y)): the rotation by π about an edge line
maps the periodic plate onto itself, so a state that starts odd stays odd, and on the edge
lines x = 0, a and y = 0, a it has w = 0, no displacement across the edge, the normal turning
about the edge only, and no bending moment across it.  The lattice of N = 2M nodes per side
(spacing Δ = a/M, nodes on the edge lines) has the same symmetry, so it realises the simply
supported plate of M cells per side with *exact* supports.  :func:`plate_modes_problem` builds
it; with ``supports=P`` it builds instead the (M + 1) × (M + 1) plate itself with the core's
hard penalty supports (:class:`cartan.supports.PenaltySupport`: positions and the normal's tilt
along each edge held by springs P·Eh/Δ² and P·D/Δ² per unit area) — the symmetric solution of
the periodic plate satisfies those supports exactly, so the two lattices give the same motion
up to the springs' compliance (O(1/P); the tests show it).

The lattice's own dispersion
----------------------------
Linearised about the flat plate, with the slopes α (about y) and β (about x) of the frames held
by the edge constraints (α_i + α_{i+1})/2 = (w_{i+1} − w_i)/Δ (u-edges, and likewise β on
v-edges), the mode w = A sin(k_x x) sin(k_y y) has α = A t_x cos(k_x x) sin(k_y y),
β = A t_y sin(k_x x) cos(k_y y) exactly, t = (2/Δ) tan(kΔ/2).  The bending strains of the edges
are the edge differences of α, β (κ_uu, κ_vv on their own edges; the twist ½(b_uv + b_vu) from a
v-edge and a u-edge), and the potential is evaluated at the lattice's corners (one u-edge and
one v-edge per corner, :mod:`cartan.schemes.lattice`), so the products κ_uu κ_vv and b_uv b_vu
pair edge averages at the nodes, which carry cos(kΔ/2).  With s = (2/Δ) sin(kΔ/2),
p = s t and q = t sin(kΔ)/Δ per axis:

    ω_h² = D [p_x² + p_y² + 2ν q_x q_y + ½(1 − ν)(t_x² s_y² + t_y² s_x² + 2 q_x q_y)]
           / (ρh + (ρh³/12)(t_x² + t_y²))

(:func:`lattice_plate_frequency`), → Dk⁴/(ρh + ρh³k²/12) as Δ → 0.  Its error is O(Δ²); for a
square mode (k_x = k_y, θ = kΔ) the numerator is 4k⁴[1 + (1 − 3ν)θ²/48 + O(θ⁴)], so its Δ²
term nearly cancels at ν = 0.3 and the error of (1, 1) and (2, 2) changes sign with Δ, while
(1, 2) shows the plain (kΔ)² error.  ``rattle`` is Störmer–Verlet on the constrained linear
system, whose frequency is (2/Δt) arcsin(ω_h Δt/2).  The runs match these predictions to
6e-7 for one mode and 2.2e-6 for the three superposed (the waves' O(A²) nonlinearity).

The case
--------
All three modes are released at rest together, each with amplitude A = 10⁻⁴a (the discrete
sines are orthogonal on the lattice and the modes do not couple in the linear range), and each
frequency is read from the first zero crossing of its modal amplitude (:func:`mode_amplitude`,
:func:`~cartan_kirchhoff_love.cases.zero_crossing_frequency`); Δt = ½Δ/c as in
``plate-flexural-wave-kl``, the run 1.1 quarter periods of the slowest mode.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import xarray as xr
from cartan_verification.case import Case

import cartan
from cartan.problem import Problem

from .cases import zero_crossing_frequency

__all__ = ["KIRCHHOFF_LAMBDA", "MODES", "SimplySupportedPlateModesKL", "frequency_parameter",
           "lattice_plate_frequency", "mode_amplitude", "mode_frequencies", "plate_frequency",
           "plate_modes_problem", "plate_modes_settings", "plot_plate_mode"]

#: the modes of the case, (m, n)
MODES: tuple[tuple[int, int], ...] = ((1, 1), (1, 2), (2, 2))
#: λ = ωa²√(ρh/D) of the Kirchhoff plate without rotary inertia, π²(m² + n²)
KIRCHHOFF_LAMBDA: dict[tuple[int, int], float] = {(m, n): float(np.pi ** 2 * (m * m + n * n)) for m, n in MODES}


def _check_mode(mode: Any) -> tuple[int, int]:
    try:
        m, n = (int(x) for x in mode)
        ok = all(float(x) == y for x, y in zip(mode, (m, n), strict=True)) and m >= 1 and n >= 1
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f"mode must be a pair of integers (m, n) ≥ 1, got {mode!r}")
    return m, n


def _kinetic(medium: Any) -> tuple[float, float]:
    inertia = np.asarray(medium.inertia(), dtype=float)
    return float(inertia[0]), float(inertia[3])


def plate_frequency(medium: Any, mode: Sequence[int], side: float = 1.0, rotary: bool = True) -> float:
    """ω of the simply supported square plate's mode (m, n) (module docstring):
    ω² = Dk⁴/(m + Jk²), k² = π²(m² + n²)/a², m and J the medium's translational and rotational
    inertia per unit area (ρh, ρh³/12); J = 0 when ``rotary`` is False (the Kirchhoff plate,
    ω = λ_mn √(D/ρh)/a², λ_mn = π²(m² + n²))."""
    m, n = _check_mode(mode)
    if not (np.isfinite(side) and side > 0.0):
        raise ValueError(f"side must be a finite number > 0, got {side!r}")
    rho_h, j = _kinetic(medium)
    k2 = np.pi ** 2 * (m * m + n * n) / side ** 2
    return float(np.sqrt(medium.bending_stiffness * k2 ** 2 / (rho_h + (j * k2 if rotary else 0.0))))


def frequency_parameter(medium: Any, omega: float, side: float = 1.0) -> float:
    """λ = ω a² √(ρh/D) of an angular frequency ω of the plate of side a."""
    rho_h, _ = _kinetic(medium)
    return float(omega * side ** 2 * np.sqrt(rho_h / medium.bending_stiffness))


def lattice_plate_frequency(medium: Any, mode: Sequence[int], side: float, spacing: float,
                            dt: float | None = None) -> float:
    """The lattice's own frequency ω_h of the mode (m, n) (module docstring), and with ``dt``
    Störmer–Verlet's (2/Δt) arcsin(ω_h Δt/2), the frequency ``rattle`` gives in the linear range."""
    m, n = _check_mode(mode)
    if not (np.isfinite(spacing) and 0.0 < spacing):
        raise ValueError(f"spacing must be a finite number > 0, got {spacing!r}")
    rho_h, j = _kinetic(medium)
    nu = medium.nu
    kx, ky = m * np.pi / side, n * np.pi / side
    if not (kx * spacing < np.pi and ky * spacing < np.pi):
        raise ValueError(f"spacing must resolve the mode: kΔ < π, got k_x Δ = {kx * spacing:.4g}, "
                         f"k_y Δ = {ky * spacing:.4g}")
    sx, sy = (2.0 / spacing * np.sin(0.5 * k * spacing) for k in (kx, ky))
    tx, ty = (2.0 / spacing * np.tan(0.5 * k * spacing) for k in (kx, ky))
    qx, qy = tx * np.sin(kx * spacing) / spacing, ty * np.sin(ky * spacing) / spacing
    px, py = sx * tx, sy * ty
    num = px ** 2 + py ** 2 + 2.0 * nu * qx * qy + 0.5 * (1.0 - nu) * (tx ** 2 * sy ** 2 + ty ** 2 * sx ** 2
                                                                       + 2.0 * qx * qy)
    omega = float(np.sqrt(medium.bending_stiffness * num / (rho_h + j * (tx ** 2 + ty ** 2))))
    if dt is None:
        return omega
    if not 0.0 < omega * dt < 2.0:
        raise ValueError(f"dt must be in (0, 2/ω_h) = (0, {2.0 / omega:.6g}), got {dt!r}")
    return float(2.0 / dt * np.arcsin(0.5 * omega * dt))


def plate_modes_problem(cells: int, *, modes: Sequence[Sequence[int]] = MODES, amplitude: float = 1e-4,
                        side: float = 1.0, supports: float | None = None, medium: Any = None,
                        **params: Any) -> Problem:
    """The simply supported square plate at rest in the superposed modes w = A Σ sin(mπx/a) sin(nπy/a).

    Parameters
    ----------
    cells : int
        M, cells per side of the plate (≥ 2); the spacing is Δ = a/M and every mode needs
        m, n < M.
    modes : sequence of (m, n)
        The modes released (each with amplitude A).
    amplitude : float
        A, in units of length (> 0; 10⁻⁴a keeps the motion linear).
    side : float
        a (> 0).
    supports : float, optional
        None (default): the odd-periodic plate — a 2M × 2M grid periodic in u and v of side 2a,
        whose symmetry realises exact simple supports on the lines x, y ∈ {0, a} (module
        docstring).  A number P > 0: the (M + 1) × (M + 1) plate with hard penalty supports on
        its four edges (:class:`cartan.supports.PenaltySupport`, positions held by P·Eh/Δ² and
        the normal's tilt along the edge by P·D/Δ², per unit area).
    medium : Medium, optional
        A ``kirchhoff-love`` medium (default E = 1, ν = 0.3, h = 0.1a, ρ = 1, or ``params``).
    **params
        Keywords of the default medium.

    Returns
    -------
    Problem
        Named ``"plate-modes-kl"``, node (i, j) at (iΔ, jΔ, w) with its frame turned by the
        slopes the lattice's edge constraints give for the sampled sines (module docstring:
        α = A t_x cos(k_x x) sin(k_y y) about y, β about x, t = (2/Δ) tan(kΔ/2)), so that
        θ_α,3 = 0 holds to O(A²) from the start.
    """
    from scipy.spatial.transform import Rotation

    if isinstance(cells, bool) or not isinstance(cells, (int, np.integer)) or cells < 2:
        raise ValueError(f"cells must be an integer ≥ 2, got {cells!r}")
    modes = [_check_mode(mn) for mn in modes]
    if not modes or any(max(mn) >= cells for mn in modes):
        raise ValueError(f"modes must be a non-empty list of (m, n) with m, n < cells = {cells}, got {modes}")
    if not (np.isfinite(amplitude) and amplitude > 0.0):
        raise ValueError(f"amplitude must be a finite number > 0, got {amplitude!r}")
    if not (np.isfinite(side) and side > 0.0):
        raise ValueError(f"side must be a finite number > 0, got {side!r}")
    if supports is not None and not (np.isfinite(supports) and supports > 0.0):
        raise ValueError(f"supports must be None (odd-periodic plate) or a penalty factor > 0, got {supports!r}")
    if medium is None:
        opts = {"E": 1.0, "poisson": 0.3, "thickness": 0.1 * side, "density": 1.0, **params}
        medium = cartan.medium("kirchhoff-love", **opts)
    spacing = side / cells
    if supports is None:
        grid = cartan.Grid((2 * cells, 2 * cells), length=(2.0 * side, 2.0 * side), periodic=(True, True))
    else:
        grid = cartan.Grid((cells + 1, cells + 1), length=(side, side))
    x, y = np.meshgrid(grid.coordinates(0), grid.coordinates(1), indexing="ij")
    w = np.zeros_like(x)
    alpha = np.zeros_like(x)
    beta = np.zeros_like(x)
    for m, n in modes:
        kx, ky = m * np.pi / side, n * np.pi / side
        tx, ty = (2.0 / spacing * np.tan(0.5 * k * spacing) for k in (kx, ky))
        w += amplitude * np.sin(kx * x) * np.sin(ky * y)
        alpha += amplitude * tx * np.cos(kx * x) * np.sin(ky * y)
        beta += amplitude * ty * np.sin(kx * x) * np.cos(ky * y)
    rotvec = np.stack([beta, -alpha, np.zeros_like(x)], axis=-1)   # e₁ tilts up by α, e₂ by β
    Phi = np.zeros((*x.shape, 4, 4))
    Phi[..., 0, 0] = 1.0
    Phi[..., 1:, 0] = np.stack([x, y, w], axis=-1)
    Phi[..., 1:, 1:] = Rotation.from_rotvec(rotvec.reshape(-1, 3)).as_matrix().reshape(*x.shape, 3, 3)
    if supports is None:
        shift_u, shift_v = np.eye(4), np.eye(4)
        shift_u[1, 0] = shift_v[2, 0] = 2.0 * side
        init = cartan.InitialState(Phi=Phi, holonomy={0: shift_u, 1: shift_v})
        return Problem(medium, grid, init, name="plate-modes-kl")
    from cartan.supports import PenaltySupport

    P = float(supports)
    support = PenaltySupport(position_stiffness=np.full(3, P * medium.E * medium.h / spacing ** 2),
                             director_stiffness=P * medium.bending_stiffness / spacing ** 2).hold(Phi)
    return Problem(medium, grid, cartan.InitialState(Phi=Phi), loads=[support], name="plate-modes-kl")


def plate_modes_settings(problem: Problem, *, modes: Sequence[Sequence[int]] = MODES, cfl: float = 0.5,
                         quarter_periods: float = 1.1, supports: float | None = None) -> dict[str, Any]:
    """Run settings of :func:`plate_modes_problem`: Δt = cfl·Δ/c (c = √(E/(ρ(1 − ν²))), the
    fastest wave the constraints leave), or with penalty supports P, cfl·Δ/(c√(1 + P)) (the
    springs' frequency is ≈ √P·c/Δ), the run ``quarter_periods`` quarter periods of the slowest
    mode (Rayleigh's ω), every step saved."""
    m = problem.medium
    side = problem.grid.length[0] if supports is not None else 0.5 * problem.grid.length[0]
    spacing = problem.grid.spacing[0]
    c = float(np.sqrt(m.E / (m.rho * (1.0 - m.nu ** 2))))
    dt_max = cfl * spacing / c / (1.0 if supports is None else np.sqrt(1.0 + float(supports)))
    omega = min(plate_frequency(m, mn, side) for mn in modes)
    t_end = quarter_periods * 0.5 * np.pi / omega
    steps = int(np.ceil(t_end / dt_max))
    return {"dt": t_end / steps, "t_end": t_end, "save_every": 1}


def _side(problem: Problem) -> float:
    """a: the grid's side, halved for the odd-periodic plate."""
    return 0.5 * problem.grid.length[0] if problem.grid.periodic[0] else problem.grid.length[0]


def mode_amplitude(ds: xr.Dataset, problem: Problem, mode: Sequence[int]) -> np.ndarray:
    """a_mn(t) = Σ z s_mn / Σ s_mn² over the nodes ``[time]``, s_mn = sin(mπx/a) sin(nπy/a): the
    amplitude of the mode (the discrete sines are orthogonal on both lattices)."""
    m, n = _check_mode(mode)
    a = _side(problem)
    x, y = np.meshgrid(problem.grid.coordinates(0), problem.grid.coordinates(1), indexing="ij")
    s = np.sin(m * np.pi * x / a) * np.sin(n * np.pi * y / a)
    z = np.asarray(ds["position"].values)[..., 2]          # [time, nu, nv]
    return np.einsum("tij,ij->t", z, s) / float(np.sum(s * s))


def mode_frequencies(ds: xr.Dataset, problem: Problem,
                     modes: Sequence[Sequence[int]] = MODES) -> dict[tuple[int, int], float]:
    """ω of every mode from the first zero crossing of its :func:`mode_amplitude` (NaN if none)."""
    t = np.asarray(ds["time"].values, dtype=float)
    return {_check_mode(mn): zero_crossing_frequency(t, mode_amplitude(ds, problem, mn)) for mn in modes}


class SimplySupportedPlateModesKL(Case):
    """Frequencies of the modes (1, 1), (1, 2), (2, 2) of a simply supported square
    Kirchhoff–Love plate, run with ``rattle`` on the odd-periodic lattice (see the module
    docstring): M = 4·2^level cells per side, Δt = ½Δ/c; the error is the largest
    |ω/ω_R − 1| over the modes, ω_R Rayleigh's frequency (the Kirchhoff frequency with the
    medium's rotary inertia)."""

    name = "plate-modes-kl"
    medium = "kirchhoff-love"
    description = ("Simply supported square plate frequencies λ = ωa²√(ρh/D) = 19.7392, 49.3480, 78.9568 (modes "
                   "(1,1), (1,2), (2,2), λ = π²(m² + n²)): Kirchhoff–Love plate (E = 1, ν = 0.3, h/a = 0.1, ρ = 1) "
                   "run with rattle, the supports realised by the odd-periodic plate of side 2a; frequencies from "
                   "the quarter periods of the modal amplitudes")
    reference = ("λ = π²(m² + n²)/√(1 + π²(m² + n²)h²/(12a²)) (Leissa, NASA SP-160 §4.1, with Rayleigh's rotary "
                 "inertia, the medium's kinetic metric ρh, ρh³/12): 19.5788, 48.3636, 76.4808 at h/a = 0.1, "
                 "→ 19.7392, 49.3480, 78.9568 as h/a → 0")
    quantity = ("angular frequency of each mode from the first zero crossing of its modal amplitude "
                "Σ w sin(mπx/a) sin(nπy/a)/Σ sin², cubic interpolation of the saved steps")
    norm = "max over the three modes of |ω/ω_ref − 1|"
    space_order = 2.0
    refine = "space"
    default_integrators = ("rattle",)
    default_schemes = ("lattice",)
    levels = (0, 1, 2, 3)
    quick_levels = (1, 2)
    tolerance = 4e-3
    tolerance_reason = ("M = 4·2^level cells per side, Δt = ½Δ/c; the error is the lattice's dispersion plus "
                        "Verlet's (ωΔt)²/24, largest for (1, 2): 7.69e-2, 1.22e-2, 2.71e-3, 6.58e-4 at M = 4, 8, 16, "
                        "32 (measured; the discrete dispersion predicts each mode to 2.2e-6); the bound holds from "
                        "M = 16 on with a 30 % margin")
    #: A/a, the modes, Δt = cfl·Δ/c, the run's length in quarter periods of the slowest mode
    amplitude = 1e-4
    modes = MODES
    cfl = 0.5
    quarter_periods = 1.1

    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        problem = plate_modes_problem(4 * 2 ** level, modes=self.modes, amplitude=self.amplitude)
        return problem, plate_modes_settings(problem, modes=self.modes, cfl=self.cfl,
                                             quarter_periods=self.quarter_periods)

    def mode_errors(self, ds: xr.Dataset, problem: Problem) -> dict[tuple[int, int], float]:
        """|ω/ω_R − 1| of every mode (inf when a mode does not cross zero)."""
        side = _side(problem)
        out = {}
        for mn, omega in mode_frequencies(ds, problem, self.modes).items():
            out[mn] = abs(omega / plate_frequency(problem.medium, mn, side) - 1.0) if np.isfinite(omega) else np.inf
        return out

    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        return float(max(self.mode_errors(ds, problem).values()))


def plot_plate_mode(ds: xr.Dataset, problem: Problem, mode: Sequence[int], path: Any, *, scale: float = 2000.0,
                    frame: int = 0) -> None:
    """Write a picture of a run of :func:`plate_modes_problem` to ``path``: the supported plate
    [0, a]² at the saved ``frame`` in 3D, w exaggerated by ``scale`` and coloured by w, and the
    modal amplitude a_mn(t)/a_mn(0) against cos(ω_h t), ω_h the lattice's frequency with
    Verlet's time error (:func:`lattice_plate_frequency`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import cm, colors

    mn = _check_mode(mode)
    a = _side(problem)
    M = int(round(a / problem.grid.spacing[0]))
    pos = np.asarray(ds["position"].values)[frame, :M + 1, :M + 1]
    w = pos[..., 2]
    fig = plt.figure(figsize=(11.0, 4.4))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    lim = float(np.max(np.abs(w))) or 1.0
    norm = colors.Normalize(vmin=-lim, vmax=lim)
    ax.plot_surface(pos[..., 0], pos[..., 1], scale * w, facecolors=cm.coolwarm(norm(w)), rstride=1, cstride=1,
                    linewidth=0.2, edgecolor="0.3", shade=False)
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel(f"w × {scale:g}")
    ax.set_title(f"mode ({mn[0]}, {mn[1]}), {M} × {M} cells, t = {float(ds['time'].values[frame]):.3g}")
    sm = cm.ScalarMappable(norm=norm, cmap=cm.coolwarm)
    sm.set_array([])
    fig.colorbar(sm, ax=ax, shrink=0.7, pad=0.12, label="w")
    ax2 = fig.add_subplot(1, 2, 2)
    t = np.asarray(ds["time"].values, dtype=float)
    amp = mode_amplitude(ds, problem, mn)
    dt = float(t[1] - t[0])
    omega_h = lattice_plate_frequency(problem.medium, mn, a, problem.grid.spacing[0], dt)
    omega = plate_frequency(problem.medium, mn, a)
    tt = np.linspace(0.0, t[-1], 400)
    ax2.plot(tt, np.cos(omega * tt), color="0.6",
             label=f"Rayleigh, λ = {frequency_parameter(problem.medium, omega, a):.4f}")
    ax2.plot(tt, np.cos(omega_h * tt), "--", color="C1",
             label=f"lattice + Verlet, λ = {frequency_parameter(problem.medium, omega_h, a):.4f}")
    ax2.plot(t, amp / amp[0], ".", color="C0", ms=4, label="rattle run (modal amplitude)")
    ax2.set_xlabel("t")
    ax2.set_ylabel("a(t) / a(0)")
    ax2.set_title(f"λ_Kirchhoff = π²(m² + n²) = {KIRCHHOFF_LAMBDA.get(mn, np.pi ** 2 * (mn[0] ** 2 + mn[1] ** 2)):.4f}")
    ax2.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
