"""Accuracy history of the main verification cases (VERIFICATION.md), tracked by asv.

Every case is a registered verification case (``cartan.registry("cases")``, from the
``cartan_verification`` package) run through :func:`cartan_verification.run_case` at its
quick levels — the two levels the test suite runs, whose finer one meets the case's
tolerance.  For each (case, integrator) the suite tracks

``track_error``
    the error at the finer quick level, in the case's own norm (``case.error``);
``track_error_over_tolerance``
    that error over the case's tolerance for the integrator (≤ 1 passes);
``track_observed_order``
    log₂(e_coarse / e_fine) between the two quick levels (each level halves dx or Δt as the
    case's ``problem(level)`` defines),
    to be read against the expected order, ``track_expected_order``.

The cases (each < 1 s on one core): the free rigid body (time refinement of ``lie-verlet``,
``rkmk4``, ``lie-euler``; exact Jacobi elliptic solution), the axial standing wave of a
periodic rod (space refinement; ω = √(EA/ρA)·k), the butterfly rod's energy error (time
refinement of ``lie-verlet``; no drift) and the sigma model's null wave (space refinement;
n = f(x − t) exactly).  A case that is not registered is skipped (``n/a``).
"""

from __future__ import annotations

import math
import warnings

#: (case, integrator) pairs, as "case / integrator"
CASES = [
    "free-rigid-body / lie-verlet",
    "free-rigid-body / rkmk4",
    "free-rigid-body / lie-euler",
    "rod-axial-wave / lie-verlet",
    "rod-butterfly-energy / lie-verlet",
    "sigma-null-wave / lie-verlet",
]


def _measure(label: str) -> dict[str, float] | None:
    import cartan

    name, integrator = (part.strip() for part in label.split("/"))
    cases = cartan.registry("cases")
    if name not in cases:
        return None
    from cartan_verification import run_case

    case = cases[name]() if isinstance(cases[name], type) else cases[name]
    levels = case.quick()
    with warnings.catch_warnings():  # lie-euler has no stable Δt for undamped motion: it warns, by design
        warnings.simplefilter("ignore")
        errors = [run_case(case, level, integrator=integrator)[0] for level in levels[-2:]]
    coarse, fine = errors
    expected = case.expected_order(integrator)
    return {
        "error": float(fine),
        "error_over_tolerance": float(fine) / case.tolerance_for(integrator),
        "observed_order": math.log2(coarse / fine) if coarse > 0 and fine > 0 else math.nan,
        "expected_order": math.nan if expected is None else float(expected),
    }


class VerificationCase:
    """Errors and observed orders of the registered cases at their quick levels."""

    params = (CASES,)
    param_names = ["case"]
    timeout = 600.0

    def setup_cache(self):
        return {label: _measure(label) for label in CASES}

    def setup(self, results, label):
        if results[label] is None:
            raise NotImplementedError(f"case {label.split('/')[0].strip()!r} is not registered")

    def track_error(self, results, label):
        """Error at the finer quick level, in the case's norm."""
        return results[label]["error"]

    def track_error_over_tolerance(self, results, label):
        """That error over the case's tolerance (≤ 1 passes)."""
        return results[label]["error_over_tolerance"]

    def track_observed_order(self, results, label):
        """log₂ of the error ratio between the two quick levels."""
        return results[label]["observed_order"]

    def track_expected_order(self, results, label):
        """The order the case expects for the integrator."""
        return results[label]["expected_order"]

    track_error.unit = "error"
    track_error_over_tolerance.unit = "ratio"
    track_observed_order.unit = "order"
    track_expected_order.unit = "order"
