"""Matrix Lie groups: the :class:`SymmetryGroup` contract and its closed-form implementations.

=========== ============================== ===== ===== ================================
class       registry name                   r     m     components
=========== ============================== ===== ===== ================================
``SO2``     ``"SO2"``                       1     2     (θ)
``SE2``     ``"SE2"``                       3     3     (v₁, v₂, ω)
``SO3``     ``"SO3"``                       3     3     (ω₁, ω₂, ω₃)
``SE3``     ``"SE3"``                       6     4     (v; ω)  translation first
``SO``      ``"SO"`` (``n`` ≥ 2)            n(n−1)/2  n  see :mod:`cartan.groups.son`
``SO13``    ``"SO13"``                      6     4     (c; d)  boost first
``Poincare`` ``"Poincare"``                 10    5     (y; c; d)
=========== ============================== ===== ===== ================================

The concrete classes are imported lazily (``from cartan.groups import SE3`` works), so that
``import cartan`` stays cheap.
"""

from __future__ import annotations

import importlib
from typing import Any

from .base import SymmetryGroup

_LAZY = {
    "SO2": ".so2",
    "SE2": ".se2",
    "SO3": ".so3",
    "SE3": ".se3",
    "SO": ".son",
    "SO13": ".so13",
    "Poincare": ".poincare",
}

__all__ = ["SymmetryGroup", *_LAZY]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
