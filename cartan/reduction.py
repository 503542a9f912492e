"""Exact reductions: run a problem on a smaller model that moves exactly like it.

A scene written on SE(3) whose data all lie in a plane moves in that plane for all time, and
its motion is the motion of the planar medium on SE(2): SE(2) is the subgroup of SE(3) that
preserves the plane, and the planar strains, velocities and stresses are the components
``(0, 1, 5)`` of the SE(3) ones (``(θ₁, θ₂, π₃)``, ``(V₁, V₂, Ω₃)``, ``(F₁, F₂, M₃)``; paper
§VI.A, §VI.C).  The SE(2) run carries half the components and none of the out-of-plane work,
and changes nothing but the cost: the two runs agree to round-off with explicit integrators,
to the Newton tolerance with implicit ones (their iterations may stop at different iterates).
The reflection z → −z maps planar data to themselves and the motion of a medium without
in-plane/out-of-plane coupling to a motion, so the planar motion is the only one.

:func:`cartan.simulate` asks this module, before a run, whether the problem admits such a
reduction (:func:`planar_reduction`); when it does, it runs the reduced problem and lifts the
frames back (:func:`run_reduced`), so that the Dataset is the one the full run returns: the
same variables, dimensions, shapes, coordinates and attributes, frames, positions, strains,
velocities, momenta and total momentum as SE(3) quantities with zero out-of-plane components,
plus the attribute ``cartan_reduction = "SE3->SE2 (planar)"``.  ``simulate(..., reduce=False)``
runs the full problem.

The plane
---------
The plane is the x–y plane of the spatial frame with the director e₃ along +z at every node
(the rod's convention: motion in the e₁–e₂ plane, bending about e₃).  A problem is reduced
only when every datum is provably planar, compared exactly (no tolerance):

* the medium declares its planar twin (:meth:`cartan.medium.Medium.planar_reduction`), the
  twin is on SE(2) and it is the restriction of the medium: the kinetic metric restricted to
  the in-plane components, no coupling between in-plane and out-of-plane components, and, for
  quadratic media, the rest strain and stiffness restricted likewise with zero out-of-plane
  rest strain (other media: checked at sample strains);
* the initial frames (z = 0, e₃ = +z), the reference frames, the holonomies, the initial
  velocities (N₃ = N₄ = N₅ = 0, components ``(V₃, Ω₁, Ω₂)``);
* the boundaries (``Clamped``, ``Free`` with an end load without out-of-plane components,
  ``Driven`` with a velocity ξ without out-of-plane components — in-plane translation, rotation
  about the normal —, whose SE(2) velocity is ``ξ[(0, 1, 5)]``: the end's frame
  Φ(0)·exp(tξ) then stays in the embedded SE(2), and exp commutes with the embedding;
  ``Held`` with any components: its held in-plane components (V₁, V₂, Ω₃) are held as the
  SE(2) components (0, 1, 2), its out-of-plane ones are zero in a planar motion anyway, so an
  end holding only (V₃, Ω₁, Ω₂) is ``Free`` in the plane; a pinned end ``Held((0, 1, 2))`` is
  ``Held((0, 1))``, and ``Held((0, 1, 2, 3, 4))`` too: the free set of a valid SE(3) end, a
  subalgebra, meets se(2) in a subalgebra, so the SE(2) end is valid);
* the loads: the core's ``Damping`` (any coefficients), ``UniformForce`` (body or spatial,
  without out-of-plane components) and constant fields (``ConstantFieldPotential`` and
  subclasses that change none of its physics, such as gravity; field with z = 0).

Anything else — an unknown load or boundary class, an out-of-plane datum (a driven end whose ξ
has a component V₃, Ω₁ or Ω₂ moves out of the plane), a medium without a twin, a restart,
periodic checkpoints, scheme state arrays that cannot be lifted — runs the full problem,
silently; :func:`planar_obstacle` names the datum that blocks the reduction (``cartan advise``
reports it).  So does a run where the reduction would not pay
(:func:`reduction_pays`): the ``lattice`` scheme's hand-written compiled loops have closed-form
and vectorised SE(3) kernels but only generic SE(2) ones, so that there the SE(2) run is the
slower one.  A reduced run that blows up is run again in full, so that the error
and the last good state on disk are those of the full problem.

A run that writes a file is not reduced: a restart continues a run on the group its file
holds, and a restart is exact (bit for bit against the uninterrupted run) only when both halves
step on the same group.  The reduction serves runs kept in memory: studies, sweeps, notebooks.
"""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .medium import Medium
from .problem import (
    Clamped,
    ConstantFieldPotential,
    Damping,
    Driven,
    Free,
    Held,
    InitialState,
    Load,
    PotentialLoad,
    Problem,
    UniformForce,
)

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

    from .simulate import _ResolvedRun

__all__ = [
    "IN_PLANE",
    "OUT_OF_PLANE",
    "PLANAR",
    "Reduction",
    "lift_components",
    "lift_records",
    "planar_obstacle",
    "planar_reduction",
    "reduction_pays",
    "run_reduced",
]

#: the value of the ``cartan_reduction`` attribute of a planar reduction
PLANAR = "SE3->SE2 (planar)"
#: SE(3) components (V₁, V₂, Ω₃) that carry the SE(2) components (V₁, V₂, Ω)
IN_PLANE = (0, 1, 5)
#: SE(3) components (V₃, Ω₁, Ω₂), zero for a planar motion
OUT_OF_PLANE = (2, 3, 4)

_IN = list(IN_PLANE)
_OUT = list(OUT_OF_PLANE)


@dataclass(frozen=True)
class Reduction:
    """An exact reduction of a problem.

    Attributes
    ----------
    kind : str
        What is reduced (the ``cartan_reduction`` attribute), e.g. ``"SE3->SE2 (planar)"``.
    full : Problem
        The problem as given (SE(3)).
    reduced : Problem
        The problem that is run (SE(2)), with the same grid and name.
    """

    kind: str
    full: Problem
    reduced: Problem


# ---------------------------------------------------------------------------- lifts and restrictions
def lift_components(v: np.ndarray) -> np.ndarray:
    """SE(2) components ``[..., 3]`` as SE(3) components ``[..., 6]`` (zero out of the plane)."""
    v = np.asarray(v, dtype=float)
    out = np.zeros((*v.shape[:-1], 6))
    out[..., _IN] = v
    return out


def _planar_elements(g: np.ndarray) -> bool:
    """Whether SE(3) elements ``[..., 4, 4]`` lie in the embedded SE(2), exactly."""
    g = np.asarray(g, dtype=float)
    return bool(np.all(g[..., 3, :3] == 0.0) and np.all(g[..., :3, 3] == 0.0) and np.all(g[..., 3, 3] == 1.0))


def _planar_components(v: Any) -> bool:
    return bool(np.all(np.asarray(v, dtype=float)[..., _OUT] == 0.0))


def _holonomy(H: Any) -> tuple[bool, Any]:
    """``(planar, restricted)`` for a holonomy (None, one element, or ``{axis: element}``)."""
    if H is None:
        return True, None
    if isinstance(H, Mapping):
        parts = {axis: _holonomy(h) for axis, h in H.items()}
        return all(ok for ok, _ in parts.values()), {axis: h for axis, (_, h) in parts.items()}
    return _planar_elements(H), np.asarray(H, dtype=float)[:3, :3].copy()


# ---------------------------------------------------------------------------- the medium's twin
def _same(a: Any, b: Any) -> bool:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and bool(np.allclose(a, b, rtol=1e-14, atol=0.0))


def _twin_is_exact(full: Medium, twin: Medium) -> bool:
    """Whether ``twin`` (SE(2)) is the restriction of ``full`` (SE(3)) to planar motions.

    Exact checks on the data: the kinetic metric has no in-plane/out-of-plane coupling and its
    in-plane block is the twin's; for quadratic media the same for the stiffness, and the rest
    strain has no out-of-plane part.  Media with other energies are checked at a few planar
    strains: the out-of-plane stress vanishes and the in-plane stress and the energy are the
    twin's (to 1e-12 of the stress scale).
    """
    if getattr(full.group, "name", "") != "SE3" or getattr(twin.group, "name", "") != "SE2":
        return False
    if full.material_dim != twin.material_dim:
        return False
    M3, M2 = np.asarray(full.kinetic_metric(), dtype=float), np.asarray(twin.kinetic_metric(), dtype=float)
    if np.any(M3[np.ix_(_OUT, _IN)] != 0.0) or not _same(M3[np.ix_(_IN, _IN)], M2):
        return False
    if (type(full).body_force is Medium.body_force) != (type(twin).body_force is Medium.body_force):
        return False
    if bool(getattr(full, "needs_structure_field", False)) != bool(getattr(twin, "needs_structure_field", False)):
        return False
    missing = set(getattr(full, "output_fields", {}) or {}) - set(getattr(twin, "output_fields", {}) or {})
    if missing:
        return False
    q3, q2 = full.quadratic_energy(), twin.quadratic_energy()
    if q3 is not None and q2 is not None:
        (X3, C3), (X2, C2) = q3, q2
        X3, C3 = np.asarray(X3, dtype=float), np.asarray(C3, dtype=float)
        return bool(
            np.all(X3[..., _OUT] == 0.0)
            and _same(X3[..., _IN], X2)
            and np.all(C3[np.ix_(_OUT, _IN)] == 0.0)
            and np.all(C3[np.ix_(_IN, _OUT)] == 0.0)
            and _same(C3[np.ix_(_IN, _IN)], C2)
        )
    X3, X2 = np.asarray(full.rest_strain(), dtype=float), np.asarray(twin.rest_strain(), dtype=float)
    if np.any(X3[..., _OUT] != 0.0) or not _same(X3[..., _IN], X2):
        return False
    rng = np.random.default_rng(7)
    samples = X2[None] + 0.05 * rng.standard_normal((4, *X2.shape))
    with np.errstate(all="ignore"):
        Q3 = np.asarray(full.stress(lift_components(samples)), dtype=float)
        Q2 = np.asarray(twin.stress(samples), dtype=float)
        U3 = np.asarray(full.potential(lift_components(samples)), dtype=float)
        U2 = np.asarray(twin.potential(samples), dtype=float)
    scale = 1e-12 * max(1.0, float(np.max(np.abs(Q2))), float(np.max(np.abs(U2))))
    return bool(
        np.all(np.isfinite(Q3))
        and np.max(np.abs(Q3[..., _OUT])) <= scale
        and np.max(np.abs(Q3[..., _IN] - Q2)) <= scale
        and np.max(np.abs(U3 - U2)) <= scale
    )


# ---------------------------------------------------------------------------- loads and boundaries
_FIELD_PHYSICS = ("force", "energy", "potential_energy", "potential_gradient", "position", "_matrix")


def _constant_field(load: Load) -> bool:
    """A :class:`ConstantFieldPotential` whose physics is the core's (subclasses that validate
    or name it differently, such as a medium's gravity, qualify)."""
    if not isinstance(load, ConstantFieldPotential):
        return False
    base = {"force": PotentialLoad.force, "energy": PotentialLoad.energy}
    return all(
        getattr(type(load), name) is base.get(name, getattr(ConstantFieldPotential, name, None))
        for name in _FIELD_PHYSICS
    )


def _planar_load(load: Load) -> Load | str:
    """The SE(2) load acting like ``load`` on planar motions, or a string: why there is none."""
    if type(load) is Damping:
        c = np.asarray(load.coefficients, dtype=float)
        return Damping(c[_IN].copy()) if c.shape == (6,) else f"its coefficients have shape {c.shape}, not (6,)"
    if type(load) is UniformForce:
        c = np.asarray(load.components, dtype=float)
        if c.shape != (6,) or not _planar_components(c):
            return f"its components {c.tolist()} have out-of-plane components (F₃, M₁, M₂)"
        return UniformForce(c[_IN].copy(), frame=load.frame)
    if _constant_field(load):
        f = np.asarray(load.field, dtype=float)
        if f.shape != (3,) or f[2] != 0.0:
            return f"its field {f.tolist()} is not in the x–y plane"
        return ConstantFieldPotential(f[:2].copy(), load.density)
    return "not a load the reduction maps (Damping, UniformForce, a constant field)"


def _planar_boundary(b: Any) -> Any:
    """The SE(2) boundary acting like ``b`` on planar motions, or a string: why there is none."""
    if type(b) is Clamped:
        return Clamped()
    if type(b) is Free:
        if b.load is None:
            return Free(follower=b.follower)
        load = np.asarray(b.load, dtype=float)
        if load.shape != (6,) or not _planar_components(load):
            return f"its end load {load.tolist()} has out-of-plane components (F₃, M₁, M₂)"
        return Free(load=load[_IN].copy(), follower=b.follower)
    if type(b) is Driven:  # Φ(t) = Φ(0)·exp(tξ) stays in SE(2) when Φ(0) does and ξ ∈ se(2)
        xi = np.asarray(b.velocity, dtype=float)
        if xi.shape != (6,) or not _planar_components(xi):
            return (
                f"its driven velocity ξ = {xi.tolist()} has out-of-plane components (V₃, Ω₁, Ω₂): the end "
                "leaves the plane"
            )
        return Driven(velocity=xi[_IN].copy())
    if type(b) is Held:  # the held in-plane components (V₁, V₂, Ω₃) are the SE(2) ones (0, 1, 2)
        comps = [k for k in b.components if not 0 <= k < 6]
        if comps:
            return f"its held components {list(b.components)} are not SE(3) components (0 … 5)"
        kept = [IN_PLANE.index(k) for k in b.components if k in IN_PLANE]
        # a planar motion has V₃ = Ω₁ = Ω₂ = 0: an end holding only those is free in the plane
        return Held(components=tuple(kept)) if kept else Free()
    return f"{type(b).__name__} ends are not mapped to SE(2)"


# ---------------------------------------------------------------------------- the test
def planar_reduction(problem: Problem) -> Reduction | None:
    """The planar reduction of ``problem``, or None when it does not provably admit one.

    Parameters
    ----------
    problem : Problem
        A problem on SE(3); its medium declares its planar twin with
        :meth:`~cartan.medium.Medium.planar_reduction`.

    Returns
    -------
    Reduction or None
        The SE(2) problem (same grid and name; medium the twin; initial and reference frames,
        holonomies, velocities, boundaries and loads restricted to the x–y plane), or None
        when some datum is not planar or not understood (see the module docstring;
        :func:`planar_obstacle` says which).
    """
    out = _planar(problem)
    return out if isinstance(out, Reduction) else None


def planar_obstacle(problem: Problem) -> str | None:
    """Why ``problem`` admits no planar reduction, or None when it admits one.

    Parameters
    ----------
    problem : Problem
        Any problem.

    Returns
    -------
    str or None
        The first datum that blocks :func:`planar_reduction` (e.g. ``"boundary 'start': its
        driven velocity ξ = [...] has out-of-plane components (V₃, Ω₁, Ω₂): the end leaves the
        plane"``), or None.
    """
    out = _planar(problem)
    return None if isinstance(out, Reduction) else out


def _planar(problem: Problem) -> Reduction | str:
    """The planar reduction of ``problem``, or the reason it has none."""
    medium = problem.medium
    if getattr(medium.group, "name", "") != "SE3":
        return f"the medium {medium.name!r} is not on SE(3)"
    try:
        twin = medium.planar_reduction()
    except (ValueError, TypeError, NotImplementedError) as exc:
        return f"the medium {medium.name!r} has no planar twin ({exc})"
    if twin is None or not isinstance(twin, Medium):
        return f"the medium {medium.name!r} declares no planar twin (Medium.planar_reduction)"
    if not _twin_is_exact(medium, twin):
        return (
            f"the planar twin {twin.name!r} is not the restriction of {medium.name!r} (in-plane/out-of-plane "
            "coupling, or different data)"
        )
    init = problem.initial
    Phi, N = np.asarray(init.Phi, dtype=float), np.asarray(init.N, dtype=float)
    if not _planar_elements(Phi):
        return "the initial frames leave the x–y plane (z ≠ 0 or e₃ ≠ +z)"
    if not _planar_components(N):
        return "the initial velocities have out-of-plane components (V₃, Ω₁, Ω₂)"
    ok, H = _holonomy(init.holonomy)
    if not ok:
        return "the holonomy is not planar"
    reference = None
    if problem.reference is not None:
        ref = problem.reference
        ok_ref, H_ref = _holonomy(ref.holonomy)
        if not (_planar_elements(ref.Phi) and ok_ref):
            return "the reference state is not planar"
        reference = InitialState(Phi=np.asarray(ref.Phi, dtype=float)[..., :3, :3].copy(), holonomy=H_ref)
    boundaries = {}
    for key, b in problem.boundaries.items():
        b2 = _planar_boundary(b)
        if isinstance(b2, str):
            return f"boundary {key!r}: {b2}"
        boundaries[key] = b2
    loads = []
    for load in problem.loads:
        l2 = _planar_load(load)
        if isinstance(l2, str):
            return f"load {type(load).__name__}: {l2}"
        loads.append(l2)
    try:
        reduced = Problem(
            twin,
            problem.grid,
            InitialState(Phi=Phi[..., :3, :3].copy(), N=N[..., _IN].copy(), holonomy=H),
            boundaries,
            loads,
            name=problem.name,
            reference=reference,
        )
    except (ValueError, TypeError) as exc:
        return f"the SE(2) problem cannot be built ({exc})"
    return Reduction(PLANAR, problem, reduced)


# ---------------------------------------------------------------------------- lifting a run
def lift_records(records: Mapping[str, list], full_group: Any) -> dict[str, list]:
    """The frames of the SE(2) run as the frames of the SE(3) run (:func:`cartan.io.frame_record`).

    Strains, velocities, momenta and the total momentum get zero out-of-plane components,
    positions z = 0, frames e₃ = +z; the group defect is recomputed on the lifted frames; the
    energies, residuals and the medium's output fields are the same numbers.
    """
    out: dict[str, list] = {}
    for name, values in records.items():
        if name in ("X", "N", "S", "total_momentum"):
            out[name] = [lift_components(v) for v in values]
        elif name == "position":
            out[name] = [np.concatenate([v, np.zeros((*np.shape(v)[:-1], 1))], axis=-1) for v in values]
        elif name == "frame":
            lifted = []
            for v in values:
                E = np.zeros((*np.shape(v)[:-2], 3, 3))
                E[..., :2, :2] = v
                E[..., 2, 2] = 1.0
                lifted.append(E)
            out[name] = lifted
        else:
            out[name] = list(values)
    if "group_defect" in out and "position" in out and "frame" in out:
        defects = []
        for pos, E in zip(out["position"], out["frame"], strict=True):
            Phi = np.zeros((*np.shape(pos)[:-1], 4, 4))
            Phi[..., 0, 0] = 1.0
            Phi[..., 1:, 0] = pos
            Phi[..., 1:, 1:] = E
            defects.append(float(np.max(full_group.defect(Phi))) if Phi.size else 0.0)
        out["group_defect"] = defects
    return out


def reduction_pays(run: _ResolvedRun) -> bool:
    """Whether the reduced run is expected to cost less than ``run``, the full one.

    Not where the full run's steps go to the ``lattice`` scheme's hand-written compiled loops
    (``Lattice.compiled_advance``: SE(3) rods with ``lie-verlet`` or ``overdamped`` of order 1,
    :func:`cartan.schemes._lattice_compiled.runs`): they are vectorised for SE(3) rods, and SE(2)
    has the generated loops only, on which the SE(2) run of a planar rod costs about what the
    SE(3) run does (0.85–1.18× its time, ``lie-verlet``, n = 101–1001 nodes): nothing to gain.
    Everywhere else the reduced run is faster: the generated loops on both groups, whose SE(2)
    passes are closed-form as SE(3)'s (the SE(3) run takes 2.3–3.0× the reduced one's time with
    ``rkmk4``, 2.3–3.2× with ``lie-euler``, 1.7–2.2× with ``lie-verlet`` on a problem the
    hand-written loops decline, at n = 101–1001; ``forward-euler``, ``overdamped`` of order 2,
    ``collocation``), the Python loop, integrators with their own compiled blocks
    (``implicit-midpoint``, 2.1–2.85×).

    Parameters
    ----------
    run : cartan.simulate._ResolvedRun
        The full run, resolved.

    Returns
    -------
    bool
    """
    if not run.compiled or getattr(run.integrator, "compiled_advance", None) is not None:
        return True
    from .schemes._lattice_compiled import runs

    return not (run.scheme.plan_module == "_lattice_compiled" and runs(run.scheme, run.integrator))


def run_reduced(run: _ResolvedRun, *, restart: Any = None) -> xr.Dataset | None:
    """Run ``run`` (resolved by :func:`cartan.simulate`) on its exact reduction, or return None.

    Parameters
    ----------
    run : cartan.simulate._ResolvedRun
        The full run, resolved and not executed: its time step, CFL estimate, step count,
        save interval, output file, history and configuration are those of the result.  Not
        modified.
    restart : path or None
        The restart file of the call; a restart is never reduced.

    Returns
    -------
    xarray.Dataset or None
        The Dataset of the full run, with the attribute ``cartan_reduction``; None when the run
        admits no exact reduction, when the reduction would not pay (:func:`reduction_pays`),
        when the run writes a file (a restart of it continues on the full group, and a restart
        is exact only when both halves step on the same group: bit for bit against the run it
        continues), when the integrator prescribes the velocity (``kinematic``: data the planar
        test cannot see), or when the reduced run blew up: the caller runs it in full.
    """
    from . import io
    from .simulate import InstabilityError, StabilityWarning, _execute_run, _resolve_run

    if (
        restart is not None
        or run.output is not None
        or run.checkpoint_every is not None
        or run.step != 0
        or not reduction_pays(run)
    ):
        return None
    if getattr(run.integrator, "velocity_field", None) is not None:
        return None  # a prescribed velocity is data the reduction cannot see: it may leave the plane
    red = planar_reduction(run.problem)
    if red is None:
        return None
    cfg = run.info["run"]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", StabilityWarning)  # the full run has warned (or not)
            small = _resolve_run(
                red.reduced,
                type(run.integrator),
                type(run.scheme),
                run.dt,
                cfg["t_end"],
                run.save_every,
                None,
                None,
                None,
                run.integrator.options(),
                run.scheme.options(),
                run.progress,
                run.growth,
                compiled=run.compiled,
                command="",
                max_steps=max(run.nsteps, 1),
            )
    except (ValueError, TypeError):
        return None
    if small.nsteps != run.nsteps:
        return None
    try:
        _execute_run(small)
    except InstabilityError as exc:  # run it in full: the error and the state on disk are the full run's
        if exc.path is not None:
            with contextlib.suppress(OSError):
                exc.path.unlink()
        return None
    records = lift_records(small.records, run.problem.medium.group)
    config = {
        "problem": run.info["problem"],
        "run": run.info["run"],
        "counters": small.integrator.counters(),
        "scene": run.info["scene"],
        "scene_path": run.info["scene_path"],
    }
    ds = io.build_dataset(run.scheme, records, config=config, history=run.history)
    ds.attrs["cartan_reduction"] = red.kind
    return ds
