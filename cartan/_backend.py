"""Selection of the compute backend for per-point kernels.

Two backends compute the same closed-form formulas:

``"numba"`` (default)
    compiled per-point kernels (``@njit(cache=True)``) looped over the flattened batch;
``"numpy"``
    the vectorised numpy reference path, used by the tests as the oracle.

The backend is chosen by the environment variable ``CARTAN_BACKEND`` and can be
overridden in-process with :func:`set_backend` or the :func:`use_backend` context manager.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator

BACKENDS = ("numba", "numpy")
_override: str | None = None


def _validate(name: str) -> str:
    name = name.strip().lower()
    if name not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {name!r}")
    return name


def get_backend() -> str:
    """Return the active backend name (``"numba"`` or ``"numpy"``)."""
    if _override is not None:
        return _override
    return _validate(os.environ.get("CARTAN_BACKEND", "numba") or "numba")


def set_backend(name: str | None) -> None:
    """Set the backend for this process; ``None`` returns control to ``CARTAN_BACKEND``."""
    global _override
    _override = None if name is None else _validate(name)


@contextlib.contextmanager
def use_backend(name: str) -> Iterator[None]:
    """Context manager that runs its body with backend ``name``."""
    global _override
    previous = _override
    _override = _validate(name)
    try:
        yield
    finally:
        _override = previous
