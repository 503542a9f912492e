"""Kernels defined where they cannot be imported from (a script, a notebook, ``exec``).

:func:`register` keeps such a function here under a name derived from its code, so that a
generated module can import it like any other kernel; the same code gives the same name in
every process, so the generated module (and numba's cache of it) is found again.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable

__all__ = ["register"]


def _fingerprint(func: Callable) -> str:
    code = func.__code__
    digest = hashlib.sha256()
    for part in (code.co_code, repr(code.co_consts).encode(), repr(code.co_names).encode(),
                 repr(code.co_varnames).encode(), func.__name__.encode()):
        digest.update(part)
    return digest.hexdigest()[:20]


def register(func: Callable) -> str:
    """Keep ``func`` (a plain Python function, the ``py_func`` of a jitted one) as a global
    of this module; returns its name here."""
    name = f"kernel_{func.__name__}_{_fingerprint(func)}"
    globals()[name] = func
    return name
