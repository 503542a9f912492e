"""What numba compiles, shown on stderr as it happens.

Compiled code is built on first use and cached on disk (nothing is compiled at install): the
first run of a combination on a machine compiles its loops, which takes seconds to a minute,
and later runs load them.  :func:`install` registers a numba event listener that prints one
line when an outermost compilation of a cartan function starts and one when it ends, so a
user waiting on a first run sees why.  It prints when ``CARTAN_SHOW_COMPILE`` is ``1`` (or
``auto``, the default, with stderr a terminal); ``0`` silences it.  The generated loops
(:mod:`cartan.compiled.codegen`) announce themselves with the combination they serve.
"""

from __future__ import annotations

import os
import sys
import time

from numba.core import event

__all__ = ["install", "showing"]

_installed = False


def showing() -> bool:
    """Whether compile progress is printed (see the module docstring)."""
    value = os.environ.get("CARTAN_SHOW_COMPILE", "auto").strip().lower()
    if value in ("1", "true", "yes", "on"):
        return True
    if value in ("0", "false", "no", "off"):
        return False
    return bool(getattr(sys.stderr, "isatty", lambda: False)())


class _CompileLog(event.Listener):
    def __init__(self) -> None:
        self.depth = 0
        self.start = 0.0
        self.name = ""

    def on_start(self, ev: event.Event) -> None:
        self.depth += 1
        if self.depth != 1:
            return
        func = getattr(ev.data["dispatcher"], "py_func", None)
        module = getattr(func, "__module__", "") or ""
        self.name = ""
        if module.startswith("cartan") and not module.startswith("cartan_generated") and showing():
            self.name = f"{module}.{func.__qualname__}"
            self.start = time.perf_counter()
            print(f"cartan: compiling {self.name} (first use on this machine; cached afterwards)", file=sys.stderr,
                  flush=True)

    def on_end(self, ev: event.Event) -> None:
        self.depth -= 1
        if self.depth == 0 and self.name:
            print(f"cartan: compiled {self.name} in {time.perf_counter() - self.start:.1f} s", file=sys.stderr,
                  flush=True)
            self.name = ""


def install() -> None:
    """Register the listener (once per process)."""
    global _installed
    if not _installed:
        event.register("numba:compile", _CompileLog())
        _installed = True
