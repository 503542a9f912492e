"""Limits on the work a run may take: time steps and memory.

Shared by :mod:`cartan.scene` (a scene's grid must fit in memory) and :mod:`cartan.simulate`
(the steps of a run, the frames it keeps in memory), below both: the time-step count is bounded
by :func:`step_limit` (``max_steps=``, ``cartan run --max-steps`` or :envvar:`CARTAN_MAX_STEPS`),
the arrays by :func:`memory_limit` (:envvar:`CARTAN_MAX_MEMORY`) through :func:`check_memory`.
"""

from __future__ import annotations

import math
import numbers
import os
import re
from typing import Any

__all__ = [
    "DEFAULT_MAX_STEPS",
    "MEMORY_ENV",
    "STEPS_ENV",
    "check_memory",
    "format_bytes",
    "memory_limit",
    "state_bytes",
    "step_limit",
]

#: time steps a run may take unless ``max_steps`` or :envvar:`CARTAN_MAX_STEPS` says otherwise
DEFAULT_MAX_STEPS = 10**9
STEPS_ENV = "CARTAN_MAX_STEPS"
MEMORY_ENV = "CARTAN_MAX_MEMORY"
_BYTE_UNITS = {"": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}


def _count(text: str) -> int | None:
    """An integer written as ``1000000``, ``1_000_000`` or ``1e6``; None if it is none."""
    try:
        return int(text)
    except ValueError:
        pass
    try:
        value = float(text)
    except ValueError:
        return None
    return int(value) if math.isfinite(value) and value.is_integer() else None


def step_limit(max_steps: int | None = None) -> int:
    """The largest number of time steps a run may take.

    Parameters
    ----------
    max_steps : int, optional
        An explicit limit (``simulate(max_steps=...)``, ``cartan run --max-steps``).  By
        default the environment variable ``CARTAN_MAX_STEPS``, else :data:`DEFAULT_MAX_STEPS`
        (10⁹).

    Returns
    -------
    int

    Raises
    ------
    ValueError
        Naming ``max_steps`` or ``CARTAN_MAX_STEPS`` when it is not an integer ≥ 1.
    """
    if max_steps is None:
        text = os.environ.get(STEPS_ENV, "").strip()
        if not text:
            return DEFAULT_MAX_STEPS
        value = _count(text)
        if value is None or value < 1:
            raise ValueError(f"{STEPS_ENV} must be an integer ≥ 1, got {text!r}")
        return value
    if isinstance(max_steps, bool) or not isinstance(max_steps, numbers.Integral) or max_steps < 1:
        raise ValueError(f"max_steps must be an integer ≥ 1, got {max_steps!r}")
    return int(max_steps)


def memory_limit() -> int:
    """The memory, in bytes, that a run's arrays may take.

    The environment variable ``CARTAN_MAX_MEMORY`` (a byte count, or a size such as ``512M``,
    ``8G``, ``1.5T``: binary units) or, by default, half the machine's physical memory
    (4 GiB where that is unknown).

    Returns
    -------
    int

    Raises
    ------
    ValueError
        Naming ``CARTAN_MAX_MEMORY`` when it is not a positive size.
    """
    text = os.environ.get(MEMORY_ENV, "").strip()
    if text:
        match = re.fullmatch(r"([0-9][0-9_.eE+]*)\s*([kKmMgGtT]?)(?:i?[bB])?", text)
        try:
            value = float(match[1]) * _BYTE_UNITS[match[2].upper()] if match else math.nan
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and value >= 1):
            raise ValueError(f"{MEMORY_ENV} must be a size in bytes such as 8G, 512M or 1000000, got {text!r}")
        return int(value)
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        total = 0
    return total // 2 if total > 0 else 4 << 30


def format_bytes(n: float) -> str:
    """A size for messages.

    Parameters
    ----------
    n : float
        Bytes.

    Returns
    -------
    str
        ``"512 B"``, ``"7.45 GiB"``, ``"1013 GiB"``, ``"1.48 TiB"`` (binary units).
    """
    unit = "B"
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if abs(n) < 1024 or unit == "TiB":
            break
        n /= 1024
    return f"{n:.0f} {unit}" if unit == "B" or abs(n) >= 100 else f"{n:.3g} {unit}"


def state_bytes(group: Any, nodes: int, d: int = 1) -> float:
    """A lower estimate of the memory a run's state takes on ``nodes`` nodes.

    Six float64 copies (the state, the forces and the scheme's work arrays) of the frames
    Φ (m × m), the velocity and momentum (r each) and the strains (d × r) of every node, for a
    group of matrix size m and dimension r: 1.6 kB a node for a rod on SE(3).

    Parameters
    ----------
    group : SymmetryGroup
    nodes : int
    d : int
        Material dimension.

    Returns
    -------
    float
        Bytes.
    """
    m, r = int(group.matrix_size), int(group.dim)
    return 6.0 * 8.0 * float(nodes) * (m * m + (2 + d) * r)


def check_memory(what: str, nbytes: float, advice: str = "") -> None:
    """Refuse work whose arrays would need more than :func:`memory_limit`.

    Parameters
    ----------
    what : str
        What needs the memory (``"a grid of 1000000000 nodes"``).
    nbytes : float
        The estimate.
    advice : str
        How to need less (``"use fewer nodes"``).

    Raises
    ------
    ValueError
        Naming ``what``, the estimate, the limit and how to raise it.
    """
    limit = memory_limit()
    if not nbytes <= limit:
        hint = f"{advice}, or raise" if advice else "raise"
        raise ValueError(
            f"{what} needs ≈ {format_bytes(nbytes)} of memory, above the limit of {format_bytes(limit)}; "
            f"{hint} the limit with the environment variable {MEMORY_ENV} (e.g. {MEMORY_ENV}=64G)"
        )
