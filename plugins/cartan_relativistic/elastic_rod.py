"""The elastic relativistic string: ``relativistic-rod`` with ``energy="elastic"`` (docs §2–§3).

Rest-frame energy per unit reference length ε(λ) = μc² + ½k(λ − 1)² by default (λ the
rest-frame stretch, tension T = ε′ = k(λ − 1), rest mass μ per unit reference length), run in
the **temporal gauge** r⁰ = ct: the core's time t is the lab time at every node, Λ = I is held (the Lorentz
part of 𝔤 is gauge), and the translation components of N and X are ṙ = (c, v⃗) and
r′ = (0, x⃗′).  The reduced Lagrangian (paper §IV.A)

    ℓ(v⃗, x⃗′) = −ε(λ) √(c² − v²)/c,        λ² = |x⃗′|² + (v⃗·x⃗′)²/(c² − v²),

couples velocity and strain, so the medium declares
:attr:`~cartan.medium.Medium.coupled_lagrangian` and gives the Legendre map pointwise:
``S = (0, p⃗, 0₆)`` with p⃗ = ∂ℓ/∂v⃗ (:meth:`momentum_at`), its inverse by Newton's method per
point (:meth:`velocity_at`, N₀ = c: the gauge), the Hamiltonian stress Q⃗ = −∂ℓ/∂x⃗′
(:meth:`stress_with`) and H = p⃗·v⃗ − ℓ − μc² (:meth:`hamiltonian`; the constant rest energy
μc² per unit u is left out of the core's energies and added back in the output ``energy``).
The lattice steps the Hamiltonian system with ``rkmk4`` (order 4), ``lie-euler`` (order 1) or
``implicit-midpoint`` (order 2, symplectic: the discrete Lagrangian method of the Legendre
transform of H_d) (:mod:`cartan.schemes._coupled`); ``lie-verlet`` refuses it.  With the
built-in laws (``quadratic``, ``quartic``) the medium declares compiled point kernels
(:meth:`point_kernels`) and ``rkmk4``, ``lie-euler``, ``forward-euler`` and ``implicit-midpoint``
run in the generated compiled loops, on the lattice and the collocation; the other laws step on
the numpy path.

A general rest-frame energy ε(λ) = μc² + W(λ) is given as ``law``
(:class:`cartan_relativistic.elastic.ElasticLaw`: W, W′, W″), checked on construction at λ = 1
and over ``stretch_range`` (ε > 0, ε″ > 0, longitudinal waves slower than light; docs §2).
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from cartan import accumulators
from cartan.medium import MediumKernels, check_finite, check_keywords, check_positive
from cartan.problem import InitialState

from .elastic import (
    ElasticLaw,
    as_law,
    law_from_repr,
    quadratic_law,
    stretch,
    temporal_lagrangian,
    temporal_momentum,
    temporal_stress,
    temporal_velocity,
)
from .string import RelativisticRod

__all__ = ["ElasticRelativisticRod"]


class ElasticRelativisticRod(RelativisticRod):
    """An elastic string in Minkowski space on the Poincaré group, temporal gauge (docs §2–§3).

    Built by ``cartan.medium("relativistic-rod", energy="elastic", stiffness=k, mu=μ, c=c)``.

    Parameters
    ----------
    c : float, default 1
        Speed of light, > 0.
    mu : float, default 1
        Rest mass per unit reference length μ, > 0.
    energy : str
        ``"elastic"``.
    stiffness : float, optional
        Axial stiffness k of ε(λ) = μc² + ½k(λ − 1)² (the ``cosserat-rod``'s stretch stiffness
        in the Newtonian limit), 0 < k < μc²: longitudinal waves at √(k/μ) < c.
    law : ElasticLaw, str, dict or tuple (W, W′, W″), optional
        Instead of ``stiffness``: a general ε(λ) = μc² + W(λ)
        (:class:`cartan_relativistic.elastic.ElasticLaw`, e.g. ``ElasticLaw.quartic(k, q)``), a
        registered law by name or as ``{"name": ..., **parameters}`` (``{"name": "quartic",
        "k": 0.25, "q": 0.5}``; :func:`cartan_relativistic.elastic.register_law`), checked on
        construction at λ = 1 and over ``stretch_range`` (ε > 0, ε″ > 0, longitudinal waves
        slower than light; docs §2, "General ε(λ)").  A run records a registered law as its
        name and parameters and restarts exactly; one built from bare callables cannot be
        recorded (``ValueError`` when the run starts, saying how to register it).
    stretch_range : (float, float), optional
        Stretches 0 < λ_min < λ_max over which the law is checked as well (201 points).
    clocks : bool, optional
        Accumulate each node's proper time in the run (default True: the output
        ``proper_time``; docs §4), in the compiled loops too (the rate kernel of
        :func:`cartan_relativistic.elastic_kernels.medium_kernels`).

    Notes
    -----
    ``X``, ``Q`` ``[..., 1, 10]`` and ``N``, ``S`` ``[..., 10]`` in the Poincaré basis; only the
    spatial translation components (1, 2, 3) are live.  :meth:`inertia` ``(0, μ, μ, μ, 0₆)`` is
    the Newtonian limit of the kinetic metric (the CFL estimate and the blow-up guard use it);
    the dynamics uses the Legendre map.  The quadratic law is causal only for moderate
    stretches: at large λ or speeds close to c along the string the Hessian of ℓ in v⃗ loses
    definiteness and :meth:`velocity_at` raises ``ValueError``.
    """

    coupled_lagrangian: ClassVar[bool] = True
    #: :meth:`outputs` takes the run's time t: the lab time of a clamped node (at rest in the lab)
    outputs_read_time: ClassVar[bool] = True
    initial_kinds: ClassVar[tuple[str, ...]] = ("straight", "ring")
    output_fields: ClassVar[dict[str, tuple[str, str]]] = {
        "energy": ("total energy E = Σ w (H + μc²) (lab frame, nodal quadrature)", "J"),
        "momentum_x": ("total momentum P¹ = Σ w p¹ (lab frame, nodal quadrature)", "kg m s-1"),
        "momentum_y": ("total momentum P² (lab frame, nodal quadrature)", "kg m s-1"),
        "momentum_z": ("total momentum P³ (lab frame, nodal quadrature)", "kg m s-1"),
        "angular_momentum_x": ("total angular momentum J₁ = Σ w (y p_z − z p_y) about the origin", "kg m2 s-1"),
        "angular_momentum_y": ("total angular momentum J₂ = Σ w (z p_x − x p_z) about the origin", "kg m2 s-1"),
        "angular_momentum_z": ("total angular momentum J₃ = Σ w (x p_y − y p_x) about the origin", "kg m2 s-1"),
        "coordinate_time": ("lab (coordinate) time of each node's event: r⁰/c (= t in the temporal gauge), "
                            "r⁰/c + t at a clamped node (at rest in the lab)", "s"),
        "lab_x": ("lab position x of each node", "m"),
        "lab_y": ("lab position y of each node", "m"),
        "lab_z": ("lab position z of each node", "m"),
        "lorentz_factor": ("γ = dt/dτ of each node (proper-time rate 1/γ)", "1"),
        "stretch": ("rest-frame stretch λ of each node", "1"),
        "tension": ("tension T = ε′(λ) of each node", "N"),
    }

    def __init__(self, c: float = 1.0, mu: float = 1.0, energy: str = "elastic", stiffness: float | None = None,
                 law: ElasticLaw | tuple | str | dict | None = None, stretch_range: tuple[float, float] | None = None,
                 clocks: bool | None = None):
        if energy != "elastic":
            raise ValueError(f"{type(self).__name__} is the energy 'elastic'; got energy={energy!r}")
        super().__init__(c=c, mu=mu, energy="nambu-goto")
        self.energy = "elastic"
        self.clocks = self._check_clocks(clocks, default=True)
        if stretch_range is not None:
            lo, hi = (float(v) for v in check_positive("stretch_range", stretch_range, shape=(2,)))
            if not lo < hi:
                raise ValueError(f"stretch_range must be (λ_min, λ_max) with 0 < λ_min < λ_max, got {stretch_range!r}")
            stretches = np.union1d(np.linspace(lo, hi, 201), [1.0])
            self.stretch_range: tuple[float, float] | None = (lo, hi)
        else:
            stretches = np.array([1.0])
            self.stretch_range = None
        if law is not None:
            if stiffness is not None:
                raise ValueError("give either stiffness k (the quadratic law) or law (an ElasticLaw W, W′, W″), "
                                 "not both")
            law = as_law(law)
            self.stiffness = None
            self.elastic_law = law
            law.check(self.mu, self.c, stretches)
            self.law = law.functions(self.mu, self.c)
            return
        if stiffness is None:
            raise ValueError("energy 'elastic' needs stiffness k > 0 (ε(λ) = μc² + ½k(λ − 1)²) or a law "
                             "(ElasticLaw: W(λ) = ε(λ) − μc², W′, W″)")
        self.stiffness = float(check_positive("stiffness", stiffness, shape=()))
        if self.stiffness >= self.mu * self.c**2:
            raise ValueError(f"stiffness must be < μc² = {self.mu * self.c**2!r} (longitudinal waves at √(k/μ), "
                             f"slower than light), got {stiffness!r}")
        self.elastic_law = ElasticLaw.quadratic(self.stiffness)
        if stretch_range is not None:
            self.elastic_law.check(self.mu, self.c, stretches)
        self.law = quadratic_law(self.mu, self.stiffness, self.c)

    # ------------------------------------------------------------------ contract
    def parameters(self) -> dict[str, Any]:
        out: dict[str, Any] = {"c": self.c, "mu": self.mu, "energy": "elastic"}
        if self.stiffness is not None:
            out["stiffness"] = self.stiffness
        elif self.elastic_law.record is not None:
            out["law"] = self.elastic_law.to_dict()  # {"name": ..., **parameters}: rebuilt on a restart
        else:
            out["law"] = self.elastic_law  # unregistered: recording it raises (ElasticLaw.to_dict)
        if self.stretch_range is not None:
            out["stretch_range"] = self.stretch_range
        if not self.clocks:
            out["clocks"] = False
        return out

    def restart_record(self, recorded: dict[str, Any], arrays: list[str], path: str) -> dict[str, Any]:
        """The record of a restart file written before laws were recorded by name and before the
        clocks, read against this medium (:meth:`cartan.medium.Medium.restart_record`).

        * A law recorded as its ``repr`` (not ``{"name": ..., **parameters}``): a built-in
          preset's repr determines it (:func:`cartan_relativistic.elastic.law_from_repr`) and is
          read as its record when it is this medium's law (``ValueError`` naming both when it is
          not); any other (``"ElasticLaw(custom)"``, bare functions) determines nothing, and the
          restart goes on only with a law given explicitly — as a registered law, ``law=...`` —
          with a warning that the file cannot confirm it, else ``ValueError`` saying so.
        * No accumulated proper time in the checkpoint (written before the clocks): the time
          already run cannot be recovered, so the restart goes on only with ``clocks=False``
          (``ValueError`` saying so); then the record reads as ``clocks = False``.

        Records of the current form are returned unchanged.
        """
        params = recorded.get("parameters")
        if recorded.get("medium") != self.name or not isinstance(params, dict) or params.get("energy") != "elastic":
            return recorded
        out = dict(params)
        where = f"restart file {path!r}"
        if "law" in params and not (isinstance(params["law"], dict) and isinstance(params["law"].get("name"), str)):
            old = params["law"]
            mine = self.elastic_law.record if self.stiffness is None else None
            preset = law_from_repr(old)
            if preset is not None:
                if mine != preset.record:
                    raise ValueError(f"{where} was written with the law {old!r} (recorded before laws were recorded "
                                     f"by name), the problem to continue has "
                                     f"{mine if mine is not None else {'stiffness': self.stiffness}}: give "
                                     f"law={preset.record!r}")
                out["law"] = mine
            elif mine is None:
                raise ValueError(
                    f"{where} records its law as {old!r}: written before laws were recorded by name, it does not "
                    "say which law ε(λ) the run used, so the medium cannot be rebuilt from it. To continue the run, "
                    "register the law (cartan_relativistic.elastic.register_law('my-law', factory)) and pass the "
                    "problem with it given explicitly: cartan.simulate(cartan.Problem(cartan.medium("
                    "'relativistic-rod', energy='elastic', law={'name': 'my-law', ...}, ...), ...), restart=...)")
            else:
                import warnings

                warnings.warn(f"{where} records its law as {old!r} (written before laws were recorded by name), "
                              f"which cannot confirm the law given, {mine!r}: continuing with it", stacklevel=3)
                out["law"] = mine
        if accumulators.key("proper_time") not in arrays and "clocks" not in params:
            if self.clocks:
                raise ValueError(
                    f"{where} holds no accumulated proper time (written before the elastic string's clocks): the "
                    "proper time of the part already run cannot be recovered. Continue it without clocks: pass the "
                    "problem with cartan.medium('relativistic-rod', energy='elastic', ..., clocks=False) (a scene: "
                    "clocks = false in its [parameters]); cartan_relativistic.clocks.proper_time(ds) gives τ from "
                    "the saved frames afterwards")
            out["clocks"] = False
        return {**recorded, "parameters": out}

    def accumulator_rates(self, q: np.ndarray, X: np.ndarray, N: np.ndarray, grid: Any) -> dict[str, np.ndarray]:
        """``dτ/dt = √(1 − |v⃗|²/c²)`` per node, ``[*grid.shape]``, v⃗ = N[..., 1:4]: the run's time is
        the lab time of every node (temporal gauge), so a node held fixed (a clamped end, N = 0)
        is at rest in the lab and its clock runs at 1, τ = t exactly."""
        v = np.asarray(N, dtype=float)[..., 1:4]
        return {"proper_time": np.sqrt(np.maximum(1.0 - np.sum(v * v, axis=-1) / self.c**2, 0.0))}

    def inertia(self) -> np.ndarray:
        """``(0, μ, μ, μ, 0₆)``: the Newtonian kinetic metric; slot 0 (N₀ = c) and the Lorentz part are gauge."""
        return np.concatenate([[0.0], np.full(3, self.mu), np.zeros(6)])

    def rest_strain(self) -> np.ndarray:
        """``φ = (0, 1, 0, 0)``: the unstretched string along e₁ (λ = 1, T = 0), shape ``(1, 10)``."""
        X0 = np.zeros((1, 10))
        X0[0, 1] = 1.0
        return X0

    def point_kernels(self) -> MediumKernels | None:
        """The potential U = H(0, X), the coupled kernels (the Legendre map and the Hamiltonian
        stress at one half-edge) and the proper time's rate of the built-in laws
        (:func:`cartan_relativistic.elastic_kernels.medium_kernels`): the generated loops of
        ``rkmk4``, ``lie-euler`` and ``forward-euler`` then run the string compiled, its clocks
        included (docs §3).  None for a law without kernels (a registered user law, bare
        callables): the numpy path."""
        from .elastic_kernels import medium_kernels

        return medium_kernels(self.elastic_law, self.mu, self.c)

    def _static(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = np.asarray(X, dtype=float)[..., 0, 1:4]
        return x, np.linalg.norm(x, axis=-1)

    def potential(self, X: np.ndarray) -> np.ndarray:
        """``U = H(S = 0, X) = ε(|x⃗′|) − μc² = W(|x⃗′|)`` (½k(|x⃗′| − 1)² for the quadratic law),
        ``[..., 1, 10]`` → ``[...]``."""
        _, lam = self._static(X)
        return np.asarray(self.elastic_law.W(lam), dtype=float)

    def stress(self, X: np.ndarray) -> np.ndarray:
        """``Q = ∂U/∂X = k(|x⃗′| − 1) x̂′`` on slots 1–3 (the Hamiltonian stress at S = 0)."""
        return self.stress_with(np.zeros((*np.shape(X)[:-2], 10)), X)

    def potential_at(self, X: np.ndarray, X0: np.ndarray) -> np.ndarray:
        return self.potential(X)

    def stress_at(self, X: np.ndarray, X0: np.ndarray) -> np.ndarray:
        return self.stress(X)

    def momentum_at(self, N: np.ndarray, X: np.ndarray) -> np.ndarray:
        """``S = (0, p⃗, 0₆)`` with p⃗ = ∂ℓ/∂v⃗(v⃗, x⃗′), v⃗ = N[..., 1:4], x⃗′ = X[..., 0, 1:4]."""
        N = np.asarray(N, dtype=float)
        x, _ = self._static(X)
        S = np.zeros(np.broadcast_shapes(N.shape, (*x.shape[:-1], 10)))
        S[..., 1:4] = temporal_momentum(N[..., 1:4], x, self.law, self.c)
        return S

    def velocity_at(self, S: np.ndarray, X: np.ndarray) -> np.ndarray:
        """``N = (c, v⃗, 0₆)``, v⃗ solving p⃗(v⃗, x⃗′) = S[..., 1:4] (Newton per point,
        :func:`cartan_relativistic.elastic.temporal_velocity`)."""
        S = np.asarray(S, dtype=float)
        x, _ = self._static(X)
        p = np.ascontiguousarray(S[..., 1:4])
        key = (p.shape, x.shape, p.tobytes(), x.tobytes())
        memo = self.__dict__.setdefault("_memo", {})
        if key not in memo:  # (the same (S, X) comes back for the stress: Newton once)
            if len(memo) >= 8:
                memo.pop(next(iter(memo)))
            # Newton from the point's own first guess, never from an earlier call's solution: the
            # result is then a function of (S, X) alone, bit for bit, so that restarts are exact
            memo[key] = ((p.copy(), x.copy()), temporal_velocity(p, x, self.law, self.c))
        N = np.zeros(np.broadcast_shapes(S.shape, (*x.shape[:-1], 10)))
        N[..., 0] = self.c
        N[..., 1:4] = memo[key][1]
        return N

    def stress_with(self, S: np.ndarray, X: np.ndarray) -> np.ndarray:
        """``Q = ∂H/∂X(S, X)``: Q⃗ = −∂ℓ/∂x⃗′ = (T√A/c)(x⃗′ + (B/A)v⃗)/λ on slots 1–3 at v⃗ = v⃗(S, X);
        zero on slot 0 (φ₀ = 0 is the gauge) and on the Lorentz part, shape ``[..., 1, 10]``."""
        N = self.velocity_at(S, X)
        x, _ = self._static(X)
        Q = np.zeros(np.broadcast_shapes(np.shape(X), (*N.shape[:-1], 1, 10)))
        Q[..., 0, 1:4] = temporal_stress(N[..., 1:4], x, self.law, self.c)
        return Q

    def hamiltonian(self, S: np.ndarray, X: np.ndarray) -> np.ndarray:
        """``H = p⃗·v⃗ − ℓ(v⃗, x⃗′) − μc²`` at v⃗ = v⃗(S, X): the lab energy per unit u less the rest
        energy (½μv² + W in the Newtonian limit)."""
        N = self.velocity_at(S, X)
        x, _ = self._static(X)
        v = N[..., 1:4]
        p = np.asarray(S, dtype=float)[..., 1:4]
        return np.sum(p * v, axis=-1) - temporal_lagrangian(v, x, self.law, self.c) - self.mu * self.c**2

    # ------------------------------------------------------------------ initial states
    def initial_state(self, grid, kind: str, **params: Any) -> InitialState:
        """Initial Φ and N in the temporal gauge (r⁰ = 0, N₀ = c, Λ = I).

        ``"straight"``: the string along e₁ with the uniform ``stretch`` λ₀ (default 1) at rest,
        ``origin`` (3,).  ``"ring"`` (periodic grid): a circle of ``radius`` R (default L/2π:
        unstretched) about ``center`` in the x–y plane, spinning at ``spin`` ω about e₃ (speed
        ωR, < c) and breathing at ``radial_speed`` (outwards).  Velocities and positions are
        lab-frame; use :meth:`state_from` for any other shape.
        """
        if grid.d != 1:
            raise ValueError(f"{self.name} needs a grid with d = 1, got d = {grid.d}")
        if kind == "straight":
            check_keywords(kind, self._straight_elastic, params)
            x, v = self._straight_elastic(grid, **params)
        elif kind == "ring":
            check_keywords(kind, self._ring, params)
            x, v = self._ring(grid, **params)
        else:
            raise ValueError(f"medium {self.name!r} (energy 'elastic') has no initial state kind {kind!r}; "
                             f"available: {', '.join(self.initial_kinds)}")
        return self.state_from(x, v)

    def _straight_elastic(self, grid, stretch=1.0, origin=None):
        lam = float(check_positive("stretch", stretch, shape=()))
        o = np.zeros(3) if origin is None else check_finite("origin", origin, (3,))
        u = grid.coordinates(0)
        x = o + np.stack([lam * u, np.zeros_like(u), np.zeros_like(u)], axis=-1)
        return x, np.zeros_like(x)

    def _ring(self, grid, radius=None, spin=0.0, radial_speed=0.0, center=None):
        if not grid.periodic[0]:
            raise ValueError("initial kind 'ring' needs a periodic grid (a closed string)")
        R = grid.length[0] / (2 * math.pi) if radius is None else float(check_positive("radius", radius, shape=()))
        w = float(check_finite("spin", spin, ()))
        vr = float(check_finite("radial_speed", radial_speed, ()))
        if math.hypot(w * R, vr) >= self.c:
            raise ValueError(f"spin·radius and radial_speed must give a speed below c = {self.c}, got "
                             f"{math.hypot(w * R, vr)!r}")
        o = np.zeros(3) if center is None else check_finite("center", center, (3,))
        ang = 2 * math.pi * grid.coordinates(0) / grid.length[0]
        er = np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], axis=-1)
        et = np.stack([-np.sin(ang), np.cos(ang), np.zeros_like(ang)], axis=-1)
        return o + R * er, w * R * et + vr * er

    # ------------------------------------------------------------------ outputs
    def outputs(self, q: np.ndarray, X: np.ndarray, N: np.ndarray, grid: Any,
                time: float = 0.0) -> dict[str, np.ndarray]:
        """Lab positions and times, γ, λ and T per node, and the charges by nodal quadrature
        (S = S(N, X) at the nodal strains; the exactly conserved discrete charges are the core's
        ``total_momentum`` and ``kinetic_energy + potential_energy``, docs §3).

        ``coordinate_time`` is the lab time of each node's event at the run's ``time`` t: r⁰/c
        at a moving node (r⁰ = ct + r⁰(0), the temporal gauge), and r⁰(0)/c + t at a clamped
        node (N = 0 while the other nodes have N₀ = c: the core holds its whole Φ, r⁰ included,
        while the node is at rest in the lab at x⃗₀, its worldline (c(t₀ + t), x⃗₀)), docs §3."""
        c = self.c
        r, rdot = self.lab_events(q, N)
        Nf = np.asarray(N, dtype=float)
        # a clamped node: N = 0 where the other nodes move at N₀ = c (the temporal gauge; a run whose
        # integrator prescribes N₀ = 0 everywhere, ``overdamped``, has no lab time to follow)
        held = np.all(Nf == 0.0, axis=-1) & bool(np.any(Nf[..., 0] != 0.0))
        rdot[..., 0] = c  # (temporal gauge ṙ = (c, v⃗); a clamped node, N = 0, is at rest in the lab)
        x = np.asarray(X, dtype=float)
        S = self.momentum_at(N, x)
        w = grid.node_weights()
        E = np.tensordot(w, self.hamiltonian(S, x) + self.mu * c * c, axes=1)
        p = S[..., 1:4]
        P = np.tensordot(w, p, axes=1)
        J = np.tensordot(w, np.cross(r[..., 1:], p), axes=1)
        v = rdot[..., 1:]
        gamma = 1.0 / np.sqrt(np.maximum(1.0 - np.sum(v * v, axis=-1) / c**2, 1e-300))
        rprime = np.concatenate([np.zeros((*x.shape[:-2], 1)), x[..., 0, 1:4]], axis=-1)
        lam = stretch(rdot, rprime)
        return {
            "energy": E, "momentum_x": P[0], "momentum_y": P[1], "momentum_z": P[2],
            "angular_momentum_x": J[0], "angular_momentum_y": J[1], "angular_momentum_z": J[2],
            "coordinate_time": r[..., 0] / c + np.where(held, float(time), 0.0),
            "lab_x": r[..., 1], "lab_y": r[..., 2], "lab_z": r[..., 3],
            "lorentz_factor": gamma, "stretch": lam, "tension": self.law[1](lam),
        }
