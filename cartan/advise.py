"""Model no more than a scene needs: which reductions a scene admits (``cartan advise``).

:func:`advise` runs a scene — the full solve of a static scene and the whole path of a
continuation scene (both cheap), a short pilot of a dynamic one — and reports, for each
reduction cartan knows, whether the scene admits it, the measured indicator, an estimate of the
error it would introduce, an estimate of the speed-up, and whether it is recommended.  With
``check=True`` it also runs the full and the reduced model side by side (the static solve or the
path again with the reduced model, or the whole dynamic run with both) and reports the actual
difference and time ratio beside the prediction.

An approximate reduction is recommended when the simpler model answers the scene within
``rtol`` (relative to the scene's displacement, or to the change of the strains) and can run
it; the speed-up is reported beside it, not required.  An exact reduction is recommended when it
is faster (measured, or :func:`cartan.reduction.reduction_pays` for dynamic runs).

The reductions
--------------
``held strains (twin)`` (approximate; paper §III.E, §VII.A, §VII.B)
    The twin the scene's medium declares (:meth:`cartan.medium.Medium.held_strain_twins`, a
    :class:`~cartan.medium.HeldStrainTwin`: the registered twin medium, the held components
    and values, the map of parameters), built by :func:`held_strain_twin` and checked to hold
    what is declared; this module names no medium.  ``cosserat-rod`` declares the Kirchhoff
    filament (θ = (1, 0, 0) held), ``planar-cosserat-rod`` the core's generic twin
    :class:`HeldStrainMedium` (the planar elastica), ``cosserat-surface`` the Kirchhoff–Love
    surface (transverse shear θ_α·e₃ = 0 held).
    *Indicator*: ``max |X − X_held|`` of the held components over the edges or nodes (and the
    saved frames of a pilot, or the points of a path).
    *Error estimate*, a rod (d = 1, every translation strain held): the centreline of the rod
    is ``r(s) = r(0) + ∫₀ˢ R θ dσ``, that of the constrained twin
    ``r_f(s) = r(0) + ∫₀ˢ R_f θ₀ dσ``, so

        r(s) − r_f(s) = ∫₀ˢ R (θ − θ₀) dσ + ∫₀ˢ (R − R_f) θ₀ dσ.

    The first term is the displacement the constraint removes, computed from the measured
    strains and frames (edge frames: the mean of the two node frames); the second comes from
    the moments the first one changes (the load's lever arms move by it) and is smaller by a
    factor of order |F|L²/B·(anisotropy of 𝕊) — it vanishes for a dead end force with
    𝕊 ∝ I, where the first term is parallel to the force.  The estimate is the largest
    ``|∫ R(θ − θ₀) dσ|`` over the nodes, integrated from a held end (clamped, driven — both
    models move it by Φ(0)·exp(tξ) —, or its position pinned by a continuation: from s = 0 when
    the start is, from s = L when only the end is), or relative to the centroid of the nodes
    when no end is held; ``∫|θ − θ₀| dσ`` bounds it.  A :class:`~cartan.problem.Driven` end
    carries over to the twin; a dynamic twin whose ``rattle`` cannot move it exactly is
    declined, with the integrator's reason (:func:`_driven_obstacle`).
    A surface (d = 2, translation strains held): the same first term, the displacement x with
    ``∂_α x = R (X_α − X_held)`` on the held components (for a shell ``R e₃ γ_α``, the
    transverse shear γ_α = θ_α·e₃), integrated by least squares over the lattice's edges and
    taken relative to the nodes the scene holds (those whose displacement stays within 10⁻³ of
    the largest; the centroid when none does).  The report also gives the held strains against
    the others' change (membrane ``|θ − θ₀|``, bending ``L·|π − π₀|``).
    The relative error is this displacement divided by the largest displacement of the scene
    (or the length L when nothing moves); the twin is recommended when it is at most
    ``rtol``.  A static or continuation scene that declares a ``measure`` (one displacement
    component at one node, :class:`cartan.scene.Measure`) is compared on it instead: the
    estimate is ``|m(x) − m(x − x_held)|``, x_held the estimated field above, relative to
    ``|m|``, and the check measures ``|m_full − m_twin|``.  On a continuation path the
    indicator is the largest over the path points, the estimate that of the path's end.
    *Speed-up estimate*: the ratio of the explicit integrator's CFL estimates of the twin
    and of the medium (the waves the constraint removes): the ratio of the time steps, an
    upper bound on the gain.  In time the twin runs with the ``rattle`` integrator (which
    holds :meth:`~cartan.medium.Medium.constrained_strains`) at its own CFL step; a
    constrained step costs more than a free one, so for a dynamic scene the twin is
    recommended only when a measured pilot (``check=True``, each model warmed up untimed) is
    faster over the same simulated time, and the report states the measured ratios (whole
    runs, and steps alone), not the CFL ratio.  The timed runs save the scene's output (its
    ``save_every`` in the full model's steps; the twin at the same interval in time), each model's
    time the fastest of up to :data:`TIMED_PAIRS` interleaved pairs.  The check compares the two runs at the full
    pilot's last step (the twin's step shortened to end there) and predicts what it measures:
    the model difference there plus the two runs' time-step errors, each by Richardson from a
    run at half the step (:func:`_advise_held_dynamic`), all three listed in the report.
``SE(3) planar → SE(2)`` (exact; :mod:`cartan.reduction`)
    Detected by :func:`cartan.reduction.planar_reduction` (planar data, planar loads and
    boundaries — a driven end with a planar ξ among them —, a medium with an exact planar twin;
    the report names what blocks it, :func:`cartan.reduction.planar_obstacle`): the reduced run
    changes nothing but the cost, so the error
    estimate is 0 (round-off).  The speed-up is measured on the pilot (the static solve of
    both, or a pilot run of both, the SE(2) problem run as such); for dynamic runs
    :func:`cartan.reduction.reduction_pays` says whether :func:`cartan.simulate` performs it (it
    does so automatically, ``reduce=True``), and it is recommended when it does.
``large radius -> plane`` (approximate; paper §VIII.A)
    A rod on the sphere of radius r (a medium with ``radius``, ``planar_parameters()`` and the
    maps between physical strains and velocities and its group components, such as
    ``sphere-rod``) tends to the planar rod with the same data as r → ∞ (the registered SE(2)
    medium that takes ``planar_parameters()``, :func:`plane_limit_problem`),
    the difference of the strains falling as (L/r)² (the ``sphere-rod-large-radius``
    verification case).  *Indicator*: L/r.  *Error estimate*: the pilot is run at r and at 2r
    with the same physical strains and velocities; with the difference O(r⁻²),
    ``e(r) ≈ (4/3)·max |X(r) − X(2r)|`` (Richardson), in the physical strains (θ₁, θ₂, π_n)
    at the pilot's end.  Open rods only (a closed rod around the sphere has no planar limit),
    with clamped or unloaded free ends and drag loads (mapped at equal dissipated power).
    *Speed-up*: the time of the planar pilot against the sphere's.

A method for a tolerance
------------------------
``advise(scene, tol=...)``: for a dynamic scene the cheapest (integrator, Δt) whose final
positions are within ``tol`` of a fine reference run (:func:`advise_method`), and the cheaper
scheme (lattice or collocation, those that apply) to reach ``tol`` with the scene's
integrator, from three runs each with h and Δt refined together, Richardson's estimates at the
observed order and measured costs (:func:`advise_schemes`); for a static scene the coarsest
grid whose equilibrium — the scene's ``measure`` when it declares one, else the node positions
— is within ``tol`` (relative) by Richardson extrapolation over three refinement levels, and
for a continuation scene the same at its path's final point (:func:`advise_resolution`).

Timings are wall-clock times of the runs after a warm-up run of each model (the numba
compilation is not counted; a static solve's time is the fastest of :data:`STATIC_REPEATS`);
they depend on the machine and its load.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import pathlib
import time
import warnings
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from .medium import HeldStrainTwin, Medium, QuadraticMedium

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr
from .problem import Clamped, Damping, Driven, Free, InitialState, Problem

__all__ = ["HELD_STRAINS", "LARGE_RADIUS", "PILOT_STEPS", "PLANAR", "TOL_SCHEMES", "Advice", "HeldStrainMedium",
           "MethodAdvice", "MethodCandidate", "ReductionAdvice", "ResolutionAdvice", "ResolutionCandidate",
           "SchemeCandidate", "advise", "advise_method", "advise_resolution", "advise_schemes", "held_strain_problem",
           "held_strain_twin", "plane_limit_problem", "scheme_table"]

#: time steps of the pilot run of a dynamic scene (fewer when the scene's run is shorter)
PILOT_STEPS = 200
#: timed static solves of each model (the fastest is reported)
STATIC_REPEATS = 2
#: timed (full, twin) pairs of a dynamic check, at most: each model's time is the fastest of its runs
TIMED_PAIRS = 3
#: seconds: a dynamic check times another pair only while a pair takes less than this
TIMED_PAIR_BUDGET = 2.0
#: default relative error accepted for an approximate reduction
DEFAULT_RTOL = 1e-3

#: the approximate reduction that holds strain components by constraint: the twin the medium declares
#: (:meth:`~cartan.medium.Medium.held_strain_twins`), e.g. a rod's Kirchhoff filament
HELD_STRAINS = "held strains (twin)"
#: the exact reduction of planar SE(3) problems (:mod:`cartan.reduction`)
PLANAR = "SE(3) planar -> SE(2)"
#: the approximate reduction of a rod on a sphere of large radius to the plane
LARGE_RADIUS = "large radius -> plane"
#: continuation pins: SE(3) components (x, y, rotation about z) → SE(2) (x, y, rotation)
_PLANAR_PIN = {0: 0, 1: 1, 5: 2}


# ---------------------------------------------------------------------------- the report
@dataclasses.dataclass
class ReductionAdvice:
    """One reduction and what the scene says about it.

    Attributes
    ----------
    name : str
        :data:`HELD_STRAINS`, :data:`PLANAR` or :data:`LARGE_RADIUS`.
    kind : str
        ``"exact"`` or ``"approximate"``.
    admitted : bool
        The scene's data allow the reduction (the reduced model can be built).
    recommended : bool
        Admitted, within ``rtol`` (approximate ones) and runnable for this scene's mode.
    indicator_name : str
    indicator : float
        The measured indicator (NaN when not admitted).
    error_estimate : float
        Estimated difference of the reduced model (absolute; length units for a held-strain
        twin, strain units for the sphere rod; 0 for exact reductions).
    error_scale : float
        The scale ``error_estimate`` is compared with (``rtol·error_scale``).
    speedup_estimate : float
        Estimated time ratio full / reduced (NaN when unknown).
    note : str
        Why (not) admitted or recommended, and what the numbers are.
    measured_difference, time_ratio : float
        With ``check=True``: the actual difference (same measure as ``error_estimate``) and the
        measured time ratio full / reduced; NaN otherwise.
    check_note : str
        What the check ran.
    predicted_difference : float
        With ``check=True``: the difference the check is predicted to measure, at the time and on
        the quantity it measures.  A static solve or path: ``error_estimate``.  A dynamic run
        (held-strain twin): the model difference at the pilot's end plus the two runs' time-step
        errors (:func:`_advise_held_dynamic`).  NaN otherwise.
    model_difference : float
        With ``check=True``: the part of ``predicted_difference`` the reduction itself causes (a
        dynamic run: the estimate at the pilot's last frame, where the check compares; the
        largest over the frames is ``error_estimate``).
    time_error, full_time_error : float
        With ``check=True`` on a dynamic run: the estimated time-step error of the reduced and of
        the full run at the pilot's end (largest over the nodes; Richardson from a second run at
        half the step); NaN when there is none (static solves, paths) or it is not estimated.
    """

    name: str
    kind: str
    admitted: bool = False
    recommended: bool = False
    indicator_name: str = ""
    indicator: float = math.nan
    error_estimate: float = math.nan
    error_scale: float = math.nan
    speedup_estimate: float = math.nan
    note: str = ""
    measured_difference: float = math.nan
    time_ratio: float = math.nan
    check_note: str = ""
    predicted_difference: float = math.nan
    model_difference: float = math.nan
    time_error: float = math.nan
    full_time_error: float = math.nan

    @property
    def relative_error(self) -> float:
        """``error_estimate / error_scale``."""
        if not (math.isfinite(self.error_estimate) and math.isfinite(self.error_scale)) or self.error_scale <= 0:
            return math.nan
        return self.error_estimate / self.error_scale

    @property
    def prediction_ratio(self) -> float:
        """``predicted_difference / measured_difference`` (NaN when either is missing or the
        measured difference is 0): within [0.5, 2] the prediction holds to a factor 2."""
        p, m = self.predicted_difference, self.measured_difference
        if not (math.isfinite(p) and math.isfinite(m)) or m <= 0:
            return math.nan
        return p / m


@dataclasses.dataclass
class Advice:
    """What :func:`advise` returns.

    Attributes
    ----------
    scene : str
        The scene's name.
    mode : str
        ``"static"``, ``"continuation"`` or ``"dynamic"``.
    medium : str
    pilot : str
        What was run to measure the indicators.
    rtol : float
        Relative error accepted for approximate reductions.
    checked : bool
        Whether the full and reduced models were run side by side.
    reductions : list of ReductionAdvice
    wall_time : float
        Seconds spent in :func:`advise`.
    """

    scene: str
    mode: str
    medium: str
    pilot: str
    rtol: float
    checked: bool
    reductions: list[ReductionAdvice]
    wall_time: float = 0.0

    def __getitem__(self, name: str) -> ReductionAdvice:
        for r in self.reductions:
            if r.name == name:
                return r
        raise KeyError(name)

    @property
    def recommended(self) -> list[str]:
        """Names of the recommended reductions."""
        return [r.name for r in self.reductions if r.recommended]

    def to_dict(self) -> dict[str, Any]:
        """The report as plain Python (JSON-serialisable, NaN as ``None``)."""

        def clean(v: Any) -> Any:
            return None if isinstance(v, float) and not math.isfinite(v) else v

        out = {k: clean(v) for k, v in dataclasses.asdict(self).items() if k != "reductions"}
        out["reductions"] = [{k: clean(v) for k, v in dataclasses.asdict(r).items()} | {
            "relative_error": clean(r.relative_error), "prediction_ratio": clean(r.prediction_ratio)}
            for r in self.reductions]
        return out

    def to_dataset(self) -> xr.Dataset:
        """The report as an :class:`xarray.Dataset` along ``reduction`` (CF attributes).

        Returns
        -------
        xarray.Dataset
            Variables ``admitted``, ``recommended`` (int 0/1), ``indicator``,
            ``error_estimate``, ``error_scale``, ``relative_error``, ``speedup_estimate``,
            ``measured_difference``, ``time_ratio``, ``predicted_difference``,
            ``model_difference``, ``time_error``, ``full_time_error``, ``prediction_ratio``
            (float), ``kind``, ``indicator_name``, ``note``, ``check_note`` (str), each
            ``[reduction]``.
        """
        import xarray as xr

        from . import __version__, io

        rs = self.reductions
        floats = {
            "indicator": "measured indicator of the reduction",
            "error_estimate": "estimated difference the reduced model introduces",
            "error_scale": "scale the estimated difference is compared with",
            "relative_error": "error_estimate / error_scale",
            "speedup_estimate": "estimated time ratio full / reduced",
            "measured_difference": "difference measured by running both models (check)",
            "time_ratio": "measured time ratio full / reduced (check)",
            "predicted_difference": "difference the check is predicted to measure: model difference and time-step "
                                    "errors (check)",
            "model_difference": "part of the predicted difference the reduction causes (check)",
            "time_error": "estimated time-step error of the reduced run at the check's end (check, dynamic)",
            "full_time_error": "estimated time-step error of the full run at the check's end (check, dynamic)",
            "prediction_ratio": "predicted_difference / measured_difference (check)",
        }
        data = {k: ("reduction", np.array([float(getattr(r, k)) for r in rs]), {"long_name": v})
                for k, v in floats.items()}
        for k in ("admitted", "recommended"):
            data[k] = ("reduction", np.array([int(getattr(r, k)) for r in rs], dtype=np.int64),
                       {"long_name": f"1 if the reduction is {k}"})
        for k in ("kind", "indicator_name", "note", "check_note"):
            data[k] = ("reduction", np.array([str(getattr(r, k)) for r in rs], dtype=object))
        ds = xr.Dataset(data, coords={"reduction": np.array([r.name for r in rs], dtype=object)})
        ds.attrs = {"Conventions": "CF-1.11", "title": f"{self.scene}: reductions the scene admits",
                    "source": f"cartan {__version__}", "history": io.history_line(
                        f"cartan.advise({self.scene!r}, check={self.checked})"),
                    "scene": self.scene, "mode": self.mode, "medium": self.medium, "pilot": self.pilot,
                    "rtol": self.rtol, "checked": int(self.checked), "wall_time": self.wall_time}
        return ds

    def __str__(self) -> str:
        def f(x: float, spec: str = ".3g") -> str:
            return "—" if not math.isfinite(x) else format(x, spec)

        lines = [f"scene {self.scene!r} ({self.mode}, {self.medium}); measured on: {self.pilot}", ""]
        for r in self.reductions:
            verdict = "RECOMMENDED" if r.recommended else ("admitted" if r.admitted else "not admitted")
            lines.append(f"{r.name} [{r.kind}]: {verdict}")
            if r.admitted:
                lines.append(f"  {r.indicator_name} = {f(r.indicator, '.5g')}; "
                             f"estimated error {f(r.error_estimate, '.5g')} "
                             f"(relative {f(r.relative_error)}, accepted {f(self.rtol)}); estimated speed-up "
                             f"{f(r.speedup_estimate, '.2f')}")
                if self.checked:
                    pred = (f"predicted {f(r.predicted_difference, '.5g')} (exact: round-off)" if r.kind == "exact"
                            else f"predicted {f(r.predicted_difference, '.5g')} (predicted / measured "
                            f"{f(r.prediction_ratio, '.3g')})")
                    lines.append(f"  check: measured difference {f(r.measured_difference, '.5g')}, {pred}, time ratio "
                                 f"{f(r.time_ratio, '.2f')}" + (f" ({r.check_note})" if r.check_note else ""))
                    if math.isfinite(r.time_error) or math.isfinite(r.full_time_error):
                        lines.append(f"  predicted = model difference {f(r.model_difference, '.5g')} at the "
                                     f"pilot's end + time-step errors: reduced run {f(r.time_error, '.5g')}, full "
                                     f"run {f(r.full_time_error, '.5g')} (Richardson, a second run of each at "
                                     "Δt/2); x_full − x_reduced = model + e_full − e_reduced, and the sum of the "
                                     "parts' sizes is its upper estimate")
            if r.note:
                lines.append(f"  {r.note}")
        rec = self.recommended
        lines += ["", "recommended: " + (", ".join(rec) if rec else "none")]
        return "\n".join(lines)


# ---------------------------------------------------------------------------- running
@dataclasses.dataclass
class _Subject:
    """What is advised: the problem and how it runs."""

    problem: Problem
    name: str
    mode: str
    solver_options: dict[str, Any]
    run_settings: dict[str, Any]
    measure: Any = None


def _load(obj: Any) -> Any:
    """``obj`` as a :class:`~cartan.scene.Scene` when it names one (a scene file, a registered
    name, a scene dict); anything else is returned as it is."""
    from .scene import load_scene
    from .scene import scene as registered

    if isinstance(obj, str | os.PathLike):
        path = pathlib.Path(obj)
        return load_scene(path) if path.suffix == ".toml" or path.exists() else registered(str(obj))
    if isinstance(obj, Mapping):
        return load_scene(obj)
    return obj


def _subject(obj: Any) -> _Subject:
    from .scene import Scene

    if isinstance(obj, Problem):
        return _Subject(obj, obj.name or obj.medium.name, "static", {}, {})
    obj = _load(obj)
    if not isinstance(obj, Scene):
        raise TypeError(f"advise takes a Problem, a Scene, a scene file or a registered scene name, got {obj!r}")
    if obj.mode == "flow":
        raise ValueError(f"scene {obj.name!r}: advise compares dynamic, static and continuation runs; a flow "
                         f"scene ([flow]) has no reduced twin to compare")
    if obj.mode == "static" and obj.initial_guess is not None:
        raise ValueError(f"scene {obj.name!r}: advise does not take a static scene with an initial_guess file")
    settings = obj.run_settings() if obj.mode == "dynamic" else {}
    return _Subject(obj.problem, obj.name or obj.problem.medium.name, obj.mode, dict(obj.solver_options), settings,
                    obj.measure)


def _timed(fn: Any, *args: Any, **kwargs: Any) -> tuple[Any, float]:
    t0 = time.perf_counter()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - t0


def _solve(problem: Problem, options: Mapping[str, Any]) -> xr.Dataset:
    from .statics import solve_static

    return solve_static(problem, **dict(options))


def _simulate(problem: Problem, settings: Mapping[str, Any], t_end: float,
              save_every: int | None = None) -> xr.Dataset:
    """``problem`` run to ``t_end`` with ``settings`` (``reduce=False``, no file), saving every
    ``save_every`` steps (default: 20 save blocks, the frames a pilot's analysis samples)."""
    from .simulate import InstabilityError, StabilityWarning, simulate

    s = dict(settings)
    s.pop("checkpoint_every", None)
    dt = s.get("dt")
    steps = max(1, round(t_end / dt)) if dt else None
    s["save_every"] = max(1, (steps or PILOT_STEPS) // 20) if save_every is None else int(save_every)
    s["t_end"] = t_end
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StabilityWarning)
        try:
            return simulate(problem, progress=False, reduce=False, **s)
        except InstabilityError as exc:  # a pilot writes nothing: its last good state is not kept
            if exc.path is None or s.get("output"):
                raise
            with contextlib.suppress(OSError):
                exc.path.unlink()
            message = str(exc).split("; last good state", 1)[0]
            raise InstabilityError(f"pilot run {message}", step=exc.step, time=exc.time, dt=exc.dt,
                                   dt_max=exc.dt_max) from None


def _initial_positions(problem: Problem) -> np.ndarray:
    """Node positions of the initial state ``[nodes, k]`` (media on affine groups)."""
    Phi = np.asarray(problem.initial.Phi, dtype=float)
    return Phi[..., 1:, 0].reshape(-1, Phi.shape[-1] - 1)


def _follow(problem: Problem, options: Mapping[str, Any], measure: Any) -> xr.Dataset:
    """The continuation path of ``problem`` as a Dataset along ``time`` (one entry per path point)
    with ``position``, ``frame`` and the edge strains ``X`` (from the frames the path's monitor
    receives), plus ``load_factor``; the attribute ``newton_iterations``."""
    import xarray as xr

    from .continuation import continuation

    g = problem.medium.group
    pos0 = _initial_positions(problem)
    seen: list[tuple[np.ndarray, np.ndarray]] = []

    def monitor(snap: Any) -> float:
        p = np.asarray(snap["position"].values[0], dtype=float).reshape(pos0.shape)
        seen.append((p.copy(), np.asarray(snap["frame"].values[0], dtype=float).copy()))
        if measure is not None:
            return float(measure(p, pos0))
        return float(np.max(np.linalg.norm(p - pos0, axis=-1)))

    path = continuation(problem, monitor=monitor, **dict(options))
    pts = np.asarray(path["position"].values, dtype=float).reshape(path.sizes["path"], *pos0.shape)
    frames = []
    for p in pts:  # the path points among the states the monitor saw (probes of a branch switch too)
        match = [E for q, E in seen if np.array_equal(q, p)]
        frames.append(match[-1] if match else np.full((pos0.shape[0], pos0.shape[1], pos0.shape[1]), np.nan))
    E = np.stack(frames)
    m = pos0.shape[1] + 1
    Phi = np.zeros((*E.shape[:2], m, m))
    Phi[..., 0, 0] = 1.0
    Phi[..., 1:, 0] = pts
    Phi[..., 1:, 1:] = E
    G = g.compose(g.inverse(Phi[:, :-1]), Phi[:, 1:])
    X = g.log(G) / float(problem.grid.spacing[0])
    ds = xr.Dataset({"position": (("time", "node", "row"), pts), "frame": (("time", "node", "row", "col"), E),
                     "X": (("time", "edge", "component"), X),
                     "load_factor": ("time", np.asarray(path["load_factor"].values, dtype=float))})
    ds.attrs["newton_iterations"] = int(path.attrs.get("newton_iterations", 0))
    return ds


def _run(subject: _Subject, problem: Problem, t_end: float | None, *, warm: bool = True,
         options: Mapping[str, Any] | None = None) -> tuple[Any, float]:
    """Solve (static) or run to ``t_end`` (dynamic, as given: ``reduce=False``) ``problem`` with the
    subject's settings: ``(Dataset, seconds)``, after a warm-up run (two steps, or one solve) when
    ``warm``; a static solve's time is the fastest of :data:`STATIC_REPEATS`."""
    if subject.mode == "continuation":  # one timed path after a warm-up static solve (λ = 1)
        if warm:
            from .statics import ConvergenceError

            with contextlib.suppress(ConvergenceError, ValueError, ArithmeticError):
                _solve(problem, {"load_steps": 4, "max_iter": 20})
        return _timed(_follow, problem, subject.solver_options if options is None else options, subject.measure)
    if subject.mode == "static":  # cheap: the best of STATIC_REPEATS timed solves after the warm-up
        opts = subject.solver_options if options is None else options
        if warm:
            _solve(problem, opts)
        runs = [_timed(_solve, problem, opts) for _ in range(STATIC_REPEATS)]
        return runs[-1][0], min(t for _, t in runs)
    if warm:
        _simulate(problem, subject.run_settings, 2 * subject.run_settings["dt"])
    return _timed(_simulate, problem, subject.run_settings, t_end)


def _dynamic_settings(subject: _Subject, pilot_steps: int) -> tuple[float, float, Any]:
    """(Δt, the pilot's end time, the resolved full run) of a dynamic subject."""
    from .simulate import StabilityWarning, _resolve_run

    s = subject.run_settings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StabilityWarning)
        run = _resolve_run(subject.problem, s.get("integrator"), s.get("scheme"), s.get("dt"), s.get("t_end"),
                           s.get("save_every"), None, None, None, s.get("integrator_options"),
                           s.get("scheme_options"), False, 1e3, compiled=True, command="", max_steps=None)
    t_end = float(run.info["run"]["t_end"])
    subject.run_settings["dt"] = float(run.dt)
    return float(run.dt), min(t_end, pilot_steps * float(run.dt)), run


# ---------------------------------------------------------------------------- held stretch and shear
class HeldStrainMedium(QuadraticMedium):
    """A quadratic medium with its translation strains θ held at their rest values by constraint.

    The adapted medium of paper §III.E: the strain components of the translations (the first
    k = m − 1 components of SE(k), k = 2, 3) are fixed at θ₀ by Lagrange multipliers in the
    statics (:meth:`constrained_strains`), and the energy keeps only the other components —
    the base medium's stiffness with the rows and columns of θ set to zero.  For a Cosserat rod
    on SE(3) (U = ½(θ − θ₀)ᵀ𝕊(θ − θ₀) + ½(π − π₀)ᵀ𝔹(π − π₀)) this is the Kirchhoff filament
    with the rod's 𝔹 and π₀ (paper §VII.A): inextensible and unshearable.  Kinetic metric,
    space, loads and initial states are the base medium's.

    Parameters
    ----------
    base : QuadraticMedium
        d = 1, on SE(2) or SE(3), with :meth:`~cartan.medium.Medium.quadratic_energy` and no
        constrained strains of its own.

    Raises
    ------
    ValueError
        When ``base`` is not such a medium.
    """

    name: ClassVar[str] = "held-strains"
    material_dim: ClassVar[int] = 1

    def __init__(self, base: Medium):
        group = getattr(base, "group", None)
        if getattr(group, "name", "") not in ("SE2", "SE3") or getattr(base, "material_dim", None) != 1:
            raise ValueError("base must be a medium with material dimension 1 on SE(2) or SE(3)")
        if base.constrained_strains() is not None:
            raise ValueError("base already holds strain components by constraint")
        energy = base.quadratic_energy()
        if energy is None:
            raise ValueError("base must have a quadratic energy (Medium.quadratic_energy)")
        X0, C = (np.asarray(a, dtype=float) for a in energy)
        k = group.matrix_size - 1
        C = C.copy()
        C[:k, :] = 0.0
        C[:, :k] = 0.0
        self.base, self.group, self.space = base, group, base.space
        self.load_kinds, self.initial_kinds = base.load_kinds, base.initial_kinds
        self._held = (np.arange(k), X0.reshape(-1)[:k].copy())
        self._inertia = np.asarray(base.inertia(), dtype=float).copy()
        self._set_energy(X0, C)

    def inertia(self) -> np.ndarray:
        """The base medium's kinetic metric, shape ``(r,)``."""
        return self._inertia.copy()

    def constrained_strains(self) -> tuple[np.ndarray, np.ndarray]:
        """The translation components ``(0, …, k − 1)`` held at θ₀."""
        return self._held[0].copy(), self._held[1].copy()

    def planar_reduction(self) -> None:
        """None: a planar twin would lose the constraints."""
        return None

    def parameters(self) -> dict[str, Any]:
        """The base medium's name and parameters, and the held components."""
        return {"base": self.base.name, "base_parameters": self.base.parameters(),
                "held_components": self._held[0].tolist()}

    def make_load(self, kind: str, **params: Any):
        """The base medium's loads."""
        return self.base.make_load(kind, **params)

    def initial_state(self, grid: Any, kind: str, **params: Any) -> InitialState:
        """The base medium's initial states."""
        return self.base.initial_state(grid, kind, **params)


def _twin_medium(medium: Medium, twin: HeldStrainTwin) -> Medium:
    """The medium of a :class:`~cartan.medium.HeldStrainTwin` declaration, checked: it holds
    exactly the declared components, at the declared values."""
    from .plugins import get_registry

    comps = tuple(int(c) for c in twin.components)
    if twin.medium is None:
        out: Medium = HeldStrainMedium(medium)
    else:
        if twin.parameters is None:
            raise ValueError(f"the twin {twin.medium!r} is declared without its parameter map")
        cls = get_registry().get("media", twin.medium)
        out = cls(**twin.parameters(medium.parameters()))
    held = out.constrained_strains()
    if held is None or tuple(int(c) for c in held[0]) != comps:
        raise ValueError(f"the twin {out.name!r} does not hold the declared components {list(comps)}")
    if twin.values is not None and not np.allclose(np.asarray(held[1], dtype=float), twin.values, rtol=0, atol=0):
        raise ValueError(f"the twin {out.name!r} holds {list(held[1])}, not the declared values {list(twin.values)}")
    if out.group.name != medium.group.name or out.material_dim != medium.material_dim:
        raise ValueError(f"the twin {out.name!r} is not on the medium's group and material dimension")
    return out


def held_strain_twin(problem: Problem) -> tuple[Problem, HeldStrainTwin]:
    """``problem`` on the first held-strain twin its medium declares
    (:meth:`~cartan.medium.Medium.held_strain_twins`), and the declaration.

    Parameters
    ----------
    problem : Problem
        Its medium declares a twin.  A reference state (a varying rest curvature) carries over
        when its held components are the values the twin holds (a curved rest shape of an
        inextensible, unshearable rod).

    Returns
    -------
    (Problem, HeldStrainTwin)
        The twin's problem (same grid, initial state, boundaries, loads and name) and what the
        medium declared.

    Raises
    ------
    ValueError
        When the medium declares no twin, the twin cannot be built or does not hold what is
        declared, or the reference state's held components differ from the held values.
    """
    twins = tuple(problem.medium.held_strain_twins())
    if not twins:
        raise ValueError(f"the medium {problem.medium.name!r} declares no held-strain twin")
    twin = twins[0]
    med = _twin_medium(problem.medium, twin)
    if problem.reference is not None:
        _check_reference_held(problem, med)
    return Problem(med, problem.grid, problem.initial, dict(problem.boundaries), list(problem.loads),
                   name=problem.name, reference=problem.reference), twin


#: a reference state's held strain components may differ from the twin's values by this (relative)
REFERENCE_HELD_RTOL = 1e-9


def _check_reference_held(problem: Problem, twin: Medium) -> None:
    """ValueError unless the strains of ``problem.reference`` (the stress-free shape) have the
    components ``twin`` holds at the values it holds them (to :data:`REFERENCE_HELD_RTOL`): a
    curved rest shape of an inextensible, unshearable rod, whose rest curvature the twin keeps."""
    from .schemes.lattice import Lattice

    comps, values = (np.asarray(a) for a in twin.constrained_strains())
    ref = problem.reference
    sch = Lattice(Problem(problem.medium, problem.grid, InitialState(Phi=ref.Phi, holonomy=ref.holonomy)))
    X = np.asarray(sch.strains(sch.initial_state()), dtype=float)
    X = X.reshape(-1, X.shape[-1])[:, comps.astype(int)]
    err = float(np.max(np.abs(X - values.astype(float)))) if X.size else 0.0
    scale = max(1.0, float(np.max(np.abs(values)))) if values.size else 1.0
    if not err <= REFERENCE_HELD_RTOL * scale:
        raise ValueError(f"the reference state's strain components {comps.tolist()} differ from the values the "
                         f"twin holds ({values.tolist()}) by up to {err:.3g}: a rest shape with stretch or shear "
                         "has no held-strain twin")


def held_strain_problem(problem: Problem) -> Problem:
    """``problem`` on its medium's held-strain twin (:func:`held_strain_twin`): for a Cosserat
    rod the Kirchhoff filament, for a Cosserat surface the Kirchhoff–Love surface.

    Raises
    ------
    ValueError
        As :func:`held_strain_twin`.
    """
    return held_strain_twin(problem)[0]


def _strain_frames(ds: Any, k: int, theta0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per saved frame: stretch/shear deviations θ − θ₀ ``[T, E, k]`` on the edges, edge frames
    ``[T, E, k, k]`` and node positions ``[T, n, k]``."""
    X = np.asarray(ds["X"].values, dtype=float)
    T = X.shape[0]
    pos = np.asarray(ds["position"].values, dtype=float).reshape(T, -1, k)
    E = np.asarray(ds["frame"].values, dtype=float).reshape(T, -1, k, k)
    X = X.reshape(T, -1, X.shape[-1])
    n = pos.shape[1]
    th = X[..., :k] - theta0
    if th.shape[1] == n - 1:
        R = 0.5 * (E[:, :-1] + E[:, 1:])
    elif th.shape[1] == n:  # nodal strains (collocation): to the edges
        th = 0.5 * (th[:, :-1] + th[:, 1:])
        R = 0.5 * (E[:, :-1] + E[:, 1:])
    else:  # a closed rod: the closing edge too
        R = 0.5 * (E + np.roll(E, -1, axis=1))
    return th, R, pos


def _anchor(subject: _Subject) -> str | None:
    """The end the displacements are measured from: a clamped or driven end (the twin's frame
    there is the medium's, Φ(0)·exp(tξ) — a clamp at Φ(0) in the statics), or an end whose
    position a continuation pins (``"start"`` first), else None (about the centroid)."""
    b = subject.problem.boundaries
    pins = subject.solver_options.get("pins") or {} if subject.mode == "continuation" else {}
    n = subject.problem.grid.shape[0]
    k = subject.problem.medium.group.matrix_size - 1
    for end, index in (("start", 0), ("end", n - 1)):
        pinned = [c for key, comps in pins.items() if key in (end, index) for c in comps if int(c) < k]
        if type(b.get(end)) in (Clamped, Driven) or pinned:
            return end
    return None


def _driven_obstacle(held: Problem, settings: Mapping[str, Any]) -> str | None:
    """Why the twin ``held`` cannot run in time with its :class:`~cartan.problem.Driven` ends, or
    None (no driven end, or ``rattle`` moves them by exp(Δtξ) per step).

    A driven end carries over to the twin unchanged (the same group, the same ξ): the constrained
    integrator holds its node at the velocity ξ in its constraint rows, when ξ's parts in the split
    free flow commute (a rotation about one body axis, any translation) and the kinetic metric is
    diagonal (:meth:`cartan.integrators.base.Integrator.driven_reason`)."""
    from .plugins import get_registry
    from .schemes.base import Scheme

    if not any(type(b) is Driven for b in held.boundaries.values()):
        return None
    name = settings.get("scheme") or "lattice"
    try:
        cls = get_registry().get("schemes", name) if isinstance(name, str) else name
        scheme: Scheme = cls(held, **dict(settings.get("scheme_options") or {}))
        reason = get_registry().get("integrators", "rattle")().driven_reason(scheme)
    except (ValueError, TypeError, KeyError) as exc:
        return f"its driven end cannot be run with rattle on the {name!r} scheme ({' '.join(str(exc).split())})"
    if reason is None:
        return None
    return f"rattle, its integrator, does not carry the driven end: {reason}"


def _filament_estimate(ds: Any, problem: Problem, k: int, theta0: np.ndarray, anchor: str | None,
                       last: bool = False, with_field: bool = False) -> tuple[Any, ...]:
    """(indicator max|θ − θ₀| over the frames, estimated position difference, the bound
    ∫|θ − θ₀|, its frame) from a run, static solve or path ``ds`` of a rod: the frame of the
    largest estimate, or the last frame (a path's end) with ``last``.  With ``with_field`` also
    the estimated displacement field of the last frame, ``x − x_twin ≈ ∫₀ˢ R(θ − θ₀) dσ``
    ``[n, k]`` (from the anchor)."""
    th, R, _ = _strain_frames(ds, k, theta0)
    h = float(problem.grid.spacing[0])
    d = np.einsum("teij,tej->tei", R, th) * h  # R(θ − θ₀) dσ per edge
    start, end = anchor == "start", anchor == "end"
    if start:
        cum = np.concatenate([np.zeros((d.shape[0], 1, k)), np.cumsum(d, axis=1)], axis=1)
    elif end:
        cum = -np.concatenate([np.cumsum(d[:, ::-1], axis=1)[:, ::-1], np.zeros((d.shape[0], 1, k))], axis=1)
    else:
        cum = np.concatenate([np.zeros((d.shape[0], 1, k)), np.cumsum(d, axis=1)], axis=1)
        cum = cum - cum.mean(axis=1, keepdims=True)
    per_frame = np.max(np.linalg.norm(cum, axis=-1), axis=1)
    i = len(per_frame) - 1 if last else int(np.nanargmax(per_frame))
    bound = float(np.sum(np.linalg.norm(th[i], axis=-1)) * h)
    out = (float(np.nanmax(np.abs(th))), float(per_frame[i]), bound, i)
    return (*out, cum[-1]) if with_field else out


def _displacement_scale(ds: Any, problem: Problem, k: int, anchor: str | None) -> float:
    """The largest node displacement from the initial state over the frames of ``ds``
    (relative to the centroid when no end is held), or the length when nothing moves."""
    pos = np.asarray(ds["position"].values, dtype=float).reshape(ds.sizes["time"], -1, k)
    pos0 = np.asarray(problem.initial.Phi, dtype=float)[..., 1:, 0].reshape(1, -1, k)
    disp = pos - pos0
    if anchor is None:
        disp = disp - disp.mean(axis=1, keepdims=True)
    scale = float(np.max(np.linalg.norm(disp, axis=-1)))
    return scale if scale > 0 else float(problem.grid.length[0])


def _cfl_ratio(full: Problem, reduced: Problem, settings: Mapping[str, Any]) -> float:
    """CFL estimate of ``reduced`` over that of ``full`` with the explicit integrator of the
    settings (``lie-verlet`` when the scene's has no stability limit or for static scenes)."""
    from .plugins import get_registry
    from .schemes.lattice import Lattice

    name = settings.get("integrator") or "lie-verlet"
    integ = get_registry().get("integrators", name)() if isinstance(name, str) else None
    if integ is None or not math.isfinite(getattr(integ, "stability", math.inf)):
        integ = get_registry().get("integrators", "lie-verlet")()
    values = []
    for p in (full, reduced):
        sch = Lattice(p)
        values.append(float(integ.dt_max(sch, sch.initial_state())))
    return values[1] / values[0] if values[0] > 0 else math.nan


def _held_nodes(ds: Any, problem: Problem, k: int) -> np.ndarray:
    """The nodes the scene holds: those whose displacement stays within 10⁻³ of the largest over
    every frame of ``ds`` (supports, clamps); all nodes (the centroid) when none does."""
    pos = np.asarray(ds["position"].values, dtype=float).reshape(ds.sizes["time"], -1, k)
    pos0 = np.asarray(problem.initial.Phi, dtype=float)[..., 1:, 0].reshape(1, -1, k)
    disp = np.max(np.linalg.norm(pos - pos0, axis=-1), axis=0)
    held = np.flatnonzero(disp <= 1e-3 * np.max(disp))
    return held if len(held) else np.arange(pos.shape[1])


def _held_surface_estimate(ds: Any, problem: Problem, comps: Sequence[int], values: np.ndarray,
                           k: int, with_field: bool = False) -> tuple[Any, ...]:
    """A medium of d ≥ 2 with held translation strains: (indicator max|X_held − value| over the
    nodes, axes and frames, the estimated position difference per frame ``[T]``, the ratio of the
    indicator to the other strains' change — membrane ``|θ − θ₀|`` and bending ``L·|π − π₀|``),
    and with ``with_field`` the estimated displacement field ``x − x_twin`` of the last frame
    ``[nodes, k]``.

    The displacement the constraint removes, x with ∂_α x = R (X_α − X_α,held) on the held
    components, is integrated by least squares over the lattice's edges (the field need not be
    a gradient), relative to its mean over the nodes the scene holds (:func:`_held_nodes`)."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import factorized

    from .schemes.lattice import Lattice

    grid = problem.grid
    shape = tuple(int(n) for n in grid.shape)
    d, nn = len(shape), int(np.prod(shape))
    X = np.asarray(ds["X"].values, dtype=float)
    T = X.shape[0]
    if X.shape[1:1 + d] != shape:
        raise ValueError("the strains of this output are not nodal")
    X = X.reshape(T, nn, d, -1)
    E = np.asarray(ds["frame"].values, dtype=float).reshape(T, nn, k, k)
    comps = [int(c) for c in comps]
    dev = X[..., comps] - values  # [T, n, d, c]
    w = np.einsum("tnic,tnac->tnai", E[..., comps], dev)  # R (X_α − X_held) on the held components [T, n, d, k]
    tails, heads = Lattice(problem).edge_nodes()
    rows, cols, vals, incr = [], [], [], []
    for a in range(d):
        i, j = tails[a], heads[a]
        e0 = sum(x.shape[1] for x in incr)
        e = np.arange(e0, e0 + len(i))
        rows += [e, e]
        cols += [i, j]
        vals += [-np.ones(len(i)), np.ones(len(i))]
        incr.append(0.5 * float(grid.spacing[a]) * (w[:, i, a] + w[:, j, a]))
    b = np.concatenate(incr, axis=1)  # [T, edges, k]
    D = sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(b.shape[1], nn))
    Dr = D[:, 1:]  # node 0 pinned (the gauge), then the mean over the held nodes removed
    anchor = _held_nodes(ds, problem, k)
    solve = factorized((Dr.T @ Dr).tocsc())
    est = np.empty(T)
    for t in range(T):
        x = np.zeros((nn, k))
        for c in range(k):
            x[1:, c] = solve(Dr.T @ b[t, :, c])
        x = x - x[anchor].mean(axis=0)
        est[t] = float(np.max(np.linalg.norm(x, axis=-1)))
    X0 = np.asarray(problem.medium.rest_strain(), dtype=float).reshape(d, -1)
    free = [c for c in range(k) if c not in comps]
    membrane = float(np.max(np.abs(X[..., free] - X0[:, free]))) if free else 0.0
    bending = float(np.max(np.abs(X[..., k:] - X0[:, k:]))) * float(max(grid.length))
    indicator = float(np.max(np.abs(dev)))
    deform = max(membrane, bending)
    out = (indicator, est, indicator / deform if deform > 0 else math.nan)
    return (*out, x) if with_field else out


def _advise_held(subject: _Subject, full_ds: Any, rtol: float, check: bool, full_time: float,
                 pilot_t: float | None, run: Any = None) -> ReductionAdvice:
    """The held-strain twin the scene's medium declares (:meth:`~cartan.medium.Medium.held_strain_twins`);
    ``run`` is the resolved full run of a dynamic scene (its integrator's order)."""
    out = ReductionAdvice(HELD_STRAINS, "approximate", indicator_name="max |X − X_held| (held strains)")
    problem = subject.problem
    try:
        held, twin = held_strain_twin(problem)
    except (ValueError, TypeError, KeyError) as exc:
        out.note = f"no held-strain twin: {' '.join(str(exc).split())[:200]}"
        return out
    label = f"{twin.label or 'held strains'}; twin {held.medium.name!r}"
    out.indicator_name = f"max |X − X_held| ({label})"
    if subject.mode == "dynamic" and (reason := _driven_obstacle(held, subject.run_settings)) is not None:
        out.note = f"twin {held.medium.name!r} declined: {reason}"
        return out
    k = problem.medium.group.matrix_size - 1
    comps, values = (np.asarray(a) for a in held.medium.constrained_strains())
    if any(int(c) >= k for c in comps):
        out.note = f"twin {held.medium.name!r}: the estimate covers held translation strains only"
        return out
    path = subject.mode == "continuation"
    at_end = ("at the path's end (λ = {:.4g}): ".format(float(full_ds["load_factor"].values[-1])) if path else "")
    if problem.grid.d == 1:
        if problem.grid.periodic[0] or [int(c) for c in comps] != list(range(k)):
            out.note = (f"twin {held.medium.name!r}: compared on open rods (d = 1, not periodic) holding every "
                        "translation strain only")
            return out
        anchor = _anchor(subject)
        ind, est, bound, _, field = _filament_estimate(full_ds, problem, k, values.astype(float), anchor,
                                                       last=path, with_field=True)
        out.error_scale = _displacement_scale(full_ds, problem, k, anchor)
        what = (f"twin {held.medium.name!r} ({twin.label}): {at_end}end-position difference |∫R(θ − θ₀)ds| = "
                f"{est:.5g} (bound ∫|θ − θ₀|ds = {bound:.5g}) against the largest displacement "
                f"{out.error_scale:.3g}")
    else:
        try:
            ind, per_frame, ratio, field = _held_surface_estimate(full_ds, problem, comps, values.astype(float), k,
                                                                  with_field=True)
        except ValueError as exc:
            out.note = f"twin {held.medium.name!r}: {exc}"
            return out
        est = float(per_frame[-1] if path else np.nanmax(per_frame))
        nodes = _held_nodes(full_ds, problem, k)
        centroid = len(nodes) == int(np.prod(problem.grid.shape))
        out.error_scale = _displacement_scale(full_ds, problem, k, None if centroid else "held")
        what = (f"twin {held.medium.name!r} ({twin.label}): held strains {ratio:.3g} of the membrane and bending "
                f"strains (L·|π − π₀|); {at_end}the displacement they carry, ∂_α x = R(X_α − X_held) integrated by "
                f"least squares, {est:.5g} against the largest displacement {out.error_scale:.3g} (both "
                + ("about the centroid)" if centroid else f"from the {len(nodes)} nodes the scene holds)"))
    out.admitted = True
    out.indicator, out.error_estimate = ind, est
    measure = subject.measure if subject.mode != "dynamic" else None
    if measure is not None:  # the quantity the scene measures: its change, full − twin ≈ the field there
        pos = np.asarray(full_ds["position"].values[-1], dtype=float).reshape(-1, k)
        pos0 = _initial_positions(problem)
        value = float(measure(pos, pos0))
        out.error_estimate = abs(value - float(measure(pos - field, pos0)))
        length = float(max(problem.grid.length))
        if abs(value) > TOL_ROUNDOFF * length:
            out.error_scale = abs(value)
        what = (f"on the scene's measure, {measure.describe()} = {value:.6g}{' ' + at_end.rstrip(': ') if path else ''}"
                f": the twin changes it by {out.error_estimate:.5g} (estimated from the displacement field the held "
                f"strains carry, relative to |{value:.4g}|"
                + ("" if abs(value) > TOL_ROUNDOFF * length else ": it does not move, so to the largest displacement")
                + f"); over every node: {what}")
    try:
        out.speedup_estimate = _cfl_ratio(problem, held, subject.run_settings)
    except (ValueError, TypeError, KeyError, NotImplementedError, AttributeError):
        out.speedup_estimate = math.nan
    within = math.isfinite(out.relative_error) and out.relative_error <= rtol
    what += ("; estimated speed-up = ratio of the explicit CFL estimates, twin / medium (the ratio of the time "
             "steps, an upper bound: a constrained step costs more than a free one" + (
                 "; measured with check)" if subject.mode == "dynamic" else "; a static solve does not gain it)"))
    if subject.mode == "dynamic":
        return _advise_held_dynamic(out, subject, held, full_ds, full_time, pilot_t, within, what, rtol, check, k,
                                    field, run)
    out.recommended = within
    out.note = what + ("" if within else f"; relative error {out.relative_error:.3g} > rtol = {rtol:g}")
    if check:
        from .statics import ConvergenceError

        try:
            fds, ftime = _run(subject, held, None)
        except ConvergenceError as exc:
            out.check_note = f"the held-strain {subject.mode} solve failed: {' '.join(str(exc).split())[:200]}"
            return out
        _measured(out, full_ds, fds, full_time, ftime, k, measure, _initial_positions(problem))
        out.predicted_difference = out.model_difference = out.error_estimate  # no time step: the model alone
        what = "static solves" if subject.mode == "static" else "continuation paths"
        of = (f"|{measure.describe()}: full − held|" if measure is not None else
              "largest |x_full − x_held| over the nodes")
        out.check_note = (f"{what}: full {full_time:.3g} s ({full_ds.attrs.get('newton_iterations')} Newton "
                          f"iterations), held {ftime:.3g} s ({fds.attrs.get('newton_iterations')}); difference "
                          f"= {of}" + (" at the path's end" if path else ""))
    return out


def _measured(out: ReductionAdvice, full_ds: Any, held_ds: Any, full_time: float, held_time: float, k: int,
              measure: Any = None, pos0: np.ndarray | None = None) -> None:
    """The check's measurements: the largest distance between the two runs' nodes at their
    last frame (or, with the scene's ``measure`` and the initial positions ``pos0`` ``[nodes, k]``,
    the difference of the measured quantity), and the time ratio full/held."""
    p_full = np.asarray(full_ds["position"].values[-1], dtype=float).reshape(-1, k)
    p_held = np.asarray(held_ds["position"].values[-1], dtype=float).reshape(-1, k)
    if measure is not None:
        out.measured_difference = abs(float(measure(p_full, pos0)) - float(measure(p_held, pos0)))
    else:
        out.measured_difference = float(np.max(np.linalg.norm(p_full - p_held, axis=-1)))
    out.time_ratio = full_time / held_time if held_time > 0 else math.nan


def _scene_save_every(subject: _Subject, run: Any = None) -> int:
    """The steps between the saved frames of the scene's run: its ``save_every``, or the one
    :func:`cartan.simulate` resolved (``run``), else the 20 save blocks of a pilot."""
    every = subject.run_settings.get("save_every") or getattr(run, "save_every", None)
    if every:
        return max(1, int(every))
    dt, t_end = subject.run_settings.get("dt"), subject.run_settings.get("t_end")
    return max(1, round(float(t_end) / float(dt)) // 20) if dt and t_end else max(1, PILOT_STEPS // 20)


def _last_positions(ds: Any, k: int) -> np.ndarray:
    """Node positions of the last frame of ``ds`` ``[nodes, k]``."""
    return np.asarray(ds["position"].values[-1], dtype=float).reshape(-1, k)


def _time_error(problem: Problem, settings: Mapping[str, Any], t_end: float, ds: Any, k: int,
                order: int) -> np.ndarray | None:
    """The time-step error of the run ``ds`` (``settings``' Δt, a whole number of steps to
    ``t_end``) at its last frame, by Richardson from a second, untimed run at Δt/2:
    ``e(Δt) ≈ (x_Δt − x_Δt/2)·2ᵖ/(2ᵖ − 1)`` ``[nodes, k]``, p the integrator's ``order``.
    None when that run fails or does not end at ``t_end``."""
    from .simulate import InstabilityError
    from .statics import ConvergenceError

    half = dict(settings)
    half["dt"] = 0.5 * float(settings["dt"])
    try:
        fine = _simulate(problem, half, t_end)
    except (InstabilityError, ConvergenceError, ValueError, ArithmeticError):
        return None
    if not math.isclose(float(fine["time"].values[-1]), float(ds["time"].values[-1]), rel_tol=1e-9, abs_tol=1e-12):
        return None
    factor = 2.0 ** order / (2.0 ** order - 1.0)
    return (_last_positions(ds, k) - _last_positions(fine, k)) * factor


def _largest(field: np.ndarray | None) -> float:
    """The largest norm over the nodes of ``field`` ``[nodes, k]`` (NaN for None)."""
    return math.nan if field is None else float(np.max(np.linalg.norm(field, axis=-1)))


def _advise_held_dynamic(out: ReductionAdvice, subject: _Subject, held: Problem, full_ds: Any, full_time: float,
                         pilot_t: float | None, within: bool, what: str, rtol: float, check: bool,
                         k: int, field: np.ndarray | None = None, run: Any = None) -> ReductionAdvice:
    """The held-strain twin of a dynamic scene: it runs with ``rattle`` (the integrator that holds
    constrained strains) at its own CFL step; recommended only when its strains allow it and a
    measured pilot (``check``) shows it faster over the same simulated time — the CFL ratio alone
    does not, since a constrained step costs more than a free one.

    The check compares the node positions at the full pilot's last step, t_c = N·Δt (N = ⌈T/Δt⌉
    steps to the pilot's end T): the twin's step, its own (half its CFL estimate, as
    :func:`cartan.simulate` picks it), is shortened so that a whole number of steps ends at t_c.
    The time ratio is that of whole runs to t_c (set-up, steps, saved frames, Dataset), both
    warm (compilation not counted), both saving the scene's output: the full model every
    ``save_every`` of its steps (:func:`_scene_save_every`), the twin at the same interval in time,
    every round(save_every·Δt/Δt') of its own steps (as many frames, to one) — not the pilot
    analysis's 20 frames, per-frame work the scene does not ask for (or more frames, when it asks
    for them) that both runs pay alike.  Each model's time is the fastest of up to :data:`TIMED_PAIRS`
    interleaved (full, twin) pairs, another pair only while one takes less than
    :data:`TIMED_PAIR_BUDGET` seconds.
    What it measures is

        x_full,Δt − x_twin,Δt' = (x_full − x_twin) + e_full(Δt) − e_twin(Δt'),

    the model difference and the two runs' time-step errors.  The prediction estimates each
    part, as its largest norm over the nodes: the model difference by ``field`` ``[nodes, k]``,
    the displacement the held strains carry at t_c (:func:`_filament_estimate`,
    :func:`_held_surface_estimate`); each time-step error by Richardson from a second run of the
    model at half its step and the order p of its integrator (:func:`_time_error`; ``run`` is the
    resolved full run, None skips the full model's).  ``predicted_difference`` is the sum of the
    three sizes, the upper estimate of the norm of the sum (triangle inequality).  Their
    directions are not combined: the model field is the first-order displacement of the held
    strains, right in size but not in direction in a moving rod, where the twin's different
    dynamics turn it (the stiff swing at n = 41: 9.4e-6 against the converged 1.22e-5, at 65° at
    the tip), so a node-by-node sum, or a root sum of squares (parts at right angles), can cancel
    what the runs do not.  The two runs share their grid, so their spatial errors cancel to
    leading order and are not part of the prediction."""
    out.note = what
    if not check:
        out.note += (". In time the twin runs with rattle at its own step; not recommended unmeasured: the time "
                     "ratio is measured with check" + (" (its strains allow it)" if within else ""))
        return out
    settings = {key: v for key, v in subject.run_settings.items() if key not in ("integrator_options", "dt")}
    settings["integrator"] = "rattle"
    from .simulate import InstabilityError, StabilityWarning, _resolve_run
    from .statics import ConvergenceError

    t_check = float(full_ds["time"].values[-1])  # the full pilot's last step (≥ pilot_t)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", StabilityWarning)
            twin_run = _resolve_run(held, "rattle", settings.get("scheme"), None, t_check, None, None, None,
                                    None, None, settings.get("scheme_options"), False, 1e3, compiled=True, command="",
                                    max_steps=None)
        dt_own = float(twin_run.dt)  # half its CFL estimate, as simulate picks it
        settings["dt"] = t_check / max(1, math.ceil(t_check / dt_own * (1.0 - 1e-12)))  # ends at t_check
        # both timed runs save the scene's output: every full_every steps of the full run, and the twin
        # at the same interval in time, to its nearest whole number of steps (as many frames, to one)
        full_every = _scene_save_every(subject, run)
        twin_every = max(1, round(full_every * float(subject.run_settings["dt"]) / settings["dt"]))
        with contextlib.suppress(InstabilityError):  # the warm-up compiles (or loads) its loop: not timed
            _simulate(held, settings, 2.0 * settings["dt"])
        # the full model is warm (the pilot): timed again with the scene's output, next to the twin, in
        # pairs (full, twin); each model's time is the fastest of its runs
        full_time = ftime = full_steps_time = twin_steps_time = math.inf
        pairs = 0
        while pairs < TIMED_PAIRS:
            timed_full, t_full = _timed(_simulate, subject.problem, subject.run_settings, t_check,
                                        save_every=full_every)
            timed_twin, t_twin = _timed(_simulate, held, settings, t_check, save_every=twin_every)
            full_time, ftime, pairs = min(full_time, t_full), min(ftime, t_twin), pairs + 1
            full_steps_time = min(full_steps_time, _step_time(timed_full, t_full))
            twin_steps_time = min(twin_steps_time, _step_time(timed_twin, t_twin))
            if t_full + t_twin > TIMED_PAIR_BUDGET:
                break
    except (ConvergenceError, InstabilityError, ValueError) as exc:
        out.check_note = f"the held-strain pilot (rattle) failed: {' '.join(str(exc).split())[:200]}"
        return out
    fds = timed_twin
    _measured(out, full_ds, fds, full_time, ftime, k)
    # the prediction: the model difference at t_check and the two runs' time-step errors
    p_twin = int(getattr(twin_run.integrator, "order", 0))
    e_twin = _time_error(held, settings, t_check, fds, k, p_twin) if p_twin > 0 else None
    p_full = int(getattr(getattr(run, "integrator", None), "order", 0))
    e_full = _time_error(subject.problem, subject.run_settings, t_check, full_ds, k, p_full) if p_full > 0 else None
    model = np.zeros_like(_last_positions(full_ds, k)) if field is None else np.asarray(field, float).reshape(-1, k)
    out.model_difference, out.time_error, out.full_time_error = _largest(model), _largest(e_twin), _largest(e_full)
    out.predicted_difference = out.model_difference + sum(e for e in (out.time_error, out.full_time_error)
                                                          if math.isfinite(e))
    steps, full_steps = int(fds["step"].values[-1]), int(timed_full["step"].values[-1])
    stepping = full_steps_time / max(twin_steps_time, 1e-300)
    dt_full = float(subject.run_settings["dt"])
    out.check_note = (f"pilot runs to t = {t_check:.6g} after an untimed warm-up of each: full "
                      f"{full_time:.3g} s ({full_steps} steps of Δt = {dt_full:.3g}), held (rattle, {steps} steps of "
                      f"Δt = {settings['dt']:.4g}) {ftime:.3g} s (the fastest of {pairs} timed pair"
                      f"{'s' if pairs > 1 else ''}), each saving the scene's output (the full run every "
                      f"{full_every} steps, {timed_full.sizes['time']} frames; the twin every {twin_every} steps, "
                      f"{fds.sizes['time']} frames); time ratio of the whole runs {out.time_ratio:.3g}×, "
                      f"of their steps alone {stepping:.3g}×; difference = largest |x_full − x_held| over the nodes "
                      "at the full run's last step (the twin's step shortened to end there); it contains the "
                      "two runs' time-step errors, estimated from runs at Δt/2 (rattle order "
                      f"{p_twin}, {getattr(getattr(run, 'integrator', None), 'name', 'the scene’s integrator')} "
                      f"order {p_full})")
    if e_twin is not None and out.time_error > max(out.model_difference, 1e-300):
        dt_even = settings["dt"] * (out.model_difference / out.time_error) ** (1.0 / p_twin)
        out.check_note += (f"; the twin's time-step error {out.time_error:.3g} exceeds the model difference "
                           f"{out.model_difference:.3g}: at Δt ≈ {dt_even:.2g} they would be equal")
    out.recommended = within and out.time_ratio > 1.0
    r = out.time_ratio
    pace = (f"{r:.3g}× faster than" if r >= 1.0 else f"{1.0 / r:.3g}× slower than" if r > 0 else "no faster than")
    measured = (f"; measured: the twin runs the pilot {pace} the medium ({ftime:.3g} s against {full_time:.3g} s "
                f"for the whole runs, {stepping:.3g}× for their steps alone; the CFL ratio is "
                f"{out.speedup_estimate:.3g})")
    out.note += measured
    if within and not out.recommended:
        out.note += "; its strains allow it but the pilot is not faster"
    elif not within:
        out.note += f"; relative error {out.relative_error:.3g} > rtol = {rtol:g}"
    if within and math.isfinite(out.time_error) and out.time_error > rtol * out.error_scale:
        out.note += (f"; at its own step the twin's time-step error, {out.time_error:.3g}, exceeds rtol of the "
                     f"scale {out.error_scale:.3g}: run it with a smaller Δt")
    return out


# ---------------------------------------------------------------------------- SE(3) planar -> SE(2)
def _advise_planar(subject: _Subject, full_ds: Any, full_time: float, run: Any, pilot_t: float | None,
                   check: bool) -> ReductionAdvice:
    from .reduction import planar_obstacle, planar_reduction, reduction_pays

    out = ReductionAdvice(PLANAR, "exact", indicator_name="planar data and loads (1 = yes)")
    problem = subject.problem
    if getattr(problem.medium.group, "name", "") != "SE3":
        out.note = f"the medium {problem.medium.name!r} is not on SE(3)"
        return out
    red = planar_reduction(problem)
    out.indicator = 1.0 if red is not None else 0.0
    if red is None:
        out.note = f"no exact planar reduction (cartan.reduction): {planar_obstacle(problem)}"
        return out
    out.admitted = True
    out.error_estimate, out.error_scale = 0.0, 1.0

    def diff(a: Any, b: Any) -> float:  # every saved frame of a run; the end of a solve or path
        pa = np.asarray(a["position"].values, dtype=float)
        pb = np.asarray(b["position"].values, dtype=float)
        if subject.mode != "dynamic":
            pa, pb = pa[-1], pb[-1]
        pb = pb if pb.shape[-1] == pa.shape[-1] else np.concatenate([pb, np.zeros((*pb.shape[:-1], 1))], -1)
        return float(np.max(np.abs(pa - pb)))

    if subject.mode != "dynamic":
        options = dict(subject.solver_options)
        if options.get("pins"):  # SE(3) pins (x, y, z, rotations about x, y, z) → SE(2) (x, y, rotation)
            options["pins"] = {end: tuple(_PLANAR_PIN[c] for c in comps if c in _PLANAR_PIN)
                               for end, comps in options["pins"].items()}
        what = "static solve" if subject.mode == "static" else "continuation path"
        rds, rtime = _run(subject, red.reduced, None, options=options)
        out.speedup_estimate = full_time / rtime if rtime > 0 else math.nan
        out.recommended = out.speedup_estimate > 1.0
        out.note = (f"exact (round-off): the SE(2) {what} takes {rtime:.3g} s against {full_time:.3g} s; "
                    f"difference at its end {diff(full_ds, rds):.2g}")
        if check:
            out.measured_difference, out.time_ratio = diff(full_ds, rds), out.speedup_estimate
            out.predicted_difference = out.model_difference = 0.0
            out.check_note = f"the same {what}s (the analysis runs the full one)"
        return out
    pays = reduction_pays(run)
    rds, rtime = _run(subject, red.reduced, pilot_t)
    out.speedup_estimate = full_time / rtime if rtime > 0 else math.nan
    out.recommended = pays
    out.note = (f"exact (round-off); pilot: {rtime:.3g} s on SE(2) against {full_time:.3g} s on SE(3), difference "
                f"{diff(full_ds, rds):.2g}. "
                + ("cartan.simulate performs it automatically (reduce=True)" if pays else
                   "reduction_pays is False for this integrator and scheme (the hand-written SE(3) loops are "
                   "faster than the generic SE(2) ones): simulate runs the full problem"))
    if check:
        t_end = float(subject.run_settings["t_end"])
        fds, ftime = _run(subject, problem, t_end, warm=False)
        cds, ctime = _run(subject, red.reduced, t_end, warm=False)
        out.measured_difference = diff(fds, cds)
        out.time_ratio = ftime / ctime if ctime > 0 else math.nan
        out.check_note = f"full runs to t = {t_end:g}: SE(3) {ftime:.3g} s, SE(2) {ctime:.3g} s"
    return out


# ---------------------------------------------------------------------------- large radius -> plane
_SPHERE_API = ("radius", "planar_parameters", "physical_strains", "strain_components", "physical_velocities",
               "velocity_components", "parameters")


def _on_sphere(medium: Medium) -> bool:
    """A rod on a sphere of radius r with a planar r → ∞ limit: the methods of :data:`_SPHERE_API`
    (physical strains and velocities ↔ group components, the limit's parameters)."""
    return all(hasattr(medium, name) for name in _SPHERE_API) and getattr(medium, "material_dim", 0) == 1


def _plane_medium(params: Mapping[str, Any]) -> Medium:
    """The registered medium on SE(2), d = 1, that takes the keywords ``params`` (the limit)."""
    from .plugins import get_registry

    for _, entry in sorted(get_registry().table("media").items()):
        cls = entry.obj
        try:
            med = cls(**params)
        except (TypeError, ValueError):
            continue
        if getattr(med.group, "name", "") == "SE2" and med.material_dim == 1:
            return med
    raise ValueError("no registered medium on SE(2) takes the planar limit's parameters")


def _sphere_variant(problem: Problem, radius: float | None) -> Problem:
    """The problem of a rod on a sphere with the same physical strains, velocities, loads and
    boundaries on the sphere of ``radius``, or in the plane (``radius=None``)."""
    from .schemes.lattice import Lattice

    rod = problem.medium
    h = float(problem.grid.spacing[0])

    def physical(Phi: np.ndarray) -> np.ndarray:
        """(θ₁, θ₂, π_n) ``[E, 3]`` of the frames ``Phi`` ``[n, m, m]`` on the edges (the lattice's)."""
        sch = Lattice(Problem(rod, problem.grid, InitialState(Phi=Phi)))
        return rod.physical_strains(sch.strains(sch.initial_state())[:, 0])

    if radius is None:
        med = _plane_medium(rod.planar_parameters())
    else:
        med = type(rod)(**(rod.parameters() | {"radius": float(radius)}))
    g = med.group

    def frames(Phi: np.ndarray) -> np.ndarray:
        """The frames ``[n, m', m']`` of ``med`` with the physical edge strains of ``Phi``, from
        the identity (the plane: node 0 at the origin, e₁ along x) or ``Phi[0]`` (a sphere)."""
        X = physical(Phi)
        Xc = X if radius is None else med.strain_components(X[:, 0], X[:, 1], X[:, 2])
        out = [np.eye(3) if radius is None else np.asarray(Phi[0], dtype=float)]
        for x in Xc:
            out.append(out[-1] @ g.exp(h * x))
        return np.stack(out)

    V = rod.physical_velocities(problem.initial.N)  # (V₁, V₂, Ω_n) [n, 3]
    N = V if radius is None else med.velocity_components(V[:, 0], V[:, 1], V[:, 2])
    Phi = frames(np.asarray(problem.initial.Phi, dtype=float))
    # the stress-free shape (a varying rest curvature) with the same physical rest strains
    reference = None if problem.reference is None else frames(np.asarray(problem.reference.Phi, dtype=float))
    boundaries = {}
    for key, b in problem.boundaries.items():
        if type(b) is Clamped:
            boundaries[key] = Clamped()
        elif type(b) is Free and b.load is None:
            boundaries[key] = Free(follower=b.follower)
        else:
            raise ValueError(f"boundary {key!r} ({type(b).__name__}, or with an end load) is not mapped to the plane")

    def squares(m: Any) -> np.ndarray:
        """``[j, k]``: the square of group component k of the unit physical velocity j."""
        if not _on_sphere(m):
            return np.eye(3)
        return np.stack([np.asarray(m.velocity_components(*row), dtype=float) for row in np.eye(3)]) ** 2

    loads = []
    for load in problem.loads:  # the same drag power Σ c_k N_k² = γ·(V₁², V₂², Ω²)
        if type(load) is not Damping:
            raise ValueError(f"load {type(load).__name__} is not mapped to the plane (drag only)")
        gamma = squares(rod) @ np.asarray(load.coefficients, dtype=float)
        loads.append(Damping(np.linalg.solve(squares(med), gamma)))
    return Problem(med, problem.grid, InitialState(Phi=Phi, N=N), boundaries, loads, name=problem.name,
                   reference=reference)


def plane_limit_problem(problem: Problem) -> Problem:
    """The r → ∞ limit of a rod on a sphere of radius r: the same physical strains (θ₁, θ₂, π_n),
    physical velocities, drag and boundaries on the registered SE(2) medium that takes the
    rod's ``planar_parameters()`` (paper §VIII.A).

    Parameters
    ----------
    problem : Problem
        An open rod (d = 1, not periodic) on a sphere (see :func:`_on_sphere`) with drag
        (:class:`~cartan.problem.Damping`, mapped at equal dissipated power) loads only and
        ``Clamped`` / unloaded ``Free`` ends.

    Returns
    -------
    Problem
        The planar problem; node 0 at the origin with e₁ along x.

    Raises
    ------
    ValueError
        When the problem does not qualify.
    """
    if not _on_sphere(problem.medium) or problem.grid.d != 1 or problem.grid.periodic[0]:
        raise ValueError("the problem is not an open rod on a sphere")
    return _sphere_variant(problem, None)


def _advise_sphere(subject: _Subject, full_ds: Any, full_time: float, rtol: float, pilot_t: float | None,
                   check: bool) -> ReductionAdvice:
    out = ReductionAdvice(LARGE_RADIUS, "approximate", indicator_name="L/r")
    problem = subject.problem
    if not _on_sphere(problem.medium):
        out.note = f"not a rod on a sphere (medium {problem.medium.name!r})"
        return out
    rod = problem.medium
    L = float(problem.grid.length[0])
    out.indicator = L / rod.radius
    if problem.grid.periodic[0]:
        out.note = "a closed rod around the sphere has no planar limit"
        return out
    if subject.mode != "dynamic":
        out.note = f"{subject.mode} scenes of rods on a sphere are not compared with the plane"
        return out
    try:
        double = _sphere_variant(problem, 2.0 * rod.radius)
        plane = plane_limit_problem(problem)
    except ValueError as exc:
        out.note = str(exc)
        return out
    out.admitted = True

    def strains(ds: Any, med: Any) -> np.ndarray:
        X = np.asarray(ds["X"].values[-1], dtype=float).reshape(-1, 3)
        return med.physical_strains(X) if _on_sphere(med) else X

    ds1, t1 = full_ds, full_time
    ds2, _ = _run(subject, double, pilot_t)
    dsp, tp = _run(subject, plane, pilot_t)
    s1 = strains(ds1, rod)
    out.error_estimate = 4.0 / 3.0 * float(np.max(np.abs(s1 - strains(ds2, double.medium))))
    moved = strains(ds1, rod) - rod.physical_strains(
        np.asarray(ds1["X"].values[0], dtype=float).reshape(-1, 3))
    out.error_scale = max(float(np.max(np.abs(moved))), float(np.max(np.abs(s1))) * 1e-3)
    out.speedup_estimate = t1 / tp if tp > 0 else math.nan
    out.recommended = bool(out.relative_error <= rtol)
    out.note = (f"difference of the physical strains (θ₁, θ₂, π_n) at the pilot's end, Richardson from r and 2r "
                f"(O(r⁻²)), against their change over the pilot {out.error_scale:.3g}; speed-up: pilot times "
                f"{t1:.3g} s (sphere) and {tp:.3g} s (plane)")
    if check:
        t_end = float(subject.run_settings["t_end"])
        fds, ft = _run(subject, problem, t_end, warm=False)
        pds, pt = _run(subject, plane, t_end, warm=False)
        out.measured_difference = float(np.max(np.abs(strains(fds, rod) - strains(pds, plane.medium))))
        out.time_ratio = ft / pt if pt > 0 else math.nan
        # the prediction at the time the check compares: the pilot's estimate when the pilot is the whole run,
        # else Richardson from r and 2r again at t_end (the same integrator and Δt on both models: their
        # time-step errors differ by O((L/r)²) of themselves, and are not estimated apart)
        same = math.isclose(float(fds["time"].values[-1]), float(ds1["time"].values[-1]), rel_tol=1e-9)
        ds2_end = ds2 if same else _run(subject, double, t_end, warm=False)[0]
        out.predicted_difference = out.model_difference = (
            out.error_estimate if same else 4.0 / 3.0 * float(np.max(np.abs(strains(fds, rod)
                                                                          - strains(ds2_end, double.medium)))))
        out.check_note = (f"full runs to t = {t_end:g}: sphere {ft:.3g} s, plane {pt:.3g} s; predicted: Richardson "
                          "from r and 2r at t = " + (f"{t_end:g} (the pilot's estimate)" if same else
                                                     f"{t_end:g} (a run at 2r to that time too)"))
    if not out.recommended:
        out.note += f"; relative error {out.relative_error:.3g} > rtol = {rtol:g}"
    elif out.speedup_estimate < 1.0:
        out.note += (f"; recommended as the simpler model within rtol, but its pilot was not faster "
                     f"({out.speedup_estimate:.2f}×)")
    return out


# ---------------------------------------------------------------------------- the entry point
def advise(problem_or_scene: Any, check: bool = False, *, rtol: float = DEFAULT_RTOL,
           pilot_steps: int = PILOT_STEPS, tol: float | None = None, quantity: str = "auto",
           schemes: Sequence[str] | None = None) -> Advice | MethodAdvice | ResolutionAdvice:
    """Which reductions a scene admits, measured on the scene (see the module docstring).

    With ``tol``: a method for the accuracy ``tol`` instead (``check`` and ``rtol`` do not
    apply) — for a dynamic scene the cheapest integrator and Δt, :func:`advise_method`; for a
    static scene the coarsest grid, :func:`advise_resolution` (a continuation scene: at its
    path's final point).

    Parameters
    ----------
    problem_or_scene : Problem, Scene, path, str or dict
        A :class:`~cartan.Problem` (advised as a static problem, default Newton settings), a
        :class:`~cartan.scene.Scene`, a scene file, a registered scene name or a scene dict.
        Static, continuation and dynamic scenes.
    check : bool, default False
        Also run the full and the reduced model side by side (the static solve or the
        continuation path with the reduced model, or the whole dynamic run with both) and report
        the measured difference and time ratio.
    rtol : float, default 1e-3
        Relative error accepted for an approximate reduction, in (0, 1].
    pilot_steps : int, default 200
        Time steps of the pilot of a dynamic scene (fewer when its run is shorter), ≥ 2.
    tol : float, optional
        Advise a method for this accuracy instead (see above).
    quantity : {"auto", "measure", "positions"}, default "auto"
        With ``tol`` on a static or continuation scene: what the error is measured on
        (:func:`advise_resolution`).
    schemes : sequence of str, optional
        With ``tol`` on a dynamic scene: the schemes compared (:func:`advise_schemes`; default
        :data:`TOL_SCHEMES`, ``()`` skips the comparison).

    Returns
    -------
    Advice, MethodAdvice or ResolutionAdvice
        Without ``tol``: one :class:`ReductionAdvice` per reduction (``Advice.to_dataset()`` for
        an xarray table, ``Advice.to_dict()``, ``str(advice)`` for the text report); with
        ``tol``: the method (dynamic) or resolution (static, continuation) advice.

    Raises
    ------
    ValueError
        Bad ``rtol``, ``check`` or ``pilot_steps``; a static scene with an ``initial_guess``; a
        scene that does not load
        (:class:`~cartan.scene.SceneError`) or whose run settings are invalid.
    TypeError
        ``problem_or_scene`` of another type.
    cartan.statics.ConvergenceError, cartan.simulate.InstabilityError
        The scene's own solve or pilot failed.
    """
    if tol is not None:
        if check:
            raise ValueError("tol and check=True do not combine: the method advice runs no reduced model")
        _check_tol(tol)
        obj = _load(problem_or_scene)
        if isinstance(obj, Problem) or getattr(obj, "mode", None) in ("static", "continuation"):
            return advise_resolution(obj, tol, quantity=quantity)
        return advise_method(obj, tol, pilot_steps=pilot_steps, **({} if schemes is None else {"schemes": schemes}))
    start = time.perf_counter()
    if not isinstance(check, bool | np.bool_):
        raise ValueError(f"check must be True or False, got {check!r}")
    if isinstance(rtol, bool) or not isinstance(rtol, int | float) or not 0.0 < float(rtol) <= 1.0:
        raise ValueError(f"rtol must be a number in (0, 1], got {rtol!r}")
    if isinstance(pilot_steps, bool) or not isinstance(pilot_steps, int | np.integer) or pilot_steps < 2:
        raise ValueError(f"pilot_steps must be an integer ≥ 2, got {pilot_steps!r}")
    subject = _subject(problem_or_scene)
    run = None
    pilot_t = None
    if subject.mode == "static":
        full_ds, full_time = _run(subject, subject.problem, None)
        pilot = f"the static solve ({full_time:.3g} s, {full_ds.attrs.get('newton_iterations')} Newton iterations)"
    elif subject.mode == "continuation":
        full_ds, full_time = _run(subject, subject.problem, None)
        pilot = (f"the continuation path ({full_time:.3g} s, {full_ds.sizes['time']} path points to λ = "
                 f"{float(full_ds['load_factor'].values[-1]):.4g}, {full_ds.attrs.get('newton_iterations')} Newton "
                 "iterations)")
    else:
        dt, pilot_t, run = _dynamic_settings(subject, int(pilot_steps))
        full_ds, full_time = _run(subject, subject.problem, pilot_t)
        pilot = (f"a pilot run to t = {pilot_t:g} ({round(pilot_t / dt)} steps of Δt = {dt:.3g}, {full_time:.3g} s; "
                 f"the scene runs to t = {float(run.info['run']['t_end']):g})")
    reductions = [
        _advise_held(subject, full_ds, float(rtol), bool(check), full_time, pilot_t, run),
        _advise_planar(subject, full_ds, full_time, run, pilot_t, bool(check)),
        _advise_sphere(subject, full_ds, full_time, float(rtol), pilot_t, bool(check)),
    ]
    return Advice(subject.name, subject.mode, subject.problem.medium.name, pilot, float(rtol), bool(check),
                  reductions, time.perf_counter() - start)



# ---------------------------------------------------------------------------- a method for a tolerance
#: the schemes the dynamic advice for a tolerance compares (those that apply)
TOL_SCHEMES = ("lattice", "collocation")
#: integrators a dynamic scene is advised among (those that do not apply to the medium are skipped)
TOL_INTEGRATORS = ("lie-verlet", "rkmk4", "implicit-midpoint", "lie-euler")
#: the candidate time steps are Δt_scene·2^k for these k
TOL_DT_POWERS = (-2, -1, 0, 1, 2)
#: the reference run takes Δt_scene divided by this, with the most accurate integrator available
TOL_REFERENCE_DIVISOR = 8
#: explicit candidates above this multiple of the integrator's CFL estimate are not run
TOL_CFL_CAP = 2.0
#: timed runs of each candidate (the fastest is its cost)
TOL_REPEATS = 2
#: the order of preference of the reference integrator (most accurate first)
_REFERENCE_ORDER = ("rkmk4", "implicit-midpoint", "lie-verlet", "lie-euler")


def _json_value(v: Any) -> Any:
    """A report value as JSON: NaN and inf as ``None``."""
    return None if isinstance(v, float) and not math.isfinite(v) else v


def _json_row(c: Any) -> dict[str, Any] | None:
    """A candidate (a dataclass) of a report as a JSON object, or ``None``."""
    return None if c is None else {k: _json_value(v) for k, v in dataclasses.asdict(c).items()}

@dataclasses.dataclass
class MethodCandidate:
    """One run of the work-precision sweep of :func:`advise_method`.

    Attributes
    ----------
    integrator, scheme : str
    dt : float
    status : str
        ``"ok"``, ``"unstable: ..."`` (the run blew up), ``"beyond CFL"`` (not run: Δt above
        :data:`TOL_CFL_CAP` times the CFL estimate of an explicit integrator) or
        ``"failed: ..."`` (another error of the run).
    error : float
        Max norm of the final node positions against the reference run (NaN unless ``ok``).
    wall_time : float
        Seconds spent stepping, after compilation (NaN unless ``ok``; see :func:`advise_method`).
    dt_max : float
        The integrator's CFL estimate at the initial state (inf: no limit).
    """

    integrator: str
    scheme: str
    dt: float
    status: str
    error: float = math.nan
    wall_time: float = math.nan
    dt_max: float = math.nan

    @property
    def ok(self) -> bool:
        """The run finished with finite results."""
        return self.status == "ok"


@dataclasses.dataclass
class MethodAdvice:
    """What :func:`advise_method` (``advise(..., tol=...)``) returns.

    Attributes
    ----------
    scene, medium, scheme : str
    n : int
        Nodes of the scene's grid (the resolution every run uses).
    tol : float
        Requested accuracy (absolute, length units: max norm of the final node positions).
    t_end : float
        End time of the study runs.
    dt_scene : float
    reference : str
        The reference run (integrator and Δt).
    reference_error : float
        Estimated error of the reference: the error of the reference integrator at
        ``2·Δt_ref`` divided by ``2^p − 1`` (p its order; NaN when that run is missing).
    candidates : list of MethodCandidate
    recommended : MethodCandidate or None
        The cheapest candidate whose error ≤ ``tol``.
    fastest : MethodCandidate or None
        The cheapest finished candidate of the sweep, whatever its error.
    wall_time : float
        Seconds spent in :func:`advise_method`.
    spatial_n : int
        Nodes of the refined grid of the spatial check (0: not made).
    spatial_difference : float
        Max norm of the final positions of the reference run on the scene's grid against the same
        run on the refined grid, at the shared nodes: the size of the spatial discretisation error
        the time-step advice does not cover (NaN when not measured).
    schemes : list of SchemeCandidate
        The scheme study (:func:`advise_schemes`): each scheme of ``schemes`` that applies to the
        medium and the scene's integrator, on three grids with Δt refined with h (empty when
        not made).
    scheme_recommended : SchemeCandidate or None
        The scheme whose cost to reach ``tol`` (measured, or extrapolated from the observed
        order) is the smallest; None when none reaches it or fewer than two apply.
    scheme_note : str
        Why: the two schemes' grids and costs at ``tol``.
    """

    scene: str
    medium: str
    scheme: str
    n: int
    tol: float
    t_end: float
    dt_scene: float
    reference: str
    reference_error: float
    candidates: list[MethodCandidate]
    recommended: MethodCandidate | None
    fastest: MethodCandidate | None
    wall_time: float = 0.0
    spatial_n: int = 0
    spatial_difference: float = math.nan
    schemes: list[SchemeCandidate] = dataclasses.field(default_factory=list)
    scheme_recommended: SchemeCandidate | None = None
    scheme_note: str = ""

    @property
    def within_2x_of_fastest(self) -> bool:
        """The recommendation costs at most twice the fastest run of the sweep."""
        if self.recommended is None or self.fastest is None:
            return False
        return self.recommended.wall_time <= 2.0 * self.fastest.wall_time

    @property
    def failures(self) -> list[MethodCandidate]:
        """The stability map: the candidates that blew up or were not run past the CFL estimate."""
        return [c for c in self.candidates if not c.ok]

    def to_dict(self) -> dict[str, Any]:
        """The report as plain Python (JSON-serialisable, NaN and inf as ``None``)."""
        clean, row = _json_value, _json_row
        out = {k: clean(getattr(self, k)) for k in ("scene", "medium", "scheme", "n", "tol", "t_end", "dt_scene",
                                                     "reference", "reference_error", "wall_time", "spatial_n",
                                                     "spatial_difference")}
        out["candidates"] = [row(c) for c in self.candidates]
        out["recommended"] = row(self.recommended)
        out["fastest"] = row(self.fastest)
        out["within_2x_of_fastest"] = self.within_2x_of_fastest
        out["schemes"] = [c.to_dict() for c in self.schemes]
        out["scheme_recommended"] = None if self.scheme_recommended is None else self.scheme_recommended.scheme
        out["scheme_note"] = self.scheme_note
        return out

    def __str__(self) -> str:
        def f(x: float, spec: str = ".3g") -> str:
            return "—" if not math.isfinite(x) else format(x, spec)

        lines = [f"scene {self.scene!r} ({self.medium}, {self.scheme}, n = {self.n}): method for tol = {self.tol:g}",
                 f"error: max |position − reference| at t = {self.t_end:g}; reference {self.reference} "
                 f"(its estimated error {f(self.reference_error)}); spatial resolution: the scene's", "",
                 f"{'integrator':<18} {'dt':>10} {'CFL est.':>10} {'error':>10} {'time [s]':>9}  status"]
        for c in self.candidates:
            lines.append(f"{c.integrator:<18} {c.dt:>10.4g} {f(c.dt_max, '.4g'):>10} {f(c.error):>10} "
                         f"{f(c.wall_time):>9}  {c.status}")
        lines.append("")
        fails = self.failures
        if fails:
            lines.append("stability map (failed): " + ", ".join(
                f"{c.integrator} at dt = {c.dt:.4g} ({c.status.split(':')[0]})" for c in fails))
        if self.recommended is None:
            lines.append(f"recommended: none — no candidate reaches tol = {self.tol:g}")
        else:
            r = self.recommended
            lines.append(f"recommended: {r.integrator}, {r.scheme}, n = {self.n}, dt = {r.dt:.4g} "
                         f"(error {r.error:.3g}, {r.wall_time:.3g} s)")
        if self.fastest is not None:
            lines.append(f"fastest in the sweep: {self.fastest.integrator}, dt = {self.fastest.dt:.4g} "
                         f"({self.fastest.wall_time:.3g} s, error {self.fastest.error:.3g}); recommendation within 2×: "
                         f"{'yes' if self.within_2x_of_fastest else 'no'}")
        if self.spatial_n:
            lines.append(f"spatial check (reference run on n = {self.spatial_n}): max |position(n = {self.n}) − "
                         f"position(n = {self.spatial_n})| = {f(self.spatial_difference)} at the shared nodes")
            if math.isfinite(self.spatial_difference) and self.spatial_difference > self.tol:
                lines.append(f"warning: the scene's grid alone differs from the refined one by more than tol "
                             f"({self.spatial_difference:.3g} > {self.tol:g}): refine the grid; the time-step advice "
                             "does not cover the spatial error")
        if math.isfinite(self.reference_error) and self.tol < 10.0 * self.reference_error:
            lines.append(f"warning: tol is below 10× the reference's estimated error ({self.reference_error:.3g}); "
                         "the errors near tol are not resolved")
        if self.schemes:
            lines += ["", scheme_table(self.schemes, self.scheme_recommended)]
            lines.append(("scheme recommended: " + self.scheme_recommended.scheme if self.scheme_recommended
                          else "scheme recommended: none") + f" — {self.scheme_note}")
        elif self.scheme_note:
            lines += ["", self.scheme_note]
        return "\n".join(lines)

    def plot(self, path: str | os.PathLike) -> pathlib.Path:
        """Work-precision chart: error against wall time per integrator (log–log), the tol line,
        the recommendation circled; with a scheme study (:attr:`schemes`), each scheme's three
        levels too (squares, dashed: Richardson's estimate of the whole discretisation error,
        h and Δt refined together), the recommended scheme's level circled; written with
        matplotlib (Agg).  Returns the path."""
        from .study import _figure, finish_chart

        plt, fig, ax = _figure()
        for name in dict.fromkeys(c.integrator for c in self.candidates):
            pts = [(c.wall_time, c.error) for c in sorted(self.candidates, key=lambda c: c.dt)
                   if c.integrator == name and c.ok and c.error > 0 and c.wall_time > 0]  # joined in Δt order
            if pts:
                ax.loglog(*zip(*pts, strict=True), "o-", label=f"{name} (time error, n = {self.n})")
        for c in self.schemes:
            pts = [(t, e) for t, e in zip(c.wall_time, c.errors, strict=True) if t > 0 and math.isfinite(e) and e > 0]
            if c.status == "ok" and pts:
                ax.loglog(*zip(*pts, strict=True), "s--", label=f"{c.scheme}, {c.integrator} (h, Δt refined; est.)")
        ax.axhline(self.tol, color="k", ls="--", lw=0.8, label=f"tol = {self.tol:g}")
        if self.recommended is not None and self.recommended.error > 0:
            ax.loglog([self.recommended.wall_time], [self.recommended.error], "o", ms=14, mfc="none", color="r",
                      label="recommended")
        chosen = self.scheme_recommended
        if chosen is not None and not chosen.extrapolated and chosen.chosen_n in chosen.n:
            i = chosen.n.index(chosen.chosen_n)
            ax.loglog([chosen.wall_time[i]], [chosen.errors[i]], "s", ms=14, mfc="none", color="m",
                      label=f"scheme recommended ({chosen.scheme}, n = {chosen.chosen_n})")
        ax.set_xlabel("wall time of the steps [s] (after compilation)")
        ax.set_ylabel("max |position − reference| (schemes: estimated error)")
        return finish_chart(fig, ax, path, f"work-precision: {self.scene}, t = {self.t_end:g}")


def _check_tol(tol: Any) -> float:
    if isinstance(tol, bool) or not isinstance(tol, int | float | np.floating | np.integer) \
            or not math.isfinite(float(tol)) or float(tol) <= 0.0:
        raise ValueError(f"tol must be a finite number > 0, got {tol!r}")
    return float(tol)


def _final_positions(ds: Any) -> np.ndarray:
    p = ds["position"]
    return np.asarray(p.isel(time=-1).values if "time" in p.dims else p.values, dtype=float)


def _step_time(ds: Any, total: float) -> float:
    """The run's own count of the seconds spent stepping (``total``, the call's time, when absent)."""
    import json

    config = ds.attrs.get("cartan_config")
    t = json.loads(config).get("counters", {}).get("wall_time") if config else None
    return float(t) if t is not None and math.isfinite(float(t)) else float(total)


def _try_resolve(problem: Problem, integrator: str, settings: Mapping[str, Any], dt: float) -> float | None:
    """The CFL estimate of ``integrator`` on the scene (with the settings' ``scheme``,
    ``scheme_options`` and ``compiled``), or None when it does not apply to the medium."""
    from .simulate import StabilityWarning, _resolve_run

    opts = settings.get("integrator_options") if integrator == settings.get("integrator") else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StabilityWarning)
        try:
            run = _resolve_run(problem, integrator, settings.get("scheme"), dt, 2 * dt, 1, None, None, None, opts,
                               settings.get("scheme_options"), False, 1e3,
                               compiled=bool(settings.get("compiled", True)), command="", max_steps=None)
        except (ValueError, TypeError, NotImplementedError):
            return None
    return float(run.dt_max)


def advise_method(problem_or_scene: Any, tol: float, *, pilot_steps: int = PILOT_STEPS,
                  integrators: tuple[str, ...] = TOL_INTEGRATORS,
                  dt_powers: tuple[int, ...] = TOL_DT_POWERS, spatial: bool = True,
                  schemes: Sequence[str] = TOL_SCHEMES) -> MethodAdvice:
    """The cheapest (integrator, Δt) that reaches ``tol`` on a dynamic scene, from a sweep on the scene.

    The output of interest is the scene's final node positions ``[nodes, k]`` at the study's end
    time ``T = min(t_end, pilot_steps·Δt_scene)``; the error of a run is the max norm of their
    difference from a reference run: the same scene with the most accurate integrator that
    applies (:data:`_REFERENCE_ORDER`, rkmk4 first) at ``Δt_scene /`` :data:`TOL_REFERENCE_DIVISOR`.
    It is a reference of the time discretisation at the scene's spatial resolution: the scheme
    and the grid are the scene's, and the spatial discretisation error is not part of the
    error; it is measured separately (``spatial``), the reference run on the refined grid.  The
    reference's own error is estimated from the same integrator at twice its Δt (Richardson,
    order p: ``e(2Δt)/(2^p − 1)``).

    Candidates: every integrator of ``integrators`` that applies to the medium (one whose run
    cannot be set up, a ``ValueError``, is skipped) at ``Δt_scene·2^k``, ``k`` in ``dt_powers``.
    An explicit integrator is not run above :data:`TOL_CFL_CAP` times its CFL estimate
    (``"beyond CFL"``); a run that blows up is recorded as ``"unstable"`` (the stability map),
    not raised.  Cost: the wall time of the time steps as the run counts it (the ``wall_time``
    counter of ``cartan_config``: the stepping loop, without the set-up and the assembly of the
    Dataset, which do not depend on the method), the fastest of :data:`TOL_REPEATS` runs, measured
    after a two-step warm-up run of the same integrator that compiles its loop; it depends on
    the machine and its load.

    Parameters
    ----------
    problem_or_scene : Scene, path, str or dict
        A dynamic scene (a :class:`~cartan.scene.Scene`, a scene file, a registered name or a dict).
    tol : float
        Accepted error, > 0 (length units: the max norm of the final node positions).
    pilot_steps : int, default 200
        Steps of the scene's Δt in the study (fewer when the scene's run is shorter).
    integrators : tuple of str
    dt_powers : tuple of int
    spatial : bool, default True
        Also run the reference on the refined grid (``n → 2n − 1`` nodes of an open
        one-dimensional grid, ``2n`` of a periodic one: the scene's nodes are every other node)
        and report the difference at the shared nodes separately (``spatial_difference``);
        skipped for grids of dimension > 1 and for scenes without a source table.
    schemes : sequence of str, default :data:`TOL_SCHEMES`
        The schemes compared for ``tol`` with the scene's integrator (:func:`advise_schemes`;
        ``()`` skips the study).  A scheme that does not apply to the medium or the integrator
        is listed as such.

    Returns
    -------
    MethodAdvice

    Raises
    ------
    ValueError
        Bad ``tol`` or ``pilot_steps``; a static or continuation scene; no integrator applies.
    cartan.simulate.InstabilityError
        The reference run blew up.
    """
    from .simulate import InstabilityError

    start = time.perf_counter()
    tol = _check_tol(tol)
    if isinstance(pilot_steps, bool) or not isinstance(pilot_steps, int | np.integer) or pilot_steps < 2:
        raise ValueError(f"pilot_steps must be an integer ≥ 2, got {pilot_steps!r}")
    if schemes:
        _check_schemes(schemes)
    subject = _subject(problem_or_scene)
    if subject.mode != "dynamic" or not subject.run_settings:
        raise ValueError(f"scene {subject.name!r}: advice for a tolerance needs a dynamic scene, got mode "
                         f"{subject.mode!r}")
    dt0, t_end, run0 = _dynamic_settings(subject, int(pilot_steps))
    problem = subject.problem
    base = dict(subject.run_settings)
    scheme = str(run0.scheme.name)
    cfl = {name: _try_resolve(problem, name, base, dt0) for name in integrators}
    usable = [name for name in integrators if cfl[name] is not None]
    if not usable:
        raise ValueError(f"scene {subject.name!r}: none of the integrators {', '.join(integrators)} applies to "
                         f"medium {problem.medium.name!r}")

    def settings(name: str, dt: float) -> dict[str, Any]:
        s = {k: v for k, v in base.items() if k not in ("integrator", "integrator_options", "dt")}
        if name == base.get("integrator") and base.get("integrator_options"):
            s["integrator_options"] = dict(base["integrator_options"])
        return s | {"integrator": name, "dt": dt}

    warmed: set[str] = set()

    def timed_run(name: str, dt: float) -> tuple[Any, float]:
        if name not in warmed:
            with contextlib.suppress(InstabilityError):
                _simulate(problem, settings(name, dt), 2 * dt)
            warmed.add(name)
        runs = [_timed(_simulate, problem, settings(name, dt), t_end) for _ in range(TOL_REPEATS)]
        return runs[-1][0], min(_step_time(ds, t) for ds, t in runs)

    ref_name = next(n for n in _REFERENCE_ORDER if n in usable)
    ref_dt = dt0 / TOL_REFERENCE_DIVISOR
    ref_ds, _ = timed_run(ref_name, ref_dt)
    ref = _final_positions(ref_ds)
    if not np.all(np.isfinite(ref)):
        raise InstabilityError(f"the reference run ({ref_name}, dt = {ref_dt:.4g}) ended with non-finite positions")

    candidates: list[MethodCandidate] = []
    for name in usable:
        explicit = bool(getattr(_registered_integrator(name), "explicit", True))
        for k in sorted(dt_powers):
            dt = dt0 * 2.0 ** k
            c = MethodCandidate(name, scheme, dt, "ok", dt_max=float(cfl[name]))
            if explicit and 0.0 < c.dt_max < math.inf and dt > TOL_CFL_CAP * c.dt_max:
                c.status = "beyond CFL"
            else:
                try:
                    ds, c.wall_time = timed_run(name, dt)
                    pos = _final_positions(ds)
                    if not np.all(np.isfinite(pos)):
                        c.status, c.wall_time = "unstable: non-finite positions", math.nan
                    else:
                        c.error = _max_distance(pos, ref)
                except InstabilityError as exc:
                    why = " ".join(str(exc).split()).split(";", 1)[0].removeprefix("pilot run ")
                    c.status = "unstable: " + why.removeprefix("unstable ")
                except (ValueError, ArithmeticError) as exc:
                    c.status = "failed: " + (" ".join(str(exc).split()) or type(exc).__name__)
            candidates.append(c)

    ref_err = math.nan
    twice = [c for c in candidates if c.integrator == ref_name and c.ok and math.isclose(c.dt, 2 * ref_dt)]
    if twice:
        order = float(getattr(_registered_integrator(ref_name), "order", 2))
        ref_err = twice[0].error / (2.0 ** order - 1.0)
    spatial_n, spatial_diff = 0, math.nan
    fine = _refined_scene(problem_or_scene) if spatial else None
    if fine is not None:
        spatial_n = int(np.prod(fine.problem.grid.shape))
        with contextlib.suppress(InstabilityError, ValueError, ArithmeticError):
            fine_ds = _simulate(fine.problem, settings(ref_name, ref_dt), t_end)
            spatial_diff = _max_distance(_shared_nodes(_final_positions(fine_ds), 1, ref.shape[:-1]),
                                         ref.reshape(-1, ref.shape[-1]))
    recommended, fastest = choose_method(candidates, tol)
    study, chosen, why = [], None, ""
    if schemes:
        try:
            study, chosen, why = advise_schemes(problem_or_scene, tol, pilot_steps=pilot_steps, schemes=schemes)
        except ValueError as exc:  # e.g. a grid the study cannot refine: the method advice stands
            why = f"the scheme comparison was not made: {' '.join(str(exc).split())[:200]}"
    return MethodAdvice(subject.name, problem.medium.name, scheme, int(np.prod(problem.grid.shape)), tol, t_end,
                        dt0, f"{ref_name} at dt = {ref_dt:.4g}", ref_err, candidates, recommended, fastest,
                        time.perf_counter() - start, spatial_n, spatial_diff, study, chosen, why)


def choose_method(candidates: Sequence[Any], tol: float, *, cost: Any = None, error: Any = None
                  ) -> tuple[Any, Any]:
    """(the cheapest finished candidate whose error is at most ``tol``, the cheapest finished
    candidate whatever its error); None where there is none.

    ``candidates`` have ``ok``; ``cost(c)`` and ``error(c)`` default to ``c.wall_time`` and
    ``c.error`` (:class:`MethodCandidate`); :func:`advise_resolution` passes the number of
    nodes and the relative error of a :class:`ResolutionCandidate`.
    """
    cost = cost if cost is not None else (lambda c: c.wall_time)
    error = error if error is not None else (lambda c: c.error)
    done = [c for c in candidates if c.ok]
    good = [c for c in done if error(c) <= tol]
    return (min(good, key=cost) if good else None, min(done, key=cost) if done else None)


# ---------------------------------------------------------------------------- the scheme for a tolerance
@dataclasses.dataclass
class SchemeCandidate:
    """One scheme of the study of :func:`advise_schemes`: three runs of the scene's integrator
    on the grids n, 2n − 1, 4n − 3 (periodic n, 2n, 4n) with Δt, Δt/2, Δt/4.

    Attributes
    ----------
    scheme : str
    status : str
        ``"ok"``, ``"not applicable: ..."`` (the medium or integrator does not run on it) or
        ``"failed: ..."`` / ``"unstable: ..."`` (a run did not finish).
    integrator : str
    n : tuple of int
        Nodes of the three levels.
    dt : tuple of float
        Their time steps (the coarsest: the scene's Δt, or half the scheme's CFL estimate when
        that is smaller; then halved with h).
    wall_time : tuple of float
        Seconds spent stepping on each level (the run's own count, the faster of
        :data:`TOL_REPEATS` runs after a warm-up run; machine- and load-dependent).
    errors : tuple of float
        Richardson's estimate of each level's error (max over the scene's nodes of
        ``|x − x(h → 0)|`` at the study's end time, length units).
    order : float
        The observed order ``log₂(d₀/d₁)`` (space and time refined together).
    differences : tuple of float
        ``d₀ = max|x(n) − x(2n − 1)|``, ``d₁ = max|x(2n − 1) − x(4n − 3)|`` at the scene's nodes.
    chosen_n : int
        The coarsest level within ``tol``, or the grid extrapolated from the finest level with
        the observed order (``extrapolated``); 0 when there is none.
    extrapolated : bool
    predicted_error : float
        The estimated error at ``chosen_n``.
    cost : float
        Seconds of stepping to reach ``tol``: measured on the chosen level, or the finest
        level's time scaled by ``(f/4)^(d + 1)`` for an extrapolated grid f times finer than the
        scene's (nodes × steps); inf when ``tol`` is not reached.
    """

    scheme: str
    status: str
    integrator: str = ""
    n: tuple[int, ...] = ()
    dt: tuple[float, ...] = ()
    wall_time: tuple[float, ...] = ()
    errors: tuple[float, ...] = ()
    order: float = math.nan
    differences: tuple[float, ...] = ()
    chosen_n: int = 0
    extrapolated: bool = False
    predicted_error: float = math.nan
    cost: float = math.inf

    @property
    def ok(self) -> bool:
        """The three runs finished and ``tol`` is reached (measured or extrapolated)."""
        return self.status == "ok" and math.isfinite(self.cost)

    def to_dict(self) -> dict[str, Any]:
        """Plain Python (NaN and inf as ``None``)."""
        def clean(v: Any) -> Any:
            return [clean(x) for x in v] if isinstance(v, tuple | list) else _json_value(v)

        return {k: clean(v) for k, v in dataclasses.asdict(self).items()}


def scheme_table(study: Sequence[SchemeCandidate], chosen: SchemeCandidate | None = None) -> str:
    """The scheme study as a text table: per scheme and level n, Δt, estimated error, stepping time."""
    def f(x: float, spec: str = ".3g") -> str:
        return "—" if not math.isfinite(x) else format(x, spec)

    lines = [f"{'scheme':<13} {'n':>6} {'dt':>10} {'est. error':>11} {'order':>6} {'time [s]':>9}  to reach tol"]
    for c in study:
        if c.status != "ok":
            lines.append(f"{c.scheme:<13} {c.status}")
            continue
        for i, (n, dt, t, e) in enumerate(zip(c.n, c.dt, c.wall_time, c.errors, strict=True)):
            reach = ""
            if i == 0:
                reach = ("not reached" if c.chosen_n == 0 else
                         f"n = {c.chosen_n}{' (extrapolated)' if c.extrapolated else ''}, est. "
                         f"{f(c.predicted_error)}, {f(c.cost)} s" + ("  <- recommended" if c is chosen else ""))
            lines.append(f"{c.scheme if i == 0 else '':<13} {n:>6} {dt:>10.4g} {f(e):>11} "
                         f"{f(c.order, '.2f') if i == 0 else '':>6} {f(t):>9}  {reach}")
    return "\n".join(lines)


def _check_schemes(schemes: Any) -> None:
    """``schemes``: a non-empty sequence of registered scheme names (``ValueError`` otherwise)."""
    from .plugins import get_registry

    if isinstance(schemes, str) or not schemes or not all(isinstance(x, str) for x in schemes):
        raise ValueError(f"schemes must be a non-empty sequence of scheme names, got {schemes!r}")
    known = sorted(get_registry().table("schemes"))
    unknown = [x for x in schemes if x not in known]
    if unknown:
        raise ValueError(f"schemes: unknown scheme {unknown[0]!r}; allowed: {', '.join(known)}")


def advise_schemes(problem_or_scene: Any, tol: float, *, pilot_steps: int = PILOT_STEPS,
                   schemes: Sequence[str] = TOL_SCHEMES, compiled: bool = True
                   ) -> tuple[list[SchemeCandidate], SchemeCandidate | None, str]:
    """Which scheme reaches ``tol`` on a dynamic scene at the smaller cost, measured on the scene.

    For each scheme of ``schemes`` on which the scene's medium and integrator run (the scene's
    ``scheme_options`` for its own scheme, the defaults for the others): the scene's integrator
    on the grids of :func:`_refined_scene`, n → 2n − 1 → 4n − 3 (periodic n → 2n → 4n), with
    Δt → Δt/2 → Δt/4, to the study's end time ``T = min(t_end, pilot_steps·Δt_scene)``.  Δt is the
    scene's, or half the scheme's CFL estimate when that is smaller, adjusted so that T is a
    whole number of steps.  Space and time are refined together, so the estimate covers the
    whole discretisation error of the scene's output (the final node positions at the scene's
    nodes): with ``d₀ = max|x(n) − x(2n − 1)|`` and ``d₁ = max|x(2n − 1) − x(4n − 3)|``, the
    observed order ``p = log₂(d₀/d₁)`` and Richardson's estimates of :func:`_richardson`,
    ``e(n) = d₀·2ᵖ/(2ᵖ − 1)`` and ``e(2n − 1) = d₀/(2ᵖ − 1)`` from the two coarse runs.  The
    level that reaches ``tol`` (absolute, length units) is the coarsest whose estimate is
    within it, else the grid f times finer than the scene's extrapolated from the finest
    (``e ∝ h^p``, f ≥ 5) — its cost the finest level's stepping time times ``(f/4)^(d + 1)``.
    The scheme recommended is the one with the smaller cost to reach ``tol``.

    Parameters
    ----------
    problem_or_scene : Scene, path, str or dict
        A dynamic scene with a ``[grid]`` table (``n``, or ``shape``).
    tol : float
        Accepted error, > 0 (length units).
    pilot_steps : int, default 200
    schemes : sequence of str, default :data:`TOL_SCHEMES`
        Registered scheme names, at least one.
    compiled : bool, default True
        ``False`` runs the Python stepping loops (``simulate(compiled=False)``).

    Returns
    -------
    (list of SchemeCandidate, SchemeCandidate or None, str)
        The study, the scheme recommended (the cheaper of those that reach ``tol``; a single
        scheme that applies is recommended when it reaches ``tol``; None when none does) and
        the reason, in words.

    Raises
    ------
    ValueError
        Bad ``tol``, ``pilot_steps`` or ``schemes``; not a dynamic scene; a grid that cannot be
        refined.
    """
    from .simulate import InstabilityError

    tol = _check_tol(tol)
    _check_schemes(schemes)
    if isinstance(pilot_steps, bool) or not isinstance(pilot_steps, int | np.integer) or pilot_steps < 2:
        raise ValueError(f"pilot_steps must be an integer ≥ 2, got {pilot_steps!r}")
    subject = _subject(problem_or_scene)
    if subject.mode != "dynamic" or not subject.run_settings:
        raise ValueError(f"scene {subject.name!r}: the scheme advice needs a dynamic scene, got mode {subject.mode!r}")
    dt0, t_end, run0 = _dynamic_settings(subject, int(pilot_steps))
    base = dict(subject.run_settings)
    integrator = str(run0.integrator.name)
    own = str(run0.scheme.name)
    scenes = [_load(problem_or_scene)]
    for _ in range(2):
        fine = _refined_scene(scenes[-1])
        if fine is None:
            raise ValueError(f"scene {subject.name!r}: the scheme advice needs a [grid] table with n (d = 1) or shape")
        scenes.append(fine)
    problem = subject.problem
    shape0 = tuple(int(n) for n in problem.grid.shape)
    d = len(shape0)
    explicit = bool(getattr(_registered_integrator(integrator), "explicit", True))
    study: list[SchemeCandidate] = []
    for name in dict.fromkeys(schemes):
        c = SchemeCandidate(name, "ok", integrator)
        opts = base.get("scheme_options") if name == own else None
        settings = {k: v for k, v in base.items() if k not in ("scheme", "scheme_options", "dt")}
        settings |= {"scheme": name, "integrator": integrator, "compiled": bool(compiled)}
        if opts:
            settings["scheme_options"] = dict(opts)
        dt_max = _try_resolve(problem, integrator, settings, dt0)
        if dt_max is None:
            c.status = f"not applicable: the {integrator} runs of {problem.medium.name!r} do not take this scheme"
            study.append(c)
            continue
        dt = dt0 if not (explicit and 0.0 < dt_max < math.inf) else min(dt0, 0.5 * dt_max)
        dt = t_end / max(1, math.ceil(t_end / dt * (1.0 - 1e-12)))
        pos, ns, dts, times = [], [], [], []
        try:
            for k, sc in enumerate(scenes):
                s = settings | {"dt": dt / 2 ** k}
                if k == 0:
                    with contextlib.suppress(InstabilityError):  # compiles the loop once: not timed
                        _simulate(sc.problem, s, 2.0 * s["dt"])
                runs = [_timed(_simulate, sc.problem, s, t_end) for _ in range(TOL_REPEATS)]
                final = _final_positions(runs[-1][0])
                if not np.all(np.isfinite(final)):
                    raise InstabilityError(f"non-finite positions on n = {int(np.prod(sc.problem.grid.shape))}")
                pos.append(_shared_nodes(final, k, shape0))
                ns.append(int(np.prod(sc.problem.grid.shape)))
                dts.append(float(s["dt"]))
                times.append(min(_step_time(ds, t) for ds, t in runs))
        except InstabilityError as exc:
            c.status = "unstable: " + " ".join(str(exc).split())[:160]
        except (ValueError, ArithmeticError, NotImplementedError) as exc:
            c.status = "failed: " + (" ".join(str(exc).split())[:160] or type(exc).__name__)
        if c.status != "ok":
            study.append(c)
            continue
        d0, d1 = _max_distance(pos[0], pos[1]), _max_distance(pos[1], pos[2])
        p, errors = _richardson(d0, d1, TOL_ROUNDOFF * float(max(problem.grid.length)))
        c.n, c.dt, c.wall_time, c.errors = tuple(ns), tuple(dts), tuple(times), tuple(errors)
        c.order, c.differences = p, (d0, d1)
        within = [i for i, e in enumerate(errors) if math.isfinite(e) and e <= tol]
        if within:
            i = within[0]
            c.chosen_n, c.predicted_error, c.cost = ns[i], errors[i], times[i]
        elif math.isfinite(errors[2]) and math.isfinite(p) and p > 0:
            ends = [0 if per else 1 for per in problem.grid.periodic]
            f = max(5, math.ceil(4.0 * (errors[2] / tol) ** (1.0 / p) * (1.0 - 1e-12)))
            c.chosen_n = int(np.prod([f * (n - e) + e for n, e in zip(shape0, ends, strict=True)]))
            c.extrapolated, c.predicted_error = True, errors[2] * (4.0 / f) ** p
            c.cost = times[2] * (f / 4.0) ** (d + 1)
        study.append(c)
    chosen, why = choose_scheme(study, tol)
    return study, chosen, why


def choose_scheme(study: Sequence[SchemeCandidate], tol: float) -> tuple[SchemeCandidate | None, str]:
    """(the scheme of ``study`` with the smallest cost to reach ``tol``, why in words); None when
    no scheme reaches it.  Costs are measured or extrapolated (:class:`SchemeCandidate`)."""
    reach = [c for c in study if c.ok]
    if not reach:
        why = (f"no scheme reaches tol = {tol:g} within the study" if any(c.status == "ok" for c in study)
               else "no scheme of " + ", ".join(c.scheme for c in study) + " ran")
        return None, why
    chosen = min(reach, key=lambda c: c.cost)
    integrator = chosen.integrator

    def where(c: SchemeCandidate) -> str:
        how = "extrapolated" if c.extrapolated else "measured"
        order = f"observed order {c.order:.2f}" if math.isfinite(c.order) else "the finer levels agree to round-off"
        return (f"{c.scheme} reaches it at n = {c.chosen_n} (estimated error {c.predicted_error:.3g}, {order}) in "
                f"{c.cost:.3g} s of stepping ({how})")

    others = [c for c in study if c is not chosen]
    why = f"the cheaper to reach tol = {tol:g} with {integrator}: " + where(chosen)
    for c in others:
        if c.ok:
            why += f"; {where(c)}, {c.cost / chosen.cost:.2g}× the cost"
        elif c.status == "ok":
            why += f"; {c.scheme} does not reach it (observed order {c.order:.3g})"
        else:
            why += f"; {c.scheme}: {c.status}"
    if len(reach) == 1 and len(study) > 1:
        why += "; the only scheme that reaches it"
    return chosen, why


def _refined_scene(obj: Any) -> Any:
    """The scene with its grid refined along every axis so that its nodes are every other node
    (``n → 2n − 1``, periodic ``n → 2n``; the ``n`` of a d = 1 ``[grid]`` table or the ``shape``
    of any), or None when that cannot be built."""
    from .scene import Scene, load_scene

    def finer(n: int, periodic: bool) -> int:
        return 2 * n if periodic else 2 * n - 1

    try:
        obj = _load(obj)
        if not isinstance(obj, Scene) or not isinstance(obj.source.get("grid"), Mapping):
            return None
        grid = dict(obj.source["grid"])
        periodic = obj.problem.grid.periodic
        if "n" in grid and len(periodic) == 1:
            grid["n"] = finer(int(grid["n"]), periodic[0])
        elif "shape" in grid:
            grid["shape"] = [finer(int(n), per) for n, per in zip(obj.problem.grid.shape, periodic, strict=True)]
        else:
            return None
        source = dict(obj.source) | {"grid": grid}
        for table in ("static", "continuation"):  # a measured node is the same material point
            measure = source.get(table, {}).get("measure") if isinstance(source.get(table), Mapping) else None
            node = measure.get("node") if isinstance(measure, Mapping) else None
            index = [node] if isinstance(node, int) and not isinstance(node, bool) else node
            if isinstance(index, list) and all(isinstance(i, int) and not isinstance(i, bool) for i in index):
                fine = [2 * i if i >= 0 or per else 2 * i + 1 for i, per in zip(index, periodic, strict=False)]
                source[table] = dict(source[table]) | {"measure": dict(measure) | {
                    "node": fine[0] if isinstance(node, int) else fine}}  # names ("end") stay
        return load_scene(source)
    except (ValueError, TypeError, OSError):
        return None


# ---------------------------------------------------------------------------- a resolution for a tolerance
#: the largest grid (nodes) :func:`advise_resolution` recommends
TOL_MAX_N = 10001
#: below this observed order the Richardson estimates of :func:`advise_resolution` are not trusted
TOL_MIN_ORDER = 0.5
#: differences of two levels below this multiple of the output's scale are round-off
TOL_ROUNDOFF = 1e-12


def _grid_label(shape: tuple[int, ...], n: int) -> str:
    """``n`` for a d = 1 grid, ``n₁×n₂…`` otherwise."""
    return "×".join(str(k) for k in shape) if len(shape) > 1 else str(n)


def _shared_nodes(pos: np.ndarray, refinements: int, shape: tuple[int, ...]) -> np.ndarray:
    """The nodes ``[prod(shape), k]`` of ``pos`` ``[*fine_shape, k]`` that a grid refined
    ``refinements`` times (:func:`_refined_scene`: ``n → 2n − 1``, periodic ``n → 2n``, along
    every axis) shares with the grid of ``shape`` it was refined from: every
    ``2^refinements``-th node along each axis."""
    step = slice(None, None, 2 ** refinements)
    shared = pos[(step,) * len(shape)][tuple(slice(0, n) for n in shape)]
    return shared.reshape(-1, pos.shape[-1])


def _max_distance(a: np.ndarray, b: np.ndarray) -> float:
    """``max_i |a_i − b_i|`` over the nodes of two position arrays ``[nodes, k]``."""
    return float(np.max(np.linalg.norm(np.asarray(a) - np.asarray(b), axis=-1)))


def _richardson(d0: float, d1: float, floor: float) -> tuple[float, list[float]]:
    """Observed order and Richardson error estimates of three levels h, h/2, h/4 from the
    differences ``d0 = |u_h − u_{h/2}|`` and ``d1 = |u_{h/2} − u_{h/4}|``.

    Returns ``(p, [e(h), e(h/2), e(h/4)])`` with ``p = log₂(d0/d1)`` and, for an error ``C hᵖ``,
    ``e(h) = d0·2ᵖ/(2ᵖ − 1)``, ``e(h/2) = d0/(2ᵖ − 1)``, ``e(h/4) = d1/(2ᵖ − 1)``.  When ``d1 ≤ floor``
    (round-off) the order is NaN and the estimates are the differences themselves
    ``[d0, d1, d1]``; when ``p`` < :data:`TOL_MIN_ORDER` (or is undefined) the estimates are NaN.
    """
    if d1 <= floor:
        return math.nan, [d0, d1, d1]
    if not d0 > 0.0 or not math.isfinite(d0 / d1):
        return math.nan, [math.nan] * 3
    p = math.log2(d0 / d1)
    if p < TOL_MIN_ORDER:
        return p, [math.nan] * 3
    f = 2.0 ** p - 1.0
    return p, [d0 * 2.0 ** p / f, d0 / f, d1 / f]


@dataclasses.dataclass
class ResolutionCandidate:
    """One grid of the refinement study of :func:`advise_resolution`.

    Attributes
    ----------
    n : int
        Nodes of the grid.
    scheme : str
    error : float
        Estimated discretisation error of the equilibrium node positions at the nodes shared
        with the scene's grid, ``max_i |x_i(n) − x_i(∞)|`` (length units; Richardson, see
        :func:`advise_resolution`; NaN when the levels are not in the asymptotic range).
    relative_error : float
        ``error / scale`` (:attr:`ResolutionAdvice.scale`): what ``tol`` bounds.
    order : float
        The observed order the estimate uses (from the three levels, the same on every level;
        NaN when the refined grids agree to round-off).
    difference : float
        ``max_i |x_i(n) − x_i(n')|`` at the shared nodes, n' the next level (NaN on the finest).
    wall_time : float
        Seconds of the solve, the fastest of :data:`STATIC_REPEATS` after a warm-up solve (of a
        continuation: the whole path, once); it depends on the machine and its load (reported,
        not used by the choice).
    newton_iterations : int
    shape : tuple of int
        The grid's nodes along each axis (n is their product).
    value : float
        The scene's measured quantity on this grid (its ``[static] measure``, or
        ``[continuation] measure`` at the path's final point) when the advice is on it
        (:attr:`ResolutionAdvice.quantity` ``"measure"``); NaN otherwise.
    """

    n: int
    scheme: str
    error: float = math.nan
    relative_error: float = math.nan
    order: float = math.nan
    difference: float = math.nan
    wall_time: float = math.nan
    newton_iterations: int = 0
    shape: tuple[int, ...] = ()
    value: float = math.nan

    @property
    def ok(self) -> bool:
        """The level has an error estimate."""
        return math.isfinite(self.relative_error)


@dataclasses.dataclass
class ResolutionAdvice:
    """What :func:`advise_resolution` (``advise(static_scene, tol=...)``) returns.

    Attributes
    ----------
    scene, medium, scheme : str
    mode : str
        ``"static"`` or ``"continuation"``.
    output : str
        What the error measures (the equilibrium node positions at the scene's nodes; of a
        continuation, at the path's final point).
    tol : float
        Requested accuracy, relative to ``scale``.
    scale : float
        The output's scale: the largest displacement of the shared nodes from the initial state
        on the finest level (the grid length when nothing moves).
    observed_order : float
        ``log₂(d₀/d₁)``, ``d₀ = max|x(n) − x(2n−1)|``, ``d₁ = max|x(2n−1) − x(4n−3)|`` at the
        shared nodes (NaN when ``d₁`` is round-off).
    levels : list of ResolutionCandidate
        The three grids n, 2n − 1, 4n − 3 (periodic: n, 2n, 4n).
    recommended : ResolutionCandidate or None
        The coarsest level whose estimated relative error is at most ``tol`` (None: none is).
    recommended_n : int
        Its number of nodes; or, when no level is within ``tol``, the grid extrapolated from the
        observed order (``extrapolated``), at most ``max_n`` nodes along any axis (``capped``); 0
        when there is no recommendation.
    extrapolated : bool
        ``recommended_n`` is an extrapolation (not solved here).
    capped : bool
        The extrapolated n exceeds ``max_n``: ``recommended_n`` is the largest grid allowed and
        does not reach ``tol`` by the estimate.
    predicted_error : float
        Estimated relative error at ``recommended_n``.
    max_n : int
    note : str
        How the recommendation was reached.
    wall_time : float
        Seconds spent in :func:`advise_resolution`.
    recommended_shape : tuple of int
        The recommended grid's nodes along each axis.
    quantity : str
        ``"measure"`` (the error is that of the scene's measured quantity, ``output`` names it)
        or ``"positions"`` (the node positions).
    extrapolated_value : float
        With ``"measure"``: Richardson's extrapolation of the measured quantity to h → 0,
        ``m(4n−3) + (m(4n−3) − m(2n−1))/(2^p − 1)`` (NaN without an order).
    """

    scene: str
    medium: str
    scheme: str
    mode: str
    output: str
    tol: float
    scale: float
    observed_order: float
    levels: list[ResolutionCandidate]
    recommended: ResolutionCandidate | None
    recommended_n: int
    extrapolated: bool
    capped: bool
    predicted_error: float
    max_n: int
    note: str = ""
    wall_time: float = 0.0
    recommended_shape: tuple[int, ...] = ()
    quantity: str = "positions"
    extrapolated_value: float = math.nan

    def to_dict(self) -> dict[str, Any]:
        """The report as plain Python (JSON-serialisable, NaN and inf as ``None``)."""
        clean, row = _json_value, _json_row
        out = {k: clean(getattr(self, k)) for k in ("scene", "medium", "scheme", "mode", "output", "tol", "scale",
                                                     "observed_order", "recommended_n", "extrapolated", "capped",
                                                     "predicted_error", "max_n", "note", "wall_time",
                                                     "recommended_shape", "quantity", "extrapolated_value")}
        out["levels"] = [row(c) for c in self.levels]
        out["recommended"] = row(self.recommended)
        return out

    def table(self) -> str:
        """The levels as a text table: n, estimated error (absolute and relative), observed
        order, difference to the next level, solve time."""
        def f(x: float, spec: str = ".3g") -> str:
            return "—" if not math.isfinite(x) else format(x, spec)

        on_measure = self.quantity == "measure"
        lines = [f"{'n':>9} " + (f"{'value':>13} " if on_measure else "")
                 + f"{'est. error':>11} {'relative':>10} {'order':>6} {'diff. next':>11} {'time [s]':>9}"]
        for c in self.levels:
            mark = "  <- recommended" if c is self.recommended else ""
            lines.append(f"{_grid_label(c.shape, c.n):>9} " + (f"{f(c.value, '.7g'):>13} " if on_measure else "")
                         + f"{f(c.error):>11} {f(c.relative_error):>10} "
                         f"{f(c.order, '.2f'):>6} {f(c.difference):>11} {f(c.wall_time):>9}{mark}")
        return "\n".join(lines)

    def __str__(self) -> str:
        ns = ", ".join(_grid_label(c.shape, c.n) for c in self.levels)
        p = "—" if not math.isfinite(self.observed_order) else format(self.observed_order, ".3f")
        lines = [f"scene {self.scene!r} ({self.medium}, {self.scheme}, {self.mode}): resolution for tol = {self.tol:g}",
                 f"error: {self.output}, relative to the scale {self.scale:.4g}",
                 f"Richardson from n = {ns}; observed order {p}"
                 + (f"; extrapolated value {self.extrapolated_value:.7g}"
                    if self.quantity == "measure" and math.isfinite(self.extrapolated_value) else ""),
                 "", self.table(), ""]
        if self.recommended_n == 0:
            lines.append(f"recommended: none — {self.note}")
        elif self.extrapolated:
            what = "capped at max_n" if self.capped else "extrapolated"
            lines.append(f"recommended: n = {_grid_label(self.recommended_shape, self.recommended_n)} ({what}; "
                         "predicted relative error "
                         f"{self.predicted_error:.3g}) — {self.note}")
        else:
            lines.append(f"recommended: n = {_grid_label(self.recommended_shape, self.recommended_n)} (estimated "
                         f"relative error {self.predicted_error:.3g}"
                         f" ≤ {self.tol:g}; solve {self.recommended.wall_time:.3g} s) — {self.note}")
        return "\n".join(lines)

    def plot(self, path: str | os.PathLike) -> pathlib.Path:
        """Convergence chart: the estimated relative error against n (log–log), the tol line and
        the recommendation; written with matplotlib (Agg).  Returns the path."""
        from .study import _figure, finish_chart

        plt, fig, ax = _figure()
        pts = [(c.n, c.relative_error) for c in self.levels if c.ok and c.relative_error > 0]
        if pts:
            ax.loglog(*zip(*pts, strict=True), "o-", label=f"{self.scheme} (estimated)")
        ax.axhline(self.tol, color="k", ls="--", lw=0.8, label=f"tol = {self.tol:g}")
        if self.recommended_n and math.isfinite(self.predicted_error) and self.predicted_error > 0:
            ax.loglog([self.recommended_n], [self.predicted_error], "o", ms=14, mfc="none", color="r",
                      label="recommended" + (" (extrapolated)" if self.extrapolated else ""))
        ax.set_xlabel("nodes n")
        ax.set_ylabel("estimated relative error of the " + ("measure" if self.quantity == "measure" else "positions"))
        return finish_chart(fig, ax, path, f"resolution: {self.scene}")


#: what :func:`advise_resolution` measures the error on
TOL_QUANTITIES = ("auto", "measure", "positions")


def advise_resolution(scene: Any, tol: float, *, max_n: int = TOL_MAX_N, quantity: str = "auto"
                      ) -> ResolutionAdvice:
    """The coarsest grid of a static scene whose equilibrium is within ``tol``, from three levels.

    The scene is solved (:func:`cartan.statics.solve_static` with its ``[static]`` settings; the
    lattice scheme, the only one it supports; a continuation scene: its path with its
    ``[continuation]`` settings, :func:`cartan.continuation`, and the output is taken at the
    path's final point, which must be at the same load factor on every level — the path ends
    on ``lambda_max`` exactly) on its grid of n nodes and on the grids refined
    twice by :func:`_refined_scene` (``n → 2n − 1 → 4n − 3``; periodic ``n → 2n → 4n``; along every
    axis of a d ≥ 2 grid), whose
    every second (fourth) node is a node of the scene's grid.  The output is the equilibrium
    node positions ``x_i`` at the scene's nodes; with ``d₀ = max_i |x_i(n) − x_i(2n−1)|`` and
    ``d₁ = max_i |x_i(2n−1) − x_i(4n−3)|``, the observed order is ``p = log₂(d₀/d₁)`` and, for an
    error ``C h^p``, Richardson's estimates are

        e(n) = d₀·2^p/(2^p − 1),   e(2n−1) = d₀/(2^p − 1),   e(4n−3) = d₁/(2^p − 1),

    compared with ``tol·scale``, the scale the largest displacement of those nodes (the grid
    length when nothing moves).

    When the scene declares what it measures (``[static] measure = {node, component}``, or
    ``[continuation] measure``: :class:`cartan.scene.Measure`, one displacement component — or
    its length — at one node, the quantity whose accuracy the user cares about, e.g. a tip
    deflection) the output is that quantity instead (``quantity="auto"`` or ``"measure"``):
    ``m(n)``, the measured node the same material point on every level; ``d₀ = |m(n) − m(2n−1)|``,
    ``d₁ = |m(2n−1) − m(4n−3)|`` in the same formulas, the scale ``|m(4n−3)|`` (the largest
    displacement when the measured value is round-off), and Richardson's value
    ``m(4n−3) + (m(4n−3) − m(2n−1))/(2^p − 1)`` is reported.  When the two differences have
    opposite signs (the quantity does not converge monotonically on these grids) there is no
    order and nothing is recommended.  The recommendation is the coarsest level within ``tol``
    (:func:`choose_method` with the number of nodes as the cost).  When none is, the grid is
    extrapolated from the finest level, ``e ∝ h^p``: the scene's intervals along every axis
    multiplied by ``f = ⌈4·(e(4n−3)/tol)^{1/p}⌉`` (at least 5, beyond the finest level; an integer,
    so that the scene's nodes stay nodes), flagged ``extrapolated`` (not solved) and capped at
    ``max_n`` nodes along any axis (``capped``).  When ``d₁`` is round-off (:data:`TOL_ROUNDOFF`
    of the scale) the differences themselves are the estimates; when ``p`` <
    :data:`TOL_MIN_ORDER` the levels are not in the asymptotic range and nothing is recommended.

    Parameters
    ----------
    scene : Scene, path, str or dict
        A static or continuation scene with a grid of ``n`` nodes (d = 1) or of any ``shape`` (its
        ``[grid]`` table), on a medium with node positions (an affine group).
    tol : float
        Accepted relative error, > 0.
    max_n : int, default :data:`TOL_MAX_N`
        The most nodes along any axis an extrapolation recommends, ≥ 3.
    quantity : {"auto", "measure", "positions"}, default "auto"
        What the error is measured on: the scene's measured quantity (``"measure"``; ``"auto"``:
        when the scene declares one) or the node positions at the scene's nodes
        (``"positions"``; ``"auto"`` without a measure).

    Returns
    -------
    ResolutionAdvice

    Raises
    ------
    ValueError
        Bad ``tol``, ``max_n`` or ``quantity`` (``"measure"`` of a scene that declares none); not a
        static or continuation scene (a
        :class:`~cartan.Problem` has no grid table to refine); a grid that cannot be refined;
        a medium without node positions; paths that end at different load factors.
    cartan.statics.ConvergenceError
        A solve or a path failed.
    """
    start = time.perf_counter()
    tol = _check_tol(tol)
    if isinstance(max_n, bool) or not isinstance(max_n, int | np.integer) or max_n < 3:
        raise ValueError(f"max_n must be an integer ≥ 3, got {max_n!r}")
    if isinstance(scene, Problem):
        raise ValueError("the advice for a tolerance needs a scene (file, registered name or dict), not a Problem: it "
                         "refines the grid of a static or continuation scene and sweeps the time step of a dynamic one")
    if quantity not in TOL_QUANTITIES:
        raise ValueError(f"quantity must be one of {', '.join(repr(q) for q in TOL_QUANTITIES)}, got {quantity!r}")
    subject = _subject(scene)
    if subject.mode not in ("static", "continuation"):
        raise ValueError(f"scene {subject.name!r}: the resolution advice needs a static or continuation scene, got "
                         f"mode {subject.mode!r}")
    if quantity == "measure" and subject.measure is None:
        raise ValueError(f"quantity='measure': scene {subject.name!r} declares no measure (its [{subject.mode}] "
                         "measure = { node, component })")
    on_measure = quantity != "positions" and subject.measure is not None
    scenes = [_load(scene)]
    for _ in range(2):
        fine = _refined_scene(scenes[-1])
        if fine is None:
            raise ValueError(f"scene {subject.name!r}: the resolution advice needs a [grid] table with n (d = 1) or "
                             "shape")
        scenes.append(fine)
    problem = subject.problem
    shape0 = tuple(int(n) for n in problem.grid.shape)
    scheme = str(subject.solver_options.get("scheme", "lattice"))
    levels, pos, lam, values = [], [], [], []
    for k, sc in enumerate(scenes):  # each level with its own subject: a measure reads its own grid
        level = subject if k == 0 else _subject(sc)
        ds, seconds = _run(level, sc.problem, None, warm=k == 0)
        if "position" not in ds:
            raise ValueError(f"scene {subject.name!r}: medium {problem.medium.name!r} has no node positions to "
                             "measure the resolution on")
        final = _final_positions(ds)
        pos.append(_shared_nodes(final, k, shape0))
        if on_measure:
            values.append(float(level.measure(final.reshape(-1, final.shape[-1]), _initial_positions(sc.problem))))
        if subject.mode == "continuation":
            lam.append(float(ds["load_factor"].values[-1]))
        shape = tuple(int(n) for n in sc.problem.grid.shape)
        levels.append(ResolutionCandidate(int(np.prod(shape)), scheme, wall_time=seconds, shape=shape,
                                          newton_iterations=int(ds.attrs.get("newton_iterations", 0))))
    if lam and not math.isclose(min(lam), max(lam), rel_tol=1e-9, abs_tol=1e-12):
        raise ValueError(f"scene {subject.name!r}: the paths on n = {levels[0].n}, {levels[1].n}, {levels[2].n} end "
                         f"at different load factors ({', '.join(f'{v:.6g}' for v in lam)}): no common final point")
    length = float(max(problem.grid.length))
    scale = _max_distance(pos[2], _initial_positions(problem))
    scale_of = "the largest displacement" if scale > TOL_ROUNDOFF * length else "the grid length"
    scale = scale if scale > TOL_ROUNDOFF * length else length
    oscillates = False
    if on_measure:
        d0, d1 = abs(values[0] - values[1]), abs(values[1] - values[2])
        if abs(values[2]) > TOL_ROUNDOFF * length:
            scale, scale_of = abs(values[2]), "the scale |m| on the finest grid"
        else:
            scale_of = f"{scale_of}: the measured value is round-off"
        oscillates = (values[0] - values[1]) * (values[1] - values[2]) < 0.0 and d1 > TOL_ROUNDOFF * scale
    else:
        d0, d1 = _max_distance(pos[0], pos[1]), _max_distance(pos[1], pos[2])
    levels[0].difference, levels[1].difference = d0, d1
    p, errors = _richardson(d0, d1, TOL_ROUNDOFF * scale)
    if oscillates:  # |m − m(∞)| is not C·h^p on these grids
        p, errors = math.nan, [math.nan] * 3
    note = "" if math.isfinite(p) or not math.isfinite(errors[0]) else \
        "the refined grids agree to round-off: the differences to the next level are the estimates"
    for c, e, v in zip(levels, errors, values or [math.nan] * 3, strict=True):
        c.error, c.relative_error, c.order, c.value = e, e / scale, p, v
    extrapolated_value = (values[2] + (values[2] - values[1]) / (2.0 ** p - 1.0)
                          if on_measure and math.isfinite(p) and p > 0 else math.nan)
    recommended, _ = choose_method(levels, tol, cost=lambda c: c.n, error=lambda c: c.relative_error)
    rec_n, rec_shape, extrapolated, capped, predicted = 0, (), False, False, math.nan
    if recommended is not None:
        rec_n, rec_shape, predicted = recommended.n, recommended.shape, recommended.relative_error
        note = note or f"the coarsest of the three levels within tol (Richardson, observed order {p:.3f})"
    elif levels[-1].ok and math.isfinite(p):
        # every axis refined by the same integer factor f of the scene's intervals (the finest level: 4)
        ends = [0 if per else 1 for per in problem.grid.periodic]
        m0 = [n - e for n, e in zip(shape0, ends, strict=True)]  # intervals of the scene's grid
        e2 = levels[-1].relative_error
        f = max(5, math.ceil(4.0 * (e2 / tol) ** (1.0 / p) * (1.0 - 1e-12)))
        f_cap = max(4, min((max_n - e) // m for m, e in zip(m0, ends, strict=True)))
        extrapolated, capped = True, f > f_cap
        f = min(f, f_cap)
        rec_shape = tuple(f * m + e for m, e in zip(m0, ends, strict=True))
        rec_n, predicted = int(np.prod(rec_shape)), e2 * (4.0 / f) ** p
        note = (f"extrapolated from the finest level with the observed order {p:.3f} (e ∝ h^p), not solved; "
                f"the scene's intervals refined {f}-fold so that its nodes stay nodes")
        if capped:
            note = (f"tol is not reached within max_n = {max_n} nodes along an axis: the largest grid allowed, "
                    f"n = {_grid_label(rec_shape, rec_n)}, is predicted at {predicted:.3g}; " + note)
    elif oscillates:
        note = ("the measured quantity does not converge monotonically on these grids (its differences to the next "
                "level change sign): no observed order; refine the scene's grid and ask again")
    elif not levels[-1].ok:
        note = (f"observed order {p:.3g} (below {TOL_MIN_ORDER} or undefined): the three levels are not in the "
                "asymptotic range; refine the scene's grid and ask again")
    else:
        note = "the finest level is not within tol and its difference is round-off: nothing to extrapolate"
    where = f" at the path's final point λ = {lam[0]:.6g}" if lam else ""
    if on_measure:
        output = f"|m − m(∞)| of the scene's measure m, the {subject.measure.describe()}{where} ({scale_of})"
    else:
        output = (f"max |x − x(∞)| of the equilibrium node positions{where} at the scene's "
                  f"{_grid_label(shape0, int(np.prod(shape0)))} nodes ({scale_of})")
    return ResolutionAdvice(subject.name, problem.medium.name, scheme, subject.mode, output, tol, scale, p, levels,
                            recommended, rec_n, extrapolated, capped, predicted, int(max_n), note,
                            time.perf_counter() - start, tuple(rec_shape),
                            "measure" if on_measure else "positions", extrapolated_value)


def _registered_integrator(name: str) -> Any:
    from .plugins import get_registry

    return get_registry().get("integrators", name)
