"""The :class:`Medium` base: the physics of a Cartan medium (paper §IV), and nothing else.

A medium knows its symmetry group G and homogeneous space X, its reduced kinetic energy
density K(N), its potential energy density U(X_α) and stresses Q^α = ∂U/∂X_α, and which
components of N are gauge (adapted media, paper §III.E and §IV.E).  It knows nothing of
grids, schemes, time steps or output: those are the core's.

Shapes
------
``N``, ``S`` : ``[..., r]`` (velocity in 𝔤, momentum in 𝔤*, per point)
``X``, ``Q`` : ``[..., d, r]`` (one strain / stress per material axis α = u, v, w)

Sign conventions follow the paper: S = ∂K/∂N, Q^α = ∂U/∂X_α, and the momentum balance
``Ṡ + ad*_N S = ∂_α Q^α + ad*_{X_α} Q^α + T`` with ``ad*_ξ = −ad_ξᵀ`` in components.

Configurational potentials
--------------------------
A body force that derives from a potential U(q) of the configuration q = Φ·q_r (gravity,
a confining field) is written as U(q) and its gradient ∂U/∂q only; :func:`pullback_gradient`
turns it into the generalised body force in 𝔤* (paper §IV.B, T_i = −Tr[𝒯 Φ b_i]
with 𝒯 = ∂U/∂q), so a plugin never writes a torque by hand.
"""

from __future__ import annotations

import abc
import inspect
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numba import njit

from .groups.base import SymmetryGroup

__all__ = [
    "HeldStrainTwin",
    "KernelMedium",
    "Medium",
    "MediumKernels",
    "QuadraticMedium",
    "check_finite",
    "check_keywords",
    "check_output_value",
    "check_positive",
    "close_on_periodic_grid",
    "output_coordinate_labels",
    "output_field_specs",
    "pullback_gradient",
]


def _as_float(name: str, value: Any) -> np.ndarray:
    """``np.asarray(value, float)`` with a ValueError naming ``name`` for non-numeric input:
    strings and booleans are not numbers (``"1e5"``, ``True`` are refused)."""
    raw = np.asarray(value, dtype=object) if not isinstance(value, np.ndarray) else value
    if raw.dtype.kind in "bUSO" and (raw.dtype.kind != "O" or any(
            isinstance(v, (bool, np.bool_, str, bytes)) for v in np.ravel(raw))):
        raise ValueError(f"{name} must be a real number or array of them, got {value!r}")
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be a real number or array, got {value!r}") from None


def check_positive(name: str, value: Any, *, allow_zero: bool = False, shape: tuple | None = None) -> np.ndarray:
    """Validate a physical parameter: finite, > 0 (or ≥ 0), optional shape; return float array.

    Raises
    ------
    ValueError
        naming the parameter and the allowed range.
    """
    arr = _as_float(name, value)
    if shape is not None and arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    bad = arr < 0 if allow_zero else arr <= 0
    if np.any(bad):
        rng = "≥ 0" if allow_zero else "> 0"
        raise ValueError(f"{name} must be {rng}, got {value!r}")
    return arr


def check_finite(name: str, value: Any, shape: tuple | None = None) -> np.ndarray:
    """Validate a finite float array (optional exact shape); ValueError naming ``name``."""
    arr = _as_float(name, value)
    if shape is not None and arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (no NaN or inf)")
    return arr


def check_keywords(kind: str, build: Any, params: dict[str, Any], extra: tuple[str, ...] = ()) -> None:
    """Reject keywords that the initial-shape builder ``build(grid, **params)`` does not take.

    Raises ``ValueError`` naming the unknown keywords and listing the accepted ones (the
    builder's own plus ``extra``, e.g. ``"velocity"`` handled by the medium itself).
    """
    accepted = [p for p in inspect.signature(build).parameters if p != "grid"]
    unknown = sorted(set(params) - set(accepted))
    if unknown:
        raise ValueError(
            f"initial kind {kind!r} takes no parameter(s) {', '.join(map(repr, unknown))}; accepted: "
            f"{', '.join([*accepted, *extra])}"
        )


def close_on_periodic_grid(group: SymmetryGroup, grid: Any, frames_on: Any) -> tuple[np.ndarray, np.ndarray]:
    """An open shape on a periodic axis (d = 1): its frames and the holonomy that closes it.

    ``frames_on(open_grid)`` returns Φ ``[n+1, m, m]`` on an open grid with one more node at
    u = L and the same spacing L/n; the result is ``(Φ[:-1], H)`` with ``H = Φ(L)Φ(0)⁻¹``, so
    that Φ(u + L) = HΦ(u) (``InitialState.holonomy``): a straight rod, an arc, a helix.
    """
    from .grid import Grid

    n, L = grid.shape[0], grid.length[0]
    ext = np.asarray(frames_on(Grid(n + 1, length=L)), dtype=float)
    return ext[:-1].copy(), group.compose(ext[-1], group.inverse(ext[0]))


def pullback_gradient(group: SymmetryGroup, space, Phi: np.ndarray, grad: np.ndarray) -> np.ndarray:
    """Generalised body force ``T ∈ 𝔤*`` of a configurational potential (paper §IV.B).

    For ``q = Φ·q_r`` and a potential U(q) with gradient ``∂U/∂q`` (same shape as a point of
    the space), ``T_i = −d/dε U(Φ exp(ε b_i)·q_r)|₀ = −⟨∂U/∂q, (Φ b_i)·q_r⟩``.  The group
    action is linear in the matrix of Φ for every space in cartan, so the generator's
    tangent vector is ``space.act(Φ b_i, q_r)`` (the affine part acting on q_r's linear
    part only).

    Parameters
    ----------
    group : SymmetryGroup
    space : HomogeneousSpace
        Provides ``act(g, q)`` (linear in g) and ``q_r``.
    Phi : array, shape ``[..., m, m]``
    grad : array, shape ``[..., *point_shape]``
        ∂U/∂q at q = Φ·q_r.

    Returns
    -------
    numpy.ndarray, shape ``[..., r]``
    """
    basis = group._basis  # [r, m, m]
    q_r = np.asarray(space.q_r, dtype=float)
    if q_r.ndim == 2 and Phi.shape[-1] == q_r.shape[0]:
        # matrix points q = Φ q_r (frame bundles): ⟨∂U/∂q, Φ b_i q_r⟩ = ⟨Φᵀ (∂U/∂q) q_rᵀ, b_i⟩,
        # one product per node instead of one per generator
        M = np.swapaxes(Phi, -1, -2) @ np.asarray(grad, dtype=float) @ q_r.T
        return -(M.reshape(*M.shape[:-2], -1) @ basis.reshape(basis.shape[0], -1).T)
    Phib = Phi[..., None, :, :] @ basis  # [..., r, m, m]
    tang = _linear_act(space, Phib)  # [..., r, *point_shape]
    g = np.expand_dims(np.asarray(grad, dtype=float), axis=Phi.ndim - 2)
    return -np.sum((tang * g).reshape(*tang.shape[: Phi.ndim - 1], -1), axis=-1)


def _linear_act(space, M: np.ndarray) -> np.ndarray:
    """``space.act`` applied to a matrix that need not be a group element (linear part)."""
    q_r = np.asarray(space.q_r, dtype=float)
    if getattr(space.group, "affine", False) and q_r.ndim == 1 and q_r.shape[-1] == space.group.space_dim:
        # affine action on a point: A q_r + a, linear in (a, A); the "1" of the homogeneous
        # coordinate is not part of the tangent map.
        return np.einsum("...ij,j->...i", M[..., 1:, 1:], q_r) + M[..., 1:, 0]
    return space.act(M, q_r) if q_r.ndim != 2 else M @ q_r


@dataclass(frozen=True)
class MediumKernels:
    """A medium's potential at one point, as numba functions (the compiled loops' physics).

    Attributes
    ----------
    energy : numba function ``(X, X0, p) -> float``
        The potential energy density U per unit reference volume.
    stress : numba function ``(X, X0, p, Q) -> None``
        Writes the stress ``Q = ∂U/∂X`` into ``Q``.
    params : array, shape ``(k,)``
        The parameter vector ``p`` (float64).

    coupled_velocity : numba function ``(S, X, p, N) -> bool``, optional
        For a medium whose Lagrangian couples N and X (:attr:`Medium.coupled_lagrangian`):
        the inverse Legendre map ``N = ∂H/∂S(S, X)`` at one point (one node's momentum ``S``
        ``(r,)`` with one edge's strain ``X`` ``(d, r)``) into ``N`` ``(r,)``, gauge
        components as the medium fixes them (:meth:`Medium.velocity_at`); False when there is
        none (the momentum is outside the range of the Legendre map, or its solve failed).
    coupled_stress : numba function ``(S, X, N, p, Q) -> None``, optional
        The Hamiltonian stress ``Q = ∂H/∂X(S, X)`` ``(d, r)`` at the same point
        (:meth:`Medium.stress_with`), ``N`` being what ``coupled_velocity`` gave there (one
        solve of the Legendre map serves both).
    coupled_jacobian : numba function ``(S, X, N, p, J) -> bool``, optional
        The Hessian of H in S, ``J = ∂N/∂S(S, X)`` ``(r, r)`` (the inverse of ∂²L/∂N² on the
        live components), at the same point, ``N`` being what ``coupled_velocity`` gave there;
        False when it has none.  ``implicit-midpoint``'s compiled stage momenta (the Legendre map
        inverted per node, :func:`cartan.integrators.newton.im_coupled_momentum`) then take
        their Newton Jacobian from it instead of by forward differences of ``coupled_velocity``.
    accumulator_rate : numba function ``(N, p, out) -> None``, optional
        For a medium that declares :meth:`Medium.accumulators`: their rates at one node from its
        velocity ``N`` ``(r,)`` into ``out`` ``(a,)``, one per accumulator in the order of
        :meth:`Medium.accumulators` — what :meth:`Medium.accumulator_rates` gives at that node
        (a rate that needs only the node's velocity).  The generated loops of the lattice
        (``lie-verlet``, ``lie-euler``, ``forward-euler``, ``rkmk4``) then integrate the
        accumulators in the loop by the trapezoidal rule of :func:`cartan.accumulators.add`
        (docs/design.md, "Per-node accumulators"); without it such a medium steps on the
        numpy path.

    ``X`` (the strain), ``X0`` (the rest strain at that point) and ``Q`` have shape ``(d, r)``.
    Every function is a module-level ``@njit`` function (the generated loops import them by
    name, and a change to their module's source recompiles the loops that use them);
    ``cartan.testing.check_medium`` checks that the stress is the gradient of the energy
    and that both agree with :meth:`Medium.potential` and :meth:`Medium.stress`.  A coupled
    medium declares ``energy`` and ``stress`` as its potential ``U(X) = H(0, X)`` and both
    coupled kernels; the lattice's compiled operators check them against
    :meth:`Medium.velocity_at` and :meth:`Medium.stress_with` (d = 1; docs/design.md, "Media
    whose Lagrangian couples N and X").  Without the coupled kernels a coupled medium steps on
    the numpy path.
    """

    energy: Callable
    stress: Callable
    params: np.ndarray
    coupled_velocity: Callable | None = None
    coupled_stress: Callable | None = None
    accumulator_rate: Callable | None = None
    coupled_jacobian: Callable | None = None


@njit(cache=True)
def quadratic_energy_point(X, X0, p):  # pragma: no cover - compiled
    """``U = ½ (X − X₀)ᵀ C (X − X₀)`` with ``C = p.reshape(d·r, d·r)``, X and X₀ flattened."""
    d, r = X.shape
    dr = d * r
    u = 0.0
    row = 0
    for a in range(d):
        for k in range(r):
            s = 0.0
            col = row * dr
            for b in range(d):
                for j in range(r):
                    s += p[col] * (X[b, j] - X0[b, j])
                    col += 1
            u += (X[a, k] - X0[a, k]) * s
            row += 1
    return 0.5 * u


@njit(cache=True)
def quadratic_stress_point(X, X0, p, Q):  # pragma: no cover - compiled
    """``Q = C (X − X₀)`` (see :func:`quadratic_energy_point`).

    The axes whose strain is at rest add exact zeros and are skipped (the lattice evaluates
    each edge with the other axes at rest): the result is that of the full product."""
    d, r = X.shape
    dr = d * r
    moved = 0  # bit b: axis b is off its rest strain (d ≤ 63)
    for b in range(d):
        for j in range(r):
            if X[b, j] - X0[b, j] != 0.0:
                moved |= 1 << b
                break
    row = 0
    for a in range(d):
        for k in range(r):
            s = 0.0
            for b in range(d):
                if moved >> b & 1:
                    col = row * dr + b * r
                    for j in range(r):
                        s += p[col + j] * (X[b, j] - X0[b, j])
            Q[a, k] = s
            row += 1


@dataclass(frozen=True)
class HeldStrainTwin:
    """A medium's approximate twin with some strain components held by constraint (paper §III.E).

    Declared by :meth:`Medium.held_strain_twins`; ``cartan advise`` (:mod:`cartan.advise`)
    builds the twin, measures how far the held components move in a scene and runs the twin
    beside the medium.  The twin keeps the medium's group, space, grid, loads, boundaries and
    initial state; it must hold exactly ``components`` (its own
    :meth:`Medium.constrained_strains`), at ``values``.

    Attributes
    ----------
    medium : str or None
        Registry name of the twin medium (e.g. ``"filament"``), or None for the core's generic
        twin (:class:`cartan.advise.HeldStrainMedium`: this medium's quadratic energy without
        the held components; d = 1 translation strains only).
    components : tuple of int
        Indices ``k < r`` into the group's basis, held on every material axis.
    values : tuple of float or None
        The held values, one per component (the same on every axis); None: this medium's rest
        values (:meth:`Medium.rest_strain`).
    parameters : callable or None
        ``parameters(this.parameters()) -> dict``: the twin's constructor keywords from this
        medium's parameters (None with ``medium=None``).
    label : str
        What is held, in words (``"stretch and shear"``, ``"transverse shear"``).
    """

    medium: str | None
    components: tuple[int, ...]
    values: tuple[float, ...] | None = None
    parameters: Callable[[dict[str, Any]], dict[str, Any]] | None = None
    label: str = ""


class Medium(abc.ABC):
    """Physics of a Cartan medium: energies, stresses and gauge (paper §IV).

    Subclasses set the class attributes ``name`` (kebab-case registry name) and
    ``material_dim`` (d), create ``self.group`` and ``self.space`` in ``__init__``, validate
    every parameter there (``ValueError`` naming the parameter and the allowed range), and
    implement :meth:`inertia`, :meth:`potential`, :meth:`stress` and :meth:`rest_strain`.

    Kinetic energy
        cartan media have a reduced kinetic energy density quadratic in N with a constant
        metric, ``K(N) = ½ Σ_k m_k N_k²`` in the group's basis, given by :meth:`inertia`
        (the ``m_k``).  ``m_k = 0`` marks a gauge direction (paper §III.E): its component of
        N is held at zero.  A diagonal metric lets ``lie-verlet`` split the free motion into
        exactly integrable one-parameter flows.  A medium whose Lagrangian ℓ(N, X) couples
        velocity and strain declares :attr:`coupled_lagrangian` and its pointwise Legendre map
        (:meth:`momentum_at`, :meth:`velocity_at`, :meth:`stress_with`, :meth:`hamiltonian`),
        and, to run in the compiled loops, the same at one point as numba kernels
        (:meth:`point_kernels`, :class:`MediumKernels` ``coupled_velocity`` and ``coupled_stress``).

    Potential energy
        ``U(X)`` per unit reference volume and its gradient ``Q^α = ∂U/∂X_α``.  The stress
        must be the exact gradient of the potential (the conformance kit checks it by finite
        differences): the discrete energy balance depends on it.

    Body forces
        :meth:`body_force` returns a generalised force density ``T ∈ 𝔤*`` that does not derive
        from U(X) (default: none).  Configurational potentials U(q) are loads given to the
        problem and pulled back by the core (:func:`pullback_gradient`).

    Static Jacobian (optional)
        :meth:`static_jacobian` may return ``∂r/∂δ``, the Jacobian of the static residual
        ``r = w·W`` on the lattice along the drift directions ``Φ_i ← Φ_i exp(δ_i)``, a sparse
        ``(nnode·r, nnode·r)`` matrix over all node components; :func:`cartan.solve_static`
        then needs no coloured finite-difference Jacobian (it may still add a small
        finite-difference correction between iterations).  Default: None (not provided).

    Supports (optional)
        :meth:`check_support` may refuse a boundary condition that the medium's equations do
        not admit at an end (a ``ValueError`` saying what to use instead); the
        :class:`~cartan.problem.Problem` calls it for every end when it is built.  Default:
        every support is accepted.
    """

    name: ClassVar[str] = ""
    #: material dimension d (a class attribute, or set per instance for media of any d)
    material_dim: int = 1
    group: SymmetryGroup
    space: Any

    # ------------------------------------------------------------------ contract
    @abc.abstractmethod
    def inertia(self) -> np.ndarray:
        """Diagonal kinetic metric ``m_k ≥ 0`` per unit reference volume, shape ``(r,)``."""

    @abc.abstractmethod
    def potential(self, X: np.ndarray) -> np.ndarray:
        """Potential energy density U(X), X ``[..., d, r]`` → ``[...]``."""

    @abc.abstractmethod
    def stress(self, X: np.ndarray) -> np.ndarray:
        """Stress ``Q^α = ∂U/∂X_α``, X ``[..., d, r]`` → ``[..., d, r]``."""

    @abc.abstractmethod
    def rest_strain(self) -> np.ndarray:
        """Strain of the stress-free reference state, shape ``(d, r)``."""

    # ------------------------------------------------------------------ varying rest strain
    def potential_at(self, X: np.ndarray, X0: np.ndarray) -> np.ndarray:
        """U at strain X with the local rest strain X0 (both ``[..., d, r]``) → ``[...]``.

        The default translates the energy, ``U(X − X0 + X̄0)`` with X̄0 = :meth:`rest_strain`
        (exact for quadratic media); media with point kernels evaluate their kernels, which
        take X0 directly.  Used where a problem has a stress-free ``reference`` configuration.
        """
        return self.potential(np.asarray(X) - X0 + self.rest_strain())

    def stress_at(self, X: np.ndarray, X0: np.ndarray) -> np.ndarray:
        """``∂U/∂X`` at X with the local rest strain X0 (see :meth:`potential_at`)."""
        return self.stress(np.asarray(X) - X0 + self.rest_strain())

    def reference_volume(self, X0: np.ndarray) -> np.ndarray | None:
        """The reference volume per unit chart volume at the rest strains ``X0 [..., d, r]`` →
        ``[...]``, or None (the default) when the chart is the reference's own measure.

        A medium whose energy reads a general chart from the rest strain (a solid on a
        non-orthonormal chart: det Θ₀) returns it; the lattice then weighs the node's mass,
        its body loads and its kinetic energy by the node's reference volume ``w_i·J_i``
        (``Lattice.weights``), while the energy keeps the chart's quadrature weights.
        """
        return None

    def reference_area(self, X0: np.ndarray, axis: int) -> np.ndarray | None:
        """The reference area of the face ⊥ ``axis`` per unit chart area at the rest strains
        ``X0 [..., d, r]`` → ``[...]``, or None (the default: the chart's own face measure);
        the lattice integrates face loads (``Free(load=...)``, per unit reference area) with it."""
        return None

    # ------------------------------------------------------------------ derived
    def parameters(self) -> dict[str, Any]:
        """The constructor parameters, JSON-serialisable (recorded in output attributes)."""
        return {}

    def body_force(self, Phi: np.ndarray | None, N: np.ndarray, t: float) -> np.ndarray | None:
        """Non-potential generalised force density ``T`` ``[..., r]`` or None (default)."""
        return None

    def point_kernels(self) -> MediumKernels | None:
        """The potential at one point as numba kernels (:class:`MediumKernels`), or None.

        A medium that declares them runs in the generated compiled loops on every group with
        point kernels (``docs/plugins.md``); None (the default) keeps it on the numpy path.
        """
        return None

    def quadratic_energy(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The potential as data, when it is quadratic: ``(X0, C)`` or None (default).

        A medium whose potential is ``U(X) = ½ Σ_α (X_α − X₀_α)ᵀ C (X_α − X₀_α)`` with a
        constant symmetric ``C`` may return ``X0`` of shape ``(r,)`` (d = 1) or ``(d, r)`` and
        ``C`` of shape ``(r, r)``; :meth:`potential` and
        :meth:`stress` must agree with them (``Q = C (X − X₀)``).  Schemes use the data to
        run whole step loops in compiled code (``docs/performance.md``); None means "not
        quadratic" and keeps the medium on the generic path, which calls :meth:`stress`.
        """
        return None

    def planar_reduction(self) -> Medium | None:
        """The planar twin of this medium on SE(2), or None (default: none).

        A medium on SE(3) whose motions in the x–y plane (director e₃ along +z) are exactly
        those of a medium on SE(2) returns that medium, its parameters mapped: SE(3)
        components ``(0, 1, 5)`` — ``(V₁, V₂, Ω₃)``, ``(θ₁, θ₂, π₃)``, ``(F₁, F₂, M₃)`` — are
        the SE(2) components ``(0, 1, 2)`` (paper §VI.A).  :func:`cartan.simulate` then runs
        problems whose data are all planar on the twin and lifts the results back
        (:mod:`cartan.reduction`, which also checks that the twin's kinetic metric, rest strain
        and stiffness are the restriction of this medium's, with no in-plane/out-of-plane
        coupling).  The twin must declare this medium's :attr:`output_fields`.

        Returns
        -------
        Medium or None
            A medium whose ``group`` is SE(2), or None when there is no exact planar twin
            (e.g. an out-of-plane rest curvature).
        """
        return None

    def static_jacobian(self, scheme: Any, state: Any, lam: float) -> Any:
        """Analytic Jacobian of the static residual, or None (default: none).

        :func:`cartan.solve_static` (and :func:`cartan.continuation`'s corrector, with λ
        anywhere in ``[0, lam_max]``) solves ``r(λ) = F_int + λ (w·W − F_int) = 0`` on the
        ``lattice`` scheme, with ``W = scheme.force(state, 0, state.t)`` the force density,
        ``F_int = scheme.internal_force(state)`` and ``w = scheme.weights`` (paper §IV; see
        ``docs/statics.md``).  A medium that can differentiate it in closed form returns

            ``J[i·r + k, j·r + l] = ∂r_{i,k} / ∂δ_{j,l}``

        along the drift directions ``Φ_j ← Φ_j exp(δ_j)`` (δ_j ∈ 𝔤 in the group's basis), at
        ``δ = 0``, over **all** node components: ``i, j`` are flat node indices in C order of
        ``scheme.grid.shape`` and ``k, l < r = group.dim``.  Rows and columns of clamped nodes
        and gauge components may hold anything: the solver keeps only the unknowns.

        Return None when the medium cannot differentiate the residual of this problem (e.g. a
        load, boundary or scheme it does not cover); the answer must depend on the problem
        only, not on the configuration.  ``solve_static(jacobian="auto")`` then falls back to
        coloured finite differences and ``jacobian="analytic"`` raises ``ValueError``.

        Parameters
        ----------
        scheme : Lattice
            The scheme the solver runs (its ``problem``, ``grid``, ``weights``, ``h``,
            ``edge_strains(state)`` ...).
        state : State
            The current iterate (``state.t`` the load time, ``state.S = 0``).
        lam : float
            Load factor λ ≥ 0 of the load step (continuation may pass λ beyond 1).

        Returns
        -------
        scipy.sparse matrix (or ndarray) of shape ``(nnode·r, nnode·r)``, or None
            ``nnode = prod(scheme.grid.shape)``.
        """
        return None

    def constrained_strains(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Strain components held at fixed values by Lagrange multipliers, or None (default).

        A medium whose strain X (paper §III.E: the adapted structure fields) has components
        fixed by the kinematics — an inextensible, unshearable Kirchhoff filament has
        ``θ = (1, 0, 0)``, components ``(0, 1, 2)`` of SE(3) — returns ``(components, values)``:
        integer indices ``k < r`` into the group's basis and their values.  On every edge of
        the lattice the statics (:func:`cartan.solve_static`, :func:`cartan.continuation`)
        then impose ``X_e[k] = value`` by one multiplier per edge and component; the multiplier
        is the edge stress ``Q_e[k]`` conjugate to the constrained strain, a reaction (the
        fictitious stress of §IV.E), not a constitutive stress.  The potential and the stress
        must therefore not depend on the constrained components (the statics check it).

        Returns
        -------
        None, or (components, values) : int array ``(c,)`` and float array ``(c,)``
        """
        return None

    def check_support(self, support: Any, end: str) -> None:
        """Refuse a support that this medium's equations do not admit (default: accept every one).

        Called by :class:`~cartan.problem.Problem` for each entry of its ``boundaries``, after
        the core's own checks (a :class:`~cartan.problem.Held` end's components are valid for
        the group).  A medium overrides it when a support is well formed but not a solution of
        its equations at an end (paper §IV.D: the end condition must be compatible with the
        medium's constraints), e.g. a ``Clamped`` end of the Nambu–Goto string, which would
        hold the time component of the worldsheet too.

        Parameters
        ----------
        support : Boundary
            The condition (``Free``, ``Clamped``, ``Held`` or ``Symmetry``).
        end : str
            Its key in ``boundaries`` (``"start"``, ``"u-end"``, ...).

        Raises
        ------
        ValueError
            Naming ``boundaries[end]`` and the support to use instead.
        """
        return None

    def held_strain_twins(self) -> tuple[HeldStrainTwin, ...]:
        """Approximate twins that hold some of this medium's strains by constraint (default: none).

        A medium whose strain components may be held at fixed values when they hardly move
        (the stretch and shear of a stiff rod, the transverse shear of a thin shell; paper
        §III.E, §VII) declares, for each such reduction, a :class:`HeldStrainTwin`: the
        registered twin medium, the held components and values, and the map of parameters.
        The medium declares data only; :mod:`cartan.advise` builds, measures and runs the twin.

        Returns
        -------
        tuple of HeldStrainTwin
            Empty when the medium has no such twin (or cannot have one with these parameters).
        """
        return ()

    #: names accepted by :meth:`make_load` and :meth:`initial_state` (for error messages and docs)
    load_kinds: ClassVar[tuple[str, ...]] = ()
    initial_kinds: ClassVar[tuple[str, ...]] = ()

    def make_load(self, kind: str, **params: Any):
        """Build a medium-specific load from a scene file entry (e.g. ``"gravity"``).

        The core handles the generic kinds (``"damping"``, ``"uniform-force"``); media add
        theirs here, typically :class:`~cartan.problem.PotentialLoad` subclasses.
        """
        raise ValueError(
            f"medium {self.name!r} has no load kind {kind!r}; available: {', '.join(self.load_kinds) or 'none'}"
        )

    def initial_state(self, grid, kind: str, **params: Any):
        """Build an :class:`~cartan.problem.InitialState` on ``grid`` from a named shape
        (e.g. ``"straight"``, ``"ring"``, ``"helix"``) with the given parameters."""
        raise ValueError(
            f"medium {self.name!r} has no initial state kind {kind!r}; "
            f"available: {', '.join(self.initial_kinds) or 'none'}"
        )

    #: extra per-frame outputs: ``{name: (long_name, units)}`` for a scalar or one value per
    #: node, ``{name: (long_name, units, dims)}`` for an array per node with the extra named
    #: dimensions ``dims`` (a tuple such as ``("row", "col")``); values come from :meth:`outputs`
    #: (checked by :func:`output_field_specs` and :func:`check_output_value`)
    output_fields: ClassVar[dict[str, tuple]] = {}
    #: optional labels of the extra dimensions of :attr:`output_fields`: ``{dim: labels}`` or
    #: ``{dim: (long_name, labels)}``, ``labels`` a sequence of distinct strings, one per index
    #: (``{"row": ["x", "y", "z"]}``); they become the dimension's coordinate in the Dataset
    output_coords: ClassVar[dict[str, Any]] = {}
    #: whether :meth:`outputs` takes the keyword ``reference``: the problem's stress-free
    #: reference at the nodes, ``{"q": q_ref [*shape, *point_shape], "X0": [*shape, d, r]}``
    #: (the nodal rest strains, averaged as the strains are), or None without one
    outputs_read_reference: ClassVar[bool] = False
    #: whether :meth:`outputs` takes the keyword ``time``: the run's time t of the frame (float)
    outputs_read_time: ClassVar[bool] = False

    def outputs(self, q: np.ndarray, X: np.ndarray, N: np.ndarray, grid: Any) -> dict[str, np.ndarray]:
        """Medium-specific diagnostics recorded in every saved frame (default: none).

        Parameters
        ----------
        q : array ``[*grid.shape, *point_shape]``
            Configuration q = Φ·q_r at the nodes.
        X : array ``[*grid.shape, d, r]``
            Strains at the nodes.
        N : array ``[*grid.shape, r]``
            Velocities at the nodes.
        grid : Grid
            The material grid (shape, spacing, periodic axes).

        Returns
        -------
        dict
            ``{name: value}`` for every name of :attr:`output_fields`; a value is a scalar
            (a time series in the output) or an array of shape ``grid.shape`` (a node field),
            and for a field declared with extra dimensions ``dims`` an array of shape
            ``(*grid.shape, *sizes)``, one size per name of ``dims`` (the length of its
            :attr:`output_coords` labels, when given).  The Dataset variable then has the
            dimensions ``(time, *node dimensions, *dims)``.
        """
        return {}

    def restart_record(self, recorded: dict[str, Any], arrays: list[str], path: str) -> dict[str, Any]:
        """The problem record of the restart file ``path`` (its checkpoint's ``problem``) in the
        form this medium records it now: :func:`cartan.simulate` compares it with the record of
        the problem it continues (default: ``recorded`` unchanged).

        A medium whose record changed form overrides it to read files written before — when
        the older record determines the parameter — or to raise ``ValueError`` saying what the
        file lacks and how to continue; never by guessing.  ``arrays`` are the names of the
        state arrays the checkpoint holds.
        """
        return recorded

    def accumulators(self) -> dict[str, tuple[str, str]]:
        """Per-node accumulators the run integrates along the time: ``{name: (long_name, units)}``
        (default: none).

        Each accumulator is ``a_i(t) = ∫₀ᵗ r_i dt`` with the rate ``r_i`` of
        :meth:`accumulator_rates`, integrated by the trapezoidal rule over every step,
        ``a ← a + ½Δt (r(before) + r(after))`` (second order in Δt): on the reference (numpy)
        path, or in the lattice's generated loops when the medium's point kernels declare the
        rates (:attr:`MediumKernels.accumulator_rate`; otherwise the compiled loops are not
        used for such a medium).  The values
        are part of the state (``state.arrays["accumulator_<name>"]``, zero at t = 0, in the
        checkpoint: a restart continues them exactly) and an output variable ``name``
        ``(time, *nodes)`` of every saved frame (:mod:`cartan.accumulators`).
        """
        return {}

    def accumulator_rates(self, q: np.ndarray, X: np.ndarray, N: np.ndarray, grid: Any) -> dict[str, np.ndarray]:
        """The rates ``{name: [*grid.shape]}`` of the :meth:`accumulators`, from the configuration
        q ``[*grid.shape, *point_shape]``, the nodal strains X ``[*grid.shape, d, r]`` and the
        velocities N ``[*grid.shape, r]`` (the arguments of :meth:`outputs`)."""
        raise NotImplementedError(f"medium {self.name!r} declares accumulators but no accumulator_rates")

    @classmethod
    def draw(cls, ds: Any, fig: Any) -> bool:
        """Draw a picture of a result of this medium into ``fig`` (default: none).

        ``cartan plot`` and :func:`cartan.plotting.plot_run` call this classmethod of the
        medium named in the file (:func:`cartan.plotting.medium_name`) before drawing their
        generic picture; a medium whose results read best in their own terms (a string's
        worldlines in the lab frame, say) overrides it.  No instance is made: the parameters
        of the run are in ``ds.attrs["cartan_config"]`` (JSON, ``problem.parameters``).

        Parameters
        ----------
        ds : xarray.Dataset
            A result of the medium: a run (frames along ``time``), a static equilibrium or
            a continuation path (:func:`cartan.plotting.result_kind`), as read from a file.
        fig : matplotlib.figure.Figure
            An empty figure (Agg canvas, constrained layout, 12 × 4.8 in; resize it with
            ``fig.set_size_inches``) to add axes to.  The caller saves it and, unless the
            method sets one, gives it the Dataset's ``title`` as ``suptitle``.

        Returns
        -------
        bool
            True when the picture is drawn; False (the default) leaves the result to the
            generic picture, in a new figure.
        """
        return False

    def kinetic_metric(self) -> np.ndarray:
        """The kinetic metric M, ``K(N) = ½ NᵀMN`` per unit reference volume, shape ``(r, r)``.

        Symmetric; it may be non-diagonal (a director with an offset centre of mass) and
        indefinite (a relativistic string: K = ½(−(N⁰)² + |N|²)); the rows and columns that
        are zero are gauge directions (paper §III.E).  Default: ``diag(inertia())``.  A medium
        that overrides it returns M's diagonal from :meth:`inertia`.  The Legendre map
        (:meth:`momentum`, :meth:`velocity`), the kinetic energy, the wave speed and the CFL
        estimate follow from M; ``lie-verlet`` splits the free flow along M's eigenvectors when
        M is not diagonal.
        """
        return np.diag(np.asarray(self.inertia(), dtype=float))

    def _diagonal_metric(self) -> bool:
        return type(self).kinetic_metric is Medium.kinetic_metric

    def inverse_metric(self) -> np.ndarray:
        """``M⁺``: the inverse of M on its live (non-gauge) block, zero on gauge rows and
        columns, shape ``(r, r)``; N = M⁺S."""
        M = np.asarray(self.kinetic_metric(), dtype=float)
        live = ~self.gauge_mask()
        A = np.zeros_like(M)
        if self._diagonal_metric():
            A[live, live] = 1.0 / np.diag(M)[live]
        else:
            A[np.ix_(live, live)] = np.linalg.inv(M[np.ix_(live, live)])
        return A

    def gauge_mask(self) -> np.ndarray:
        """Boolean ``(r,)``: True for components of N that are gauge (held at zero): the zero
        rows of the kinetic metric."""
        if self._diagonal_metric():
            return self.inertia() == 0
        return np.all(np.asarray(self.kinetic_metric()) == 0, axis=1)

    def kinetic(self, N: np.ndarray) -> np.ndarray:
        """``K(N) = ½ NᵀMN``, ``[..., r]`` → ``[...]``."""
        if self._diagonal_metric():
            return 0.5 * np.einsum("...k,k,...k->...", N, self.inertia(), N)
        return 0.5 * np.einsum("...k,kl,...l->...", N, self.kinetic_metric(), N)

    def momentum(self, N: np.ndarray) -> np.ndarray:
        """``S = ∂K/∂N = MN``, ``[..., r]`` → ``[..., r]``."""
        if self._diagonal_metric():
            return np.asarray(N) * self.inertia()
        return np.einsum("kl,...l->...k", self.kinetic_metric(), N)

    def velocity(self, S: np.ndarray) -> np.ndarray:
        """Inverse Legendre map N = M⁺S (gauge components zero), ``[..., r]`` → ``[..., r]``."""
        if self._diagonal_metric():
            m = self.inertia()
            safe = np.where(m > 0, m, 1.0)
            return np.where(m > 0, np.asarray(S) / safe, 0.0)
        return np.einsum("kl,...l->...k", self.inverse_metric(), S)

    # ------------------------------------------------------------------ coupled Lagrangians (optional)
    #: True when the reduced Lagrangian ℓ(N, X) couples velocity and strain (paper §IV: S = ∂ℓ/∂N
    #: depends on X, Q = −∂ℓ/∂X on N), so that it is not K(N) − U(X).  The medium then gives its
    #: Legendre map and Hamiltonian pointwise — :meth:`momentum_at`, :meth:`velocity_at`,
    #: :meth:`stress_with`, :meth:`hamiltonian` — and the schemes that support it
    #: (``Scheme.supports_coupled_lagrangian``: the ``lattice`` and the ``collocation`` for d = 1;
    #: ``Scheme.coupled_module`` discretises it) step the Hamiltonian
    #: system ``Φ̇ = ΦN``, ``Ṡ + ad*_N S = D*Q`` with ``N = ∂H/∂S(S, X)`` and ``Q = ∂H/∂X(S, X)``
    #: (docs/design.md, "Media whose Lagrangian couples N and X").  The integrators that split
    #: K(S) + U(X) (``lie-verlet``, ``rattle``) refuse it; ``implicit-midpoint`` runs it as a
    #: discrete Lagrangian method (symplectic).  ``rkmk4``, ``lie-euler`` and ``forward-euler``
    #: run it in the generated compiled loops when :meth:`point_kernels` declares the coupled
    #: kernels (:class:`MediumKernels`: ``coupled_velocity``, ``coupled_stress``) on the lattice,
    #: else (and on the collocation) on the numpy path.
    coupled_lagrangian: ClassVar[bool] = False

    def momentum_at(self, N: np.ndarray, X: np.ndarray) -> np.ndarray:
        """The Legendre map ``S = ∂ℓ/∂N(N, X)``, N ``[..., r]`` and X ``[..., d, r]`` → ``[..., r]``
        (default: :meth:`momentum`, X unused)."""
        return self.momentum(N)

    def velocity_at(self, S: np.ndarray, X: np.ndarray) -> np.ndarray:
        """The inverse Legendre map ``N = ∂H/∂S(S, X)``, S ``[..., r]`` and X ``[..., d, r]`` →
        ``[..., r]``, gauge components as the medium fixes them (default: :meth:`velocity`)."""
        return self.velocity(S)

    def stress_with(self, S: np.ndarray, X: np.ndarray) -> np.ndarray:
        """The Hamiltonian stress ``Q = ∂H/∂X(S, X) = −∂ℓ/∂X(N(S, X), X)``, ``[..., d, r]``
        (default: :meth:`stress`, S unused)."""
        return self.stress(X)

    def hamiltonian(self, S: np.ndarray, X: np.ndarray) -> np.ndarray:
        """The Hamiltonian density ``H(S, X) = ⟨S, N⟩ − ℓ(N, X)`` at ``N = N(S, X)``, ``[...]``
        (default: ``K(N(S)) + U(X)``)."""
        return self.kinetic(self.velocity(S)) + self.potential(X)

    def stiffness(self, X: np.ndarray | None = None, eps: float = 1e-6) -> np.ndarray:
        """Hessian ``∂Q/∂X`` at X (default: the rest strain), shape ``(d, r, d, r)``.

        Central differences of :meth:`stress`; media with closed forms may override.  Used
        for wave speeds and stability estimates.
        """
        X0 = self.rest_strain() if X is None else np.asarray(X, dtype=float)
        d, r = X0.shape
        H = np.empty((d, r, d, r))
        for a in range(d):
            for k in range(r):
                dX = np.zeros_like(X0)
                dX[a, k] = eps
                H[:, :, a, k] = (self.stress(X0 + dX) - self.stress(X0 - dX)) / (2 * eps)
        return H

    def wave_speed(self) -> float:
        """Fastest characteristic speed of the linearised medium about the rest state.

        For K = ½ NᵀMN and U with stiffness C: along each axis α the waves of
        ``M N̈ = C_αα ∂²N`` have speeds ``√|eig(M⁻¹ C_αα)|`` on the non-gauge components.
        """
        live = ~self.gauge_mask()
        Minv = self.inverse_metric()[np.ix_(live, live)]
        H = self.stiffness()
        c2 = 0.0
        for a in range(H.shape[0]):
            C = H[a, :, a, :][np.ix_(live, live)]
            # |eig|: an indefinite metric has waves of either sign of M⁻¹C
            c2 = max(c2, float(np.max(np.abs(np.real(np.linalg.eigvals(Minv @ C))))))
        return float(np.sqrt(max(c2, 0.0)))

    def __repr__(self) -> str:
        params = ", ".join(f"{k}={v!r}" for k, v in self.parameters().items())
        return f"{type(self).__name__}({params})"


#: dimension names an output field cannot use: the core's time and node dimensions and their coordinates
_RESERVED_DIMS = ("time", "step", "node", "edge", "u", "v", "w", "u_edge")


def _medium_label(medium: Any) -> str:
    return f"medium {getattr(medium, 'name', '') or type(medium).__name__!r}"


def output_field_specs(medium: Medium) -> dict[str, tuple[str, str, tuple[str, ...]]]:
    """The medium's :attr:`~Medium.output_fields`, checked and completed with their extra dimensions,
    followed by its :meth:`~Medium.accumulators` (node fields).

    Parameters
    ----------
    medium : Medium

    Returns
    -------
    dict
        ``{name: (long_name, units, dims)}`` in declaration order; ``dims = ()`` for a scalar
        or node field declared as ``(long_name, units)``.

    Raises
    ------
    ValueError
        Naming the medium and the field: an entry that is not ``(long_name, units)`` or
        ``(long_name, units, dims)`` with strings ``long_name`` and ``units``, or ``dims`` not a
        tuple of distinct non-empty names, or a name of the core's time and node dimensions
        (``time``, ``step``, ``node``, ``edge``, ``u``, ``v``, ``w``, ``u_edge``).
    """
    fields = dict(getattr(medium, "output_fields", None) or {})
    acc = medium.accumulators() if callable(getattr(medium, "accumulators", None)) else {}
    clash = sorted(set(acc) & set(fields))
    if clash:
        raise ValueError(f"{_medium_label(medium)}: accumulators {clash} are named like output fields")
    fields.update(acc)  # (an accumulator is written as a node field of every frame)
    out: dict[str, tuple[str, str, tuple[str, ...]]] = {}
    for name, entry in fields.items():
        where = f"{_medium_label(medium)}: output_fields[{name!r}]"
        if not isinstance(name, str) or not name:
            raise ValueError(f"{_medium_label(medium)}: output field names must be non-empty strings, got {name!r}")
        if not isinstance(entry, (tuple, list)) or len(entry) not in (2, 3):
            raise ValueError(f"{where} must be (long_name, units) or (long_name, units, dims), got {entry!r}")
        long_name, units = entry[0], entry[1]
        if not isinstance(long_name, str) or not isinstance(units, str):
            raise ValueError(f"{where}: long_name and units must be strings, got {entry[:2]!r}")
        dims: tuple[str, ...] = ()
        if len(entry) == 3:
            raw = entry[2]
            if isinstance(raw, str) or not isinstance(raw, (tuple, list)):
                raise ValueError(f"{where}: dims must be a tuple of dimension names such as ('row', 'col'), "
                                 f"got {raw!r}")
            dims = tuple(raw)
            bad = [d for d in dims if not isinstance(d, str) or not d]
            if bad:
                raise ValueError(f"{where}: dims must be non-empty strings, got {raw!r}")
            if len(set(dims)) != len(dims):
                raise ValueError(f"{where}: dims must be distinct, got {raw!r}")
            reserved = [d for d in dims if d in _RESERVED_DIMS]
            if reserved:
                raise ValueError(f"{where}: dims {reserved} are the core's time and node dimensions; "
                                 f"choose other names (not {', '.join(_RESERVED_DIMS)})")
        out[name] = (long_name, units, dims)
    return out


def output_coordinate_labels(medium: Medium) -> dict[str, tuple[str, tuple[str, ...]]]:
    """The medium's :attr:`~Medium.output_coords`, checked: ``{dim: (long_name, labels)}``.

    A value given as labels alone gets the long name ``"<dim> of the medium's output fields"``.
    Labels of a dimension no output field uses are kept (and unused).

    Raises
    ------
    ValueError
        Naming the medium and the dimension: labels that are not a non-empty sequence of
        distinct strings, or a long name that is not a string.
    """
    coords = getattr(medium, "output_coords", None) or {}
    if not isinstance(coords, dict):
        raise ValueError(f"{_medium_label(medium)}: output_coords must be a dict {{dim: labels}}, got {coords!r}")
    out: dict[str, tuple[str, tuple[str, ...]]] = {}
    for dim, value in coords.items():
        where = f"{_medium_label(medium)}: output_coords[{dim!r}]"
        long_name = f"{dim} of the medium's output fields"
        if (isinstance(value, tuple) and len(value) == 2 and isinstance(value[0], str)
                and not isinstance(value[1], str)):
            long_name, value = value
        if isinstance(value, str) or not isinstance(value, (tuple, list)):
            raise ValueError(f"{where} must be a list of labels (strings), or (long_name, labels), got {value!r}")
        labels = tuple(value)
        if not labels or not all(isinstance(v, str) for v in labels) or len(set(labels)) != len(labels):
            raise ValueError(f"{where} must be a non-empty list of distinct strings, got {value!r}")
        out[str(dim)] = (long_name, labels)
    return out


def check_output_value(medium: Medium, name: str, value: Any, shape: tuple[int, ...], dims: tuple[str, ...] = (),
                       labels: dict[str, tuple[str, tuple[str, ...]]] | None = None) -> np.ndarray:
    """One value returned by :meth:`Medium.outputs`, checked against its declaration, as a float array.

    Parameters
    ----------
    medium : Medium
        Named in the messages.
    name : str
        The output field.
    value : array_like
        A scalar or an array ``shape`` (``dims = ()``), else an array ``(*shape, *sizes)``.
    shape : tuple of int
        The grid's shape (the node dimensions).
    dims : tuple of str
        The field's extra dimensions (:func:`output_field_specs`).
    labels : dict, optional
        :func:`output_coordinate_labels`: a labelled dimension must have one index per label.

    Returns
    -------
    numpy.ndarray
        A float copy of ``value``.

    Raises
    ------
    ValueError
        Naming the medium and the field, when the shape does not fit the declaration.
    """
    arr = np.array(value, dtype=float)
    shape = tuple(int(n) for n in shape)
    where = f"{_medium_label(medium)}: output {name!r}"
    if not dims:
        if arr.ndim and arr.shape != shape:
            raise ValueError(f"{where} must be a scalar or one value per node, shape {shape}, got shape {arr.shape}")
        return arr
    lead, trailing = arr.shape[: len(shape)], arr.shape[len(shape):]
    if arr.ndim != len(shape) + len(dims) or lead != shape:
        raise ValueError(f"{where} declares the extra dimensions {dims}: it must have shape (*{shape}, "
                         f"{', '.join(f'n_{d}' for d in dims)}), got shape {arr.shape}")
    for dim, n in zip(dims, trailing, strict=True):
        known = (labels or {}).get(dim)
        if known is not None and len(known[1]) != n:
            raise ValueError(f"{where}: its dimension {dim!r} has {n} entries but output_coords[{dim!r}] has "
                             f"{len(known[1])} labels {list(known[1])}; trailing shape {trailing}")
    return arr


class QuadraticMedium(Medium):
    """A medium with a quadratic potential, the form of every linear-elastic Cartan medium:
    ``U(X) = ½ (X − X₀)ᵀ C (X − X₀)`` over the flattened strain ``X`` ``(d·r,)``.

    ``C`` is either one symmetric ``(r, r)`` matrix shared by every axis,
    ``U = ½ Σ_α (X_α − X₀_α)ᵀ C (X_α − X₀_α)`` and ``Q^α = C (X_α − X₀_α)`` (Cosserat rods
    §VI.C, rods on spheres §VIII.A, the sigma model §VIII.B), or a full symmetric
    ``(d·r, d·r)`` matrix whose off-diagonal blocks couple the axes (plates and shells, whose
    membrane energy couples θ_u and θ_v; micropolar solids with λ(tr ε)²).

    Subclasses call :meth:`_set_energy` in ``__init__`` and implement :meth:`inertia`; the
    potential, stress, stiffness, :meth:`quadratic_energy` and the point kernels of the
    compiled loops (:meth:`point_kernels`) follow.
    """

    def _set_energy(self, X0: Any, C: Any) -> None:
        """Set the rest strain ``X0`` ``(d, r)`` (or ``(r,)`` for d = 1) and the stiffness ``C``:
        a symmetric ``(r, r)`` matrix or its diagonal ``(r,)`` (the same on every axis), or a
        symmetric ``(d·r, d·r)`` matrix over the flattened strain (axes coupled)."""
        r = self.group.dim
        X0 = np.asarray(X0, dtype=float).reshape(-1, r)
        d = X0.shape[0]
        C = np.asarray(C, dtype=float)
        C = np.diag(C) if C.ndim == 1 else C
        scale = 1e-12 * max(1.0, float(np.abs(C).max())) if C.size else 1.0
        if C.shape not in ((r, r), (d * r, d * r)) or not np.allclose(C, C.T, rtol=0, atol=scale):
            raise ValueError(
                f"the stiffness must be a symmetric ({r}, {r}) or ({d * r}, {d * r}) matrix, got shape {C.shape}")
        if C.shape == (r, r):
            self._X0, self._C = X0, C
            self._Cfull = np.kron(np.eye(d), C)
        else:
            blocks = C.reshape(d, r, d, r)
            same = all(np.array_equal(blocks[a, :, a, :], blocks[0, :, 0, :]) for a in range(d))
            off = all(not np.any(blocks[a, :, b, :]) for a in range(d) for b in range(d) if a != b)
            self._X0, self._Cfull = X0, C
            self._C = blocks[0, :, 0, :].copy() if same and off else None

    def rest_strain(self) -> np.ndarray:
        return self._X0.copy()

    def potential(self, X: np.ndarray) -> np.ndarray:
        D = np.asarray(X, dtype=float) - self._X0
        if self._C is not None:
            return 0.5 * np.einsum("...ak,kl,...al->...", D, self._C, D)
        F = D.reshape(*D.shape[:-2], -1)
        return 0.5 * np.einsum("...k,kl,...l->...", F, self._Cfull, F)

    def stress(self, X: np.ndarray) -> np.ndarray:
        D = np.asarray(X, dtype=float) - self._X0
        if self._C is not None:
            return np.einsum("kl,...al->...ak", self._C, D)
        F = D.reshape(*D.shape[:-2], -1)
        return np.einsum("kl,...l->...k", self._Cfull, F).reshape(D.shape)

    def potential_at(self, X: np.ndarray, X0: np.ndarray) -> np.ndarray:
        F = (np.asarray(X, dtype=float) - X0).reshape(*np.shape(X)[:-2], -1)
        return 0.5 * np.einsum("...k,kl,...l->...", F, self._Cfull, F)

    def stress_at(self, X: np.ndarray, X0: np.ndarray) -> np.ndarray:
        D = np.asarray(X, dtype=float) - X0
        return np.einsum("kl,...l->...k", self._Cfull, D.reshape(*D.shape[:-2], -1)).reshape(D.shape)

    def stiffness(self, X: np.ndarray | None = None, eps: float = 1e-6) -> np.ndarray:
        """``∂Q/∂X``, shape ``(d, r, d, r)`` (exact; X and eps are unused)."""
        d, r = self._X0.shape
        return self._Cfull.reshape(d, r, d, r).copy()

    def point_kernels(self) -> MediumKernels | None:
        """:func:`quadratic_energy_point` and :func:`quadratic_stress_point` with the full
        ``(d·r, d·r)`` stiffness as parameters: the energy :meth:`_set_energy` declared.  None
        when a subclass replaces that energy (overrides ``potential``, ``stress`` or
        ``rest_strain``) without declaring its own kernels."""
        if any(getattr(type(self), name) is not getattr(QuadraticMedium, name)
               for name in ("potential", "stress", "rest_strain")):
            return None
        return MediumKernels(quadratic_energy_point, quadratic_stress_point, self._Cfull.ravel().copy())

    def quadratic_energy(self) -> tuple[np.ndarray, np.ndarray] | None:
        """``(X₀, C)`` for d = 1; None for d ≥ 2, where the compiled lattice loops read the
        rest strain per axis and ``C`` of a :class:`QuadraticMedium` directly (when it does
        not override the energy methods); None when the stiffness couples the axes."""
        if self._X0.shape[0] != 1 or self._C is None:
            return None
        return self._X0[0].copy(), self._C.copy()


class KernelMedium(Medium):
    """A medium whose potential is written once, as numba point kernels.

    Subclasses implement :meth:`point_kernels` (:class:`MediumKernels`), :meth:`inertia` and
    :meth:`rest_strain`; :meth:`potential`, :meth:`stress` and their ``_at`` forms (a rest
    strain that varies over the body) evaluate the kernels over any batch of points, so the
    numpy reference path and the compiled loops run the same formulas.  ``docs/plugins.md``
    has a complete example.
    """

    @abc.abstractmethod
    def point_kernels(self) -> MediumKernels:
        """The energy density and stress at one point (see :class:`MediumKernels`)."""

    def _batch(self, which: str, X: np.ndarray, X0: np.ndarray) -> np.ndarray:
        from .compiled.kernels import medium_batch

        X = np.asarray(X, dtype=float)
        d, r = X.shape[-2:]
        lead = np.broadcast_shapes(X.shape[:-2], np.shape(X0)[:-2])
        Xf = np.ascontiguousarray(np.broadcast_to(X, (*lead, d, r))).reshape(-1, d, r)
        X0f = np.ascontiguousarray(np.broadcast_to(X0, (*lead, d, r))).reshape(-1, d, r)
        kernels = self.point_kernels()
        params = np.ascontiguousarray(kernels.params, dtype=float).ravel()
        module = medium_batch(kernels)
        if which == "energy":
            out = np.empty(Xf.shape[0])
            module.energy_batch(Xf, X0f, params, out)
            return out.reshape(lead)
        out = np.empty_like(Xf)
        module.stress_batch(Xf, X0f, params, out)
        return out.reshape(*lead, d, r)

    def potential(self, X: np.ndarray) -> np.ndarray:
        return self._batch("energy", X, np.asarray(self.rest_strain(), dtype=float))

    def stress(self, X: np.ndarray) -> np.ndarray:
        return self._batch("stress", X, np.asarray(self.rest_strain(), dtype=float))

    def potential_at(self, X: np.ndarray, X0: np.ndarray) -> np.ndarray:
        return self._batch("energy", X, X0)

    def stress_at(self, X: np.ndarray, X0: np.ndarray) -> np.ndarray:
        return self._batch("stress", X, X0)
