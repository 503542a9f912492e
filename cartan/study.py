"""Convergence, work-precision and stability studies (``docs/verification.md``).

:func:`converge` refines a verification case in space and/or time and returns one Dataset with
dims ``(integrator, scheme, level)``: the error, the cost (wall time, force evaluations,
steps), the step sizes and the observed order of accuracy fitted on the asymptotic levels.
:func:`stability` bisects the largest stable time step against the grid spacing beside the
integrator's CFL estimate.  :func:`plot_work_precision`, :func:`plot_error_vs_h` and
:func:`plot_stability` chart them; :func:`traces` records the integrability residual and the
relative energy error of one run per integrator × scheme, charted by :func:`plot_traces`.

A case runs through its own ``case.run`` (a dynamic run by :func:`cartan.simulate`, or a
static solve whose "integrator" is ``newton``; see ``cartan_verification.case``); an object
without one is run by :func:`cartan.simulate`.

Scale-out
---------
Every (integrator, scheme, level) run is an independent task.  ``client=None`` runs them in
this process one after the other; ``client="local"`` starts a ``dask.distributed.LocalCluster``
(two worker processes); a ``"tcp://host:port"`` string connects to a running scheduler (see
``dask scheduler`` / ``dask worker``); a ``distributed.Client`` is used as given.  With
``store=DIR`` each finished task is written to ``DIR/<task key>.json`` as soon as it completes
(atomically, first completion wins), and a rerun with the same store loads finished tasks
instead of running them again, so a study interrupted at any point loses no finished work.  A
task whose worker dies is retried by dask on another worker; its result file is still written
once.  With workers on several machines, ``DIR`` must be on a shared file system.  dask is the
optional extra ``dist``: ``pip install 'cartan[dist]'``.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import pathlib
import re
import tempfile
import time
import warnings
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np

__all__ = [
    "StudyError",
    "converge",
    "expected_order",
    "observed_order",
    "plot_error_vs_h",
    "plot_stability",
    "plot_traces",
    "plot_work_precision",
    "stability",
    "task_key",
    "traces",
]

REFINE = ("space", "time", "both")
#: Time-refinement reference: a run of the same integrator with the finest Δt divided by this.
REFERENCE_DIVISOR = 8
#: Errors at or below this are round-off: they are left out of the order fit.
ROUNDOFF = 1e-12
DIST_HINT = "pip install 'cartan[dist]'"


class StudyError(RuntimeError):
    """A study cannot run as asked (bad refinement, missing optional dependency, ...)."""


# ---------------------------------------------------------------------------- case helpers
def _case_obj(case: Any) -> Any:
    """A case instance from an instance, a Case subclass or a registered case name."""
    if isinstance(case, str):
        from .plugins import get_registry

        case = get_registry().get("cases", case)
    return case() if isinstance(case, type) else case


def expected_order(case: Any, integrator: str, refine: str) -> float:
    """The order the case expects for ``integrator`` under ``refine`` (nan when unknown, or when
    the case is met to round-off at every level: ``case.roundoff``)."""
    if getattr(case, "roundoff", False):
        return math.nan
    if getattr(case, "parameter_order", None) is not None:
        return float(case.parameter_order)
    space = getattr(case, "space_order", None)
    spec = getattr(case, "time_order_of", None)
    if callable(spec):
        t = spec(integrator)
    elif isinstance(spec, dict):
        t = spec.get(integrator)
    else:
        t = None
    if t is None:
        try:
            from .plugins import get_registry

            t = getattr(get_registry().get("integrators", integrator), "order", None)
        except Exception:  # noqa: BLE001 - an unknown integrator simply has no expectation
            t = None
    space = math.nan if space is None else float(space)
    t = math.nan if t is None else float(t)
    if refine == "space":
        return space
    if refine == "time":
        return t
    finite = [v for v in (space, t) if math.isfinite(v)]
    return min(finite) if finite else math.nan


def _self_referenced(case: Any, refine: str) -> bool:
    """Time refinement of a spatially discretised case: compared with a fine-Δt run."""
    return refine == "time" and getattr(case, "space_order", None) is not None


def task_key(case_name: str, refine: str, levels: int | str, integrator: str, scheme: str, level: int | str) -> str:
    """The name of one task (and of its file in a store): safe in file names and dask keys."""
    raw = f"{case_name}--{refine}{levels}--{integrator}--{scheme}--{level}"
    return re.sub(r"[^A-Za-z0-9_.+=-]", "_", raw)


def _settings(case: Any, level: int | str, scheme: str, refine: str, finest: int) -> tuple[Any, dict]:
    """(problem, run settings) of one task; ``level="ref"`` is the fine-Δt reference run; ``finest``
    the study's finest level."""
    if refine == "both":
        problem, run = case.problem(int(level), scheme)
        return problem, dict(run)
    if refine == "space":
        problem, run = case.problem(int(level), scheme)
        run = dict(run)
        if "dt" not in run:  # a static case: nothing to step in time
            return problem, run
        fine = dict(case.problem(finest, scheme)[1])
        dt = min(float(run["dt"]), float(fine["dt"]))
        if run.get("save_every"):  # the same saved times as the case asked for at this level
            run["save_every"] = max(1, round(float(run["dt"]) * int(run["save_every"]) / dt))
        run["dt"] = dt
        return problem, run
    problem, run = case.problem(0, scheme)
    run = dict(run)
    factor = 2 ** finest * REFERENCE_DIVISOR if level == "ref" else 2 ** int(level)
    run["dt"] = float(run["dt"]) / factor
    if run.get("save_every"):
        run["save_every"] = int(run["save_every"]) * factor
    return problem, run


def _final(ds: Any, name: str) -> np.ndarray:
    var = ds[name]
    if "time" in var.dims:
        var = var.isel(time=-1)
    return np.asarray(var.values, dtype=float).ravel()


def _quantity(case: Any, ds: Any) -> np.ndarray:
    """The compared quantity at the final time, for self-referenced (fine-Δt) errors."""
    fn = getattr(case, "quantity_of", None)
    if callable(fn):
        return np.asarray(fn(ds), dtype=float).ravel()
    q = getattr(case, "quantity", None)
    if isinstance(q, str) and q in ds.data_vars:
        return _final(ds, q)
    names = [n for n in ("X", "N", "position") if n in ds.data_vars] or list(ds.data_vars)[:1]
    return np.concatenate([_final(ds, n) for n in names])


def _spacing(problem: Any) -> tuple[float, int]:
    grid = problem.grid
    return float(min(grid.spacing)), int(np.prod(grid.shape))


# ---------------------------------------------------------------------------- one task
def _execute(case: Any, problem: Any, run: dict, integrator: str, scheme: str, compiled: bool) -> Any:
    """The Dataset of one run: ``case.run(problem, run, integrator, scheme, compiled)`` when the
    case has it (verification cases: dynamic or static), else :func:`cartan.simulate`."""
    fn = getattr(case, "run", None)
    if callable(fn):
        return fn(problem, run, integrator, scheme, compiled)
    from .simulate import simulate

    return simulate(problem, integrator=integrator, scheme=scheme, dt=run["dt"], t_end=run["t_end"],
                    save_every=run.get("save_every"), compiled=compiled, progress=False,
                    integrator_options=run.get("integrator_options"), scheme_options=run.get("scheme_options"))


def _counters(ds: Any) -> dict[str, float]:
    """nstep, nforce, wall_time of a run's Dataset (NaN where the run did not count them)."""
    config = ds.attrs.get("cartan_config")
    counters = json.loads(config).get("counters", {}) if config else {}
    return {"nstep": float(counters.get("nstep", math.nan)), "nforce": float(counters.get("nforce", math.nan)),
            "wall_time": float(counters.get("wall_time", ds.attrs.get("wall_time", math.nan)))}


def _unstable_status(exc: Exception) -> str:
    """The one-line reason of an InstabilityError, its last-good-state file removed."""
    path = getattr(exc, "path", None)
    if path is not None and pathlib.Path(path).name.startswith("cartan-unstable-"):
        pathlib.Path(path).unlink(missing_ok=True)
    return "unstable: " + re.sub(r";\s*last good state.*$", "", " ".join(str(exc).split()))


def _store_path(store: str | os.PathLike, key: str) -> pathlib.Path:
    return pathlib.Path(store) / f"{key}.json"


def _load(path: pathlib.Path) -> dict | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _write_once(path: pathlib.Path, result: dict) -> None:
    """Write ``result`` to ``path`` atomically; the first completion wins (later ones are dropped)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as fh:
            json.dump(result, fh)
            fh.flush()
            os.fsync(fh.fileno())
        try:
            os.link(tmp, path)  # fails if the file is already there: written exactly once
        except FileExistsError:
            pass
        except OSError:  # file systems without hard links: an atomic rename
            os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)


def _run_task(case: Any, integrator: str, scheme: str, level: int | str, refine: str, finest: int,
              key: str, store: str | None, compiled: bool = True) -> dict:
    """Run one (integrator, scheme, level) task and return (and store) its result."""
    from .simulate import InstabilityError
    from .statics import ConvergenceError

    path = _store_path(store, key) if store else None
    if path is not None and path.exists():
        done = _load(path)
        if done is not None:
            done["cached"] = True
            return done
    problem, run = _settings(case, level, scheme, refine, finest)
    h, n = _spacing(problem)
    result: dict[str, Any] = {"key": key, "integrator": integrator, "scheme": scheme, "level": level,
                              "dt": float(run.get("dt", math.nan)), "h": h, "n": n, "status": "ok"}
    start = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ds = _execute(case, problem, run, integrator, scheme, compiled)
        result.update(_counters(ds))
        resid = np.asarray(ds["integrability_residual"].values, float) if "integrability_residual" in ds else None
        result["integrability_residual"] = float(np.max(resid)) if resid is not None and resid.size else math.nan
        if _self_referenced(case, refine):
            result["quantity"] = _quantity(case, ds).tolist()
            result["error"] = math.nan
        else:
            result["error"] = float(case.error(ds, problem))
    except (InstabilityError, ConvergenceError) as exc:
        status = (_unstable_status(exc) if isinstance(exc, InstabilityError)
                  else "no equilibrium: " + " ".join(str(exc).split()))
        result.update(status=status, error=math.inf, nstep=-1, nforce=-1, wall_time=time.perf_counter() - start,
                      integrability_residual=math.nan)
        if _self_referenced(case, refine):
            result["quantity"] = None
    if path is not None:
        _write_once(path, result)
        return _load(path) or result
    return result


# ---------------------------------------------------------------------------- scheduling
def _dask():
    try:
        import distributed
    except ImportError as exc:
        raise StudyError(f"distributed studies need dask.distributed: {DIST_HINT}") from exc
    return distributed


@contextlib.contextmanager
def _client(client: Any):
    """None (serial), "local", "tcp://..." or a distributed.Client → a client (or None)."""
    if client is None:
        yield None
        return
    if isinstance(client, str):
        distributed = _dask()
        if client == "local":
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                                   dashboard_address=None)
            c = distributed.Client(cluster)
            try:
                yield c
            finally:
                c.close()
                cluster.close()
            return
        try:
            c = distributed.Client(client, timeout="20s")
        except OSError as exc:
            raise StudyError(f"cannot reach the dask scheduler at {client}: {exc}") from None
        try:
            yield c
        finally:
            c.close()
        return
    yield client


def _map(fn: Callable, tasks: Sequence[tuple[str, tuple]], client: Any) -> dict[str, Any]:
    """Run ``fn(*args)`` for every ``(key, args)``; results by key."""
    with _client(client) as c:
        if c is None:
            return {key: fn(*args) for key, args in tasks}
        distributed = _dask()
        futures = {c.submit(fn, *args, key=f"cartan-study-{key}", pure=False, retries=1): key
                   for key, args in tasks}
        out = {}
        for fut in distributed.as_completed(list(futures)):
            out[futures[fut]] = fut.result()
            fut.release()
        return out


# ---------------------------------------------------------------------------- converge
def observed_order(x: Iterable[float], error: Iterable[float], roundoff: float = ROUNDOFF) -> float:
    """Fitted slope of log(error) against log(x) on the asymptotic levels.

    Levels whose error is not finite or is at round-off (≤ ``roundoff``) are left out; with
    four or more levels left the coarsest is dropped too (pre-asymptotic).  Least squares on
    the rest; nan with fewer than two.
    """
    x = np.asarray(list(x), dtype=float)
    e = np.asarray(list(error), dtype=float)
    ok = np.isfinite(x) & np.isfinite(e) & (x > 0) & (e > roundoff)
    x, e = x[ok], e[ok]
    if len(x) >= 4:
        coarse = np.argmax(x)
        keep = np.arange(len(x)) != coarse
        x, e = x[keep], e[keep]
    if len(x) < 2 or np.ptp(np.log(x)) == 0:
        return math.nan
    return float(np.polyfit(np.log(x), np.log(e), 1)[0])


def converge(case: Any, integrators: Sequence[str] | None = None, schemes: Sequence[str] | None = None,
             levels: int | Sequence[int] = 4, refine: str | None = None, client: Any = None,
             store: str | os.PathLike | None = None, compiled: bool = True,
             order_slack: float | tuple[float, float] = (0.2, 0.3)) -> Any:
    """Refine ``case`` over ``levels`` levels for every integrator × scheme.

    Parameters
    ----------
    case : Case, Case subclass or registered case name
        A verification case (``cartan_verification.case.Case`` interface): ``problem(level,
        scheme) -> (problem, dict(dt=, t_end=, save_every=))`` and ``error(ds, problem)``.
    integrators, schemes : sequence of str
        Registered names (default: the case's ``default_integrators`` and ``default_schemes``,
        else ``["lattice"]``).
    levels : int or sequence of int
        Number of refinement levels 0, 1, … (≥ 2; the protocol asks for ≥ 4), or the levels
        themselves, increasing (a case's own ``levels``, which need not start at 0).
    refine : {"space", "time", "both"}
        ``"space"``: the case's level-``k`` problems, all run with the finest level's Δt so that
        time errors do not contaminate the space order (a static case has no Δt).  ``"time"``: the level-0 problem with
        Δt/2ᵏ; when the case is discretised in space (``space_order`` not None) the error is the
        max-norm distance of the compared quantity at the final time from a run with the
        finest Δt / 8 (so the spatial error cancels), otherwise ``case.error``.  ``"both"``:
        the case's level-``k`` problem and run settings as given.  Default: the case's own
        ``refine`` attribute when it has one, else ``"both"`` for a parameter limit
        (``parameter_order``), ``"space"`` when the case has a ``space_order``, else ``"time"``.
        A static case (``case.static``) is refined in space only.
    client : None, "local", "tcp://host:port" or distributed.Client
        Where the tasks run (see the module docstring).
    store : directory, optional
        One JSON file per finished task, named by its key (:func:`task_key`); finished tasks
        are not rerun.
    compiled : bool
        Passed to :func:`cartan.simulate`.
    order_slack : float or (float, float)
        ``passed`` accepts an observed order p_obs in [p − below, p + above] for
        ``order_slack = (below, above)`` (a float s: [p − s, p + s]), p the expected order.

    Returns
    -------
    xarray.Dataset
        dims (integrator, scheme, level); variables ``error``, ``wall_time``, ``nforce``,
        ``nstep`` (time steps, or Newton iterations of a static case), ``dt``, ``h``, ``n``,
        ``integrability_residual`` (max over the run's saved frames), ``local_order`` (log₂ of
        successive error ratios), ``status``, and per (integrator, scheme)
        ``observed_order``, ``expected_order``, ``tolerance`` and ``passed``.
    """
    import xarray as xr

    from . import __version__, io

    case = _case_obj(case)
    if getattr(case, "kind", "convergence") != "convergence":
        raise StudyError(f"case {getattr(case, 'name', case)!r} is a {case.kind} study, not refined against a "
                         f"reference: run it with `cartan verify --case {getattr(case, 'name', '')}`")
    below, above = (order_slack, order_slack) if np.ndim(order_slack) == 0 else order_slack
    below, above = float(below), float(above)
    if not (below >= 0 and above >= 0):
        raise ValueError(f"order_slack must be ≥ 0 (a number or a pair), got {order_slack!r}")
    if refine is None:
        refine = getattr(case, "refine", None)
    if refine is None:
        if getattr(case, "parameter_order", None) is not None:
            refine = "both"  # a limit case: its levels refine a parameter (e.g. r → ∞)
        else:
            refine = "space" if getattr(case, "space_order", None) is not None else "time"
    if refine not in REFINE:
        raise StudyError(f"refine must be one of {', '.join(REFINE)}, got {refine!r}")
    if getattr(case, "static", False) and refine != "space":
        raise StudyError(f"the static case {getattr(case, 'name', '')!r} is refined in space only "
                         f"(refine='space'), got refine={refine!r}")
    if np.ndim(levels) == 0:
        level_list, tag = list(range(int(levels))), str(int(levels))
    else:
        level_list = [int(v) for v in levels]
        tag = "L" + "_".join(map(str, level_list))
        if any(b <= a for a, b in zip(level_list, level_list[1:], strict=False)) or min(level_list, default=0) < 0:
            raise StudyError(f"levels must be increasing levels ≥ 0, got {list(levels)}")
    levels = len(level_list)
    if levels < 2:
        raise StudyError(f"a convergence study needs at least 2 levels, got {levels}")
    finest = level_list[-1]
    integrators = list(integrators or getattr(case, "default_integrators", None) or ["lie-verlet"])
    schemes = list(schemes or getattr(case, "default_schemes", None) or ["lattice"])
    name = str(getattr(case, "name", type(case).__name__))
    store_s = None if store is None else str(pathlib.Path(store).resolve())
    if store_s is not None:
        pathlib.Path(store_s).mkdir(parents=True, exist_ok=True)

    tasks: list[tuple[str, tuple]] = []
    extra: list[int | str] = ["ref"] if _self_referenced(case, refine) else []
    for integ in integrators:
        for sch in schemes:
            for lev in [*level_list, *extra]:
                key = task_key(name, refine, tag, integ, sch, lev)
                tasks.append((key, (case, integ, sch, lev, refine, finest, key, store_s, compiled)))
    # finished tasks in the store are loaded here, not sent anywhere
    results: dict[str, dict] = {}
    pending = []
    for key, args in tasks:
        done = _load(_store_path(store_s, key)) if store_s else None
        if done is not None:
            results[key] = done
        else:
            pending.append((key, args))
    results.update(_map(_run_task, pending, client))

    shape = (len(integrators), len(schemes), levels)
    arrays = {v: np.full(shape, np.nan) for v in ("error", "wall_time", "nforce", "nstep", "dt", "h", "n",
                                                  "integrability_residual")}
    status = np.full(shape, "", dtype=object)
    for i, integ in enumerate(integrators):
        for j, sch in enumerate(schemes):
            ref = results.get(task_key(name, refine, tag, integ, sch, "ref")) if extra else None
            for k, lev in enumerate(level_list):
                r = results[task_key(name, refine, tag, integ, sch, lev)]
                for v in arrays:
                    if v != "error":
                        arrays[v][i, j, k] = r.get(v, math.nan)
                status[i, j, k] = r.get("status", "ok")
                if ref is None:
                    arrays["error"][i, j, k] = r.get("error", math.nan)
                elif r.get("quantity") is None or ref.get("quantity") is None:
                    arrays["error"][i, j, k] = math.inf
                else:
                    diff = np.asarray(r["quantity"], float) - np.asarray(ref["quantity"], float)
                    arrays["error"][i, j, k] = float(np.max(np.abs(diff))) if diff.size else 0.0
    x_name = "dt" if refine == "time" or (refine == "both" and getattr(case, "space_order", None) is None) else "h"
    limit = getattr(case, "limit_levels", None) if getattr(case, "parameter_order", None) is not None else None
    if limit is not None:  # refinement in a limit parameter p (error ∝ p^-order): x = 1/p
        params = limit(level_list)
        arrays["limit"] = np.broadcast_to(np.array([1.0 / params[k] for k in level_list]), shape).copy()
        x_name = "limit"
    obs = np.full(shape[:2], np.nan)
    exp = np.full(shape[:2], np.nan)
    tols = np.full(shape[:2], np.nan)
    passed = np.zeros(shape[:2], dtype=np.int8)
    for i, integ in enumerate(integrators):
        for j, sch in enumerate(schemes):
            tol = tols[i, j] = _tolerance(case, integ, sch)
            if not getattr(case, "roundoff", False):  # round-off errors have no order to fit
                obs[i, j] = observed_order(arrays[x_name][i, j], arrays["error"][i, j])
            exp[i, j] = expected_order(case, integ, refine)
            e_fine = arrays["error"][i, j, -1]
            ok = bool(np.isfinite(e_fine) and e_fine <= tol)
            if math.isfinite(exp[i, j]) and math.isfinite(obs[i, j]):
                ok = ok and exp[i, j] - below <= obs[i, j] <= exp[i, j] + above
            passed[i, j] = ok
    with np.errstate(divide="ignore", invalid="ignore"):
        err = arrays["error"]
        local = np.full(shape, np.nan)
        local[..., 1:] = np.log(err[..., :-1] / err[..., 1:]) / np.log(
            arrays[x_name][..., :-1] / arrays[x_name][..., 1:])

    dims = ("integrator", "scheme", "level")
    units = {"error": ("error of the compared quantity in the case's norm", "1"),
             "wall_time": ("wall-clock time of the time loop", "s"),
             "nforce": ("number of force evaluations", "1"), "nstep": ("number of time steps", "1"),
             "dt": ("time step", "s"), "h": ("smallest grid spacing", "m"), "n": ("number of grid nodes", "1"),
             "integrability_residual": ("largest temporal integrability residual over the run's saved frames", "1"),
             "limit": ("inverse of the limit parameter (e.g. 1/r)", "1"),
             "local_order": (f"log of successive error ratios over log of successive {x_name} ratios", "1")}
    data = {v: (dims, a, {"long_name": units[v][0], "units": units[v][1]}) for v, a in arrays.items()}
    data["local_order"] = (dims, local, {"long_name": units["local_order"][0], "units": "1"})
    data["status"] = (dims, status.astype(str), {"long_name": "run status ('ok' or why it failed)"})
    data["observed_order"] = (dims[:2], obs, {
        "long_name": f"fitted slope of log error against log {x_name} on the asymptotic levels", "units": "1"})
    data["expected_order"] = (dims[:2], exp, {"long_name": "order of accuracy the case expects", "units": "1"})
    data["tolerance"] = (dims[:2], tols, {"long_name": "largest accepted error at the finest level", "units": "1"})
    data["passed"] = (dims[:2], passed, {
        "long_name": "finest error within tolerance and observed order in [expected − below, expected + above]",
        "flag_values": np.array([0, 1], dtype=np.int8), "flag_meanings": "fail pass"})
    ds = xr.Dataset(data, coords={"integrator": integrators, "scheme": schemes,
                                  "level": ("level", np.array(level_list), {"long_name": "refinement level"})})
    ds.attrs = {
        "Conventions": "CF-1.11",
        "title": f"convergence study: {name}",
        "source": f"cartan {__version__}",
        "history": io.history_line(f"cartan.converge({name!r}, integrators={integrators}, schemes={schemes}, "
                                   f"levels={level_list if tag.startswith('L') else levels}, refine={refine!r})"),
        "case": name,
        "medium": str(getattr(case, "medium", "")),
        "description": str(getattr(case, "description", "")),
        "reference": str(getattr(case, "reference", "")),
        "quantity": str(getattr(case, "quantity", "")),
        "norm": str(getattr(case, "norm", "")),
        "tolerance": float(np.nanmax(tols)) if np.isfinite(tols).any() else math.inf,
        "tolerance_reason": str(getattr(case, "tolerance_reason", "")),
        "refine": refine,
        "order_variable": x_name,
        "order_slack": [below, above],
        "error_reference": (f"run with the finest dt / {REFERENCE_DIVISOR}" if extra else "the case's reference"),
    }
    return ds


def _tolerance(case: Any, integrator: str, scheme: str) -> float:
    """The case's pass threshold for ``integrator`` on ``scheme`` (``tolerance_for(integrator,
    scheme)``, ``tolerance_for(integrator)`` or ``tolerance``)."""
    tol_of = getattr(case, "tolerance_for", None)
    if tol_of is None:
        return float(getattr(case, "tolerance", math.inf) or math.inf)
    try:
        return float(tol_of(integrator, scheme))
    except TypeError:  # a case whose tolerance_for takes the integrator only
        return float(tol_of(integrator))


# ---------------------------------------------------------------------------- traces
def _energy_error(ds: Any) -> np.ndarray:
    """|E(t) − E(0)| / E(0) with E = kinetic + potential (− dissipated + external work when recorded)."""
    energy = ds["kinetic_energy"].values + ds["potential_energy"].values
    for name, sign in (("dissipated_energy", 1.0), ("external_work", -1.0)):
        if name in ds:
            energy = energy + sign * ds[name].values
    scale = max(abs(float(energy[0])), 1e-300)
    return np.abs(energy - energy[0]) / scale


def traces(case: Any, integrators: Sequence[str], schemes: Sequence[str], level: int, frames: int = 100,
           compiled: bool = True) -> Any:
    """Invariant time series of one run per integrator × scheme of ``case`` at ``level``.

    Each run uses the case's own settings at ``level`` (its Δt, end time and run options, through
    ``case.run``), saving about ``frames`` frames.  Returns a Dataset with dims (integrator, scheme, frame): ``t``,
    ``integrability_residual`` (from the run's Dataset) and ``energy_error`` (relative energy
    error, see :func:`_energy_error`), and per (integrator, scheme) ``status`` (``"ok"`` or why
    the run stopped; a run that stops has NaN series).
    """
    import xarray as xr

    from .simulate import InstabilityError

    case = _case_obj(case)
    integrators, schemes = list(integrators), list(schemes)
    shape = (len(integrators), len(schemes), frames + 1)
    arr = {v: np.full(shape, np.nan) for v in ("t", "integrability_residual", "energy_error")}
    status = np.full(shape[:2], "ok", dtype=object)
    for i, integ in enumerate(integrators):
        for j, sch in enumerate(schemes):
            try:
                problem, run = case.problem(int(level), sch)
                run = dict(run)
                steps = max(1, round(float(run["t_end"]) / float(run["dt"])))
                run["save_every"] = max(1, steps // frames)
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    ds = _execute(case, problem, run, integ, sch, compiled)
            except InstabilityError as exc:
                status[i, j] = _unstable_status(exc)
                continue
            except ValueError as exc:  # the scheme does not support the problem
                status[i, j] = "unsupported: " + " ".join(str(exc).split())
                continue
            m = min(len(ds["time"]), frames + 1)
            arr["t"][i, j, :m] = ds["time"].values[:m]
            if "integrability_residual" in ds:
                arr["integrability_residual"][i, j, :m] = ds["integrability_residual"].values[:m]
            arr["energy_error"][i, j, :m] = _energy_error(ds)[:m]
    dims = ("integrator", "scheme", "frame")
    attrs = {"t": ("time of the saved frame", "s"),
             "integrability_residual": ("temporal integrability residual max|X_stored − X(Φ)|", "1"),
             "energy_error": ("relative energy error |E(t) − E(0)|/E(0), E = kinetic + potential", "1")}
    data = {v: (dims, a, {"long_name": attrs[v][0], "units": attrs[v][1]}) for v, a in arr.items()}
    data["status"] = (dims[:2], status.astype(str), {"long_name": "run status ('ok' or why it stopped)"})
    out = xr.Dataset(data, coords={"integrator": integrators, "scheme": schemes, "frame": np.arange(frames + 1)})
    out.attrs = {"case": str(getattr(case, "name", type(case).__name__)), "level": int(level)}
    return out


# ---------------------------------------------------------------------------- stability
def _run_steps(steps: int, horizon: float, dt: float) -> int:
    """Steps of a stability trial: at least ``steps``, and enough to cover ``horizon``."""
    return max(int(steps), math.ceil(horizon / dt * (1.0 - 1e-12)))


def _stable_run(problem: Any, integrator: str, scheme: str, dt: float, steps: int, horizon: float, growth: float,
                trend: float | None, compiled: bool) -> bool:
    """Bounded energy over :func:`_run_steps` steps (the physical time ``horizon``, at least
    ``steps`` steps): no blow-up and an energy-balance error of at most ``growth`` × the initial
    energy at every saved frame; with ``trend``, also no growth of that error from the first
    half of the run to the second by more than ``trend`` times."""
    from .simulate import InstabilityError, simulate

    nsteps = _run_steps(steps, horizon, dt)
    every = max(1, nsteps // 40)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ds = simulate(problem, integrator=integrator, scheme=scheme, dt=dt, t_end=nsteps * dt,
                          save_every=every, compiled=compiled, progress=False)
    except InstabilityError as exc:
        _unstable_status(exc)  # removes its last-good-state file
        return False
    energy = ds["kinetic_energy"].values + ds["potential_energy"].values
    for name, sign in (("dissipated_energy", 1.0), ("external_work", -1.0)):
        if name in ds:
            energy = energy + sign * ds[name].values
    if not np.all(np.isfinite(energy)):
        return False
    dev = np.abs(energy - energy[0])
    scale = max(abs(float(ds["kinetic_energy"].values[0])) + abs(float(ds["potential_energy"].values[0])),
                1e-300)
    if dev.max() > growth * scale:
        return False
    if trend is None:
        return True
    half = len(dev) // 2
    first, second = dev[1: half + 1].max(initial=0.0), dev[half + 1:].max(initial=0.0)
    return second <= trend * first + 1e-10 * scale


def _stability_task(problem_factory: Callable[[int], Any], integrator: str, scheme: str, n: int, steps: int,
                    growth: float, trend: float | None, rtol: float, bracket: tuple[float, float],
                    compiled: bool, horizon: float | None = None) -> dict:
    from .plugins import get_registry

    problem = problem_factory(n)
    reg = get_registry()
    sch = reg.get("schemes", scheme)(problem)
    state = sch.initial_state()
    integ = reg.get("integrators", integrator)()
    with np.errstate(all="ignore"):
        cfl = float(integ.dt_max(sch, state))
        leapfrog = 2.0 * float(sch.dt_max(state, rate=getattr(integ, "rate", "inertial")))
    h, nn = _spacing(problem)
    ref = cfl if 0 < cfl < math.inf else leapfrog
    out = {"integrator": integrator, "n": nn, "h": h, "dt_cfl": cfl, "dt_reference": ref, "runs": 0,
           "dt_max": math.nan, "bracketed": 0, "horizon": math.nan}
    if not (0 < ref < math.inf):
        return out
    window = float(horizon) if horizon is not None else steps * ref
    out["horizon"] = window
    lo, hi = ref * bracket[0], ref * bracket[1]

    def stable(dt: float) -> bool:
        out["runs"] += 1
        return _stable_run(problem, integrator, scheme, dt, steps, window, growth, trend, compiled)

    if not stable(lo):
        out.update(dt_max=0.0, bracketed=1)
        return out
    if stable(hi):
        out.update(dt_max=hi, bracketed=0)
        return out
    while hi / lo > 1 + rtol:
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    out.update(dt_max=lo, bracketed=1)
    return out


def stability(problem_factory: Callable[[int], Any], integrator: str | Sequence[str], n_values: Sequence[int],
              scheme: str = "lattice", steps: int = 1000, growth: float = 10.0, trend: float | None = None,
              rtol: float = 0.01, bracket: tuple[float, float] = (1 / 64, 4.0), client: Any = None,
              compiled: bool = True, horizon: float | None = None) -> Any:
    """Largest stable Δt against the grid spacing, beside the CFL estimate.

    For each ``n`` in ``n_values`` the problem ``problem_factory(n)`` is run at trial Δt over a
    fixed physical time, ``horizon`` (default: ``steps`` × the bisection's reference Δt), and
    at least ``steps`` steps — so a trial far below the limit runs proportionally more steps
    and sees the same stretch of the motion.  A Δt is stable when the run does not blow up and
    its energy-balance error |E(t) + D(t) − W(t) − E(0)| stays below ``growth`` times the
    initial energy at every saved frame: an instability grows exponentially in time, so over a
    fixed time it exceeds any such bound, while a stable integrator's bounded O(Δt^p) error
    shrinks with Δt.  (Forward Euler multiplies the energy of a mode of frequency ω by
    1 + ω²Δt² per step, exp(ω²Δt·t) over a time t: over the default horizon its fastest mode,
    ω ≈ 2/ref, gains exp(4·steps·Δt/ref), e.g. e^12.5 at steps = 200 and Δt = ref/64, the bottom
    of the default bracket.)  ``trend`` adds a drift test — no growth of the error from the
    first half of the run to the second by more than ``trend`` times — which a short window can
    misread for a bounded oscillation; it is off by default.  Δt_max is bisected
    (geometrically, to relative ``rtol``) in ``bracket`` × the integrator's CFL estimate (× the
    leapfrog estimate 2/ω_max for integrators with none, e.g. forward-euler): ``dt_max = 0``
    means unstable at every Δt of the bracket, ``bracketed = 0`` stable at its top.
    ``problem_factory`` must be picklable to run on a dask ``client``.

    Returns
    -------
    xarray.Dataset
        dims (integrator, n): ``dt_max``, ``dt_cfl`` (the integrator's estimate), ``dt_reference``
        (the bisection's scale), ``h``, ``ratio`` = dt_max / dt_reference, ``runs``, ``bracketed``,
        ``horizon`` (the physical time of every trial).
    """
    import xarray as xr

    from . import __version__, io

    integrators = [integrator] if isinstance(integrator, str) else list(integrator)
    n_values = [int(n) for n in n_values]
    if int(steps) < 1:
        raise ValueError(f"steps must be an integer ≥ 1, got {steps!r}")
    if not (math.isfinite(growth) and growth > 0):
        raise ValueError(f"growth must be a finite number > 0, got {growth!r}")
    if horizon is not None and not (math.isfinite(horizon) and horizon > 0):
        raise ValueError(f"horizon must be a finite time > 0 (or None), got {horizon!r}")
    if not (len(bracket) == 2 and 0 < bracket[0] < bracket[1] < math.inf):
        raise ValueError(f"bracket must be two numbers 0 < low < high, got {bracket!r}")
    tasks = [(f"stability-{integ}-{scheme}-{n}", (problem_factory, integ, scheme, n, steps, growth, trend, rtol,
                                                   tuple(bracket), compiled, horizon))
             for integ in integrators for n in n_values]
    results = _map(_stability_task, tasks, client)
    names = ("dt_max", "dt_cfl", "dt_reference", "h", "runs", "bracketed", "horizon")
    arr = {v: np.full((len(integrators), len(n_values)), np.nan) for v in names}
    nodes = np.zeros(len(n_values), dtype=int)
    for i, integ in enumerate(integrators):
        for j, n in enumerate(n_values):
            r = results[f"stability-{integ}-{scheme}-{n}"]
            for v in names:
                arr[v][i, j] = r[v]
            nodes[j] = r["n"]
    attrs = {"dt_max": ("largest stable time step found", "s"), "dt_cfl": ("CFL estimate of the integrator", "s"),
             "dt_reference": ("time-step scale of the bisection bracket", "s"), "h": ("smallest grid spacing", "m"),
             "runs": ("number of trial runs", "1"), "bracketed": ("1 when dt_max lies inside the bracket", "1"),
             "horizon": ("physical time of every trial run", "s")}
    data = {v: (("integrator", "n"), a, {"long_name": attrs[v][0], "units": attrs[v][1]}) for v, a in arr.items()}
    with np.errstate(divide="ignore", invalid="ignore"):
        data["ratio"] = (("integrator", "n"), arr["dt_max"] / arr["dt_reference"],
                         {"long_name": "dt_max over dt_reference", "units": "1"})
    ds = xr.Dataset(data, coords={"integrator": integrators, "n": ("n", n_values, {"long_name": "requested size"}),
                                  "nodes": ("n", nodes, {"long_name": "number of grid nodes"})})
    ds.attrs = {"Conventions": "CF-1.11", "title": f"stability study ({scheme})", "source": f"cartan {__version__}",
                "history": io.history_line(f"cartan.study.stability(integrator={integrators}, n_values={n_values})"),
                "scheme": scheme, "steps": steps, "growth": growth, "trend": "off" if trend is None else trend,
                "rtol": rtol, "bracket": list(bracket),
                "horizon": "steps × dt_reference" if horizon is None else float(horizon)}
    return ds


# ---------------------------------------------------------------------------- plots
def _figure():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.8), constrained_layout=True)
    return plt, fig, ax


def finish_chart(fig: Any, ax: Any, path: str | os.PathLike, title: str, legend_size: int = 8) -> pathlib.Path:
    """Title, log grid and legend on ``ax``; write ``fig`` to ``path`` (PNG, 110 dpi) and close it."""
    import matplotlib.pyplot as plt

    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=legend_size)
    path = pathlib.Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _slopes(ax: Any, x: np.ndarray, y: np.ndarray, orders: Iterable[float], sign: float = 1.0) -> None:
    """Dashed reference lines of the given slopes, through the finest point of the data."""
    ok = np.isfinite(x) & np.isfinite(y) & (x > 0) & (y > 0)
    if not ok.any():
        return
    x, y = x[ok], y[ok]
    x0, y0 = x[np.argmin(y)], y.min()
    xs = np.array([x.min(), x.max()])
    for p in sorted({float(o) for o in orders if math.isfinite(o)}):
        ax.plot(xs, y0 * (xs / x0) ** (sign * p), color="0.5", ls="--", lw=0.8)
        ax.annotate(f"slope {sign * p:g}", (xs[-1], y0 * (xs[-1] / x0) ** (sign * p)), color="0.4", fontsize=8)


def _lines(ds: Any, x_name: str, path: str | os.PathLike, xlabel: str, sign: float, title: str) -> pathlib.Path:
    plt, fig, ax = _figure()
    allx, ally = [], []
    for integ in ds["integrator"].values:
        for sch in ds["scheme"].values:
            sel = ds.sel(integrator=integ, scheme=sch)
            x, y = np.asarray(sel[x_name].values, float), np.asarray(sel["error"].values, float)
            ok = np.isfinite(x) & np.isfinite(y) & (x > 0) & (y > 0)
            if not ok.any():
                continue
            p = float(sel["observed_order"])
            ax.loglog(x[ok], y[ok], "o-", label=f"{integ} / {sch} (p = {p:.2f})")
            allx.append(x[ok])
            ally.append(y[ok])
    if allx:
        work = 2.0 if (x_name == "wall_time" and ds.attrs.get("refine") == "both") else 1.0
        _slopes(ax, np.concatenate(allx), np.concatenate(ally),
                [p / work for p in np.ravel(ds["expected_order"].values)], sign)
        ax.legend(fontsize=8)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("error")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    path = pathlib.Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_work_precision(ds: Any, path: str | os.PathLike) -> pathlib.Path:
    """Error against wall time, one line per integrator × scheme (log–log), reference slopes −p."""
    return _lines(ds, "wall_time", path, "wall time [s]", -1.0, f"work-precision: {ds.attrs.get('case', '')}")


def plot_error_vs_h(ds: Any, path: str | os.PathLike) -> pathlib.Path:
    """Error against the refined step (dx, or Δt for time refinement), reference slopes p."""
    x_name = ds.attrs.get("order_variable", "h")
    label = {"dt": "Δt", "limit": "1/(limit parameter)"}.get(x_name, "dx")
    return _lines(ds, x_name, path, label, 1.0, f"error vs {label}: {ds.attrs.get('case', '')}")


def plot_traces(ds: Any, path: str | os.PathLike) -> pathlib.Path:
    """Integrability residual and relative energy error against time (a :func:`traces` Dataset),
    one line per integrator × scheme, two log-scale panels; stopped runs are listed in the legend."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 1, figsize=(7.0, 7.0), sharex=True, constrained_layout=True)
    for integ in ds["integrator"].values:
        for sch in ds["scheme"].values:
            sel = ds.sel(integrator=integ, scheme=sch)
            label = f"{integ} / {sch}"
            status = str(sel["status"].values)
            if status != "ok":
                for ax in axes:
                    ax.plot([], [], "x", label=f"{label}: {status.split(':')[0]}")
                continue
            t = np.asarray(sel["t"].values, float)
            for ax, v in zip(axes, ("integrability_residual", "energy_error"), strict=True):
                y = np.asarray(sel[v].values, float)
                ok = np.isfinite(t) & np.isfinite(y)
                # exact zeros (commuting motions, round-off-free lattice) are drawn at 1e-17
                ax.semilogy(t[ok], np.maximum(y[ok], 1e-17), "-", label=label)
    axes[0].set_ylabel("integrability residual")
    axes[1].set_ylabel("|E(t) − E(0)| / E(0)")
    axes[1].set_xlabel("t")
    axes[0].set_title(f"invariants at level {ds.attrs.get('level', '')}: {ds.attrs.get('case', '')}")
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, ncol=2)
    path = pathlib.Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_stability(ds: Any, path: str | os.PathLike) -> pathlib.Path:
    """Largest stable Δt against dx beside the CFL estimate, one line per integrator (log–log)."""
    plt, fig, ax = _figure()
    for integ in ds["integrator"].values:
        sel = ds.sel(integrator=integ)
        h, dtm, cfl = (np.asarray(sel[v].values, float) for v in ("h", "dt_max", "dt_cfl"))
        ok = (dtm > 0) & np.isfinite(dtm)
        line = ax.loglog(h[ok], dtm[ok], "o-", label=f"{integ}: Δt_max")[0] if ok.any() else None
        if (~ok).any():
            ax.plot([], [], "x", label=f"{integ}: unstable at every Δt tried")
        okc = (cfl > 0) & np.isfinite(cfl)
        if okc.any():
            ax.loglog(h[okc], cfl[okc], "--", color=None if line is None else line.get_color(),
                      label=f"{integ}: CFL estimate")
    h_all = np.asarray(ds["h"].values, float).ravel()
    d_all = np.asarray(ds["dt_max"].values, float).ravel()
    _slopes(ax, h_all, np.where(d_all > 0, d_all, np.nan), [1.0])
    ax.set_xlabel("dx")
    ax.set_ylabel("Δt")
    return finish_chart(fig, ax, path, ds.attrs.get("title", "stability"))
