"""The Kirchhoff filament on SE(3): inextensible, unshearable, with bending, twist and a
natural curvature and twist (paper §III.E, §IV.E, §VII.A).

The structure field is the material frame Φ = (d₁, d₂, d₃; x) along the centreline; its strain
X = Φ⁻¹∂_sΦ = {θ; π} (translation first, as for :class:`cartan_cosserat.rod.CosseratRod`).
The filament is the adapted medium of §III.E: the tangent is d₁ and the centreline is not
stretched, θ = (1, 0, 0), declared by :meth:`Filament.constrained_strains`; the frame carries
the twist (no gauge freedom is fixed in this version: the material frame is the structure
field).  The potential depends on π only,

    U(π) = ½C(π₁ − π₁⁰)² + ½B₂(π₂ − π₂⁰)² + ½B₃(π₃ − π₃⁰)²,

and the force n conjugate to θ is not constitutive: it is the multiplier of the constraint
θ = (1, 0, 0), the fictitious stress of §IV.E, which :func:`cartan.solve_static` and
:func:`cartan.continuation` compute and return as ``constraint_force``.

In time, :func:`cartan.simulate` runs it with the ``rattle`` integrator
(:mod:`cartan.integrators.constrained`, the default for media with constrained strains): the
same rows held to round-off at every step by multipliers, the fictitious stresses in time.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from cartan_cosserat.rod import CosseratRod

from cartan.medium import check_finite, check_positive

__all__ = ["Filament"]


class Filament(CosseratRod):
    """Kirchhoff filament on SE(3) (paper §VII.A): inextensible and unshearable by constraint.

    Parameters
    ----------
    bending : float or array_like, shape ``(2,)``, default 1
        Bending stiffnesses B = B₂ = B₃ > 0, or (B₂, B₃) (about d₂ and d₃).
    twist : float, default 1
        Twist stiffness C > 0 (about d₁).
    rest_curvature : array_like, shape ``(2,)``, default 0
        Natural curvatures (π₂⁰, π₃⁰), finite.
    rest_twist : float, default 0
        Natural twist π₁⁰, finite.
    mass : float, default 1
        Mass per unit length ρA > 0 (the kinetic metric, for a valid medium; the statics do
        not use it).
    rotational_inertia : float or array_like, shape ``(3,)``, default 0.01
        (ρJ, ρI₂, ρI₃) > 0 per unit length (a scalar: the same on the three axes).

    Notes
    -----
    ``X``, ``Q`` have shape ``[..., 1, 6]``, components ``(θ; π)``; the stress of θ is zero
    (the energy does not depend on it) and the rest strain is θ₀ = (1, 0, 0),
    π₀ = (π₁⁰, π₂⁰, π₃⁰).  Initial states as for ``cosserat-rod`` (``straight``, ``ring``,
    ``arc``, ``helix``, ``arrays``).
    """

    name: ClassVar[str] = "filament"

    def __init__(self, *, bending: Any = 1.0, twist: float = 1.0, rest_curvature: Any = (0.0, 0.0),
                 rest_twist: float = 0.0, mass: float = 1.0, rotational_inertia: Any = 0.01):
        b = np.atleast_1d(check_positive("bending", bending))
        if b.shape not in ((1,), (2,)):
            raise ValueError(f"bending must be a positive number or 2 positive numbers (B₂, B₃), got {bending!r}")
        b = np.broadcast_to(b, (2,)).astype(float)
        c = float(check_positive("twist", twist, shape=()))
        kappa = check_finite("rest_curvature", rest_curvature, (2,))
        tau = float(check_finite("rest_twist", rest_twist, ()))
        m = float(check_positive("mass", mass, shape=()))
        inertia = np.atleast_1d(check_positive("rotational_inertia", rotational_inertia))
        if inertia.shape not in ((1,), (3,)):
            raise ValueError("rotational_inertia must be a positive number or 3 positive numbers (ρJ, ρI₂, ρI₃), "
                             f"got {rotational_inertia!r}")
        inertia = np.broadcast_to(inertia, (3,)).astype(float)
        super().__init__(stretch_shear=np.zeros(3), bend_twist=np.array([c, b[0], b[1]]), mass=m,
                         rotational_inertia=inertia, rest_curvature=np.array([tau, kappa[0], kappa[1]]))
        self._filament_params = {"bending": b.tolist() if b[0] != b[1] else float(b[0]), "twist": c,
                                 "rest_curvature": kappa.tolist(), "rest_twist": tau, "mass": m,
                                 "rotational_inertia": inertia.tolist()}

    # ------------------------------------------------------------------ contract
    def parameters(self) -> dict[str, Any]:
        """Constructor keywords (JSON-serialisable); ``Filament(**parameters())`` rebuilds it."""
        return dict(self._filament_params)

    def constrained_strains(self) -> tuple[np.ndarray, np.ndarray]:
        """θ = (1, 0, 0): components (0, 1, 2) of X held at (1, 0, 0) — inextensible and
        unshearable (paper §III.E); their multipliers are the force n (§IV.E)."""
        return np.array([0, 1, 2]), np.array([1.0, 0.0, 0.0])

    def planar_reduction(self) -> None:
        """None: the planar twin would lose the constraints."""
        return None

    def bending_twist(self) -> np.ndarray:
        """𝔹 = diag(C, B₂, B₃), shape ``(3,)``."""
        return self._stiff[3:].copy()

    def rest_curvature_twist(self) -> np.ndarray:
        """π⁰ = (π₁⁰, π₂⁰, π₃⁰), shape ``(3,)``."""
        return self._X0[0, 3:].copy()

    def kirchhoff_invariants(self, X: np.ndarray, n: np.ndarray) -> dict[str, np.ndarray]:
        """The first integrals of the Kirchhoff equilibrium along the edges (paper §VII.A; the
        Kirchhoff kinetic analogy): with m = 𝔹(π − π⁰) and n the constraint force (both in the
        body frame), ``|n|``, ``m·n``, the twist moment ``m₁`` (constant for B₂ = B₃ and no
        natural curvature) and ``H = ½ m·𝔹⁻¹m + n·d₁`` (= ½m·𝔹⁻¹m + n₁).

        Parameters
        ----------
        X : array ``[E, 6]``
            Edge strains.
        n : array ``[E, 3]``
            Edge constraint forces (``constraint_force`` of a static solve).

        Returns
        -------
        dict of arrays ``[E]``: ``"n_norm"``, ``"m_dot_n"``, ``"twist_moment"``, ``"hamiltonian"``.
        """
        B = self.bending_twist()
        m = B * (np.asarray(X)[:, 3:] - self.rest_curvature_twist())
        n = np.asarray(n)
        return {"n_norm": np.linalg.norm(n, axis=-1), "m_dot_n": np.sum(m * n, axis=-1), "twist_moment": m[:, 0],
                "hamiltonian": 0.5 * np.sum(m * m / B, axis=-1) + n[:, 0]}
