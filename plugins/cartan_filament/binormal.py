"""The binormal (local induction) flow of a filament as a prescribed velocity N(t, u, X) for
the ``kinematic`` integrator (paper §III.B, §III.E, §VII.A).

The local induction approximation of a thin vortex filament moves each point of the
centreline along its binormal with speed proportional to the curvature, ∂_t r = c κ b
(Hasimoto 1972; c = Γ/(4π)·log(ℓ/a), the "circulation coefficient", 1 by default).  In an
adapted frame (e₁ the unit tangent, strain θ = (h, 0, 0), ∂_u e₁ = π₃e₂ − π₂e₃, §VII.A) the
curvature vector is κn = ∂_se₁ = (π₃e₂ − π₂e₃)/h and κb = e₁ × κn = (π₂e₂ + π₃e₃)/h: in the
body frame,

    V = c (0, π₂, π₃)/h .

The frame stays adapted when ∂_tθ₂ = ∂_tθ₃ = 0 in the kinematic equation of §III.B,
∂_tθ = ∂_uV + π × V − Ω × θ (for SE(3), [X, N] = (π × V − Ω × θ, π × Ω)), which fixes

    Ω₂ = −(∂_uV₃ + π₁V₂ − π₂V₁)/h,      Ω₃ = (∂_uV₂ + π₃V₁ − π₁V₃)/h

(for the Frenet frame, π₂ = 0, these are the formulas of §VII.A).  Ω₁ is the gauge.  From
∂_tπ₁ = ∂_uΩ₁ + π₂Ω₃ − π₃Ω₂ = ∂_u(Ω₁ + ½c κ²) (h uniform, V₁ = 0) the choice

    Ω₁ = −½ c κ²,   κ² = (π₂² + π₃²)/h²      (``gauge="bishop"``, the default)

keeps π₁ constant in time at every point: a Bishop frame (π₁ = 0) stays a Bishop frame, and its
two curvatures (π₂, π₃)/h form Hasimoto's complex curvature, which obeys the cubic nonlinear
Schrödinger equation.
``gauge="none"`` sets Ω₁ = 0 (the frame is not turned about the tangent; π₁ drifts by
∂_u(½cκ²)).  The length is kept in the continuum: ∂_tθ₁ = ∂_uV₁ + π₂V₃ − π₃V₂ = 0.

Discretely, the velocity is evaluated from the nodal strains X the scheme supplies (on the
lattice: the mean of the two neighbouring edge strains) and ∂_uV by centred differences of
spacing h (periodic on a closed filament; second-order one-sided at the ends of an open one).
The flow is dispersive (linearised about a straight line it is i∂_tψ = c∂²_sψ), and the
explicit RKMK step is stable only for Δt ≤ C·dx²/c; :func:`binormal_dt_limit` gives the
measured C (see ``docs/media/filament.md``).

Both forms evaluate the same formulas: :func:`binormal_velocity` returns a numpy function (the
``kinematic`` integrator's Python path) or, with ``compiled=True``, a ``numba.njit`` closure
that the core's generated RKMK loop accepts.
"""

from __future__ import annotations

from collections.abc import Callable

import numba
import numpy as np

__all__ = ["GAUGES", "STABILITY_CONSTANT", "binormal_dt_limit", "binormal_velocity", "binormal_velocity_numpy"]

#: gauge name → code: Ω₁ = −½cκ² (Bishop kept), Ω₁ = 0
GAUGES = {"bishop": 0, "none": 1}

#: Δt·c/dx² below which the order-4 RKMK run of the binormal flow is stable on the lattice.
#: Measured on a perturbed vortex ring (1500 steps, bisection): the runs blow up at
#: 2.87, 2.83, 2.82, 2.80 (n = 32, 64, 128, 256), tending to about 2.8 — the linear bound of RK4 on the
#: imaginary axis, 2√2, times dx²/max|symbol| = dx² (the lattice's two centred differences give
#: the symbol sin²(k dx)/dx²), lowered slightly by the ring's curvature.  2.7 keeps a margin.
STABILITY_CONSTANT = {4: 2.7}


def _check(dx: float | None, periodic: bool, gauge: str, coefficient: float) -> tuple[float, bool, int, float]:
    """Validated (h, periodic, gauge code, c); h = 0 stands for "the spacing of u"."""
    if dx is None:
        h = 0.0
    else:
        h = float(dx)
        if not (np.isfinite(h) and h > 0):
            raise ValueError(f"dx must be a finite number > 0 (or None: the spacing of the node coordinates), "
                             f"got {dx!r}")
    if gauge not in GAUGES:
        raise ValueError(f"gauge must be one of {sorted(GAUGES)}, got {gauge!r}")
    c = float(coefficient)
    if not (np.isfinite(c) and c != 0):
        raise ValueError(f"coefficient must be a finite non-zero number, got {coefficient!r}")
    return h, bool(periodic), GAUGES[gauge], c


def _velocity_loop(u, X, dx, periodic, gauge, c):
    """N ``[n, 6]`` from the nodal strains X ``[n, 1, 6]`` (loops; compiled by numba or run as is);
    ``dx = 0``: the spacing of the node coordinates u ``[n, 1]``."""
    n = X.shape[0]
    if dx == 0.0:
        dx = u[1, 0] - u[0, 0]
    V = np.zeros((n, 3))
    for i in range(n):
        h = X[i, 0, 0]
        V[i, 1] = c * X[i, 0, 4] / h
        V[i, 2] = c * X[i, 0, 5] / h
    N = np.zeros((n, 6))
    for i in range(n):
        if periodic:
            ip = i + 1 if i + 1 < n else 0
            im = i - 1 if i > 0 else n - 1
            dV2 = (V[ip, 1] - V[im, 1]) / (2.0 * dx)
            dV3 = (V[ip, 2] - V[im, 2]) / (2.0 * dx)
        elif i == 0:
            dV2 = (-3.0 * V[0, 1] + 4.0 * V[1, 1] - V[2, 1]) / (2.0 * dx)
            dV3 = (-3.0 * V[0, 2] + 4.0 * V[1, 2] - V[2, 2]) / (2.0 * dx)
        elif i == n - 1:
            dV2 = (3.0 * V[i, 1] - 4.0 * V[i - 1, 1] + V[i - 2, 1]) / (2.0 * dx)
            dV3 = (3.0 * V[i, 2] - 4.0 * V[i - 1, 2] + V[i - 2, 2]) / (2.0 * dx)
        else:
            dV2 = (V[i + 1, 1] - V[i - 1, 1]) / (2.0 * dx)
            dV3 = (V[i + 1, 2] - V[i - 1, 2]) / (2.0 * dx)
        h = X[i, 0, 0]
        p1, p2, p3 = X[i, 0, 3], X[i, 0, 4], X[i, 0, 5]
        N[i, 1] = V[i, 1]
        N[i, 2] = V[i, 2]
        N[i, 4] = -(dV3 + p1 * V[i, 1] - p2 * V[i, 0]) / h
        N[i, 5] = (dV2 + p3 * V[i, 0] - p1 * V[i, 2]) / h
        if gauge == 0:
            N[i, 3] = -0.5 * c * (p2 * p2 + p3 * p3) / (h * h)
    return N


_velocity_kernel = numba.njit(cache=True)(_velocity_loop)


def binormal_velocity_numpy(X: np.ndarray, dx: float, periodic: bool = True, gauge: str = "bishop",
                            coefficient: float = 1.0) -> np.ndarray:
    """The binormal-flow velocity N = {V; Ω} from nodal strains (vectorised numpy).

    Parameters
    ----------
    X : ndarray ``[n, 1, 6]`` or ``[n, 6]``
        Nodal strains (θ; π) of an adapted frame (e₁ tangent).
    dx : float
        Grid spacing h_u > 0.
    periodic : bool
        Closed filament (periodic differences).
    gauge : {"bishop", "none"}
        Ω₁ = −½cκ² or 0.
    coefficient : float
        c in V = cκb.

    Returns
    -------
    ndarray ``[n, 6]``
        (V₁, V₂, V₃, Ω₁, Ω₂, Ω₃) in the body frame.
    """
    h, periodic, code, c = _check(dx, periodic, gauge, coefficient)
    x = np.asarray(X, dtype=float).reshape(-1, 6)
    th1, p1, p2, p3 = x[:, 0], x[:, 3], x[:, 4], x[:, 5]
    V2, V3 = c * p2 / th1, c * p3 / th1
    if periodic:
        dV2 = (np.roll(V2, -1) - np.roll(V2, 1)) / (2 * h)
        dV3 = (np.roll(V3, -1) - np.roll(V3, 1)) / (2 * h)
    else:
        dV2, dV3 = np.gradient(V2, h, edge_order=2), np.gradient(V3, h, edge_order=2)
    N = np.zeros((x.shape[0], 6))
    N[:, 1], N[:, 2] = V2, V3
    N[:, 4] = -(dV3 + p1 * V2) / th1
    N[:, 5] = (dV2 - p1 * V3) / th1
    if code == 0:
        N[:, 3] = -0.5 * c * (p2**2 + p3**2) / th1**2
    return N


def binormal_velocity(dx: float | None = None, periodic: bool = True, gauge: str = "bishop", coefficient: float = 1.0,
                      compiled: bool = False) -> Callable:
    """The velocity function ``f(t, u, X) -> N`` of the binormal flow for
    :class:`cartan.integrators.Kinematic` (``velocity=``).

    Parameters
    ----------
    dx : float or None, default None
        The grid spacing (``grid.spacing[0]``), > 0; None: read from the node coordinates u
        at every call (then one compiled module serves every grid: numba freezes a captured
        spacing into the machine code, and each value would compile its own module).
    periodic : bool, default True
        A closed filament on a periodic grid.
    gauge : {"bishop", "none"}, default "bishop"
        Ω₁ = −½cκ² (π₁ kept: a Bishop frame stays Bishop) or Ω₁ = 0.
    coefficient : float, default 1
        c in ∂_t r = cκb (non-zero).
    compiled : bool, default False
        Return a ``numba.njit`` closure: the ``kinematic`` integrator then runs in the core's
        generated RKMK loop (its first use compiles a module, tens of seconds).

    Returns
    -------
    callable ``(t, u, X) -> N``
        t float, u ``[n, 1]``, X ``[n, 1, 6]``; N ``[n, 6]``.
    """
    h, per, code, c = _check(dx, periodic, gauge, coefficient)
    if compiled:
        import numba

        @numba.njit
        def binormal_flow(t, u, X):
            return _velocity_kernel(u, X, h, per, code, c)

        return binormal_flow

    def binormal_flow(t: float, u: np.ndarray, X: np.ndarray) -> np.ndarray:
        spacing = h if h > 0 else float(u[1, 0] - u[0, 0])
        return binormal_velocity_numpy(X, spacing, per, gauge, c)

    return binormal_flow


def binormal_dt_limit(dx: float, order: int = 4, coefficient: float = 1.0) -> float:
    """The measured stability limit Δt ≤ C·dx²/|c| of the binormal flow run by the order-4
    ``kinematic`` integrator on the lattice (C = :data:`STABILITY_CONSTANT`).

    Parameters
    ----------
    dx : float
        Grid spacing (arclength), > 0.
    order : int, default 4
        The RKMK order; only 4 has a limit: orders 1 and 2 are unstable at every Δt on the
        dispersive (imaginary) spectrum, their growth per step ≈ (λΔt)²/2 and (λΔt)⁴/8.
    coefficient : float, default 1
        c in ∂_t r = cκb.

    Returns
    -------
    float
    """
    if dx is None:
        raise ValueError("dx must be a finite number > 0, got None")
    h, _, _, c = _check(dx, True, "bishop", coefficient)
    if order not in STABILITY_CONSTANT:
        raise ValueError(f"order must be one of {sorted(STABILITY_CONSTANT)} (orders 1 and 2 are unstable at every "
                         f"Δt on the binormal flow), got {order!r}")
    return STABILITY_CONSTANT[order] * h * h / abs(c)
