"""The verification case: a runnable problem with an exact reference and an error norm.

A case answers two questions for the convergence and stability studies:

``case.problem(level, scheme)``
    The :class:`~cartan.Problem` at refinement ``level`` (the grid doubles its node count with
    the level for space refinement; Δt halves with the level for time refinement) and the run
    settings ``dict(dt=, t_end=, save_every=)`` to pass to :func:`cartan.simulate` — a case may
    add ``integrator_options`` when its reference fixes an integrator option (the overdamped
    order), which :func:`cartan.simulate` accepts as they are.
``case.error(ds, problem)``
    The error of a run's Dataset against the exact reference, in the case's stated norm.

so that a study runs::

    problem, settings = case.problem(level, scheme)
    ds = cartan.simulate(problem, integrator=name, scheme=scheme, **settings)
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
tolerance, tolerance_reason
    Pass threshold on the error at the finest default level with the first default
    integrator, and why (:meth:`Case.tolerance_for` gives per-integrator thresholds).
default_integrators, default_schemes, levels, quick_levels
    What the studies run by default; ``quick_levels`` are cheap enough for the test suite
    (their finest level meets the tolerance too).
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

__all__ = ["Case", "observed_orders", "run_case", "run_config"]


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
    tolerance: float = math.inf
    tolerance_reason: str = ""
    tolerances: Mapping[str, float] = {}
    default_integrators: tuple[str, ...] = ("lie-verlet",)
    default_schemes: tuple[str, ...] = ("lattice",)
    levels: tuple[int, ...] = (0, 1, 2, 3)
    quick_levels: tuple[int, ...] | None = None

    @abc.abstractmethod
    def problem(self, level: int, scheme: str = "lattice") -> tuple[Problem, dict[str, Any]]:
        """The problem at refinement ``level`` and its run settings ``dict(dt=, t_end=, save_every=)``."""

    @abc.abstractmethod
    def error(self, ds: xr.Dataset, problem: Problem) -> float:
        """Error of a run's Dataset against the exact reference."""

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
        parameter order of a limit case, else the time order, else the space order."""
        if self.parameter_order is not None:
            return float(self.parameter_order)
        integrator = integrator or self.default_integrators[0]
        if self.time_order_of is not None:
            return self.expected_time_order(integrator)
        return None if self.space_order is None else float(self.space_order)

    def tolerance_for(self, integrator: str | None = None) -> float:
        """Pass threshold for ``integrator`` at the finest default level."""
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
    """Run ``case`` at ``level`` and return ``(error, dataset)``."""
    import cartan

    problem, settings = case.problem(level, scheme)
    settings = {**settings, **overrides}
    ds = cartan.simulate(problem, integrator=integrator or case.default_integrators[0], scheme=scheme,
                         progress=False, **settings)
    return float(case.error(ds, problem)), ds
