"""The verification case: a runnable problem with an exact reference and an error norm.

A case answers three questions for the convergence and stability studies:

``case.problem(level, scheme)``
    The :class:`~cartan.Problem` at refinement ``level`` (the grid doubles its node count with
    the level for space refinement; Δt halves with the level for time refinement) and the run
    settings.  For a dynamic case they are ``dict(dt=, t_end=, save_every=)`` for
    :func:`cartan.simulate`; a case may add ``integrator_options`` (e.g. when its reference
    fixes the overdamped order) and ``scheme_options`` (e.g. ``track_frames``), which
    :func:`cartan.simulate` accepts as they are.  For a static case they are the keyword
    arguments of its solver (:func:`cartan.statics.solve_static` or
    :func:`cartan.continuation.continuation`).
``case.run(problem, settings, integrator, scheme, compiled)``
    The Dataset of one run.  The default calls :func:`cartan.simulate`; a case that is not a
    dynamic run overrides it — :class:`StaticCase` solves for equilibria, and its
    "integrator" is ``"newton"``.  The studies (:func:`cartan.study.converge`,
    :func:`cartan.study.traces`) and :func:`run_case` always run a case through this method.
    The Dataset's ``cartan_config`` attribute (JSON) records the run settings under ``"run"``
    and the cost under ``"counters"`` (``nstep``: time steps or Newton iterations,
    ``nforce`` where counted, ``wall_time``).
``case.error(ds, problem)``
    The error of a run's Dataset against the exact reference, in the case's stated norm.

so that a study runs::

    problem, settings = case.problem(level, scheme)
    ds = case.run(problem, settings, integrator, scheme)
    e = case.error(ds, problem)

Attributes (class attributes of each case)
------------------------------------------
name, medium, description, reference, quantity, norm
    Registry name (kebab-case), registered medium, one-line description, the exact reference
    formula or number with its source, what is compared and how it is measured.
space_order : float or None
    Expected order of the error in dx (``None``: the case is not refined in space).
time_order_of : callable, dict or None
    Integrator name → expected order in Δt (``None``: the case is not refined in time).
    :meth:`Case.expected_time_order` reads either form.
parameter_order : float or None
    Expected order in a physical parameter doubled with the level (a limit such as r → ∞);
    ``None`` for ordinary cases.  :meth:`Case.expected_order` returns whichever order applies.
refine : {"space", "time", "both"} or None
    What the studies refine by default (``None``: "both" for a parameter limit, else "space"
    when the case has a space order, else "time").  "both" runs each level exactly as
    :meth:`Case.problem` gives it — for cases whose levels change Δt together with what is
    saved (an energy balance integrated over every step) or a physical parameter.
static : bool
    True for cases solved for equilibria (:class:`StaticCase`): refined in space only.
roundoff : bool
    True when the reference is met to round-off at every level (an exact property such as a
    symmetry reduction or a relative equilibrium): no order is expected, whatever the
    integrator's order.
tolerance, tolerance_reason
    Pass threshold on the error at the finest default level with the first default
    integrator, and why.  ``tolerances`` refines it per integrator (key ``"lie-verlet"``) or
    per integrator and scheme (key ``"lie-verlet/collocation"``);
    :meth:`Case.tolerance_for` reads them.
default_integrators, default_schemes, levels, quick_levels
    What the studies run by default; ``quick_levels`` are cheap enough for the test suite
    (their finest level meets the tolerance too).
compare_methods : bool
    True for the case on which ``cartan verify`` compares every integrator × scheme (work
    precision, error against dx, integrability and energy against time).
kind : {"convergence", "stability"}
    ``"convergence"`` (the default): the studies refine the case and compare with its reference.
    ``"stability"``: the case is a stability study, not refined against a reference;
    ``cartan verify`` calls its :meth:`Case.report_section` instead of a convergence study and
    ``cartan converge`` refuses it.
"""

from __future__ import annotations

import abc
import json
import math
from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

    from cartan.problem import Problem

__all__ = ["Case", "StaticCase", "observed_orders", "run_case", "run_config"]

#: The "integrator" of a static case: Newton's method on the group.
NEWTON = "newton"


class Case(abc.ABC):
    """Base class of verification cases (see the module docstring for the contract)."""

    name: str = ""
    medium: str = ""
    description: str = ""
    reference: str = ""
    quantity: str = ""
    norm: str = ""
    space_order: float | None = None
    time_order_of: Callable[[str], float] | Mapping[str, float] | None = None
    parameter_order: float | None = None
    refine: str | None = None
    static: bool = False
    roundoff: bool = False
    tolerance: float = math.inf
    tolerance_reason: str = ""
    tolerances: Mapping[str, float] = {}
    default_integrators: tuple[str, ...] = ("lie-verlet",)
    default_schemes: tuple[str, ...] = ("lattice",)
    levels: tuple[int, ...] = (0, 1, 2, 3)
    quick_levels: tuple[int, ...] | None = None
    compare_methods: bool = False
    kind: str = "convergence"

    @abc.abstractmethod
    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        """The problem at refinement ``level`` and its run settings ``dict(dt=, t_end=, save_every=)``."""

    @abc.abstractmethod
    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        """Error of a run's Dataset against the exact reference."""

    def run(self, problem: Problem, settings: Mapping[str, Any], integrator: str, scheme: str = "lattice",
            compiled: bool = True) -> xr.Dataset:
        """One run of ``problem`` with the ``settings`` of :meth:`problem`: :func:`cartan.simulate`.

        Parameters
        ----------
        problem : Problem
            From :meth:`problem`.
        settings : mapping
            ``dt``, ``t_end``, ``save_every`` and optionally ``integrator_options`` and
            ``scheme_options`` (the keywords of :func:`cartan.simulate`).
        integrator, scheme : str
            Registered names.
        compiled : bool
            Use the compiled step loops where they exist.

        Returns
        -------
        xarray.Dataset
            The run (frames along ``time``).
        """
        import cartan

        return cartan.simulate(problem, integrator=integrator, scheme=scheme, compiled=compiled, progress=False,
                               **dict(settings))

    def report_section(self, out_dir: Any, quick: bool, client: Any = None) -> tuple[str, list, int, int]:
        """The report section of a ``kind = "stability"`` case.

        Parameters
        ----------
        out_dir : pathlib.Path
            The report directory, where the section writes its charts.
        quick : bool
            ``cartan verify --quick`` (the cheap default levels).
        client
            The dask scheduler option of ``cartan verify`` (None: in this process).

        Returns
        -------
        (markdown, datasets, checks, failed)
            The Markdown section (charts linked by file name), Datasets to merge into
            ``verification.nc`` (``cartan verify`` prefixes their variables with the case name),
            the number of pass/fail checks and the number of failed ones.
        """
        raise NotImplementedError(f"case {self.name!r} has no report section (kind = {self.kind!r})")

    # ------------------------------------------------------------------ derived
    def expected_time_order(self, integrator: str) -> float | None:
        """Expected order in Δt for ``integrator`` (None: not refined in time or unknown)."""
        of = self.time_order_of
        if of is None:
            return None
        if isinstance(of, Mapping):
            value = of.get(integrator)
            return None if value is None else float(value)
        return float(of(integrator))

    def expected_order(self, integrator: str | None = None) -> float | None:
        """The order the refinement over :attr:`levels` should show for ``integrator``: the
        parameter order of a limit case, else the time order, else the space order (None for a
        :attr:`roundoff` case)."""
        if self.roundoff:
            return None
        if self.parameter_order is not None:
            return float(self.parameter_order)
        integrator = integrator or self.default_integrators[0]
        if self.time_order_of is not None:
            return self.expected_time_order(integrator)
        return None if self.space_order is None else float(self.space_order)

    def tolerance_for(self, integrator: str | None = None, scheme: str | None = None) -> float:
        """Pass threshold for ``integrator`` (on ``scheme``) at the finest default level: the
        ``tolerances`` entry ``"integrator/scheme"``, else ``"integrator"``, else :attr:`tolerance`."""
        if integrator is not None and scheme is not None and f"{integrator}/{scheme}" in self.tolerances:
            return float(self.tolerances[f"{integrator}/{scheme}"])
        if integrator is not None and integrator in self.tolerances:
            return float(self.tolerances[integrator])
        return float(self.tolerance)

    def quick(self) -> tuple[int, ...]:
        """The levels the test suite runs (default: the two finest :attr:`levels`)."""
        return tuple(self.quick_levels) if self.quick_levels is not None else tuple(self.levels[-2:])

    def __setattr__(self, key: str, value: Any) -> None:
        raise AttributeError(f"case {self.name!r} is immutable")

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r} ({self.medium})>"


class StaticCase(Case):
    """A case solved for equilibria rather than run in time.

    Its "integrator" is ``"newton"`` (:data:`NEWTON`) and its scheme ``"lattice"`` (the only
    scheme of the static solvers); it is refined in space.  Subclasses implement
    :meth:`problem` — returning the solver's keyword arguments as the settings — and
    :meth:`error`, and override :meth:`solve` when the solver is not
    :func:`~cartan.statics.solve_static`.  :meth:`run` calls :meth:`solve` and records the settings and the cost
    (Newton iterations as ``nstep``, the solver's wall time) in ``cartan_config`` like a
    dynamic run.
    """

    static = True
    refine = "space"
    time_order_of = None
    #: the function whose keyword arguments the settings are, when :meth:`solve` calls another
    #: solver than :func:`~cartan.statics.solve_static` or :func:`~cartan.continuation.continuation`
    #: (a flow of equilibria, say); None for those two
    solver: Any = None
    default_integrators = (NEWTON,)
    default_schemes = ("lattice",)

    def solve(self, problem: Problem, settings: Mapping[str, Any]) -> xr.Dataset:
        """The solver's Dataset for ``problem`` with ``settings``: :func:`~cartan.statics.solve_static`
        (this default) or, overridden, :func:`~cartan.continuation.continuation` or another solver."""
        from cartan.statics import solve_static

        return solve_static(problem, **dict(settings))

    def run(self, problem: Problem, settings: Mapping[str, Any], integrator: str = NEWTON, scheme: str = "lattice",
            compiled: bool = True) -> xr.Dataset:
        """Solve for the equilibria of ``problem`` (``integrator`` must be ``"newton"``,
        ``scheme`` ``"lattice"``; ``compiled`` is unused)."""
        if integrator != NEWTON:
            raise ValueError(f"integrator must be {NEWTON!r} for the static case {self.name!r}, got {integrator!r}")
        if scheme != "lattice":
            raise ValueError(f"scheme must be 'lattice' for the static case {self.name!r}, got {scheme!r}")
        ds = self.solve(problem, settings)
        config = json.loads(ds.attrs["cartan_config"]) if "cartan_config" in ds.attrs else {}
        iterations = int(ds.attrs.get("newton_iterations", 0))
        wall = float(ds.attrs.get("newton_wall_time", ds.attrs.get("wall_time", math.nan)))
        config.setdefault("problem", problem.to_dict())
        config["run"] = {**config.get("run", {}), "integrator": NEWTON, "scheme": scheme,
                         "settings": {k: v for k, v in settings.items() if not callable(v)}}
        config["counters"] = {**config.get("counters", {}), "nstep": iterations, "wall_time": wall}
        ds.attrs["cartan_config"] = json.dumps(config, default=str)
        return ds


# ---------------------------------------------------------------------------- helpers
def run_config(ds: xr.Dataset) -> dict[str, Any]:
    """The run settings recorded in a Dataset (integrator, scheme, dt, t_end, save_every, …)."""
    return json.loads(ds.attrs["cartan_config"])["run"]


def observed_orders(errors: Iterable[float], ratio: float = 2.0) -> np.ndarray:
    """p = log_ratio(e_h / e_{h/ratio}) between successive levels."""
    e = np.asarray(list(errors), dtype=float)
    return np.log(e[:-1] / e[1:]) / math.log(ratio)


def run_case(case: Case, level: int, integrator: str | None = None, scheme: str = "lattice",
             **overrides: Any) -> tuple[float, xr.Dataset]:
    """Run ``case`` at ``level`` (through :meth:`Case.run`, ``overrides`` replacing run settings)
    and return ``(error, dataset)``."""
    problem, settings = case.problem(level, scheme)
    settings = {**settings, **overrides}
    ds = case.run(problem, settings, integrator or case.default_integrators[0], scheme)
    return float(case.error(ds, problem)), ds


def run_levels(case: Case, levels: Iterable[int] | None = None, integrator: str | None = None,
               scheme: str = "lattice") -> list[tuple[float, xr.Dataset, Any, dict[str, Any]]]:
    """:func:`run_case` at every level of ``levels`` (default: all of ``case.levels``), keeping
    what each run started from: ``[(error, dataset, problem, settings)]``."""
    out = []
    for level in case.levels if levels is None else levels:
        problem, settings = case.problem(level, scheme)
        err, ds = run_case(case, level, integrator, scheme)
        out.append((err, ds, problem, settings))
    return out
