"""Buckling of a complete spherical shell under uniform external pressure (``cosserat-surface``).

The closed sphere of radius R on the glued longitude × colatitude chart (``"sphere"`` initial
kind, :mod:`.cases_sphere`) under the conservative follower pressure
:class:`~cartan_cosserat_surface.surface.VolumePressure` p > 0 (the chart's ∂_u r × ∂_v r points
inward, so p > 0 pushes in: the potential is p·V with V the enclosed volume).  The sphere
contracts uniformly until, at the first critical pressure, the second variation of U + pV loses
its positivity in the 2l + 1 modes of a spherical-harmonic degree l.

Reference: the exact critical pressure of this medium's continuum shell
------------------------------------------------------------------------
**Fundamental state.**  The sphere scaled to radius λR (directors radial) has the equibiaxial
membrane strain e = ½(λ² − 1) and the bending change κ = (λ − 1)/R·a⁰ (b = θ·d scales with θ);
the energy of :mod:`.surface` per unit reference area is u(λ) = Eh e²/(1 − ν) + D(1 + ν)(λ − 1)²/R²,
and dΠ/dλ = 0 with Π = 4πR²u(λ) + p·(4π/3)λ³R³ gives the exact pressure of the contracted sphere

    p(λ) = −[2Ehλ e/(1 − ν) + 2D(1 + ν)(λ − 1)/R²] / (Rλ²)        (:func:`homogeneous_pressure`).

**Second variation.**  Π is invariant under the rotations of the sphere and so is the contracted
state: its Hessian is block diagonal in the spherical harmonics (l, m), the 2l + 1 blocks of a
degree equal.  The m = 0 block is that of the axisymmetric fields

    r = (λR + a₀P_l) e_r + a₁P_l' e_θ + a₃P_l' e_φ,   R = R₀ exp([a₂P_l' e₁ + a₄P_l' e₂]×),

(P_l = P_l(cos θ), ' = d/dθ, R₀ = (e_φ, −e_θ, e_r) the rest frame; a₀, a₁, a₂ the poloidal
displacement, meridional displacement and director tilt, a₃, a₄ the toroidal ones), closed under
the Hessian by the symmetry.  Π(a) is the medium's own energy density (:func:`shell_energy`, the
kernel :func:`~cartan_cosserat_surface.surface.shell_point` with Green–Lagrange membrane strain,
transverse shear κ_sGh and Naghdi's bending measure) of the exact strains X_α = Φ⁻¹∂_αΦ of
these fields (the frame's rates through the right Jacobian of exp), plus p·V with
V = ⅓∮ r·(r_θ × r_φ) dθ dφ, integrated by Gauss–Legendre in θ (exact to round-off with 2l + 40
points: the integrand is a trigonometric polynomial but for the rotation's exponential).  The
5 × 5 Hessian in a comes from complex-step gradients (no cancellation) differenced at fourth order
(steps 10⁻⁴: error 10⁻¹⁰ of its entries), :func:`mode_hessian`.  Its gradient vanishes on the
fundamental path, so it is the Hessian of Π whatever the fields' parametrisation.  The degree-l
critical point is the stretch λ_l < 1 at which the smallest eigenvalue of the poloidal 3 × 3
block vanishes (the toroidal block stays positive: no normal displacement, no pressure work at
first order) and p_l = p(λ_l) (:func:`critical_pressure`); the sphere's first critical pressure is
min_l p_l (:func:`first_critical_pressure`).

**Thin shells.**  Neglecting the prebuckling strain, the transverse shear and the O(1/l²) terms of
the curvature, the second variation of the degree-l mode is the shallow-shell (Donnell) one with
∇² → −l(l + 1)/R²: Dλ_l²/R⁴ + Eh/R² = (pR/2)λ_l/R², λ_l = l(l + 1),

    p_l ≈ (2/R)(Dλ_l/R² + Eh/λ_l)                                     (:func:`donnell_pressure`),

whose minimum over a continuous λ_l = R√(Eh/D) is Zoelly's (1915) classical value
p_Z = 4√(EhD)/R² = 2Eh²/(R²√(3(1 − ν²))) (:func:`zoelly_pressure`).  At h/R = 0.1 (ν = 0.3,
κ_s = 5/6) this medium's p_l has its minimum at l = 5, p₅ = 0.010884 E (p₆ = 0.011050 E), 10.1 %
below p_Z = 0.012105 E: the transverse shear softens the bending of a short wave
(D → D/(1 + Dλ_l/(κ_sGhR²)), 8.6 % at l = 5), the shell has contracted by 3.7 % at the critical
point, and l is an integer (Donnell's p₅ is 0.5 % above p_Z).  As h/R → 0 the ratio p_cr/p_Z → 1
(:func:`first_critical_pressure` at h/R = 0.02: measured in docs/media/cosserat-surface.md).

The lattice's first critical pressure
-------------------------------------
:func:`lattice_critical_pressure` follows the fundamental path of the N × N/2 lattice under
``VolumePressure`` (Newton at increasing p, rigid motions held by six gauge pins that carry no
force) and locates the first load at which the symmetric stiffness −J (J the statics' whole
Jacobian, the stencil part plus the volume's rank-6 part, :meth:`VolumePressure.jacobian_parts`),
with the pins as penalties, acquires a negative eigenvalue: its six lowest eigenvalues by
shift-invert Lanczos below the spectrum, matched from point to point by their eigenvectors and
extrapolated linearly to zero, approached from the stable side.  The 2l + 1 modes of a degree are
split by the chart (the poles), so a change of the sign of det J alone can straddle several
crossings, and Newton fails close to the critical load (the pole rows are an imperfection along
the even-l, m = 0 modes).  Measured (h/R = 0.1): p = 0.0094241, 0.0101231, 0.0103971 at
N = 24, 32, 40, errors 13.4 %, 7.0 %, 4.5 % against p₅, observed order 2.27, 2.00.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["critical_pressure", "donnell_pressure", "first_critical_pressure", "homogeneous_pressure",
           "homogeneous_stretch", "lattice_critical_pressure", "mode_hessian", "shell_energy",
           "sphere_buckling_problem", "zoelly_pressure"]


# ---------------------------------------------------------------------------- closed forms
def zoelly_pressure(E: float, nu: float, h: float, R: float = 1.0) -> float:
    """Zoelly's thin-shell critical pressure 2Eh²/(R²√(3(1 − ν²)))."""
    return 2.0 * E * h * h / (R * R * math.sqrt(3.0 * (1.0 - nu * nu)))


def donnell_pressure(E: float, nu: float, h: float, degree: int, R: float = 1.0) -> float:
    """The shallow-shell critical pressure of the degree-l mode, (2/R)(Dλ_l/R² + Eh/λ_l), λ_l = l(l + 1)."""
    D = E * h ** 3 / (12.0 * (1.0 - nu * nu))
    lam = degree * (degree + 1.0)
    return 2.0 / R * (D * lam / R ** 2 + E * h / lam)


def homogeneous_pressure(stretch: float, E: float, nu: float, h: float, R: float = 1.0) -> float:
    """p(λ): the external pressure holding this medium's sphere uniformly contracted to λR (module docstring)."""
    lam = float(stretch)
    D = E * h ** 3 / (12.0 * (1.0 - nu * nu))
    e = 0.5 * (lam * lam - 1.0)
    return -(2.0 * E * h * e * lam / (1.0 - nu) + 2.0 * D * (1.0 + nu) * (lam - 1.0) / R ** 2) / (R * lam * lam)


def homogeneous_stretch(pressure: float, E: float, nu: float, h: float, R: float = 1.0) -> float:
    """The stretch λ ∈ (0.5, 1] with :func:`homogeneous_pressure` (λ) = ``pressure`` ≥ 0 (bisection)."""
    lo, hi = 0.5, 1.0
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if homogeneous_pressure(mid, E, nu, h, R) > pressure:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


# ---------------------------------------------------------------------------- the shell's energy (numpy)
def _constitutive(x: np.ndarray, A: np.ndarray, nu: float, c: float) -> np.ndarray:
    """c [ν A tr_A(x) + (1 − ν) A x A] of symmetric ``[..., 2, 2]`` tensors (the kernel's ``_constitutive``)."""
    tr = np.einsum("...ij,...ij->...", A, x)
    return c * (nu * A * tr[..., None, None] + (1.0 - nu) * A @ x @ A)


def shell_energy(X: np.ndarray, X0: np.ndarray, E: float, nu: float, h: float, ks: float) -> np.ndarray:
    """Energy density per unit chart area of :func:`~cartan_cosserat_surface.surface.shell_point`
    (Naghdi shell, ``nm = 3``), vectorised and complex-analytic: X ``[..., 2, 6]`` (any dtype),
    X₀ ``[..., 2, 6]`` real; returns ``[...]``."""
    def T(a):
        return np.swapaxes(a, -1, -2)

    th, pi, th0, pi0 = X[..., :3], X[..., 3:], X0[..., :3], X0[..., 3:]
    a, a0 = th @ T(th), th0 @ T(th0)
    det0 = a0[..., 0, 0] * a0[..., 1, 1] - a0[..., 0, 1] ** 2
    A = np.stack([np.stack([a0[..., 1, 1], -a0[..., 0, 1]], -1),
                  np.stack([-a0[..., 0, 1], a0[..., 0, 0]], -1)], -2) / det0[..., None, None]
    eps = 0.5 * (a - a0)

    def bend(t, q):  # sym(θ_a · d_b), d_b = (π_b2, −π_b1, 0)
        d = np.stack([q[..., 1], -q[..., 0], 0.0 * q[..., 0]], -1)
        b = t @ T(d)
        return 0.5 * (b + T(b))

    kap = bend(th, pi) - bend(th0, pi0)
    cs = E / (1.0 - nu * nu)
    n = _constitutive(eps, A, nu, cs * h)
    m = _constitutive(kap, A, nu, cs * h ** 3 / 12.0)
    g = th[..., 2] - th0[..., 2]
    q = ks * 0.5 * E / (1.0 + nu) * h * np.einsum("...ij,...j->...i", A, g)
    return 0.5 * np.sqrt(det0) * (np.einsum("...ij,...ij->...", n, eps) + np.einsum("...ij,...ij->...", m, kap)
                                  + np.sum(q * g, -1))


def _skew(w: np.ndarray) -> np.ndarray:
    Z = np.zeros(w.shape[:-1] + (3, 3), dtype=w.dtype)
    Z[..., 0, 1], Z[..., 0, 2] = -w[..., 2], w[..., 1]
    Z[..., 1, 0], Z[..., 1, 2] = w[..., 2], -w[..., 0]
    Z[..., 2, 0], Z[..., 2, 1] = -w[..., 1], w[..., 0]
    return Z


def _exp_coefficients(t2: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """sin t/t, (1 − cos t)/t², (t − sin t)/t³ as analytic functions of t² (complex allowed)."""
    small = np.abs(t2) < 1e-6
    ts = np.where(small, 1.0, t2)
    t = np.sqrt(ts)
    a = np.where(small, 1.0 - t2 / 6.0 + t2 ** 2 / 120.0, np.sin(t) / t)
    b = np.where(small, 0.5 - t2 / 24.0 + t2 ** 2 / 720.0, (1.0 - np.cos(t)) / ts)
    c = np.where(small, 1.0 / 6.0 - t2 / 120.0 + t2 ** 2 / 5040.0, (t - np.sin(t)) / (ts * t))
    return a, b, c


def mode_energy(amplitudes: np.ndarray, stretch: float, pressure: float, degree: int, E: float, nu: float,
                h: float, ks: float, R: float = 1.0, n_quad: int | None = None) -> np.ndarray:
    """Π = 2π∫₀^π [U(X, X₀) + p r·(r_θ × r_φ)/3] dθ of the axisymmetric degree-l fields of the module
    docstring about the sphere contracted to λR; ``amplitudes`` ``(B, 5)`` = (a₀ … a₄), any dtype;
    returns ``(B,)``."""
    from numpy.polynomial import legendre

    n_quad = 2 * degree + 40 if n_quad is None else int(n_quad)
    x, wq = legendre.leggauss(n_quad)
    th = 0.5 * math.pi * (x + 1.0)
    wq = 0.5 * math.pi * wq
    s, c = np.sin(th), np.cos(th)
    coef = np.zeros(degree + 1)
    coef[degree] = 1.0
    P = legendre.legval(c, coef)
    d1, d2 = legendre.legval(c, legendre.legder(coef)), legendre.legval(c, legendre.legder(coef, 2))
    dP, ddP = -s * d1, s * s * d2 - c * d1                  # d/dθ, d²/dθ² of P_l(cos θ)
    a = np.asarray(amplitudes)[:, :, None]
    rho = stretch * R
    w, wp, u, up, v, vp = a[:, 0] * P, a[:, 0] * dP, a[:, 1] * dP, a[:, 1] * ddP, a[:, 3] * dP, a[:, 3] * ddP
    zero = 0.0 * w
    om = np.stack([a[:, 2] * dP, a[:, 4] * dP, zero], -1)      # the frame's rotation vector (body e₁, e₂)
    omp = np.stack([a[:, 2] * ddP, a[:, 4] * ddP, zero], -1)
    # components on (e_r, e_θ, e_φ)
    r = np.stack([rho + w, u, v], -1)
    rt = np.stack([wp - u, rho + w + up, vp], -1)
    rf = np.stack([-v * s, -v * c, (rho + w) * s + u * c], -1)

    def body(y):  # on the rest frame (e_φ, −e_θ, e_r)
        return np.stack([y[..., 2], -y[..., 1], y[..., 0]], -1)

    sa, sb, sc = _exp_coefficients(np.sum(om * om, -1))
    W = _skew(om)
    W2 = W @ W
    eye = np.eye(3)
    Qt = np.swapaxes(eye + sa[..., None, None] * W + sb[..., None, None] * W2, -1, -2)
    Jr = eye - sb[..., None, None] * W + sc[..., None, None] * W2   # right Jacobian of exp

    def mv(M, y):
        return np.einsum("...ij,...j->...i", M, y)

    k_t = np.stack([np.ones_like(s), 0.0 * s, 0.0 * s], -1)        # R₀ᵀ∂_θR₀, R₀ᵀ∂_φR₀ (axial)
    k_f = np.stack([0.0 * s, s, c], -1)
    X = np.stack([np.concatenate([mv(Qt, body(rf)), mv(Qt, k_f)], -1),
                  np.concatenate([mv(Qt, body(rt)), mv(Qt, k_t) + mv(Jr, omp)], -1)], -2)  # u = φ, v = θ
    X0 = np.zeros((th.size, 2, 6))
    X0[:, 0, 0], X0[:, 1, 1] = R * s, -R
    X0[:, 0, 4], X0[:, 0, 5], X0[:, 1, 3] = s, c, 1.0
    U = shell_energy(X, X0, E, nu, h, ks)
    vol = np.sum(r * np.cross(rt, rf), -1) / 3.0
    return 2.0 * math.pi * ((U + pressure * vol) @ wq)


def mode_hessian(stretch: float, degree: int, E: float, nu: float, h: float, ks: float, R: float = 1.0,
                 n_quad: int | None = None, step: float = 1e-4) -> tuple[np.ndarray, float]:
    """The Hessian ``(5, 5)`` of :func:`mode_energy` in the amplitudes at a = 0 on the fundamental
    path (p = :func:`homogeneous_pressure` (λ)), and p: complex-step gradients (step 10⁻³⁰)
    differenced at fourth order (``step``)."""
    p = homogeneous_pressure(stretch, E, nu, h, R)
    hc = 1e-30
    steps = np.array([2.0, 1.0, -1.0, -2.0]) * step
    weights = np.array([-1.0, 8.0, -8.0, 1.0]) / (12.0 * step)
    amps = np.zeros((5, 4, 5, 5), dtype=complex)  # [differenced j, stencil k, complex-step i, component]
    for j in range(5):
        for k in range(4):
            amps[j, k, :, j] += steps[k]
            amps[j, k, np.arange(5), np.arange(5)] += 1j * hc
    vals = mode_energy(amps.reshape(-1, 5), stretch, p, degree, E, nu, h, ks, R, n_quad).imag.reshape(5, 4, 5) / hc
    H = np.einsum("jki,k->ij", vals, weights)
    return 0.5 * (H + H.T), p


def critical_pressure(degree: int, E: float = 1.0, nu: float = 0.3, h: float = 0.1, ks: float = 5.0 / 6.0,
                      R: float = 1.0, n_quad: int | None = None) -> tuple[float, float]:
    """(p_l, λ_l): the degree-l critical point of this medium's sphere (module docstring), the first
    stretch below 1 at which the poloidal block of :func:`mode_hessian` is singular (Brent, to 10⁻¹⁴)."""
    from scipy.optimize import brentq

    if degree < 2:
        raise ValueError(f"degree must be ≥ 2 (l = 0 breathes, l = 1 translates), got {degree!r}")

    def lowest(lam: float) -> float:
        return float(np.linalg.eigvalsh(mode_hessian(lam, degree, E, nu, h, ks, R, n_quad)[0][:3, :3])[0])

    hi, lo = 1.0 - 1e-6, 1.0 - 0.05
    while lowest(lo) > 0.0:
        hi, lo = lo, 1.0 - 1.5 * (1.0 - lo)
        if lo < 0.3:
            raise ValueError(f"no critical point of degree {degree} above λ = 0.3")
    lam = brentq(lowest, lo, hi, xtol=1e-14)
    return homogeneous_pressure(lam, E, nu, h, R), lam


def first_critical_pressure(E: float = 1.0, nu: float = 0.3, h: float = 0.1, ks: float = 5.0 / 6.0,
                            R: float = 1.0) -> tuple[float, int, dict[int, float]]:
    """(min_l p_l, its l, {l: p_l}) over the degrees around Zoelly's λ_l = R√(Eh/D) (±3 and
    further while p_l decreases)."""
    D = E * h ** 3 / (12.0 * (1.0 - nu * nu))
    l0 = max(2, int(round(-0.5 + math.sqrt(0.25 + R * math.sqrt(E * h / D)))))
    ps: dict[int, float] = {}
    for l in range(max(2, l0 - 3), l0 + 4):
        ps[l] = critical_pressure(l, E, nu, h, ks, R)[0]
    while min(ps, key=ps.get) == min(ps) and min(ps) > 2:
        ps[min(ps) - 1] = critical_pressure(min(ps) - 1, E, nu, h, ks, R)[0]
    while min(ps, key=ps.get) == max(ps):
        ps[max(ps) + 1] = critical_pressure(max(ps) + 1, E, nu, h, ks, R)[0]
    best = min(ps, key=ps.get)
    return ps[best], best, ps


# ---------------------------------------------------------------------------- the lattice
def sphere_buckling_problem(N: int, pressure: float = 1.0, *, thickness: float = 0.1):
    """The sphere (E = R = 1, ν = 0.3, κ_s = 5/6) on N × N/2 nodes under ``VolumePressure(pressure)``
    (p > 0 external) and its gauge pins (node N/4's position and two rotations, the y of the node
    opposite it: six components, a rigid motion's, which carry no force)."""
    import cartan
    from cartan.problem import Problem

    from .surface import VolumePressure

    if N < 8 or N % 4:
        raise ValueError(f"N must be a multiple of 4, ≥ 8, got {N!r}")
    med = cartan.medium("cosserat-surface", E=1.0, poisson=0.3, thickness=thickness, density=1.0)
    grid = cartan.Grid((N, N // 2), (2.0 * math.pi, math.pi), periodic=(True, False), glued=(None, 0))
    prob = Problem(med, grid, med.initial_state(grid, "sphere"), loads=[VolumePressure(pressure)],
                   name="sphere-buckling")
    pins = {N // 4: [0, 1, 2, 3, 4], (N // 2) * (N // 2) + N // 4: [1]}
    return prob, pins


class _Path:
    """The fundamental path of a problem whose loads are scaled by p: Newton at each p from the last
    converged point, and the stiffness's lowest eigenvalue there."""

    def __init__(self, problem: Any, pins: dict, tol: float = 1e-9, log: Any = None):
        from cartan.statics import _Equilibrium, rigid_gauge_pins

        self.eq = eq = _Equilibrium(problem, pins=rigid_gauge_pins(problem, pins), probe_lam=0.0)
        self.state, self.mu, self.p = eq.state0, np.zeros(eq.nmult), 0.0
        self.tol = tol
        self.fref = float(np.abs(eq.dlam(eq.state0)[: eq.nunk]).max())  # the largest nodal force at p = 1
        self.log = log
        self.points: list[dict[str, Any]] = []
        self.iterations = 0
        self.capacitance: list[float] = []

    def solve(self, p: float):
        """The equilibrium at load factor p from the last one (the state, multipliers)."""
        from cartan.statics import ConvergenceError, _factorise, _newton, _Point

        eq = self.eq
        # predictor: the homogeneous contraction from the last point's load to p (a drift along e₃)
        E, nu, h = eq.problem.medium.E, eq.problem.medium.nu, eq.problem.medium.h
        dw = homogeneous_stretch(p, E, nu, h) - homogeneous_stretch(self.p, E, nu, h)
        state = self.state.copy()
        drift = np.zeros((*eq.shape, eq.r_dim))
        drift[..., 2] = dw
        eq.sch.drift(state, 1.0, drift)

        def move(pt, alpha, d):
            s, u = eq.update(pt.state, pt.mu, d, alpha)
            return _Point(s, u, p)

        out = _newton(eq, _Point(state, self.mu, p), residual=lambda pt: eq.residual(pt.state, pt.mu, p),
                      factorise=lambda pt, offset: _factorise(eq, pt.state, pt.mu, p, offset), move=move,
                      converged=lambda pt, r: float(np.abs(r).max()) <= self.tol * p * self.fref,
                      scale=np.concatenate([eq.delta_scale, np.zeros(eq.nmult)]), max_iter=30, max_halvings=20,
                      xtol=1e-14)
        self.iterations += out.iterations
        if not out.converged:
            raise ConvergenceError(f"no equilibrium at p = {p:g}: {out.reason}", out.iterations,
                                   out.residuals[-1], out.residuals)
        return out.point.state, out.point.mu, out.iterations

    def lowest(self, state, mu, p: float, k: int = 4, with_vectors: bool = False):
        """The k smallest eigenvalues of the symmetric stiffness −sym J on the drifts, J the statics'
        whole Jacobian (stencil part + the load's rank-k part), the pins as penalty springs
        k_p BᵀB (B their constraint rows, k_p the largest diagonal entry times the number of nodes,
        which puts the rigid motions far above the buckling modes): shift-invert Lanczos
        about a shift below the spectrum (the LU of an SPD matrix, the rank part by Woodbury).
        Also (sign, log|det|) of the bordered whole J (the continuation's det)."""
        import scipy.sparse as sp
        import scipy.sparse.linalg as spla

        from cartan.continuation import _log_det, _symmetric_low_rank

        eq = self.eq
        K, low = eq.jacobian(state, mu, p, low_rank=True)
        det = _log_det(K, low)
        if low is not None:  # the condition of the Woodbury capacitance I + Vᵀ K_s⁻¹ U (the statics' check)
            lu_k = spla.splu(K.tocsc())
            C = np.eye(low[0].shape[1]) + low[1].T @ np.column_stack([lu_k.solve(x) for x in low[0].T])
            self.capacitance.append(float(np.linalg.cond(C)))
        n = eq.nunk
        K = K.tocsr()
        A, B = K[:n, :n], K[n:eq.nunk + eq.npin, :n]
        # the rigid motions' eigenvalues are ~k_p|B r|² with |B r|² ~ 1/(number of nodes): k_p = n·max|diag|
        kp = float(np.abs(A.diagonal()).max()) * eq.nnode
        S = (-0.5 * (A + A.T) + kp * (B.T @ B)).tocsc()
        sym = None if low is None else _symmetric_low_rank(-low[0][:n], low[1][:n])
        # a shift below the spectrum: the smallest eigenvalue is at least −‖rank part‖ − |the crossing|
        scale = kp * 1e-3 / eq.nnode
        op = (spla.LinearOperator((n, n), matvec=lambda x: S @ x, dtype=float) if sym is None else
              spla.LinearOperator((n, n), matvec=lambda x: S @ x + sym[0] @ (sym[1].T @ x), dtype=float))
        for sigma in (-scale, -10.0 * scale):
            lu = spla.splu((S - sigma * sp.identity(n, format="csc")).tocsc())
            if sym is None:
                inv = lu.solve
            else:
                Ut, Bv = sym
                Z = np.column_stack([lu.solve(Ut[:, j]) for j in range(Ut.shape[1])])
                Cinv = np.linalg.inv(np.eye(Ut.shape[1]) + Bv.T @ Z)

                def inv(x, lu=lu, Z=Z, Cinv=Cinv, Bv=Bv):
                    y = lu.solve(np.ravel(x))
                    return y - Z @ (Cinv @ (Bv.T @ y))
            vals, vecs = spla.eigsh(op, k=k, sigma=sigma, which="LM", tol=1e-10,
                                    OPinv=spla.LinearOperator((n, n), matvec=inv, dtype=float),
                                    v0=np.ones(n) / math.sqrt(n))
            order = np.argsort(vals)
            vals, vecs = vals[order], vecs[:, order]
            if vals[0] > sigma:  # the shift is below the spectrum: these are the lowest
                break
        return (vals, vecs, det) if with_vectors else (vals, det)

    def point(self, p: float) -> dict[str, Any]:
        """Solve at p (from the last converged point) and record the lowest eigenvalues."""
        state, mu, its = self.solve(p)
        vals, vecs, det = self.lowest(state, mu, p, k=6, with_vectors=True)
        pt = {"p": p, "state": state, "mu": mu, "eig": vals, "vectors": vecs, "det": det, "iterations": its}
        self.points.append(pt)
        if self.log is not None:
            self.log(f"p = {p:.7g}: Newton {its}, lowest eigenvalues {vals}, det sign {det[0]}")
        return pt

    def accept(self, pt: dict[str, Any]) -> None:
        self.state, self.mu, self.p = pt["state"], pt["mu"], pt["p"]


def lattice_critical_pressure(N: int, *, thickness: float = 0.1, p_start: float, growth: float = 1.05,
                              rtol: float = 2e-4, approach: float = 0.7, max_points: int = 40,
                              log: Any = None) -> dict[str, Any]:
    """The first critical pressure of the N × N/2 lattice sphere, approached from the stable side.

    Newton at increasing p from the last stable point; at each stable point the lowest eigenvalues
    μ_i of the stiffness (:meth:`_Path.lowest`) are matched to the previous point's by their
    eigenvectors' overlap and extrapolated linearly to zero, p*_i = p − μ_i/(dμ_i/dp); the
    critical estimate p* = min_i p*_i (the eigenvalues that decrease).  The next load is
    min(p·growth, p + approach·(p* − p)); a load at which Newton fails or a negative eigenvalue
    appears halves the step.  Stops when p* − p ≤ rtol·p*: the extrapolation over that gap errs
    by its square times the eigenvalue's curvature.

    Returns
    -------
    dict
        ``pressure`` (p*), ``points`` (p, lowest μ, det sign of the whole bordered J, Newton
        iterations per point), ``iterations`` (Newton, total), ``path`` (the :class:`_Path`, its
        last stable point) and ``mode`` (the eigenvector ``(unknowns,)`` of the eigenvalue
        extrapolated to zero first, at the last stable point).
    """
    from cartan.statics import ConvergenceError

    prob, pins = sphere_buckling_problem(N, 1.0, thickness=thickness)
    path = _Path(prob, pins, log=log)
    prev = None
    p = float(p_start)
    estimate, mode = math.inf, None
    while len(path.points) < max_points:
        try:
            pt = path.point(p)
        except ConvergenceError:
            pt = None
        if pt is None or pt["eig"][0] <= 0.0:
            if prev is None:
                raise ValueError(f"p_start = {p_start:g} is above the first critical pressure: lower it")
            p = 0.5 * (prev["p"] + p)
            continue
        path.accept(pt)
        if prev is not None:
            match = np.argmax(np.abs(prev["vectors"].T @ pt["vectors"]), axis=0)  # previous index of each
            slope = (pt["eig"] - prev["eig"][match]) / (pt["p"] - prev["p"])
            zeros = np.where(slope < 0.0, pt["p"] - pt["eig"] / np.where(slope < 0.0, slope, -1.0), math.inf)
            i = int(np.argmin(zeros))
            estimate, mode = float(zeros[i]), pt["vectors"][:, i]
            if log is not None:
                log(f"    extrapolated critical pressure {estimate:.7g}")
            if estimate - pt["p"] <= rtol * estimate:
                break
        prev = pt
        p = min(pt["p"] * growth, pt["p"] + approach * (estimate - pt["p"]))
    else:
        raise RuntimeError(f"no critical pressure located in {max_points} points")
    return {"pressure": estimate, "points": [(q["p"], float(q["eig"][0]), q["det"][0], q["iterations"])
                                             for q in path.points],
            "iterations": path.iterations, "path": path, "mode": mode}


def plot_sphere_buckling(results: dict[int, dict[str, Any]], degrees: dict[int, float], p_zoelly: float,
                         filename: str, donnell: dict[int, float] | None = None) -> None:
    """The picture of docs/media/cosserat-surface.md, "Buckling of the sphere": the finest lattice's
    buckling mode on the contracted sphere (3D, coloured by its radial component), p_l against l
    (this medium's continuum, Donnell's, Zoelly's and the lattices' first critical pressures) and
    the lattices' error against the continuum's min_l p_l.

    ``results[N]``: ``pressure``, ``Phi`` ``(nodes, 4, 4)`` (the last stable point), ``mode``
    ``(unknowns,)``, ``cols`` (the unknowns' flat indices among nodes × 6), ``shape`` (N, N/2).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import cm

    p_ref = min(degrees.values())
    fig = plt.figure(figsize=(15, 4.8))
    ax = fig.add_subplot(1, 3, 1, projection="3d")
    N = max(results)
    res = results[N]
    shape = tuple(int(k) for k in res["shape"])
    Phi = np.asarray(res["Phi"])
    full = np.zeros(Phi.shape[0] * 6)
    full[np.asarray(res["cols"])] = res["mode"]
    v = np.einsum("nij,nj->ni", Phi[:, 1:, 1:], full.reshape(-1, 6)[:, :3])   # spatial displacement
    x = Phi[:, 1:, 0]
    n = (x - x.mean(axis=0)) / np.linalg.norm(x - x.mean(axis=0), axis=1)[:, None]
    w = np.sum(v * n, axis=1)
    w = w / np.abs(w).max()
    y = x + 0.12 * w[:, None] * n
    Y = np.concatenate([y.reshape(*shape, 3), y.reshape(*shape, 3)[:1]], axis=0)   # close the seam
    W = np.concatenate([w.reshape(shape), w.reshape(shape)[:1]], axis=0)
    ax.plot_surface(Y[..., 0], Y[..., 1], Y[..., 2], facecolors=cm.coolwarm(0.5 + 0.5 * W), rstride=1, cstride=1,
                    linewidth=0.2, edgecolor="k", shade=False)
    ax.set_box_aspect((1, 1, 1))
    ax.set_axis_off()
    ax.set_title(f"first buckling mode, {N} × {N // 2} lattice\n"
                 f"(radial part, exaggerated; p = {res['pressure']:.5f} E)")
    ax2 = fig.add_subplot(1, 3, 2)
    ls = np.array(sorted(degrees))
    ax2.plot(ls, [degrees[k] for k in ls], "o-", label="this medium, continuum p_l (exact)")
    if donnell:
        ld = np.array(sorted(donnell))
        ax2.plot(ld, [donnell[k] for k in ld], "s--", ms=4, label="Donnell (2/R)(Dλ_l/R² + Eh/λ_l)")
    ax2.axhline(p_zoelly, color="k", lw=1, label="Zoelly 2Eh²/(R²√(3(1−ν²)))")
    for k, (NN, r) in enumerate(sorted(results.items())):
        ax2.axhline(r["pressure"], color=f"C{k + 2}", ls=":", label=f"lattice {NN} × {NN // 2}")
    ax2.set_xlabel("degree l")
    ax2.set_ylabel("critical pressure p / E")
    ax2.set_title("h/R = 0.1, ν = 0.3, κ_s = 5/6")
    ax2.legend(fontsize=7)
    ax3 = fig.add_subplot(1, 3, 3)
    Ns = np.array(sorted(results))
    err = np.array([abs(results[k]["pressure"] / p_ref - 1.0) for k in Ns])
    ax3.loglog(Ns, err, "o-", label="|p_N / p_5 − 1|")
    ax3.loglog(Ns, err[0] * (Ns[0] / Ns) ** 2, "k--", label="order 2")
    ax3.set_xlabel("N (nodes around)")
    ax3.set_title("lattice first critical pressure")
    ax3.legend()
    fig.tight_layout()
    fig.savefig(filename, dpi=110)
    plt.close(fig)
