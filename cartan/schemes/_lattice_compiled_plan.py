"""The problem of an SE(3) rod as data for the structure-of-arrays loops (``docs/performance.md``).

:func:`build_plan` turns a qualifying problem — SE(3), d = 1 — into the plan tuple ``P`` read
by the loops of :mod:`cartan.schemes._lattice_compiled_soa` (layout ``I_*`` below), or
returns None; every other lattice problem runs the generated loops
(:mod:`cartan.schemes._lattice_ops`).
"""

from __future__ import annotations

import numpy as np

from ._lattice_compiled_kernels import CHUNK

#: blow-up tests after each step: none, momentum (finite, kinetic energy), configuration
CHECK_NONE = 0
CHECK_MOMENTUM = 1
CHECK_CONFIGURATION = 2

#: layout of the plan tuple P (see :func:`build_plan`)
(I_H, I_X0, I_C, I_DIAG, I_W, I_WINV, I_MASS, I_LIVE, I_CLAMPED, I_CONSTRAINED, I_DAMP, I_HAS_DAMP, I_UBODY,
 I_HAS_UBODY, I_FIELD, I_HAS_FIELD, I_END_IDX, I_END_LOAD, I_END_FOLLOW, I_END_DIV, I_END_FACE, I_END_CHUNK,
 I_HAS_POWER) = range(23)


def _compiled_loads(problem, group, r: int) -> tuple | None:
    """The loads and boundaries the structure-of-arrays loops can run, as data:
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


def _same_methods(obj, base, names) -> bool:
    return all(getattr(type(obj), name, None) is getattr(base, name) for name in names)


def _quadratic_axis(medium, r: int) -> tuple[np.ndarray, np.ndarray] | None:
    """``(X₀ (r,), C [r, r])`` of a rod medium whose potential is ``½(X − X₀)ᵀC(X − X₀)``
    (``medium.quadratic_energy()``), checked against its ``stress``; None when it is not known
    to be quadratic."""
    quad = medium.quadratic_energy()
    if quad is None:
        return None
    X0 = np.array(quad[0], dtype=float)
    C = np.array(quad[1], dtype=float)
    if X0.shape == (1, r):
        X0 = X0.reshape(r)
    if X0.shape != (r,) or C.shape != (r, r) or not (np.all(np.isfinite(X0)) and np.all(np.isfinite(C))):
        raise ValueError(
            f"medium {medium.name!r}: quadratic_energy() must return finite X0 of shape ({r},) or (1, {r}) "
            f"and C of shape ({r}, {r}); got shapes {np.shape(quad[0])} and {np.shape(quad[1])}"
        )
    delta = 1e-2 * np.sin(np.arange(1.0, r + 1.0))
    Q = np.asarray(medium.stress((X0 + delta)[None, None]), dtype=float).reshape(r)
    if not np.allclose(Q, C @ delta, rtol=1e-9, atol=1e-12 * max(1.0, float(np.abs(C).max()))):
        raise ValueError(f"medium {medium.name!r}: quadratic_energy() disagrees with stress(): Q ≠ C (X − X0)")
    return X0, C


def build_plan(scheme) -> tuple | None:
    """The problem of a lattice scheme as structure-of-arrays loop data ``P`` (layout ``I_*``),
    or None when it does not qualify: SE(3) on a d = 1 grid; a medium with a quadratic
    potential (:meth:`~cartan.medium.Medium.quadratic_energy`) and the base kinetic energy and
    body force; ``Damping``, body-frame ``UniformForce`` and ``ConstantFieldPotential`` loads;
    free (loaded or not) and clamped ends; frames stepped when a load needs them.

    Raises
    ------
    ValueError
        When the medium's ``quadratic_energy`` is malformed or disagrees with its ``stress``.
    """
    from ..groups.se3 import SE3
    from ..medium import Medium
    from .base import Scheme
    from .lattice import Lattice

    problem, medium, group, grid = scheme.problem, scheme.medium, scheme.group, scheme.grid
    if type(group) is not SE3 or grid.d != 1:
        return None  # the generated loops run every other group and grid
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
    if problem.reference is not None:
        return None  # rest strains per edge: the generated loops' operators
    r = group.dim
    quad = _quadratic_axis(medium, r)
    if quad is None:
        return None
    X0, C = quad
    loads = _compiled_loads(problem, group, r)
    if loads is None:
        return None
    damp, has_damp, ubody, has_ubody, field, has_field = loads
    if (has_field or any(not b.follower for _, b in scheme._end_loads)) and not scheme.track:
        return None
    n = int(grid.size)
    h = float(scheme.h[0])
    weights = np.ascontiguousarray(scheme.weights, dtype=float).reshape(n)
    # end loads, one entry per loaded end node, sorted by node (stably: the reference path's
    # order at a node loaded by both ends)
    entries = scheme.end_load_entries()
    end_idx = np.array([i for i, _, _ in entries], dtype=np.int64)
    end_div = np.full(len(entries), 0.5 * h)
    end_face = np.array([weights[i] / (0.5 * h) for i, _, _ in entries], dtype=float)
    nch = (n + CHUNK - 1) // CHUNK
    end_chunk = np.searchsorted(end_idx, np.arange(nch + 1) * CHUNK).astype(np.int64)
    live = np.ascontiguousarray(scheme.live, dtype=np.bool_)
    clamped = np.ascontiguousarray(scheme._clamped, dtype=np.bool_).reshape(n)
    return (
        h,
        np.ascontiguousarray(X0),
        np.ascontiguousarray(C),
        bool(np.count_nonzero(C - np.diag(np.diag(C))) == 0),
        weights,
        1.0 / weights,
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
        end_div,
        end_face,
        end_chunk,
        bool(scheme.has_external_power()),
    )
