"""The free rigid body on SO(3): exact solution and reference integrators.

The free rigid body is the smallest problem with the structure of every Cartan medium: a
configuration on a Lie group, a momentum in the dual of its algebra, and an energy that a
geometric integrator must respect.  It is the one-node reference case of the project
(free rigid body, 𝕀 = diag(1, 2, 3), ω₀ = (1, 0, 0.5), Ω-period 14.940779).

Equations of motion
-------------------
Body frame = principal axes, principal moments ``I = (I₁, I₂, I₃)``, attitude ``R ∈ SO(3)``
(body → space), body angular velocity ``Ω``, body angular momentum ``M = 𝕀Ω``::

    Ṁ = M × Ω          (Euler's equations)
    Ṙ = R hat(Ω)       (reconstruction)

Two Casimir/energy invariants, ``G² = |M|²`` and ``2E = Σ Mᵢ²/Iᵢ``, and the spatial
angular momentum ``m = R M`` are conserved.

Exact solution
--------------
*Angular velocity* (Landau & Lifshitz, *Mechanics*, 3rd ed., §37).  Order the moments
``I₁ < I₂ < I₃`` and let ``p = 2EI₃ − G² ≥ 0``, ``q = G² − 2EI₁ ≥ 0``.  When ``G² > 2EI₂`` the
momentum circulates around axis 3 and, with ``u = λt + u₀``, ::

    Ω₁ = √(p/(I₁(I₃−I₁))) cn u,  Ω₂ = s √(p/(I₂(I₃−I₂))) sn u,  Ω₃ = s √(q/(I₃(I₃−I₁))) dn u,
    λ² = (I₃−I₂) q/(I₁I₂I₃),     k² = (I₂−I₁) p/((I₃−I₂) q),

with ``s = sign Ω₃(0)``.  When ``G² < 2EI₂`` it circulates around axis 1 (the roles of 1 and
3 exchange)::

    Ω₁ = s √(p/(I₁(I₃−I₁))) dn u,  Ω₂ = s √(q/(I₂(I₂−I₁))) sn u,  Ω₃ = √(q/(I₃(I₃−I₁))) cn u,
    λ² = (I₂−I₁) p/(I₁I₂I₃),     k² = (I₃−I₂) q/((I₂−I₁) p),

with ``s = sign Ω₁(0)``.  ``u₀ = F(atan2(sn u₀, cn u₀) | k²)`` is fixed by ``Ω(0)``, and the
period of ``Ω`` is ``T = 4K(k²)/λ``.  ``G² = 2EI₂`` is the separatrix (homoclinic motion,
infinite period) and is rejected.

*Attitude* (Landau & Lifshitz §37; Celledoni, Fassò, Säfström & Zanna, "The exact
computation of the free rigid body motion and its use in splitting methods", SIAM J. Sci.
Comput. 30 (2008) 2084–2112).  Pick the principal axis ``b = e_a`` that the momentum never
approaches (``a = 1`` when circulating around axis 3, ``a = 3`` around axis 1) and let
``A(t) ∈ SO(3)`` be the rotation with rows ``u = b×w/|b×w|``, ``v = w×u``, ``w = M/G``, so
that ``A M = G e₃``.  Then ::

    R(t) = R₀ A(0)ᵀ Rot_{e₃}(ψ(t)) A(t),
    ψ̇ = G (2E − M_a²/I_a)/(G² − M_a²) = G Σ_{i≠a} (Mᵢ²/Iᵢ) / Σ_{i≠a} Mᵢ²,

which follows from ``Rᵀ Ṙ = ψ̇ hat(w) + AᵀȦ`` (for ``a = 3`` it is Landau's precession
rate ``ψ̇ = G(I₁Ω₁² + I₂Ω₂²)/(I₁²Ω₁² + I₂²Ω₂²)``).  The rate is a weighted mean of the
``1/Iᵢ`` — no cancellation — and periodic with period ``T/2``; ``ψ`` is obtained by
composite Gauss–Legendre quadrature over one period, refined until two successive
refinements agree to 1e-13 relative, and extended by periodicity.  ``m = R M`` is
conserved by construction.

Integrators
-----------
:func:`step_rigid_body` implements three methods:

``"lie-verlet"``
    Symplectic splitting of ``H = Σ Mᵢ²/(2Iᵢ)`` into three exactly integrable rotations
    about the body axes, composed palindromically ``φ₁(h/2) φ₂(h/2) φ₃(h) φ₂(h/2) φ₁(h/2)``
    (McLachlan, Phys. Rev. Lett. 71 (1993) 3043; Reich, SIAM J. Numer. Anal. 31 (1994)
    1390; Dullweber, Leimkuhler & McLachlan, J. Chem. Phys. 107 (1997) 5840).  Second
    order, symmetric, ``|M|`` exact, energy error bounded; ``R`` is updated by ``exp``.
``"rkmk4"``
    Runge–Kutta–Munthe-Kaas of order 4: ``R = Rₙ exp(σ)`` with ``σ̇ = dexp⁻¹_{−σ} Ω``
    (the right-trivialised form of ``Ṙ = R hat(Ω)``) and classical RK4 for ``M``.
``"forward-euler"``
    ``R ← R + h R hat(Ω)``, ``M ← M + h M × Ω``: first order, leaves SO(3).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.special import ellipj, ellipk, ellipkinc

__all__ = [
    "METHODS",
    "kinetic_energy",
    "period",
    "rigid_body_exact",
    "step_rigid_body",
]

#: Integrators accepted by :func:`step_rigid_body`.
METHODS = ("lie-verlet", "rkmk4", "forward-euler")

_GL_ORDER = 16
_QUAD_RTOL = 1e-13


# ---------------------------------------------------------------------------- helpers
def _hat(v: np.ndarray) -> np.ndarray:
    """so(3) hat map ``[..., 3] → [..., 3, 3]`` (``hat(v) x = v × x``)."""
    v = np.asarray(v, dtype=float)
    out = np.zeros((*v.shape[:-1], 3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def _principal_frame(inertia: Any) -> tuple[np.ndarray, np.ndarray]:
    """Sorted principal moments and the body → principal change of frame.

    Parameters
    ----------
    inertia : array_like, shape ``(3,)`` or ``(3, 3)``
        Principal moments in body axes, or a symmetric positive definite inertia tensor.

    Returns
    -------
    moments : numpy.ndarray, shape ``(3,)``
        ``I₁ < I₂ < I₃``.
    Q : numpy.ndarray, shape ``(3, 3)``
        Rotation (``det Q = +1``) whose columns are the principal axes in the body frame:
        ``𝕀 = Q diag(moments) Qᵀ``.
    """
    J = np.asarray(inertia, dtype=float)
    if J.shape == (3,):
        order = np.argsort(J, kind="stable")
        moments = J[order]
        Q = np.eye(3)[:, order]
    elif J.shape == (3, 3):
        if not np.allclose(J, J.T, rtol=1e-13, atol=0.0):
            raise ValueError("inertia tensor must be symmetric")
        moments, Q = np.linalg.eigh(J)
    else:
        raise ValueError(f"inertia must have shape (3,) or (3, 3), got {J.shape}")
    if np.any(moments <= 0.0):
        raise ValueError(f"principal moments must be positive, got {moments}")
    if np.min(np.diff(moments)) <= 1e-12 * moments[-1]:
        raise ValueError(
            f"principal moments must be distinct (got {moments}); the symmetric top is not handled"
        )
    if np.linalg.det(Q) < 0.0:
        Q = Q.copy()
        Q[:, 0] = -Q[:, 0]
    return moments, Q


def _body_moments(inertia: Any) -> np.ndarray:
    """Principal moments ``(3,)`` of an inertia given in principal body axes."""
    J = np.asarray(inertia, dtype=float)
    if J.shape == (3, 3):
        if np.any(J - np.diag(np.diag(J))):
            raise ValueError("step_rigid_body needs body axes = principal axes (diagonal inertia)")
        J = np.diag(J).copy()
    if J.shape != (3,):
        raise ValueError(f"inertia must have shape (3,) or diagonal (3, 3), got {J.shape}")
    if np.any(J <= 0.0):
        raise ValueError(f"principal moments must be positive, got {J}")
    return J


def kinetic_energy(inertia: Any, M: Any) -> np.ndarray:
    """Kinetic energy ``E = ½ Σ Mᵢ²/Iᵢ``.

    Parameters
    ----------
    inertia : array_like, shape ``(3,)``
        Principal moments (body axes = principal axes).
    M : array_like, shape ``[..., 3]``
        Body angular momentum.

    Returns
    -------
    numpy.ndarray, shape ``[...]``
    """
    moments = _body_moments(inertia)
    M = np.asarray(M, dtype=float)
    return 0.5 * np.sum(M * M / moments, axis=-1)


class _EllipticMotion:
    """Jacobi elliptic solution of Euler's equations in the sorted principal frame."""

    def __init__(self, moments: np.ndarray, M0: np.ndarray):
        I1, I2, I3 = moments
        self.moments = moments
        self.M0 = M0
        M2 = M0 * M0
        self.G2 = float(np.sum(M2))
        self.G = np.sqrt(self.G2)
        self.twoE = float(np.sum(M2 / moments))
        if self.G2 == 0.0:
            self.static = True
            return
        self.static = False
        # p = 2EI₃ − G², q = G² − 2EI₁ and G² − 2EI₂, as sums without cancellation.
        p = M2[0] * (I3 - I1) / I1 + M2[1] * (I3 - I2) / I2
        q = M2[1] * (I2 - I1) / I2 + M2[2] * (I3 - I1) / I3
        delta = M2[0] * (I1 - I2) / I1 + M2[2] * (I3 - I2) / I3
        if abs(delta) <= 1e-12 * self.G2:
            raise ValueError(
                "initial condition on the separatrix |M|² = 2E·I₂ (homoclinic motion, infinite period)"
            )
        W0 = M0 / moments
        if delta > 0.0:  # circulates around axis 3
            self.axis = 3
            self.amp = np.sqrt([p / (I1 * (I3 - I1)), p / (I2 * (I3 - I2)), q / (I3 * (I3 - I1))])
            self.lam = np.sqrt((I3 - I2) * q / (I1 * I2 * I3))
            self.m = (I2 - I1) * p / ((I3 - I2) * q)
            self.sign = np.array([1.0, 1.0, 1.0]) if W0[2] > 0 else np.array([1.0, -1.0, -1.0])
            cn_idx = 0
            self.ref = 0  # reference axis of the attitude construction (never approached)
            degenerate = p == 0.0
        else:  # circulates around axis 1
            self.axis = 1
            self.amp = np.sqrt([p / (I1 * (I3 - I1)), q / (I2 * (I2 - I1)), q / (I3 * (I3 - I1))])
            self.lam = np.sqrt((I2 - I1) * p / (I1 * I2 * I3))
            self.m = (I3 - I2) * q / ((I2 - I1) * p)
            self.sign = np.array([1.0, 1.0, 1.0]) if W0[0] > 0 else np.array([-1.0, -1.0, 1.0])
            cn_idx = 2
            self.ref = 2
            degenerate = q == 0.0
        self.K = float(ellipk(self.m))
        # Steady rotation about a principal axis: Ω is constant and any phase will do.
        if degenerate:
            self.u0 = 0.0
        else:  # amplitude φ₀ = atan2(sn u₀, cn u₀), u₀ = F(φ₀ | k²)
            sn0 = self.sign[1] * W0[1] / self.amp[1]
            cn0 = W0[cn_idx] / self.amp[cn_idx]
            self.u0 = float(ellipkinc(np.arctan2(sn0, cn0), self.m))
        self.period = 4.0 * self.K / self.lam

    def omega(self, t: np.ndarray) -> np.ndarray:
        """Body angular velocity ``[..., 3]`` at times ``t`` ``[...]``."""
        t = np.asarray(t, dtype=float)
        if self.static:
            return np.zeros((*t.shape, 3))
        four_k = 4.0 * self.K
        u = self.lam * t + self.u0
        u = u - four_k * np.round(u / four_k)  # sn, cn, dn have period 4K
        sn, cn, dn, _ = ellipj(u, self.m)
        if self.axis == 3:
            cols = (cn, sn, dn)
        else:
            cols = (dn, sn, cn)
        return np.stack(cols, axis=-1) * (self.amp * self.sign)

    def psi_rate(self, t: np.ndarray) -> np.ndarray:
        """Precession rate ``ψ̇ = G Σ_{i≠a} Mᵢ²/Iᵢ / Σ_{i≠a} Mᵢ²`` at times ``t`` ``[...]``."""
        M = self.omega(t) * self.moments
        keep = [i for i in range(3) if i != self.ref]
        M2 = M[..., keep] ** 2
        return self.G * np.sum(M2 / self.moments[keep], axis=-1) / np.sum(M2, axis=-1)

    def _cumulative(self, npanel: int) -> np.ndarray:
        """``∫₀^{jP/npanel} ψ̇`` for ``j = 0..npanel`` (P = T/2) by Gauss–Legendre panels."""
        x, w = np.polynomial.legendre.leggauss(_GL_ORDER)
        h = 0.5 * self.period / npanel
        nodes = h * (np.arange(npanel)[:, None] + 0.5 * (x + 1.0))
        panel = 0.5 * h * (self.psi_rate(nodes) @ w)
        return np.concatenate([[0.0], np.cumsum(panel)])

    def psi(self, t: np.ndarray) -> np.ndarray:
        """Precession angle ``ψ(t) = ∫₀ᵗ ψ̇`` ``[...]`` (ψ(0) = 0)."""
        t = np.asarray(t, dtype=float)
        if self.static:
            return np.zeros(t.shape)
        # Refine the panels until two successive levels agree to _QUAD_RTOL.
        npanel, cum = 8, self._cumulative(8)
        while True:
            finer = self._cumulative(2 * npanel)
            err = np.max(np.abs(finer[::2] - cum))
            npanel, cum = 2 * npanel, finer
            if err <= _QUAD_RTOL * max(1.0, abs(cum[-1])):
                break
            if npanel > 2**14:
                raise RuntimeError(f"precession-angle quadrature did not converge (difference {err:.2e})")
        P = 0.5 * self.period  # ψ̇ depends on M_a² only: period T/2
        h = P / npanel
        n = np.floor(t / P)
        r = t - n * P
        j = np.clip(np.floor(r / h).astype(np.int64), 0, npanel - 1)
        a = j * h
        x, w = np.polynomial.legendre.leggauss(_GL_ORDER)
        half = 0.5 * (r - a)
        nodes = a[..., None] + half[..., None] * (x + 1.0)
        tail = half * (self.psi_rate(nodes) @ w)
        return n * cum[-1] + cum[j] + tail

    def frame(self, t: np.ndarray) -> np.ndarray:
        """The rotation ``A(t)`` ``[..., 3, 3]`` with ``A M(t) = G e₃``."""
        w = self.omega(t) * self.moments / self.G
        b = np.zeros(3)
        b[self.ref] = 1.0
        u = np.cross(b, w)
        u /= np.linalg.norm(u, axis=-1, keepdims=True)
        v = np.cross(w, u)
        return np.stack([u, v, w], axis=-2)


def _rot_z(psi: np.ndarray) -> np.ndarray:
    c, s = np.cos(psi), np.sin(psi)
    out = np.zeros((*np.shape(psi), 3, 3))
    out[..., 0, 0], out[..., 0, 1] = c, -s
    out[..., 1, 0], out[..., 1, 1] = s, c
    out[..., 2, 2] = 1.0
    return out


# ---------------------------------------------------------------------------- exact solution
def period(inertia: Any, omega0: Any) -> float:
    """Period ``T = 4K(k²)/λ`` of the body angular velocity Ω(t).

    Parameters
    ----------
    inertia : array_like, shape ``(3,)`` or ``(3, 3)``
        Principal moments (body axes = principal axes) or a symmetric inertia tensor;
        the principal moments must be distinct.
    omega0 : array_like, shape ``(3,)``
        Initial body angular velocity.

    Returns
    -------
    float
        The period of Ω; ``inf`` at rest.  For a steady rotation about the largest or
        smallest axis it is the limit of nearby motions (the linearised period).

    Raises
    ------
    ValueError
        On the separatrix ``|M|² = 2E·I₂`` or for repeated principal moments.
    """
    moments, Q = _principal_frame(inertia)
    M0 = moments * (Q.T @ np.asarray(omega0, dtype=float))
    motion = _EllipticMotion(moments, M0)
    return np.inf if motion.static else float(motion.period)


def rigid_body_exact(
    inertia: Any, omega0: Any, t: Any, R0: Any = None
) -> tuple[np.ndarray, np.ndarray]:
    """Exact motion of the free rigid body (Jacobi elliptic functions + precession angle).

    Parameters
    ----------
    inertia : array_like, shape ``(3,)`` or ``(3, 3)``
        Principal moments in body axes, or a symmetric inertia tensor 𝕀 in the body frame;
        the principal moments must be distinct.
    omega0 : array_like, shape ``(3,)``
        Initial body angular velocity Ω(0) (``M(0) = 𝕀 Ω(0)``).
    t : array_like, shape ``(nt,)``
        Times (any order, negative allowed).
    R0 : array_like, shape ``(3, 3)``, optional
        Initial attitude (body → space); the identity by default.

    Returns
    -------
    omega : numpy.ndarray, shape ``(nt, 3)``
        Body angular velocity Ω(t).
    R : numpy.ndarray, shape ``(nt, 3, 3)``
        Attitude R(t), ``Ṙ = R hat(Ω)``.

    Raises
    ------
    ValueError
        On the separatrix ``|M|² = 2E·I₂`` or for repeated principal moments.

    Notes
    -----
    See the module docstring for the formulas and their sources.  Ω is accurate to a few
    ulps times ``1 + λ|t|``; the precession angle to ~1e-13 relative per period.
    """
    t = np.atleast_1d(np.asarray(t, dtype=float))
    if t.ndim != 1:
        raise ValueError(f"t must be one-dimensional, got shape {t.shape}")
    R0 = np.eye(3) if R0 is None else np.asarray(R0, dtype=float)
    if R0.shape != (3, 3):
        raise ValueError(f"R0 must have shape (3, 3), got {R0.shape}")
    moments, Q = _principal_frame(inertia)
    M0 = moments * (Q.T @ np.asarray(omega0, dtype=float))
    motion = _EllipticMotion(moments, M0)
    if motion.static:
        return np.zeros((t.size, 3)), np.broadcast_to(R0, (t.size, 3, 3)).copy()
    omega_p = motion.omega(t)
    A = motion.frame(t)
    A0 = motion.frame(np.zeros(1))[0]
    R_p = (R0 @ Q @ A0.T) @ _rot_z(motion.psi(t)) @ A  # attitude of the principal frame
    return omega_p @ Q.T, R_p @ Q.T


# ---------------------------------------------------------------------------- integrators
def _axis_rotation(M: np.ndarray, i: int, angle: float) -> np.ndarray:
    """``exp(angle·hat(eᵢ)) M`` for a vector ``M`` ``(3,)`` (rotation about body axis i)."""
    j, k = (i + 1) % 3, (i + 2) % 3
    c, s = np.cos(angle), np.sin(angle)
    out = M.copy()
    out[j] = c * M[j] - s * M[k]
    out[k] = s * M[j] + c * M[k]
    return out


def step_rigid_body(
    group: Any,
    R: Any,
    M: Any,
    inertia: Any,
    dt: float,
    nsteps: int,
    method: str = "lie-verlet",
    save_every: int = 1,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Integrate the free rigid body ``Ṁ = M × Ω``, ``Ṙ = R hat(Ω)``, ``Ω = M/I``.

    Parameters
    ----------
    group : SymmetryGroup
        An SO(3) implementation (``dim == matrix_size == 3``, standard so(3) basis); its
        ``exp`` (and ``dexp_inv`` for ``"rkmk4"``) update the attitude.
    R : array_like, shape ``(3, 3)``
        Initial attitude.
    M : array_like, shape ``(3,)``
        Initial body angular momentum.
    inertia : array_like, shape ``(3,)`` or diagonal ``(3, 3)``
        Principal moments; the body axes are the principal axes.
    dt : float
        Time step.
    nsteps : int
        Number of steps.
    method : {"lie-verlet", "rkmk4", "forward-euler"}
        Integrator (see the module docstring).
    save_every : int
        Save cadence: the state is returned after steps ``0, s, 2s, …, ⌊nsteps/s⌋·s``.

    Returns
    -------
    t : numpy.ndarray, shape ``(ns,)``
        Save times, ``ns = nsteps // save_every + 1``.
    R : numpy.ndarray, shape ``(ns, 3, 3)``
        Attitudes.
    M : numpy.ndarray, shape ``(ns, 3)``
        Body angular momenta.
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if getattr(group, "dim", None) != 3 or getattr(group, "matrix_size", None) != 3:
        raise ValueError(f"group must be SO(3) (dim 3, 3×3 matrices), got {group!r}")
    nsteps, save_every = int(nsteps), int(save_every)
    if nsteps < 0 or save_every < 1:
        raise ValueError("nsteps must be ≥ 0 and save_every ≥ 1")
    moments = _body_moments(inertia)
    R = np.array(R, dtype=float)
    M = np.array(M, dtype=float)
    if R.shape != (3, 3) or M.shape != (3,):
        raise ValueError(f"R must be (3, 3) and M (3,), got {R.shape} and {M.shape}")
    h = float(dt)

    def lie_verlet(R: np.ndarray, M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        for i, frac in ((0, 0.5), (1, 0.5), (2, 1.0), (1, 0.5), (0, 0.5)):
            # Flow of Mᵢ²/(2Iᵢ): Ω = (Mᵢ/Iᵢ)eᵢ, M ← exp(−θ hat eᵢ) M, R ← R exp(θ hat eᵢ).
            theta = frac * h * M[i] / moments[i]
            xi = np.zeros(3)
            xi[i] = theta
            R = R @ group.exp(xi)
            M = _axis_rotation(M, i, -theta)
        return R, M

    def rkmk4(R: np.ndarray, M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        def f(sigma: np.ndarray, Mk: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            W = Mk / moments
            return group.dexp_inv(-sigma) @ W, np.cross(Mk, W)

        s1, m1 = f(np.zeros(3), M)
        s2, m2 = f(0.5 * h * s1, M + 0.5 * h * m1)
        s3, m3 = f(0.5 * h * s2, M + 0.5 * h * m2)
        s4, m4 = f(h * s3, M + h * m3)
        sigma = h / 6.0 * (s1 + 2.0 * s2 + 2.0 * s3 + s4)
        return R @ group.exp(sigma), M + h / 6.0 * (m1 + 2.0 * m2 + 2.0 * m3 + m4)

    def forward_euler(R: np.ndarray, M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        W = M / moments
        return R + h * R @ group.hat(W), M + h * np.cross(M, W)

    advance = {"lie-verlet": lie_verlet, "rkmk4": rkmk4, "forward-euler": forward_euler}[method]
    nsave = nsteps // save_every + 1
    t_out = h * save_every * np.arange(nsave)
    R_out = np.empty((nsave, 3, 3))
    M_out = np.empty((nsave, 3))
    R_out[0], M_out[0] = R, M
    for n in range(1, nsave * save_every - save_every + 1):
        R, M = advance(R, M)
        if n % save_every == 0:
            R_out[n // save_every], M_out[n // save_every] = R, M
    return t_out, R_out, M_out
