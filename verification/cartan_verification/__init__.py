"""cartan_verification — registered analytic cases and run-independent invariant checks.

Every case is a :class:`~cartan_verification.case.Case` registered through the
``cartan_register_cases`` hook (``cartan.registry("cases")``): the medium and scene, the exact
reference with its source, the compared quantity and norm, the expected orders in dx and Δt,
and a justified tolerance.  :mod:`cartan_verification.invariants` measures the invariants every
run must respect (integrability, ring closure, group membership, energy balance, momentum,
the dissipation law of damped and gradient flows); :mod:`cartan_verification.references` holds
the exact references (elastica, Timoshenko, rod dispersion) that cases and tests share.
"""

from __future__ import annotations

from .case import Case, StaticCase, observed_orders, run_case
from .invariants import (
    check_invariants,
    dissipation_balance,
    dissipation_rate,
    energy_balance,
    group_membership,
    momentum_drift,
    ring_closure,
    spatial_integrability,
    temporal_integrability,
)

__all__ = [
    "Case",
    "StaticCase",
    "check_invariants",
    "dissipation_balance",
    "dissipation_rate",
    "energy_balance",
    "group_membership",
    "momentum_drift",
    "observed_orders",
    "ring_closure",
    "run_case",
    "spatial_integrability",
    "temporal_integrability",
]
