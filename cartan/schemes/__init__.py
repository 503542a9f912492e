"""Discretisation schemes: the :class:`Scheme` contract and the built-in ``lattice`` and ``collocation`` schemes."""

from .base import Scheme, State
from .collocation import Collocation
from .lattice import Lattice

__all__ = ["Collocation", "Lattice", "Scheme", "State"]
