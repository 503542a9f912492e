"""cartan_verification — registered analytic cases and run-independent invariant checks.

Every case is a :class:`~cartan_verification.case.Case` registered through the
``cartan_register_cases`` hook (``cartan.registry("cases")``): the medium and scene, the exact
reference with its source, the compared quantity and norm, the expected orders in dx and Δt,
and a justified tolerance.  :mod:`cartan_verification.invariants` measures the invariants every
run must respect (integrability, ring closure, group membership, energy balance, momentum).
"""

from __future__ import annotations

from .case import Case, observed_orders, run_case
from .invariants import (
    check_invariants,
    energy_balance,
    group_membership,
    momentum_drift,
    ring_closure,
    spatial_integrability,
    temporal_integrability,
)

__all__ = [
    "Case",
    "check_invariants",
    "energy_balance",
    "group_membership",
    "momentum_drift",
    "observed_orders",
    "ring_closure",
    "run_case",
    "spatial_integrability",
    "temporal_integrability",
]
