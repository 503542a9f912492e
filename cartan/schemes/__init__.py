"""Discretisation schemes: the :class:`Scheme` contract and the built-in ``lattice`` scheme."""

from .base import Scheme, State
from .lattice import Lattice

__all__ = ["Lattice", "Scheme", "State"]
