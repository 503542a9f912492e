"""A runnable problem: medium × grid × boundaries × loads × initial state.

Everything here is generic over the group and the medium.  A problem is built in Python::

    problem = cartan.Problem(
        medium=cartan.medium("cosserat-rod", ...),
        grid=cartan.Grid(101, length=1.0),
        boundaries={"start": cartan.Clamped(), "end": cartan.Free(load=[0, 0, -1, 0, 0, 0])},
        loads=[...],
        initial=cartan.InitialState(Phi=..., N=...),
    )

or from a TOML scene file (:func:`cartan.load_scene`).

Boundary conditions (paper §IV.D, ``n_α Q^α = P`` on ∂M) are given per end of each open
axis: ``"start"``/``"end"`` for d = 1 (or ``"u-start"``, ``"v-end"``, … in general).
"""

from __future__ import annotations

import abc
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .grid import Grid
from .medium import Medium, check_finite, check_positive, pullback_gradient

__all__ = [
    "Boundary",
    "Clamped",
    "ConstantFieldPotential",
    "Damping",
    "Driven",
    "Free",
    "Held",
    "InitialState",
    "Load",
    "NodeForce",
    "PotentialLoad",
    "Problem",
    "Symmetry",
    "UniformForce",
    "held_components",
]


# ---------------------------------------------------------------------------- validation
def _numeric(name: str, value: Any) -> Any:
    """``value`` if it is numeric data (numbers or arrays of them); a ValueError naming ``name``
    for strings, booleans and other objects, which ``np.asarray(value, float)`` would convert."""
    arr = np.asarray(value) if not isinstance(value, str | bytes) else None
    if arr is None or arr.dtype.kind not in "iuf":
        raise ValueError(f"{name} must be a real number or an array of real numbers, got {value!r}")
    return value


def _flag(name: str, value: Any) -> bool:
    """``value`` as a bool when it is one (Python or numpy); a ValueError naming ``name`` otherwise."""
    if not isinstance(value, bool | np.bool_):
        raise ValueError(f"{name} must be True or False, got {value!r}")
    return bool(value)


# ---------------------------------------------------------------------------- boundaries
class Boundary:
    """Condition at one end of an open material axis (base of :class:`Free`, :class:`Clamped`)."""

    kind: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind}


@dataclass
class Free(Boundary):
    """Free end with an applied generalised load P ∈ 𝔤* (n_α Q^α = P, paper §IV.D).

    Parameters
    ----------
    load : array_like, shape ``(r,)``
        Components of P in the dual basis (for SE(3): force then moment).
    follower : bool
        True: ``load`` is fixed in the body frame (a follower load).  False (default): it
        is a dead load fixed in the spatial frame at the material point; its body components
        are ``Ad_{R}ᵀ P`` with R the rotational part of Φ at the end.
    """

    load: Any = None
    follower: bool = False
    kind: str = field(default="free", init=False)

    def __post_init__(self):
        self.follower = _flag("follower", self.follower)
        if self.load is not None:
            load = check_finite("load", _numeric("load", self.load))
            if load.ndim != 1:
                raise ValueError(f"load must be a vector of load components, got shape {load.shape}")

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "free", "load": None if self.load is None else np.asarray(self.load).tolist(),
                "follower": self.follower}


@dataclass
class Clamped(Boundary):
    """Clamped end: Φ held at its initial value (N = 0, S = 0 at the end node)."""

    kind: str = field(default="clamped", init=False)


@dataclass
class Driven(Boundary):
    """Driven end: a clamp that moves with a prescribed constant body velocity ξ ∈ 𝔤, so that
    the end's frame is Φ(t) = Φ(0)·exp(tξ) exactly (paper §IV.D: a time-dependent Dirichlet
    condition on Φ; the end's momentum is the reaction's).

    At the end node (every node of the face for d ≥ 2) the velocity is N = ξ and the momentum
    S = ∂K/∂N(ξ) at every step; the force there is not applied: the support supplies whatever
    holds the end on its prescribed motion, the reaction ``R = −w(W + ad_ξᵀ S)`` (W the force
    density the rest of the body, the loads and the boundary put on the node, w its weight;
    :meth:`cartan.schemes.base.Scheme.support_reaction`).  Its power ``R·ξ = −w W·ξ`` is booked
    as external work, so that the energy balance of a run closes.  ``velocity = 0`` is
    :class:`Clamped`.  A rate of twist ω about the end's tangent d₁ of an SE(3) rod is
    ``Driven(velocity=[0, 0, 0, ω, 0, 0])``.

    Parameters
    ----------
    velocity : array_like, shape ``(r,)``
        ξ in the basis of 𝔤 (for SE(3): linear then angular velocity), in the body frame of the
        end node; constant in time, finite, zero on the medium's gauge components.

    Notes
    -----
    Runs on the ``lattice`` scheme (its numpy path and the generated loops of its operator set;
    its hand-written rod loops decline a driven end) and on the ``collocation`` scheme's numpy
    path (its compiled operators decline it; frames stepped by default, the driven node's
    strain drifted by the same Lie group integrator, docs/schemes.md "Driven ends") with the
    integrators that move the end by exactly
    exp(Δtξ) per step: ``lie-euler``, ``rkmk4``, ``overdamped``, ``implicit-midpoint``,
    ``lie-verlet`` and ``rattle`` (the latter two when ξ's parts in the split free flow commute,
    e.g. a rotation about one body axis, any translation, and with a diagonal kinetic metric;
    ``rattle`` with the driven velocity in its constraint rows); the others refuse it
    (``ValueError`` naming the integrator).
    In the statics a driven end is a clamp at its initial frame.  On a face of a d ≥ 2 grid every
    node turns by Φᵢ(0)·exp(tξ): a rigid motion of the face when ξ is a translation and the
    frames are equal, or a rotation about an axis through every node (a plate's edge turned about
    its own line).
    """

    velocity: Any = None
    kind: str = field(default="driven", init=False)

    def __post_init__(self):
        if self.velocity is None:
            raise ValueError("velocity must be given: the end's body velocity ξ, a vector of r finite components "
                             "(for SE(3): [v1, v2, v3, w1, w2, w3])")
        v = check_finite("velocity", _numeric("velocity", self.velocity))
        if v.ndim != 1 or v.size == 0:
            raise ValueError(f"velocity must be a vector of r components (the dimension of the group), got shape "
                             f"{v.shape}")
        self.velocity = np.asarray(v, dtype=float)

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "driven", "velocity": np.asarray(self.velocity, dtype=float).tolist()}


@dataclass
class Held(Boundary):
    """End whose node holds chosen components of its body velocity N at zero: a support for any
    medium (paper §IV.D), exact, not a penalty.

    At the end node (every node of the face for d ≥ 2) the components ``components`` of N, of
    the momentum S and of the force are zero (the reaction); the other components obey the end
    node's balance with no applied load (the natural condition n_α Q^α = 0 on them, as on a
    free end).  The node moves by Φ̇ = ΦN with N in 𝔥 = span{e_k : k free and live} (live: the
    non-gauge components, :meth:`cartan.medium.Medium.gauge_mask`), which must be a
    subalgebra: the node then stays on the coset Φ̄·exp(𝔥) of its initial Φ̄, a holonomic
    support (a set of held components whose free ones do not close under the bracket would be
    a non-holonomic constraint, refused).  Clamped is the case of every component held.

    Examples: SE(3) ``(0, 1, 2)``, a pinned end (a ball joint: the position held, the frame
    free; ``(3, 4, 5)``: the frame held, the position free).  Poincaré (``relativistic-rod``)
    ``(1, 2, 3)``: an end fixed in space in its frame Λ whose time component r⁰ evolves (the
    Lorentz part of the Nambu–Goto string is gauge): the fixed end of the Nambu–Goto string
    (docs/media/relativistic-rod.md, "Fixed ends").

    Parameters
    ----------
    components : sequence of int
        The indices k ∈ [0, r) of N held at zero (r = the group's dimension), at least one,
        no repeats; in the body frame of the end node (its structure field's frame, which the
        held components keep when they include the frame's rotations).

    Notes
    -----
    The scheme holds the components like a clamp holds all of them (the ``lattice``: its numpy
    path and its generated compiled operators, every integrator, ``solve_static``; the
    ``collocation`` scheme's numpy path; the ``kinematic`` compiled loop, the collocation's
    compiled operators and ``rattle`` on the collocation scheme decline it).  The
    held momentum components are those of the reaction only when the kinetic metric does not
    couple them with the free live ones (checked).
    """

    components: Any = None
    kind: str = field(default="held", init=False)

    def __post_init__(self):
        c = self.components
        if isinstance(c, numbers.Integral) and not isinstance(c, bool | np.bool_):
            c = [c]
        try:
            items = list(c)
        except TypeError:
            items = None
        if (not items or any(isinstance(k, bool | np.bool_) or not isinstance(k, numbers.Integral) for k in items)
                or any(int(k) < 0 for k in items) or len(set(int(k) for k in items)) != len(items)):
            raise ValueError(f"components must be a non-empty sequence of distinct integers k ≥ 0 (indices of N held "
                             f"at zero), got {self.components!r}")
        self.components = tuple(sorted(int(k) for k in items))

    def mask(self, medium: Medium, name: str = "held") -> np.ndarray:
        """The held components ``(r,)`` bool for ``medium``'s group, checked.

        Raises
        ------
        ValueError
            A component outside [0, r); free live components that do not span a subalgebra;
            a kinetic metric coupling held and free live components.
        """
        g = medium.group
        r = g.dim
        bad = [k for k in self.components if k >= r]
        if bad:
            raise ValueError(f"boundaries[{name!r}]: components must be in [0, {r}) (the dimension of {g.name}), "
                             f"got {bad}")
        held = np.zeros(r, dtype=bool)
        held[list(self.components)] = True
        live = ~np.asarray(medium.gauge_mask(), dtype=bool)
        free = np.flatnonzero(live & ~held)
        if free.size > 1:
            # ad_{e_a} for every basis element, [r(a), r, r] (the group's numpy reference: no kernel
            # is compiled for a check run once per problem)
            ad = np.asarray(g._ad(np.eye(r)), dtype=float)
            outside = np.flatnonzero(~np.isin(np.arange(r), free))
            leak = np.abs(ad[np.ix_(free, outside, free)])  # components of [e_a, e_b] off the free span
            if leak.size and float(np.max(leak)) > 1e-12:
                a, k, b = np.unravel_index(np.argmax(leak), leak.shape)
                raise ValueError(
                    f"boundaries[{name!r}]: the free components {free.tolist()} do not span a subalgebra "
                    f"([e_{int(free[a])}, e_{int(free[b])}] has a component along e_{int(outside[k])}); a Held end "
                    "must leave free a set closed under the bracket (a holonomic support)")
        metric = np.asarray(medium.kinetic_metric(), dtype=float)
        if metric.shape == (r, r) and np.any(metric[np.ix_(held & live, free)]):
            raise ValueError(f"boundaries[{name!r}]: the kinetic metric of {medium.name!r} couples the held components "
                             "with the free ones; not supported")
        return held

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "held", "components": list(self.components)}


_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


@dataclass
class Symmetry(Boundary):
    """Symmetry (mirror, roller) face of a medium on SE(3): the face is the mirror plane of a
    symmetric body whose other half is not modelled.

    Under the mirror P = I − 2 n nᵀ of the plane with unit normal n a displacement u (a vector)
    maps to P u and a micro-rotation φ (a pseudovector) to −P φ.  A mirror-symmetric field takes
    at a point of the plane the value it maps to, so there

        u·n = 0  and  φ × n = 0  (φ ∥ n):

    the face's nodes slide in the plane and their frames turn about n only, R R̄ᵀ a rotation
    about n.  The reactions are the normal force and the two in-plane couples; the in-plane
    tractions and the couple about n vanish (natural conditions, as on a free face).

    Exact, not a penalty (compare :class:`cartan.supports.SymmetrySupport`): with R̄ the face
    node's initial frame and m = R̄ᵀn its body-frame normal, the body velocities (and static
    increments) that keep the conditions are ξ = (v, ω) with m·v = 0 and ω ∥ m, a subalgebra
    ≅ se(2) whose exponential keeps Rᵀn = m and n·x exactly.  When m is a frame axis ±e_k at each
    face node the scheme holds the components v_k and ω_j (j ≠ k) at zero like a clamp holds all
    six: zero body velocity, momentum and force there (the reaction), for every integrator of the
    numpy path, ``solve_static`` and ``continuation``.  The held momentum components are those of
    the reaction only when the kinetic metric does not couple them with the free ones (a
    diagonal metric, checked).

    Parameters
    ----------
    normal : str or array_like, shape ``(3,)``, optional
        The plane's spatial normal: ``"x"``, ``"y"``, ``"z"`` or a non-zero vector (normalised).
        Default: the face's conormal R̄ m at its nodes, m the part of the rest strain's
        translation along the face's axis orthogonal to those along the other axes (for a block
        of frames R̄ = I on a box, the face's normal; for a rod, its tangent).

    Notes
    -----
    The face's initial nodes must lie in one plane n·x = c, and R̄ᵀn must be a frame axis
    (to 1e-9) at each of them (ValueError otherwise).  A medium on SE(3) only.
    """

    normal: Any = None
    kind: str = field(default="symmetry", init=False)

    def __post_init__(self):
        if self.normal is None:
            return
        if isinstance(self.normal, str):
            if self.normal not in _AXES:
                raise ValueError(f"normal must be 'x', 'y', 'z', a non-zero vector (3,) or None, got {self.normal!r}")
            n = np.array(_AXES[self.normal])
        else:
            n = check_finite("normal", _numeric("normal", self.normal), (3,))
            if not np.linalg.norm(n) > 0.0:
                raise ValueError(f"normal must be 'x', 'y', 'z', a non-zero vector (3,) or None, got {self.normal!r}")
        self.normal = n / np.linalg.norm(n)

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "symmetry", "normal": None if self.normal is None else np.asarray(self.normal).tolist()}


def held_components(problem: Problem) -> np.ndarray | None:
    """The body-velocity components held at zero by the problem's :class:`Symmetry` faces and
    :class:`Held` ends, ``(*grid.shape, r)`` bool (clamped ends not included), or None without
    either.

    At a node of a symmetry face with body-frame normal m = R̄ᵀn = ±e_k (R̄ its initial frame):
    the translation component k and the rotation components j ≠ k (:class:`Symmetry`); at a
    node of a held end, its ``components`` (:class:`Held`).  A node on several faces holds the
    union (on the edge of two planes it moves along the edge only).
    """
    grid = problem.grid
    faces = [(axis, side, problem.boundary(axis, side)) for axis in range(grid.d)
             if not (grid.periodic[axis] or grid.is_glued(axis)) for side in ("start", "end")]
    held_ends = [(axis, side, b) for axis, side, b in faces if isinstance(b, Held)]
    faces = [(axis, side, b) for axis, side, b in faces if isinstance(b, Symmetry)]
    if not faces and not held_ends:
        return None
    g = problem.medium.group
    held = np.zeros((*grid.shape, g.dim), dtype=bool)
    for axis, side, b in held_ends:
        sl = [slice(None)] * grid.d
        sl[axis] = 0 if side == "start" else -1
        held[tuple(sl)] |= b.mask(problem.medium, f"{grid.axis_names[axis]}-{side}")
    if not faces:
        return held
    if g.dim != 6 or g.matrix_size != 4 or not getattr(g, "affine", False):
        raise ValueError(f"boundaries: a Symmetry face needs a medium on SE(3) (positions and rotations); medium "
                         f"{problem.medium.name!r} is on {g.name}")
    metric = np.asarray(problem.medium.kinetic_metric(), dtype=float)
    Phi = np.asarray(problem.initial.Phi, dtype=float)
    X0 = np.asarray(problem.medium.rest_strain(), dtype=float).reshape(grid.d, -1)[:, :3]
    for axis, side, b in faces:
        name = f"{grid.axis_names[axis]}-{side}"
        sl = [slice(None)] * grid.d
        sl[axis] = 0 if side == "start" else -1
        F = Phi[tuple(sl)].reshape(-1, 4, 4)
        x, R = F[:, 1:, 0], F[:, 1:, 1:]
        if b.normal is None:
            t = X0[axis]
            others = np.delete(X0, axis, axis=0)
            if others.size:
                q, _ = np.linalg.qr(others.T)
                t = t - q @ (q.T @ t)
            if not np.linalg.norm(t) > 1e-12:
                raise ValueError(f"boundaries[{name!r}]: the rest strain gives the face no conormal; "
                                 "give Symmetry(normal=...)")
            nn = np.einsum("nij,j->ni", R, t / np.linalg.norm(t))
            n = nn[0]
            if float(np.max(np.abs(nn - n))) > 1e-9:
                raise ValueError(f"boundaries[{name!r}]: the face's conormals R̄m differ between its nodes (by "
                                 f"{float(np.max(np.abs(nn - n))):.2e}); a Symmetry face is a plane: give normal=")
        else:
            n = np.asarray(b.normal, dtype=float)
        c = x @ n
        scale = max(1.0, float(np.max(np.abs(x))))
        if float(np.ptp(c)) > 1e-9 * scale:
            raise ValueError(f"boundaries[{name!r}]: the face's nodes are not in one plane ⊥ n = {n.round(6).tolist()} "
                             f"(n·x spans {float(np.ptp(c)):.2e}); a Symmetry face is a mirror plane")
        m = np.einsum("nji,j->ni", R, n)  # R̄ᵀ n per node
        k = np.argmax(np.abs(m), axis=1)
        off = float(np.max(1.0 - np.abs(m[np.arange(len(k)), k])))
        if off > 1e-9:
            raise ValueError(f"boundaries[{name!r}]: the plane's normal n = {n.round(6).tolist()} is not a frame axis "
                             f"at every face node (R̄ᵀn off a frame axis by {off:.2e}); a Symmetry face holds body "
                             "components and needs R̄ᵀn = ±e_k")
        comp = np.zeros((len(k), 6), dtype=bool)
        comp[np.arange(len(k)), k] = True       # v·m = 0
        comp[:, 3:] = True
        comp[np.arange(len(k)), 3 + k] = False  # ω ∥ m
        view = held[tuple(sl)].reshape(-1, 6)
        held[tuple(sl)] = (view | comp).reshape(held[tuple(sl)].shape)
        if metric.shape == (6, 6):
            for kk in np.unique(k):
                h = comp[k == kk][0]
                if np.any(metric[np.ix_(h, ~h)]):
                    raise ValueError(f"boundaries[{name!r}]: the kinetic metric of {problem.medium.name!r} couples "
                                     "the held components of a Symmetry face with its free ones; not supported")
    return held


# ---------------------------------------------------------------------------- loads
class Load(abc.ABC):
    """An external or dissipative generalised force density.

    ``force(Phi, N, t)`` returns T ``[..., r]`` per unit reference volume; ``Phi`` is None
    when the load does not need the structure field (:attr:`needs_structure_field`).
    Each load reports its power contribution so that the energy balance closes:
    :attr:`conservative` loads contribute :meth:`energy` to the potential energy, dissipative
    loads (:attr:`dissipative`) to the dissipated energy, the others to the external work.

    In statics and continuation the loads are multiplied by the load parameter λ, except a
    load with :attr:`scaled` False: a support (an elastic spring holding the body) acts at every
    λ, so that a body held only by it is supported from λ = 0 on.

    A load density at a point depends on the frame there only (:attr:`local` True, paper
    §IV.B); a load whose value at a node reads its neighbours along the grid axes (a pressure on
    the deformed area, whose tangents are differences of positions) sets :attr:`local` False,
    and the statics' Jacobian then differences it on the lattice's stencil with the internal
    forces instead of node by node.
    """

    needs_structure_field: bool = False
    conservative: bool = False
    dissipative: bool = False
    velocity_dependent: bool = False
    scaled: bool = True
    local: bool = True

    def bind(self, medium: Medium) -> None:  # noqa: B027 - optional hook
        """Called once with the medium before a run (validate shapes against its group)."""

    def measure(self, volumes: np.ndarray) -> None:  # noqa: B027 - optional hook
        """Called by a scheme on a general chart with its nodes' reference volumes per unit
        chart volume, ``volumes`` ``(*grid.shape)`` (``w_i J_i``: the weights it multiplies every
        load density by; :meth:`cartan.medium.Medium.reference_volume`).  A load that is not a
        density (a point force) takes its node's volume here.  Default: nothing."""

    def attach(self, problem: Problem) -> None:  # noqa: B027 - optional hook
        """Called by every :class:`Problem` holding the load, once it is built (after :meth:`bind`).

        A load whose data come from the problem — its grid (a pressure differencing the node
        positions), the initial state and its holonomy, the initial positions it holds — takes
        them here, so that it can be built from a scene's ``[[loads]]`` table, which knows
        neither.  Raise ``ValueError`` (naming the parameter) when the load does not fit the
        problem; ``Problem`` reports it as ``loads[i]: ...``.  The hook may run again for a new
        problem with the same loads (``solve_static`` from another start): keep what the caller
        gave explicitly and refresh only what was taken from a problem.  Default: nothing.
        """

    @abc.abstractmethod
    def force(self, Phi: np.ndarray | None, N: np.ndarray, t: float) -> np.ndarray:
        """Generalised force density ``[..., r]``."""

    def energy(self, Phi: np.ndarray | None) -> np.ndarray:
        """Potential energy density ``[...]`` of a conservative load (0 otherwise)."""
        return np.zeros(np.shape(Phi)[:-2] if Phi is not None else ())

    def jacobian_parts(self, Phi: np.ndarray, t: float) -> tuple[Any, np.ndarray, np.ndarray] | None:
        """The statics' Jacobian of a load that reads beyond the lattice's stencil (``local``
        False, e.g. through a mean over every node), or None (default: the statics difference
        :meth:`force` on the stencil).

        The Jacobian of the force density T_i along the drifts Φ_j ← Φ_j exp(η_j) is split as

            ∂T_i/∂η_j = ∂T̃_i/∂η_j + Σ_k U[i, :, k] ⊗ V[j, :, k],

        T̃ = ``frozen(Φ')`` the force with its global quantities held at their values at ``Phi``
        (it reads the stencil only: the statics difference it there) and U Vᵀ the rank-k rest
        (the statics solve with it by the Sherman–Morrison–Woodbury identity, never forming it).

        Parameters
        ----------
        Phi : array ``[*shape, m, m]``
            The configuration.
        t : float
            Time at which the load is evaluated.

        Returns
        -------
        (frozen, U, V) or None
            ``frozen``: callable ``Phi' → [*shape, r]``; U, V ``[*shape, r, k]`` (U per unit
            reference volume, as :meth:`force`).
        """
        return None

    def to_dict(self) -> dict[str, Any]:
        return {"kind": type(self).__name__}


class PotentialLoad(Load):
    """A configurational potential U(q), q = Φ·q_r, pulled back to 𝔤* by the core.

    Subclasses implement :meth:`potential_energy` (U per unit reference volume) and
    :meth:`potential_gradient` (∂U/∂q, the same shape as a point of the medium's space);
    the force ``T_i = −⟨∂U/∂q, (Φ b_i)·q_r⟩`` follows (paper §IV.B).
    """

    needs_structure_field = True
    conservative = True

    def bind(self, medium: Medium) -> None:
        self._group = medium.group
        self._space = medium.space

    @abc.abstractmethod
    def potential_energy(self, q: np.ndarray) -> np.ndarray:
        """U(q) ``[...]``."""

    @abc.abstractmethod
    def potential_gradient(self, q: np.ndarray) -> np.ndarray:
        """∂U/∂q ``[..., *point_shape]``."""

    def _q(self, Phi: np.ndarray) -> np.ndarray:
        return self._space.act(Phi, self._space.q_r)

    def force(self, Phi, N, t):
        return pullback_gradient(self._group, self._space, Phi, self.potential_gradient(self._q(Phi)))

    def energy(self, Phi):
        return self.potential_energy(self._q(Phi))


class ConstantFieldPotential(PotentialLoad):
    """A uniform field acting on position: ``U(q) = −density·(f · x)`` per unit reference volume.

    ``x`` is the position of the configuration q = Φ·q_r in the space the (affine) group acts
    on — the translation part of Φ, for spaces whose reference point has zero translation
    (frame bundles with ``q_r = I``, E³ with ``q_r = 0``, point-director spaces).  Gravity is
    the example: ``f = g``, ``density = ρA``.  The core's pull-back gives the generalised force
    ``T = (Rᵀ density f, 0)``: a force density ``density·f`` fixed in space, expressed in the
    body frame (R the rotational part of Φ), and no moment.

    Parameters
    ----------
    field : array_like, shape ``(k,)``
        The field f in the spatial frame, k the dimension of the space the group acts on
        (3 for SE(3), 2 for SE(2)).
    density : float
        The density it acts on (mass per unit reference volume for gravity).
    """

    def __init__(self, field: Any, density: float):
        self.field = check_finite("field", field)
        if self.field.ndim != 1:
            raise ValueError(f"field must be a vector, got shape {self.field.shape}")
        self.density = float(check_finite("density", density, ()))

    def bind(self, medium: Medium) -> None:
        super().bind(medium)
        g = medium.group
        if not getattr(g, "affine", False):
            raise ValueError(f"{type(self).__name__} needs an affine group (positions), not {g.name}")
        k = g.space_dim
        if self.field.shape != (k,):
            raise ValueError(f"field must have shape ({k},) for medium {medium.name!r}, got {self.field.shape}")
        space = medium.space
        q_r = None if space is None else np.asarray(space.q_r, dtype=float)
        if q_r is None or not (q_r.shape == (k + 1, k + 1) or (q_r.ndim == 1 and q_r.shape[0] >= k)):
            raise ValueError(f"{type(self).__name__} needs a space whose points carry a position")
        self._matrix_points = q_r.ndim == 2
        # the position of Φ·q_r must be the translation of Φ (reference point at the origin)
        Phi = g.exp(np.linspace(0.3, 0.9, g.dim))
        if not np.allclose(self.position(space.act(Phi, q_r)), Phi[1:, 0], rtol=1e-12, atol=1e-12):
            raise ValueError(
                f"{type(self).__name__} needs a reference point at the origin: the position of Φ·q_r "
                f"must be the translation of Φ (space {getattr(space, 'name', '')!r})"
            )

    def _matrix(self, q: np.ndarray) -> bool:
        """True when points are (k+1) × (k+1) matrices (frame bundles), False for vectors."""
        k = self.field.shape[0]
        return getattr(self, "_matrix_points", q.ndim >= 2 and q.shape[-2:] == (k + 1, k + 1))

    def position(self, q: np.ndarray) -> np.ndarray:
        """Position ``x`` ``[..., k]`` of points q ``[..., *point_shape]``."""
        q = np.asarray(q, dtype=float)
        return q[..., 1:, 0] if self._matrix(q) else q[..., : self.field.shape[0]]

    def potential_energy(self, q: np.ndarray) -> np.ndarray:
        """``U = −density f·x``, ``[..., *point_shape]`` → ``[...]``."""
        return -self.density * np.einsum("...i,i->...", self.position(q), self.field)

    def potential_gradient(self, q: np.ndarray) -> np.ndarray:
        """``∂U/∂q``: ``−density f`` in the position slots, zero elsewhere."""
        q = np.asarray(q, dtype=float)
        grad = np.zeros(q.shape)
        if self._matrix(q):
            grad[..., 1:, 0] = -self.density * self.field
        else:
            grad[..., : self.field.shape[0]] = -self.density * self.field
        return grad

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "ConstantFieldPotential", "field": self.field.tolist(), "density": self.density}


@dataclass
class UniformForce(Load):
    """Uniform generalised force density, fixed in the body frame (``frame="body"``) or a
    dead load fixed in the spatial frame (``frame="spatial"``, rotated like :class:`Free`).
    Not conservative in general: its power goes to ``external_work``."""

    components: Any
    frame: str = "body"

    def __post_init__(self):
        if self.frame not in ("body", "spatial"):
            raise ValueError(f"frame must be 'body' or 'spatial', got {self.frame!r}")
        self.needs_structure_field = self.frame == "spatial"

    def bind(self, medium):
        self._group = medium.group
        self.components = check_finite(
            "components", _numeric("components", self.components), (medium.group.dim,)
        )

    def force(self, Phi, N, t):
        if self.frame == "body":
            return np.broadcast_to(self.components, np.shape(N)).copy()
        return dead_to_body(self._group, Phi, self.components)

    def to_dict(self):
        return {"kind": "UniformForce", "components": np.asarray(self.components).tolist(), "frame": self.frame}


class NodeForce(Load):
    """A generalised point force P ∈ 𝔤* on one node of the grid (scene load kind ``"node-force"``).

    The node receives P: the force density (per unit reference volume, as every
    :class:`~cartan.problem.Load`) is P/w at the node, w its quadrature weight
    (:meth:`~cartan.grid.Grid.node_weights`, trapezoidal: the lattice's and fd2 collocation's
    weights; fd4 collocation's SBP norm weighs the rows next to an open end differently), and 0
    elsewhere.  On a general chart, whose scheme weighs a node by its reference volume w·J
    (:meth:`~cartan.medium.Medium.reference_volume`), the scheme hands the load these volumes
    (:meth:`measure`) and the density is P/(wJ): the node receives P on every chart (the volumes
    of the scheme built last for the problem).  As :class:`~cartan.problem.UniformForce`, P is
    either fixed in the spatial frame
    (``frame="spatial"``, the default: a dead load, body components Ad_Rᵀ P with R the rotational
    part of Φ at the node, as a free end's dead load) or in the body frame (``frame="body"``, a
    follower load).  Not conservative in general: its power goes to ``external_work``.

    Parameters
    ----------
    grid : Grid
        The grid the node belongs to.
    force : array_like, shape ``(r,)``
        P in the dual basis of the group's Lie algebra, r its dimension (SE(3): force then
        moment, as a free end's ``load``); checked against the medium's group in :meth:`bind`.
    node : int or sequence of int, optional
        The node's index along each axis (d entries; a negative index counts from the end).
    at : float or sequence of float, optional
        Material coordinates of the point (d entries): the nearest node is taken (every point of
        the chart is within half a cell of one along each axis).  A coordinate must lie in the
        chart, [0, L] along each axis (periodic axes wrap the last half cell to node 0), up to
        10⁻⁶ of a cell for written decimals.  Give exactly one of ``node`` and ``at``.
    frame : {"spatial", "body"}
        The frame P is fixed in.

    Attributes
    ----------
    node : tuple of int
        The node's index (d entries, ≥ 0).
    force_components : ndarray, shape ``(r,)``
        P.
    weight : float
        w, the node's quadrature weight (w·J on a general chart, :meth:`measure`).
    """

    def __init__(self, grid: Grid, force: Any, *, node: Any = None, at: Any = None, frame: str = "spatial"):
        if not isinstance(grid, Grid):
            raise TypeError(f"grid must be a Grid, got {type(grid).__name__}")
        self.force_components = check_finite("force", force)
        if self.force_components.ndim != 1:
            raise ValueError(f"force must be a vector of load components, got shape {self.force_components.shape}")
        if frame not in ("spatial", "body"):
            raise ValueError(f"frame must be 'spatial' or 'body', got {frame!r}")
        self.frame = frame
        self.needs_structure_field = frame == "spatial"
        if (node is None) == (at is None):
            raise ValueError(f"give exactly one of node (an index per axis) and at (material coordinates per axis), "
                             f"got {'both' if node is not None else 'neither'}")
        if at is not None:
            at = np.atleast_1d(check_finite("at", at))
            if at.ndim != 1:
                raise ValueError(f"at must be a list of coordinates, one per grid axis, got shape {at.shape}")
        self.at = None if at is None else tuple(float(x) for x in at)
        self.node = _node_index(grid, node) if node is not None else _nearest_node(grid, self.at)
        self.weight = float(grid.node_weights()[self.node])
        self.shape = grid.shape

    def bind(self, medium: Any) -> None:
        self._group = medium.group
        r = medium.group.dim
        if self.force_components.shape != (r,):
            raise ValueError(f"force must have {r} components (the dimension of {medium.group.name}, medium "
                             f"{medium.name!r}), got {self.force_components.shape[0]}")

    def measure(self, volumes: np.ndarray) -> None:
        """Take the node's reference volume w·J from a scheme's ``volumes`` ``(*shape)`` (a
        general chart), so that the node receives P."""
        volumes = np.asarray(volumes, dtype=float)
        if volumes.shape != tuple(self.shape):
            raise ValueError(f"volumes must have the grid's shape {tuple(self.shape)}, got {volumes.shape}")
        self.weight = float(volumes[self.node])

    def force(self, Phi: np.ndarray | None, N: np.ndarray, t: float) -> np.ndarray:
        """``[*shape, r]``: P/w (body components) at the node, 0 elsewhere (w the node's
        reference volume per unit chart volume, :meth:`measure`)."""
        out = np.zeros((*self.shape, self.force_components.shape[0]))
        P = self.force_components
        if self.frame == "spatial":
            P = dead_to_body(self._group, np.asarray(Phi)[self.node], P)
        out[self.node] = P / self.weight
        return out

    def to_dict(self) -> dict[str, Any]:
        out = {"kind": "node-force", "node": list(self.node), "force": self.force_components.tolist(),
               "frame": self.frame}
        if self.at is not None:
            out["at"] = list(self.at)
        return out


def _node_index(grid: Grid, node: Any) -> tuple[int, ...]:
    """``node`` (an int for d = 1, or d ints) as a non-negative index of ``grid``; ValueError naming node."""
    idx = [node] if grid.d == 1 and not isinstance(node, list | tuple) else node
    ranges = ", ".join(f"{-n}..{n - 1}" for n in grid.shape)
    if not (isinstance(idx, list | tuple) and len(idx) == grid.d and all(
            isinstance(i, numbers.Integral) and not isinstance(i, bool) and -n <= i < n
            for i, n in zip(idx, grid.shape, strict=True))):
        raise ValueError(f"node must be {grid.d} integer(s), one per axis, in {ranges}, got {node!r}")
    return tuple(int(i) % n for i, n in zip(idx, grid.shape, strict=True))


def _nearest_node(grid: Grid, at: tuple[float, ...]) -> tuple[int, ...]:
    """The node nearest to the material point ``at`` (d coordinates in the chart); ValueError naming at."""
    if len(at) != grid.d:
        raise ValueError(f"at must have {grid.d} coordinate(s), one per grid axis, got {list(at)}")
    out = []
    for name, x, n, L, h, periodic in zip(grid.axis_names, at, grid.shape, grid.length, grid.spacing,
                                          grid.periodic, strict=True):
        if not -1e-6 * h <= x <= L + 1e-6 * h:
            raise ValueError(f"at = {list(at)} is outside the chart: {name} = {x:g} is not in [0, {L:g}]")
        i = round(x / h)
        out.append(i % n if periodic else min(max(i, 0), n - 1))
    return tuple(out)


@dataclass
class Damping(Load):
    """Linear (Rayleigh) damping ``T = −Γ N`` with ``Γ = diag(coefficients)``; its power
    ``−NᵀΓN`` is dissipated (tracked as ``dissipated_energy``)."""

    coefficients: Any
    dissipative: bool = field(default=True, init=False)
    velocity_dependent: bool = field(default=True, init=False)

    def bind(self, medium):
        c = np.asarray(_numeric("coefficients", self.coefficients), dtype=float)
        if c.ndim == 0:
            c = np.full(medium.group.dim, float(c))
        self.coefficients = check_positive("coefficients", c, allow_zero=True, shape=(medium.group.dim,))

    def force(self, Phi, N, t):
        return -np.asarray(N) * self.coefficients

    def to_dict(self):
        return {"kind": "Damping", "coefficients": np.asarray(self.coefficients).tolist()}


def _check_holonomy(name: str, H: Any, g, grid: Grid) -> Any:
    """Validate a holonomy (see :class:`InitialState`): one ``(m, m)`` element of the group for
    a periodic d = 1 grid, or ``{axis: H}`` over periodic axes; returned as given (float arrays)."""
    if H is None:
        return None
    m = g.matrix_size
    if isinstance(H, Mapping):
        out = {}
        for axis, value in H.items():
            if isinstance(axis, bool) or not isinstance(axis, (int, np.integer)) or not 0 <= axis < grid.d:
                raise ValueError(f"{name}: axis must be an integer in [0, {grid.d - 1}], got {axis!r}")
            if not grid.periodic[axis]:
                raise ValueError(f"{name}[{axis}]: axis {grid.axis_names[axis]!r} is not periodic")
            out[int(axis)] = _check_holonomy(f"{name}[{axis}]", value, g, Grid(grid.shape[axis], grid.length[axis],
                                                                                  periodic=True))
        return out or None
    if not (grid.d == 1 and grid.periodic[0]):
        raise ValueError(f"{name} is only meaningful on a periodic grid with d = 1 (for d ≥ 2 give "
                         "{axis: H} over the periodic axes)")
    H = check_finite(name, _numeric(name, H), (m, m))
    if float(g.defect(H)) > 1e-8:
        raise ValueError(f"{name} is not in {g.name}")
    return H


def axis_holonomies(state: InitialState | None, d: int) -> dict[int, np.ndarray]:
    """The holonomies of a (validated) initial or reference state as ``{axis: H}``."""
    if state is None or state.holonomy is None:
        return {}
    return dict(state.holonomy) if isinstance(state.holonomy, Mapping) else {0: state.holonomy}


def axis_glues(state: InitialState | None) -> dict[int, np.ndarray]:
    """The glue elements of a (validated) initial or reference state as ``{axis: Γ}``."""
    return {} if state is None or state.glue is None else dict(state.glue)


def rotation_part(group, Phi: np.ndarray) -> np.ndarray:
    """Φ with its translation removed (affine groups), i.e. the frame at the material point."""
    if not getattr(group, "affine", False):
        return Phi
    R = np.array(Phi, dtype=float, copy=True)
    R[..., 1:, 0] = 0.0
    return R


def dead_to_body(group, Phi: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Body components of a dead (spatially fixed) load P applied at the material point:
    ``Ad_{R}ᵀ P`` with R the rotational part of Φ (for SE(3): (Rᵀf, Rᵀm))."""
    P = np.broadcast_to(P, np.shape(Phi)[:-2] + np.shape(P))
    return np.einsum("...ji,...j->...i", group.Ad(rotation_part(group, Phi)), P)


# ---------------------------------------------------------------------------- state
@dataclass
class InitialState:
    """Initial structure field and velocity on the nodes.

    Parameters
    ----------
    Phi : array, shape ``(*grid.shape, m, m)``
        Structure field Φ₀ (q₀ = Φ₀·q_r).
    N : array, shape ``(*grid.shape, r)``, optional
        Initial velocity N₀ = Φ⁻¹Φ̇ (zero by default).
    holonomy : array, shape ``(m, m)``, or dict of int → array, optional
        For a periodic axis: the group element H with Φ(u + L) = H Φ(u), so that the closing
        edge is Φ₀[-1]⁻¹ H Φ₀[0].  Identity (a closed rod, a closed shell) by default; a
        translation by L for a straight rod with periodic boundary conditions, a screw motion
        for a helix.  d = 1: one array; any d: ``{axis: H_α}`` for the periodic axes that have
        one (a box of a solid periodic up to a translation along each axis: H_α the
        translation by L_α).
    glue : array, shape ``(m, m)``, or dict of int → array, optional
        For a glued axis (:class:`~cartan.grid.Grid` ``glued``): the constant group element Γ
        the chart turns by across the axis's ends, so that the ghost of node j beyond an end is
        the opposite node j' seen in the frame Φ_j' Γ (Γ² = I).  For the sphere charted by
        (longitude, colatitude) with e₃ the normal, the half-turn about e₃.  Identity by
        default; d = 2 with one glued axis: one array, otherwise ``{axis: Γ_α}``.
    reference : InitialState or array, optional
        The stress-free reference configuration the state comes with (an initial kind that
        charts a body, e.g. a disk by a square, returns it): a :class:`Problem` given no
        ``reference`` takes this one, so that a scene's ``[initial]`` table can set it.
    """

    Phi: Any
    N: Any = None
    holonomy: Any = None
    reference: Any = None
    glue: Any = None


def _check_glue(name: str, glue: Any, g, grid: Grid) -> dict[int, np.ndarray] | None:
    """Validate a glue declaration (see :class:`InitialState`) against the grid's glued axes:
    ``{axis: Γ}`` with every glued axis present (identity when not given), None without glued axes."""
    axes = [a for a in range(grid.d) if grid.is_glued(a)]
    if not axes:
        if glue is not None:
            raise ValueError(f"{name} is only meaningful on a grid with a glued axis (Grid(glued=...))")
        return None
    m = g.matrix_size
    if glue is None:
        glue = {}
    elif not isinstance(glue, Mapping):
        if len(axes) != 1:
            raise ValueError(f"{name}: give {{axis: element}} for the glued axes {axes}")
        glue = {axes[0]: glue}
    out = {}
    for axis, value in glue.items():
        if axis not in axes:
            raise ValueError(f"{name}: axis must be one of the glued axes {axes}, got {axis!r}")
        G = np.asarray(check_finite(f"{name}[{axis}]", _numeric(f"{name}[{axis}]", value), (m, m)), dtype=float)
        if float(g.defect(G)) > 1e-8:
            raise ValueError(f"{name}[{axis}] is not in {g.name}")
        if np.max(np.abs(G @ G - np.eye(m))) > 1e-8:
            raise ValueError(f"{name}[{axis}] must be an involution (Γ² = I: the ghost of the ghost is the node)")
        out[int(axis)] = G
    for axis in axes:
        out.setdefault(axis, np.eye(m))
    return out


@dataclass
class Problem:
    """Medium, grid, boundaries, loads and initial state: what ``cartan.simulate`` runs."""

    medium: Medium
    grid: Grid
    initial: InitialState
    boundaries: dict[str, Boundary] = field(default_factory=dict)
    loads: list[Load] = field(default_factory=list)
    name: str = ""
    #: the stress-free reference configuration Φ_ref ``(*grid.shape, m, m)`` (or an
    #: :class:`InitialState` with a holonomy for a periodic axis), when the rest strain varies
    #: over the body (curved shells, rods with varying natural curvature): the rest strain at
    #: each point is then that of Φ_ref (on the lattice, X₀ of an edge is log(Φ_ref,i⁻¹Φ_ref,j)/h,
    #: so Φ_ref is exactly stress-free).  None: the medium's constant ``rest_strain()``.
    reference: Any = None

    def __post_init__(self):
        self._check_types()
        g = self.medium.group
        if self.medium.material_dim != self.grid.d:
            raise ValueError(
                f"grid has d = {self.grid.d} axes but medium {self.medium.name!r} has material "
                f"dimension {self.medium.material_dim}"
            )
        shape = self.grid.shape
        Phi = check_finite("initial.Phi", _numeric("initial.Phi", self.initial.Phi),
                           (*shape, g.matrix_size, g.matrix_size))
        defect = float(np.max(g.defect(Phi)))
        if defect > 1e-8:
            raise ValueError(f"initial.Phi is not in {g.name}: defect {defect:.2e} > 1e-8")
        N = np.zeros((*shape, g.dim)) if self.initial.N is None else self.initial.N
        N = check_finite("initial.N", _numeric("initial.N", N), (*shape, g.dim))
        H = _check_holonomy("initial.holonomy", self.initial.holonomy, g, self.grid)
        if self.reference is None and self.initial.reference is not None:
            self.reference = self.initial.reference
        glue = _check_glue("initial.glue", self.initial.glue, g, self.grid)
        self.initial = InitialState(Phi=Phi, N=N, holonomy=H, glue=glue)
        valid = self.boundary_names()
        for key, b in self.boundaries.items():
            if key not in valid:
                raise ValueError(f"boundaries: unknown end {key!r}; this grid has ends {sorted(valid) or 'none'}")
            if not isinstance(b, Boundary):
                raise ValueError(f"boundaries[{key!r}] must be Free(...), Clamped(), Driven(...), Held(...) or "
                                 "Symmetry(...), "
                                 f"got {b!r}")
            if isinstance(b, Held):
                b.mask(self.medium, key)
            if isinstance(b, Free) and b.load is not None:
                b.load = check_finite(f"boundaries[{key!r}].load", b.load, (g.dim,))
            if isinstance(b, Driven):
                b.velocity = check_finite(f"boundaries[{key!r}].velocity", b.velocity, (g.dim,))
                gauge = np.flatnonzero(np.asarray(self.medium.gauge_mask(), dtype=bool) & (b.velocity != 0.0))
                if gauge.size:
                    raise ValueError(f"boundaries[{key!r}].velocity must be zero on the gauge components of "
                                     f"{self.medium.name!r} (not dynamical), got nonzero components {gauge.tolist()}")
            self.medium.check_support(b, key)
        ends = {}
        for key in self.boundaries:  # "start" and "u-start" are the same end (d = 1)
            end = f"{self.grid.axis_names[0]}-{key}" if key in ("start", "end") else key
            if end in ends:
                raise ValueError(
                    f"boundaries: {ends[end]!r} and {key!r} name the same end; give one condition per end"
                )
            ends[end] = key
        for load in self.loads:
            if not isinstance(load, Load):
                raise ValueError(f"loads must be Load instances, got {load!r}")
            load.bind(self.medium)
        for i, load in enumerate(self.loads):
            try:
                load.attach(self)
            except ValueError as exc:
                raise ValueError(f"loads[{i}]: {exc}") from None
        if self.reference is not None:
            ref = self.reference if isinstance(self.reference, InitialState) else InitialState(Phi=self.reference)
            Phi_ref = check_finite("reference", ref.Phi, (*shape, g.matrix_size, g.matrix_size))
            if float(np.max(g.defect(Phi_ref))) > 1e-8:
                raise ValueError(f"reference is not in {g.name}")
            H_ref = _check_holonomy("reference.holonomy", ref.holonomy, g, self.grid)
            glue_ref = glue if ref.glue is None else _check_glue("reference.glue", ref.glue, g, self.grid)
            self.reference = InitialState(Phi=Phi_ref, holonomy=H_ref, glue=glue_ref)

    def _check_types(self) -> None:
        """TypeError naming the argument for arguments of the wrong kind."""
        expected = (("medium", Medium, "a Medium (cartan.medium(name, ...))"), ("grid", Grid, "a Grid"),
                    ("initial", InitialState, "an InitialState (medium.initial_state(grid, kind))"))
        for name, cls, what in expected:
            value = getattr(self, name)
            if not isinstance(value, cls):
                raise TypeError(f"{name} must be {what}, got {type(value).__name__}")
        if not isinstance(self.boundaries, Mapping):
            raise TypeError(
                f"boundaries must be a dict {{end: Free(...) or Clamped()}}, got {type(self.boundaries).__name__}"
            )
        self.boundaries = dict(self.boundaries)
        for key in self.boundaries:
            if not isinstance(key, str):
                raise TypeError(f"boundaries: ends are named by strings ('start', 'u-end', ...), got {key!r}")
        if not isinstance(self.loads, list | tuple):
            raise TypeError(f"loads must be a list of Load instances, got {type(self.loads).__name__}")
        self.loads = list(self.loads)
        if not isinstance(self.name, str):
            raise TypeError(f"name must be a string, got {type(self.name).__name__}")

    def boundary_names(self) -> set[str]:
        names = set()
        for axis, (name, p) in enumerate(zip(self.grid.axis_names, self.grid.periodic)):
            if p or self.grid.is_glued(axis):
                continue
            if self.grid.d == 1:
                names |= {"start", "end"}
            names |= {f"{name}-start", f"{name}-end"}
        return names

    def boundary(self, axis: int, side: str) -> Boundary:
        """The condition at ``side`` ("start"/"end") of ``axis`` (Free() if none given)."""
        name = self.grid.axis_names[axis]
        for key in (f"{name}-{side}", side if self.grid.d == 1 else None):
            if key and key in self.boundaries:
                return self.boundaries[key]
        return Free()

    @property
    def needs_structure_field(self) -> bool:
        """True when some force depends on Φ: potentials, dead loads, or the medium itself."""
        if getattr(self.medium, "needs_structure_field", False):
            return True
        if any(load.needs_structure_field for load in self.loads):
            return True
        return any(isinstance(b, Free) and b.load is not None and not b.follower for b in self.boundaries.values())

    @property
    def velocity_free(self) -> bool:
        """True when no force reads the velocity N: no velocity-dependent load (damping) and no
        velocity-dependent forces of the medium."""
        return not (getattr(self.medium, "velocity_dependent_forces", False)
                    or any(load.velocity_dependent for load in self.loads))

    def to_dict(self) -> dict[str, Any]:
        out = {
            "name": self.name,
            "medium": self.medium.name,
            "parameters": self.medium.parameters(),
            "grid": self.grid.to_dict(),
            "boundaries": {k: b.to_dict() for k, b in self.boundaries.items()},
            "loads": [load.to_dict() for load in self.loads],
        }
        holonomies = axis_holonomies(self.initial, self.grid.d)
        if holonomies:  # the periodic axes' closing elements (a picture closes its seams with them)
            out["holonomy"] = {str(a): np.asarray(H, dtype=float).tolist() for a, H in sorted(holonomies.items())}
        return out
