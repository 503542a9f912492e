"""Hand-written compiled step loops of the ``lattice`` scheme: SE(3) rods (ARCHITECTURE.md §7).

Whole multi-step loops between saves run here, in numba, for the problems the T1 benchmark
(a Cosserat rod, ``docs/performance.md``) needs: SE(3) on a d = 1 grid with a quadratic
potential, loads that are data (damping, body-frame uniform force, constant-field
potentials, end loads, clamps), stepped by ``lie-verlet`` with every free-flow piece in
closed form (every rod with positive inertias) or by ``overdamped`` of order 1.  They run
the structure-of-arrays loops of :mod:`cartan.schemes._lattice_compiled_soa` on the plan of
:mod:`cartan.schemes._lattice_compiled_plan`.  Every other lattice problem — the other
groups, d = 2 and 3, the other integrators, free-flow pieces without closed form — runs the
generated loops (:mod:`cartan.schemes._lattice_ops` with :mod:`cartan.integrators.loops`),
which :meth:`cartan.schemes.lattice.Lattice.compiled_advance` leaves them to by returning False
(``docs/design.md``, "Decision (lattice)").

* **Same formulas as the reference path.**  Every step performs the operations of
  ``Integrator.step`` with ``Lattice.force``/``drift``/``velocity``/``constrain``/``powers``,
  including the trapezoidal booking of dissipated power and external work, in the same
  order, so that the compiled and the Python paths agree to round-off (≈1e-13 in the
  tests).
* **No per-step allocation.**  The work arrays are kept on the scheme between calls; the
  state arrays are updated in place.
* **Per-step blow-up test.**  After every step the loop tests what the run's guard tests
  (``cartan.simulate``): finite momentum and ``½Σ w S²/m ≤ kinetic_limit`` (or, for
  ``overdamped``, a finite configuration), and stops after the first failing step so that
  the caller can name it.
* **Threads.**  With ``CARTAN_THREADS`` (or :func:`cartan.set_threads`) above 1 and a rod of
  at least :data:`cartan._threads.MIN_NODES` nodes the threaded builds run, with the same
  results bit for bit.
"""

from __future__ import annotations

import contextlib
import time

import numpy as np

from .._threads import loop_threads, numba_threads
from . import _lattice_compiled_soa as soa
from ._lattice_compiled_kernels import KIND_GENERIC, KIND_ROTATION, KIND_SE3_TRANSLATION
from ._lattice_compiled_plan import CHECK_CONFIGURATION, CHECK_MOMENTUM, build_plan
from ._lattice_compiled_soa import lie_verlet_se3_loop, overdamped_se3_loop

__all__ = [
    "advance",
    "build_plan",
    "compiled_kind",
    "finish_advance",
    "force_once",
    "lie_verlet_se3_loop",
    "may_run",
    "overdamped_se3_loop",
    "runs",
]


# ---------------------------------------------------------------------------- Python glue
def _writable(a: np.ndarray) -> np.ndarray:
    """``a`` itself when it is a writable C-contiguous float64 array, else such a copy."""
    if isinstance(a, np.ndarray) and a.dtype == np.float64 and a.flags.c_contiguous and a.flags.writeable:
        return a
    return np.array(a, dtype=np.float64, order="C")


def _cache(scheme) -> dict:
    """The scheme's cache of compiled data (work arrays, free-flow sequences, ``1/m``)."""
    return scheme.__dict__.setdefault("_compiled_cache", {})


def _inverse_mass(scheme) -> np.ndarray:
    """``1/m`` on the live components, 0 on gauge ones ``(6,)``, cached on the scheme."""
    cache = _cache(scheme)
    inv = cache.get("inv")
    if inv is None:
        inv = cache["inv"] = np.where(scheme.live, 1.0 / np.where(scheme.live, scheme.mass, 1.0), 0.0)
    return inv


def _lie_verlet_sequence(integrator, scheme, dt: float, cache: dict) -> tuple[np.ndarray, np.ndarray]:
    """``LieVerlet._sequence`` as arrays, cached per Δt in ``cache`` (the sequence depends on
    the scheme's group and live components only): ``τ/m`` per piece and component ``[k, 6]``,
    and (kind, body axis) per piece ``[k, 2]`` (:data:`KIND_SE3_TRANSLATION`,
    :data:`KIND_ROTATION` about one body axis, else :data:`KIND_GENERIC`)."""
    key = ("lie-verlet", dt)
    if key in cache:
        return cache[key]
    seq = integrator._sequence(scheme)
    r = scheme.group.dim
    mask = np.zeros((len(seq), r), dtype=np.bool_)
    frac = np.empty(len(seq))
    kind = np.zeros((len(seq), 2), dtype=np.int64)
    for p, (P, f) in enumerate(seq):
        idx = sorted(int(i) for i in np.flatnonzero(np.diag(P)))
        mask[p, idx] = True
        frac[p] = f
        if idx == [0, 1, 2]:
            kind[p] = (KIND_SE3_TRANSLATION, 0)
        elif len(idx) == 1 and idx[0] >= 3:
            kind[p] = (KIND_ROTATION, idx[0] - 3)
    fac = np.where(mask, (frac * dt)[:, None] / np.where(scheme.live, scheme.mass, 1.0), 0.0)
    if len(cache) > 16:
        cache.clear()
    cache[key] = (np.ascontiguousarray(fac), kind)
    return cache[key]


def _soa_workspace(cache: dict, n: int, ne: int, nf: int, nblocks: int) -> tuple:
    """The work arrays of the structure-of-arrays loops (:func:`~cartan.schemes._lattice_compiled_soa.workspace`),
    kept in the scheme's cache between calls so that a run touches their pages once (the
    latest size only)."""
    key = (n, ne, nf, nblocks)
    held = cache.get("soa_work")
    if held is None or held[0] != key:
        held = cache["soa_work"] = (key, soa.workspace(n, ne, nf, nblocks))
    return held[1]


def _rod_arrays(scheme, state) -> tuple[np.ndarray, np.ndarray] | None:
    """``(G [ne, 4, 4], Phi [n or 1, 4, 4])`` of a rod state (views of the state's arrays,
    made writable C-contiguous float64 in place), or None for another layout."""
    key = scheme._key(0)
    frame_key = "Phi" if scheme.track else "Phi_root"
    if set(state.arrays) != {key, frame_key}:
        return None
    G = state.arrays[key] = _writable(state.arrays[key])
    Phi = state.arrays[frame_key] = _writable(state.arrays[frame_key])
    return G, Phi.reshape(-1, 4, 4)


#: the built-in integrators whose steps these loops take (:func:`compiled_kind` refines per problem)
_KINDS = ("lie-verlet", "overdamped")


def may_run(integrator) -> bool:
    """Whether these loops can take the steps of ``integrator`` on some problem: one of the
    built-in ``lie-verlet`` or ``overdamped`` (the type and name only, no plan built).  When False,
    :func:`compiled_kind` is None on every scheme, so that
    :meth:`~cartan.schemes.lattice.Lattice.compiled_advance` declines at once, before building the
    plan, at every save block of the run (``rattle``, ``rkmk4``, … take the generated loops)."""
    return type(integrator).__module__ == "cartan.integrators.explicit" and integrator.name in _KINDS


def compiled_kind(scheme, integrator) -> tuple | None:
    """``(integrator name, drag Γ or None)`` when the loops of this module run ``integrator``,
    else None: ``lie-verlet`` with every free-flow piece in closed form (no zero inertia), and
    ``overdamped`` of order 1 with a positive drag on every live component (without, the
    reference path raises the error)."""
    # the built-in integrators (known by name; the loops below are their steps), not subclasses
    kind = integrator.name if may_run(integrator) else None
    if kind == "lie-verlet":
        _, kinds = _lie_verlet_sequence(integrator, scheme, 1.0, _cache(scheme))
        return (kind, None) if np.all(kinds[:, 0] != KIND_GENERIC) else None
    if kind == "overdamped" and integrator.order == 1:
        gam = np.asarray(scheme.drag(), dtype=float)
        return None if np.any(scheme.live & ~(gam > 0)) else (kind, gam)
    return None


def runs(scheme, integrator) -> bool:
    """Whether :meth:`~cartan.schemes.lattice.Lattice.compiled_advance` takes the steps of
    ``integrator`` on ``scheme``'s problem (with the numba backend): the problem has a plan
    (:func:`build_plan`) and the integrator is one of :func:`compiled_kind`'s."""
    if scheme.coupled_lagrangian or getattr(scheme, "_glue", None):
        return False
    return scheme.compiled_plan("_lattice_compiled") is not None and compiled_kind(scheme, integrator) is not None


def advance(scheme, plan: tuple, integrator, state, dt: float, nsteps: int, kinetic_limit: float) -> bool:
    """Run up to ``nsteps`` steps of ``integrator`` on ``state`` in compiled code (see
    :meth:`cartan.schemes.lattice.Lattice.compiled_advance`); False, touching nothing, when
    the integrator is not supported (the generated loops then take the steps)."""
    supported = compiled_kind(scheme, integrator)
    if supported is None:
        return False
    kind, gam = supported
    if not set(state.arrays) == {scheme._key(0), "Phi" if scheme.track else "Phi_root"}:
        return False
    nsteps = int(nsteps)
    if nsteps <= 0:
        return True
    t_start = time.perf_counter()
    dt = float(dt)
    n, r = scheme.grid.size, scheme.group.dim
    S = state.S = _writable(state.S)
    S2 = S.reshape(n, r)
    G, Phi3 = _rod_arrays(scheme, state)
    nstep0, stamp, t0, diss, ext, check, limit, cache, inv = advance_context(scheme, integrator, state,
                                                                             kinetic_limit)
    threads = loop_threads(n)
    W = None
    with numba_threads(threads) if threads > 1 else contextlib.nullcontext():
        work = _soa_workspace(cache, n, G.shape[0], Phi3.shape[0], threads)
        if kind == "lie-verlet":
            velocity_free, have, W = lie_verlet_force(scheme, integrator, stamp, S)
            fac, kinds = _lie_verlet_sequence(integrator, scheme, dt, cache)
            loop = soa.THREADED["lie_verlet_se3_loop"] if threads > 1 else soa.lie_verlet_se3_loop
            done, nforce, t, diss, ext = loop(
                plan, S2, G, Phi3, W.reshape(n, r), have, bool(velocity_free), fac,
                np.ascontiguousarray(kinds[:, 0]), np.ascontiguousarray(kinds[:, 1]), t0, dt, nsteps, diss, ext,
                check, limit, inv, soa.THREAD_BLOCK_CHUNKS, work, threads)
        else:
            hit, N = overdamped_velocity(integrator, stamp, S)
            # the velocity of the state, from the state alone (overdamped_velocity)
            soa.overdamped_velocity(plan, G, Phi3, N.reshape(n, r), gam, inv, work)
            loop = soa.THREADED["overdamped_se3_loop"] if threads > 1 else soa.overdamped_se3_loop
            done, t, diss, ext = loop(plan, S2, G, Phi3, N.reshape(n, r), gam, t0, dt, nsteps, diss, ext, check, inv,
                                      work, threads)
            nforce = overdamped_books(integrator, state, done, hit, t, nstep0, N)
    return finish_advance(integrator, state, t, diss, ext, nstep0, done, nforce, W, t_start)


def lie_verlet_force(scheme, integrator, stamp: tuple, S: np.ndarray) -> tuple[bool, bool, np.ndarray]:
    """``(velocity_free, have, W)`` for a compiled ``lie-verlet`` loop: whether no force depends
    on the velocity, whether the integrator's first-same-as-last force belongs to the state
    (``stamp`` of :func:`advance_context`), and that force (a C-ordered copy shaped like
    ``S``) or zeros."""
    velocity_free = scheme.problem.velocity_free
    fsal = integrator._fsal
    have = bool(velocity_free and fsal is not None and fsal[0] == stamp)
    W = np.array(fsal[1], dtype=float, order="C").reshape(S.shape) if have else np.zeros_like(S)
    return velocity_free, have, W


def overdamped_velocity(integrator, stamp: tuple, S: np.ndarray) -> tuple[bool, np.ndarray]:
    """``(hit, N)`` for a compiled overdamped loop: an empty array for the caller to fill with
    the velocity of the state computed by the compiled kernels
    (:func:`cartan.schemes._lattice_compiled_soa.overdamped_velocity`), and ``hit`` when the
    integrator holds a velocity for the state (``Overdamped.velocity``, e.g. from a saved
    frame), which the reference path would reuse — for the force count only.

    That velocity is not taken: it comes from the reference path, which agrees with the
    compiled kernels to round-off only, and a restarted run, whose state comes from a file,
    has none.  Computed from the state alone — bit for bit the velocity the loop carries from
    one step to the next — the steps do not depend on how they are grouped into calls, and a
    restart continues a run bit for bit."""
    cached = integrator._cache
    return bool(cached is not None and cached[0] == stamp), np.empty_like(S)


def overdamped_books(integrator, state, done: int, hit: bool, t: float, nstep0: int, N: np.ndarray) -> int:
    """The force evaluations of ``done`` overdamped steps (order 1) as the reference path counts
    them (the velocity of the state after every step, which is also the first stage of the
    next, and the velocity of the initial state unless the integrator's cache holds it
    (``hit``, as :func:`overdamped_velocity` reports it)), and the overdamped velocity ``N`` of
    the final state cached on the integrator."""
    integrator._cache = ((id(state), t, nstep0 + done), N.copy(), True)
    return done + (0 if hit else 1)


def advance_context(scheme, integrator, state, kinetic_limit: float) -> tuple:
    """What a compiled ``advance`` reads from ``state`` and the scheme before its loop:
    ``(nstep0, stamp, t0, dissipated, external, check, kinetic_limit, cache, inv)`` — the step
    count, the continuation stamp of the integrator's caches, the time and energy
    accumulators, the blow-up test (:data:`CHECK_MOMENTUM` for integrators that carry momenta,
    else :data:`CHECK_CONFIGURATION`), the scheme's cache of compiled data and ``1/m`` on the
    live components (0 on gauge ones)."""
    nstep0 = state.scalars.get("nstep", 0)
    inv = _inverse_mass(scheme)
    return (nstep0, (id(state), state.t, nstep0), float(state.t), float(state.scalars.get("dissipated_energy", 0.0)),
            float(state.scalars.get("external_work", 0.0)),
            CHECK_MOMENTUM if integrator.uses_momentum else CHECK_CONFIGURATION, float(kinetic_limit),
            _cache(scheme), inv)


def finish_advance(integrator, state, t: float, diss: float, ext: float, nstep0: int, done: int, nforce: int,
                   W, t_start: float) -> bool:
    """Book ``done`` compiled steps as ``integrator.step`` would: ``state.t``, the energy
    accumulators and ``"nstep"`` of ``state.scalars``, the FSAL force ``W`` (or None), and the
    integrator's counters (``wall_time`` since ``t_start``).  Returns True (steps were taken)."""
    state.t = t
    state.scalars["dissipated_energy"] = diss
    state.scalars["external_work"] = ext
    state.scalars["nstep"] = nstep0 + done
    if W is not None:
        integrator._fsal = ((id(state), t, nstep0 + done), W)
    integrator.nstep += done
    integrator.nforce += nforce
    integrator.wall_time += time.perf_counter() - t_start
    return True


def force_once(scheme, plan: tuple, G: np.ndarray, Phi: np.ndarray, N: np.ndarray, W: np.ndarray,
               V: np.ndarray | None = None, tau: float = 0.0) -> None:
    """One force evaluation ``W [n, 6]`` (filled in place) of the rod ``G [ne, 4, 4]``,
    ``Phi [n or 1, 4, 4]`` at the velocity ``N [n, 6]``, after the drift ``Φ ← Φ exp(τV)``
    when ``V`` is given (``G`` and ``Phi`` are not modified): the force of the loops
    (:func:`cartan.schemes._lattice_compiled_soa.force_at`), compared with ``Lattice.force``
    by the tests and used by the CFL probe."""
    n = W.shape[0]
    G = np.ascontiguousarray(G, dtype=float).reshape(-1, 4, 4)
    Phi = np.ascontiguousarray(Phi, dtype=float).reshape(-1, 4, 4)
    work = _soa_workspace(_cache(scheme), n, G.shape[0], Phi.shape[0], 1)
    N = np.ascontiguousarray(N, dtype=float).reshape(n, 6)
    V = N if V is None else np.ascontiguousarray(V, dtype=float).reshape(n, 6)
    soa.force_at(plan, G, Phi, N, V, float(tau) if V is not N else 0.0, W, _inverse_mass(scheme), work)
