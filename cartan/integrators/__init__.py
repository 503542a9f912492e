"""Time integrators: the :class:`Integrator` contract and the explicit integrators."""

from .base import Integrator
from .explicit import RKMK4, ForwardEuler, Kinematic, LieEuler, LieVerlet, Overdamped

__all__ = ["RKMK4", "ForwardEuler", "Integrator", "Kinematic", "LieEuler", "LieVerlet", "Overdamped"]
