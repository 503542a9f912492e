"""Time integrators: the :class:`Integrator` contract, the explicit integrators and the implicit midpoint rule."""

from .base import Integrator
from .constrained import Rattle
from .explicit import RKMK4, ForwardEuler, Kinematic, LieEuler, LieVerlet, Overdamped
from .implicit import ImplicitMidpoint

__all__ = ["RKMK4", "ForwardEuler", "ImplicitMidpoint", "Integrator", "Kinematic", "LieEuler", "LieVerlet",
           "Overdamped", "Rattle"]
