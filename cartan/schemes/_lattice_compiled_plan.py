"""The problem of a lattice scheme as data for the compiled loops (``docs/performance.md``).

:func:`build_plan` turns a qualifying problem into the plan tuple ``P`` read by the compiled
loops of :mod:`cartan.schemes._lattice_compiled` (layout ``I_*`` below), or returns None.
The first 22 entries describe one axis (d = 1: spacing ``I_H``, rest strain ``I_X0``); the
others hold the d-dimensional grid (d = 1, 2, 3), padded to three axes.
"""

from __future__ import annotations

import numpy as np

from ._lattice_compiled_kernels import CHUNK, GID_SE2, GID_SE3, GID_SO2, GID_SO3

#: blow-up tests after each step: none, momentum (finite, kinetic energy), configuration
CHECK_NONE = 0
CHECK_MOMENTUM = 1
CHECK_CONFIGURATION = 2

#: layout of the plan tuple P (see :func:`build_plan`)
(I_GID, I_TRACK, I_AFFINE, I_H, I_X0, I_C, I_DIAG, I_W, I_MASS, I_LIVE, I_CLAMPED, I_CONSTRAINED,
 I_DAMP, I_HAS_DAMP, I_UBODY, I_HAS_UBODY, I_FIELD, I_HAS_FIELD, I_END_IDX, I_END_LOAD, I_END_FOLLOW,
 I_HAS_POWER,
 I_D, I_SHAPE, I_NE, I_PERIODIC, I_ESTR, I_EOFF, I_ECH, I_HS, I_X0S, I_SCALES, I_END_DIV, I_END_FACE,
 I_END_CHUNK, I_WINV) = range(36)


def _compiled_loads(problem, group, r: int) -> tuple | None:
    """The loads and boundaries the lattice's hand-written loops can run, as data:
    ``(damp, has_damp, ubody, has_ubody, field, has_field)`` — summed ``Damping`` coefficients
    ``(r,)``, body-frame ``UniformForce`` components ``(r,)``, ``ConstantFieldPotential``
    density × field ``(k,)`` — or None when a load or a boundary is of another kind."""
    from ..problem import Clamped, ConstantFieldPotential, Damping, Free, PotentialLoad, UniformForce

    k = group.space_dim if getattr(group, "affine", False) else 1
    damp, ubody, field = np.zeros(r), np.zeros(r), np.zeros(k)
    has_damp = has_ubody = has_field = False
    for load in problem.loads:
        if type(load) is Damping:
            damp = damp + np.asarray(load.coefficients, dtype=float)
            has_damp = True
        elif type(load) is UniformForce and load.frame == "body":
            ubody = ubody + np.asarray(load.components, dtype=float)
            has_ubody = True
        elif (
            isinstance(load, ConstantFieldPotential)
            and type(load).force is PotentialLoad.force
            and _same_methods(load, ConstantFieldPotential, ("potential_gradient", "position", "_matrix"))
        ):
            field = field + load.density * np.asarray(load.field, dtype=float)
            has_field = True
        else:
            return None
    if any(type(b) not in (Free, Clamped) for b in problem.boundaries.values()):
        return None
    return damp, has_damp, ubody, has_ubody, field, has_field


def _group_id(group) -> int | None:
    from ..groups.se2 import SE2
    from ..groups.se3 import SE3
    from ..groups.so2 import SO2
    from ..groups.so3 import SO3

    return {SO2: GID_SO2, SE2: GID_SE2, SO3: GID_SO3, SE3: GID_SE3}.get(type(group))


def _same_methods(obj, base, names) -> bool:
    return all(getattr(type(obj), name, None) is getattr(base, name) for name in names)


def _quadratic_axes(medium, d: int, r: int) -> tuple[np.ndarray, np.ndarray] | None:
    """``(X₀ [d, r], C [r, r])`` of a medium whose potential is ``½Σ_α(X_α − X₀_α)ᵀC(X_α − X₀_α)``,
    checked against its ``stress``; None when it is not known to be quadratic.

    From ``medium.quadratic_energy()`` (X₀ of shape (r,) for d = 1, or (d, r); the (r,) form
    is not taken for d ≥ 2), or, for d ≥ 2, from a :class:`~cartan.medium.QuadraticMedium`
    with the base energy methods.
    """
    from ..medium import QuadraticMedium

    quad = medium.quadratic_energy()
    if quad is not None and d > 1 and np.shape(quad[0]) == (r,):
        quad = None  # one axis' data (the d = 1 form): not a description of this medium
    if quad is not None:
        X0 = np.array(quad[0], dtype=float)
        C = np.array(quad[1], dtype=float)
        if X0.shape == (r,):
            X0 = X0.reshape(1, r)
        if X0.shape != (d, r) or C.shape != (r, r) or not (np.all(np.isfinite(X0)) and np.all(np.isfinite(C))):
            raise ValueError(
                f"medium {medium.name!r}: quadratic_energy() must return finite X0 of shape ({r},) or ({d}, {r}) "
                f"and C of shape ({r}, {r}); got shapes {np.shape(quad[0])} and {np.shape(quad[1])}"
            )
    elif d > 1 and isinstance(medium, QuadraticMedium) and medium._C is not None and _same_methods(
            medium, QuadraticMedium, ("potential", "stress", "stiffness", "rest_strain")):
        X0 = np.array(medium.rest_strain(), dtype=float).reshape(d, r)
        C = np.array(medium.stiffness()[0, :, 0, :], dtype=float)
    else:
        return None
    delta = 1e-2 * np.sin(np.arange(1.0, r + 1.0))
    for axis in range(d):
        full = X0.copy()
        full[axis] += delta
        Q = np.asarray(medium.stress(full[None]), dtype=float).reshape(d, r)[axis]
        if not np.allclose(Q, C @ delta, rtol=1e-9, atol=1e-12 * max(1.0, float(np.abs(C).max()))):
            raise ValueError(f"medium {medium.name!r}: quadratic_energy() disagrees with stress(): Q ≠ C (X − X0)")
    return X0, C


def build_plan(scheme) -> tuple | None:
    """The problem of a lattice scheme as compiled-loop data ``P`` (layout ``I_*``), or None
    when it does not qualify: SO(2), SE(2), SO(3), SE(3); a medium with a quadratic potential
    (:meth:`~cartan.medium.Medium.quadratic_energy`, or a
    :class:`~cartan.medium.QuadraticMedium` for d ≥ 2) and the base kinetic energy and body
    force; ``Damping``, body-frame ``UniformForce`` and ``ConstantFieldPotential`` loads; free
    (loaded or not) and clamped ends; frames stepped when a load needs them.

    Raises
    ------
    ValueError
        When the medium's ``quadratic_energy`` is malformed or disagrees with its ``stress``.
    """
    from ..medium import Medium
    from .base import Scheme
    from .lattice import Lattice

    problem, medium, group, grid = scheme.problem, scheme.medium, scheme.group, scheme.grid
    gid = _group_id(group)
    d = grid.d
    if gid is None or not 1 <= d <= 3:
        return None
    if not _same_methods(scheme, Lattice, ("force", "internal_force", "drift", "frames", "_boundary_power",
                                           "_axis_stress", "initial_state", "_key")):
        return None
    if not _same_methods(scheme, Scheme, ("velocity", "constrain", "powers", "has_external_power", "drag")):
        return None
    if not scheme.diagonal_metric or np.any(scheme.mass < 0):
        return None  # the kinetic metric of these loops is a positive diagonal
    if not _same_methods(medium, Medium, ("velocity", "body_force")):
        return None
    if getattr(medium, "velocity_dependent_forces", False):
        return None
    if problem.reference is not None or getattr(scheme, "coupled", False):
        return None  # rest strains per edge, corner energies: the generated loops' operators
    r = group.dim
    quad = _quadratic_axes(medium, d, r)
    if quad is None:
        return None
    X0s, C = quad
    loads = _compiled_loads(problem, group, r)
    if loads is None:
        return None
    damp, has_damp, ubody, has_ubody, field, has_field = loads
    if (has_field or any(not b.follower for _, b in scheme._end_loads)) and not scheme.track:
        return None
    shape = tuple(int(s) for s in grid.shape)
    n = int(np.prod(shape))
    h = tuple(float(v) for v in scheme.h)
    weights = np.ascontiguousarray(scheme.weights, dtype=float).reshape(n)
    # end loads, one entry per node of each loaded end (face), sorted by node (stably: the
    # reference path's order at a node loaded by two faces)
    entries = scheme.end_load_entries()
    end_idx = np.array([i for i, _, _ in entries], dtype=np.int64)
    end_div = np.array([0.5 * h[a] for _, _, a in entries], dtype=float)
    end_face = np.array([weights[i] / (0.5 * h[a]) for i, _, a in entries], dtype=float)
    nch = (n + CHUNK - 1) // CHUNK
    end_chunk = np.searchsorted(end_idx, np.arange(nch + 1) * CHUNK).astype(np.int64)
    # the grid padded to three axes: node shape, edges and chunks per axis, edge strides
    shape3 = np.array(shape + (1,) * (3 - d), dtype=np.int64)
    periodic3 = np.array(tuple(grid.periodic) + (False,) * (3 - d), dtype=np.bool_)
    ne3 = np.where(periodic3, shape3, shape3 - 1)
    ne3[d:] = 1
    estr = np.zeros((3, 3), dtype=np.int64)
    eoff = np.zeros(4, dtype=np.int64)
    ech = np.zeros(4, dtype=np.int64)
    for a in range(3):
        E = shape3.copy()
        E[a] = ne3[a]
        if a < d:
            estr[a] = (E[1] * E[2], E[2], 1)
        count = int(np.prod(E)) if a < d else 0
        eoff[a + 1] = eoff[a] + count
        ech[a + 1] = ech[a] + (count + CHUNK - 1) // CHUNK
    cell = float(np.prod(h))
    live = np.ascontiguousarray(scheme.live, dtype=np.bool_)
    clamped = np.ascontiguousarray(scheme._clamped, dtype=np.bool_).reshape(n)
    return (
        int(gid),
        bool(scheme.track),
        bool(getattr(group, "affine", False)),
        h[0],
        np.ascontiguousarray(X0s[0]),
        np.ascontiguousarray(C),
        bool(np.count_nonzero(C - np.diag(np.diag(C))) == 0),
        weights,
        np.ascontiguousarray(scheme.mass, dtype=float),
        live,
        clamped,
        bool(clamped.any() or not live.all()),
        damp,
        has_damp,
        ubody,
        has_ubody,
        field,
        has_field,
        end_idx,
        np.array([np.asarray(b.load, dtype=float) for _, b, _ in entries], dtype=float).reshape(len(entries), r),
        np.array([bool(b.follower) for _, b, _ in entries], dtype=np.bool_),
        bool(scheme.has_external_power()),
        int(d),
        shape3,
        ne3,
        periodic3,
        estr,
        eoff,
        ech,
        np.array(h, dtype=float),
        np.ascontiguousarray(X0s),
        np.array([cell / h[a] for a in range(d)], dtype=float),
        end_div,
        end_face,
        end_chunk,
        1.0 / weights,
    )
