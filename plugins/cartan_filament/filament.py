"""The Kirchhoff filament on SE(3): inextensible, unshearable, with bending, twist and a
natural curvature and twist (paper §III.E, §IV.E, §VII.A).

The structure field is the material frame Φ = (d₁, d₂, d₃; x) along the centreline; its strain
X = Φ⁻¹∂_sΦ = {θ; π} (translation first, as for :class:`cartan_cosserat.rod.CosseratRod`).
The filament is the adapted medium of §III.E: the tangent is d₁ and the centreline is not
stretched, θ = (1, 0, 0), declared by :meth:`Filament.constrained_strains`; the frame carries
the twist: the material frame is the structure field.  What is left of the adaptation is the
SO(2) gauge, the rotation of (d₂, d₃) about d₁ (§III.E); the parameter ``gauge`` names a
reference frame for it — ``"bishop"`` (parallel transport) or ``"frenet"`` (Frenet–Serret) —
to which the initial frames of the named centrelines are adapted and relative to which the
output ``twist_angle`` measures the material frame (:mod:`cartan_filament.gauges`);
``"material"`` (the default) takes the frames as the initial kinds build them and records no
angle.  The potential depends on π only,

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
from cartan.problem import InitialState

from .gauges import GAUGES, adapt_frames, twist_angle

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
    gauge : {"material", "bishop", "frenet"}, default "material"
        The reference frame of the SO(2) gauge (paper §III.E).  ``"bishop"``/``"frenet"``: the
        initial frames are turned about their tangents into the Bishop (parallel transport
        from node 0, closure angle spread on a closed filament) or the Frenet–Serret frame of
        the initial centreline (:func:`~cartan_filament.gauges.adapt_frames`), and every saved
        frame records ``twist_angle``, the angle φ of the material frame relative to that
        frame of the current centreline, E = E_gauge·Rot_{d₁}(φ)
        (:func:`~cartan_filament.gauges.twist_angle`).  ``"frenet"`` raises a ``ValueError``
        naming the node where κ = 0.  The energy does not depend on the gauge.

    Notes
    -----
    ``X``, ``Q`` have shape ``[..., 1, 6]``, components ``(θ; π)``; the stress of θ is zero
    (the energy does not depend on it) and the rest strain is θ₀ = (1, 0, 0),
    π₀ = (π₁⁰, π₂⁰, π₃⁰).  Initial states as for ``cosserat-rod`` (``straight``, ``ring``,
    ``arc``, ``helix``, ``arrays``).
    """

    name: ClassVar[str] = "filament"

    def __init__(self, *, bending: Any = 1.0, twist: float = 1.0, rest_curvature: Any = (0.0, 0.0),
                 rest_twist: float = 0.0, mass: float = 1.0, rotational_inertia: Any = 0.01,
                 gauge: str = "material"):
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
        if not isinstance(gauge, str) or gauge not in GAUGES:
            raise ValueError(f"gauge must be one of {', '.join(map(repr, GAUGES))}, got {gauge!r}")
        self.gauge = gauge
        if gauge != "material":
            self.output_fields = {"twist_angle": (f"angle of the material frame about d1 relative to the {gauge} frame",
                                                  "rad")}
        super().__init__(stretch_shear=np.zeros(3), bend_twist=np.array([c, b[0], b[1]]), mass=m,
                         rotational_inertia=inertia, rest_curvature=np.array([tau, kappa[0], kappa[1]]))
        self._filament_params = {"bending": b.tolist() if b[0] != b[1] else float(b[0]), "twist": c,
                                 "rest_curvature": kappa.tolist(), "rest_twist": tau, "mass": m,
                                 "rotational_inertia": inertia.tolist()}
        if gauge != "material":
            self._filament_params["gauge"] = gauge

    # ------------------------------------------------------------------ contract
    def parameters(self) -> dict[str, Any]:
        """Constructor keywords (JSON-serialisable); ``Filament(**parameters())`` rebuilds it."""
        return dict(self._filament_params)

    def constrained_strains(self) -> tuple[np.ndarray, np.ndarray]:
        """θ = (1, 0, 0): components (0, 1, 2) of X held at (1, 0, 0) — inextensible and
        unshearable (paper §III.E); their multipliers are the force n (§IV.E)."""
        return np.array([0, 1, 2]), np.array([1.0, 0.0, 0.0])

    def initial_state(self, grid, kind: str, **params: Any) -> InitialState:
        """The initial kinds of ``cosserat-rod`` (``straight``, ``ring``, ``arc``, ``helix``,
        ``arrays``), their frames turned about the tangents into the ``gauge``
        (:func:`~cartan_filament.gauges.adapt_frames`; unchanged for ``"material"``); the
        velocity options are applied to the adapted frames.

        Raises
        ------
        ValueError
            As ``cosserat-rod``; ``gauge = "frenet"`` on a centreline with κ = 0 at a node (a
            straight piece), naming the node; a closed centreline built with a holonomy (a
            ``straight``, ``arc`` or ``helix`` on a periodic grid) in a gauge other than
            ``"material"``.
        """
        if self.gauge == "material":
            return super().initial_state(grid, kind, **params)
        motion = {k: params.pop(k) for k in ("velocity", "rigid_velocity", "center") if k in params}
        init = super().initial_state(grid, kind, **params)
        if init.holonomy is not None:
            raise ValueError(f"gauge {self.gauge!r}: initial kind {kind!r} on a periodic grid closes with a "
                             "holonomy; give a closed centreline ('ring' or 'arrays') or gauge = 'material'")
        Phi = np.array(init.Phi, dtype=float)
        Phi[:, 1:, 1:] = adapt_frames(Phi[:, 1:, 0], Phi[:, 1:, 1:], self.gauge, grid.spacing[0],
                                      closed=bool(grid.periodic[0]))
        N = self._velocities(grid, Phi, motion.get("velocity"), motion.get("rigid_velocity"), motion.get("center"))
        return InitialState(Phi=Phi, N=N)

    def outputs(self, q: np.ndarray, X: np.ndarray, N: np.ndarray, grid: Any) -> dict[str, np.ndarray]:
        """``twist_angle`` ``[n]`` (gauges ``"bishop"``, ``"frenet"``): the angle of the material
        frame relative to the gauge frame of the current centreline
        (:func:`~cartan_filament.gauges.twist_angle`, from the frames q and the nodal strains X)."""
        if self.gauge == "material":
            return {}
        q = np.asarray(q)
        return {"twist_angle": twist_angle(q[:, 1:, 1:], np.asarray(X)[:, 0, :], self.gauge, grid.spacing[0],
                                           length=grid.length[0])}

    @classmethod
    def draw(cls, ds: Any, fig: Any) -> bool:
        """A run or equilibrium recorded with a gauge (``twist_angle`` in the file): the last
        centreline in 3D coloured by the twist angle, with the director d₂ drawn at the nodes
        (the first centreline in grey); the twist angle along the filament at a few saved
        times; the energies of a run.  False (the generic picture) without ``twist_angle``."""
        from matplotlib import cm, colormaps, colors
        from mpl_toolkits.mplot3d.art3d import Line3DCollection

        from cartan.plotting import _draw_energies, _snapshot_indices

        if "twist_angle" not in ds or "position" not in ds or "frame" not in ds or "time" not in ds.dims:
            return False
        pos = np.asarray(ds["position"].values, dtype=float)
        frames = np.asarray(ds["frame"].values, dtype=float)
        phi = np.asarray(ds["twist_angle"].values, dtype=float)
        if pos.ndim != 3 or pos.shape[-1] != 3:
            return False
        t = np.asarray(ds["time"].values, dtype=float)
        dynamic = t.size > 1 and "kinetic_energy" in ds
        ncols = 3 if dynamic else 2
        fig.set_size_inches(5.6 * ncols, 4.8)
        ax = fig.add_subplot(1, ncols, 1, projection="3d")
        ax.plot(*pos[0].T, color="0.7", lw=1, label=f"t = {t[0]:.3g}")
        last = pos[-1]
        norm = colors.Normalize(float(phi[-1].min()), float(max(phi[-1].max(), phi[-1].min() + 1e-12)))
        cmap = colormaps["viridis"]
        segs = np.stack([last[:-1], last[1:]], axis=1)
        mid = 0.5 * (phi[-1][:-1] + phi[-1][1:])
        ax.add_collection3d(Line3DCollection(segs, colors=cmap(norm(mid)), linewidths=3))
        span = float(np.ptp(pos.reshape(-1, 3), axis=0).max()) or 1.0
        d2 = frames[-1][:, :, 1]
        sticks = np.stack([last, last + 0.06 * span * d2], axis=1)
        ax.add_collection3d(Line3DCollection(sticks, colors="tab:red", linewidths=1))
        lo, hi = pos.reshape(-1, 3).min(axis=0), pos.reshape(-1, 3).max(axis=0)
        c, r = 0.5 * (lo + hi), 0.5 * span
        ax.set_xlim(c[0] - r, c[0] + r)
        ax.set_ylim(c[1] - r, c[1] + r)
        ax.set_zlim(c[2] - r, c[2] + r)
        ax.set_xlabel("x")
        ax.set_ylabel("y")
        ax.set_zlabel("z")
        ax.set_title(f"t = {t[-1]:.3g} (grey: t = {t[0]:.3g}), d₂ in red", fontsize="medium")
        fig.colorbar(cm.ScalarMappable(norm=norm, cmap=cmap), ax=ax, shrink=0.6, pad=0.12, location="left",
                     label="twist angle φ (rad)")
        ax2 = fig.add_subplot(1, ncols, 2)
        seg = np.linalg.norm(np.diff(pos[-1], axis=0), axis=-1)
        s = np.concatenate([[0.0], np.cumsum(seg)])
        for i in _snapshot_indices(t.size, 5):
            ax2.plot(s, phi[i], label=f"t = {t[i]:.3g}")
        ax2.set_xlabel("arclength s")
        ax2.set_ylabel("twist angle φ (rad)")
        gauge = str(ds["twist_angle"].attrs.get("long_name", "")).rsplit(" the ", 1)[-1]
        ax2.set_title(f"material frame relative to the {gauge}")
        ax2.legend(fontsize="small")
        ax2.grid(True, alpha=0.3)
        if dynamic:
            _draw_energies(fig, 3, ncols, ds)
        return True

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
