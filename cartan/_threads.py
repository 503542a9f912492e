"""Threads for the compiled step loops (opt-in; ``docs/performance.md``, "Threads").

The compiled loops run serially by default.  With ``k > 1`` threads, set by the environment
variable ``CARTAN_THREADS=k`` or in-process by :func:`set_threads` (or the :func:`use_threads`
context manager), a loop whose grid has at least :data:`MIN_NODES` nodes runs its passes over
the nodes and edges as numba ``prange`` loops on ``k`` threads; smaller grids stay serial,
where starting a parallel region would cost more than it saves (:func:`use_min_nodes` changes
the threshold for a block of code; :func:`threaded_everywhere` lowers it to one node, which
``cartan warm`` uses to compile the threaded builds on small problems).  Results do not
depend on the number of threads: every pass works on fixed chunks of nodes or edges, and sums
over the grid (powers, the kinetic energy of the blow-up test) add the chunks' partial sums
in chunk order.

The threads come from numba's threading layer (``NUMBA_THREADING_LAYER``: ``omp``, ``tbb``
or ``workqueue``); ``k`` can be at most ``NUMBA_NUM_THREADS``, which numba fixes when it
starts (default: the number of cores).

:func:`threaded_twins` makes the threaded variants of a module's kernels from the serial
ones, so that each pass is written once (the hand-written SE(3) rod loops).  The generated
loops' threaded build is a generated module of its own, in which an operator set's threaded
passes replace its serial operators (:meth:`cartan.compiled.operators.OperatorSet.generated`,
``threaded=True``; the lattice's in :mod:`cartan.schemes._lattice_ops`).
"""

from __future__ import annotations

import contextlib
import os
import types
from collections.abc import Iterator, Sequence
from typing import Any

ENV = "CARTAN_THREADS"
#: grids with fewer nodes run serially whatever the thread setting.  A step opens three or
#: four parallel regions (more for ``rkmk4``); on an idle 2-core machine two threads pay
#: from about 3000 rod elements (1.35×; 1.9× from 10⁴) and from a few thousand nodes of the
#: sigma model (``benchmarks/scaling.py --min-nodes 0``); the threshold keeps at least 8
#: chunks of nodes (4 per thread for 2 threads)
MIN_NODES = 8192
_override: int | None = None
#: calls of :func:`loop_threads` in this process (see :func:`thread_queries`)
_queries = 0


def max_threads() -> int:
    """The most threads the loops may use: numba's ``NUMBA_NUM_THREADS``."""
    from numba import config

    return int(config.NUMBA_NUM_THREADS)


def _validate(value: Any, name: str) -> int:
    """``value`` as a thread count, or ValueError naming ``name`` and the allowed range; a
    string (the environment variable) is parsed, other values must be integers."""
    top = max_threads()
    k: Any = value
    if isinstance(value, str):
        try:
            k = int(value.strip())
        except ValueError:
            k = None
    if isinstance(k, bool) or not isinstance(k, int) or not 1 <= k <= top:
        raise ValueError(f"{name} must be an integer in 1..{top} (NUMBA_NUM_THREADS = {top}), got {value!r}")
    return k


def get_threads() -> int:
    """The number of threads the compiled loops may use (1: serial, the default)."""
    if _override is not None:
        return _override
    value = os.environ.get(ENV, "")
    return 1 if value.strip() == "" else _validate(value, ENV)


def set_threads(k: int | None) -> None:
    """Let the compiled loops use ``k`` threads (1 ≤ k ≤ ``NUMBA_NUM_THREADS``) on grids of at
    least :data:`MIN_NODES` nodes; ``None`` returns control to ``CARTAN_THREADS``.

    Raises
    ------
    ValueError
        When ``k`` is not an integer in that range.
    """
    global _override
    if isinstance(k, str):
        raise ValueError(f"threads must be an integer in 1..{max_threads()}, got {k!r}")
    _override = None if k is None else _validate(k, "threads")


@contextlib.contextmanager
def use_threads(k: int) -> Iterator[None]:
    """Context manager: run its body with ``k`` threads (see :func:`set_threads`)."""
    global _override
    if isinstance(k, str):
        raise ValueError(f"threads must be an integer in 1..{max_threads()}, got {k!r}")
    previous = _override
    _override = _validate(k, "threads")
    try:
        yield
    finally:
        _override = previous


def loop_threads(nodes: int, count: bool = True) -> int:
    """Threads for a loop over a grid of ``nodes`` nodes: :func:`get_threads` when it is more
    than 1 and ``nodes ≥ MIN_NODES``, else 1.  Every compiled loop that has a threaded build
    asks here before it runs; the hand-written loops are counted by :func:`thread_queries`,
    the generated ones (``count=False``) are not: ``cartan warm`` compiles the threaded builds of
    the first only (a generated loop's threaded build compiles on its first threaded run)."""
    global _queries
    if count:
        _queries += 1
    k = get_threads()
    return k if k > 1 and nodes >= MIN_NODES else 1


def thread_queries() -> int:
    """How many times compiled loops have asked :func:`loop_threads` for their thread count in
    this process (the generated loops, which ask with ``count=False``, left out): a workload
    that leaves it unchanged never reaches a hand-written loop with a threaded build
    (``cartan warm`` runs only the others threaded)."""
    return _queries


@contextlib.contextmanager
def use_min_nodes(n: int) -> Iterator[None]:
    """Context manager: run its body with the node threshold :data:`MIN_NODES` set to ``n``
    (restored afterwards, also on error).

    The threshold is process-wide: other threads of the process see it too while the body
    runs.

    Raises
    ------
    ValueError
        When ``n`` is not an integer ≥ 1.
    """
    global MIN_NODES
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"min_nodes must be an integer ≥ 1, got {n!r}")
    previous = MIN_NODES
    MIN_NODES = n
    try:
        yield
    finally:
        MIN_NODES = previous


@contextlib.contextmanager
def threaded_everywhere(k: int = 2) -> Iterator[None]:
    """Context manager: the compiled loops of its body run their threaded builds with ``k``
    threads on every grid, however small (:func:`use_threads` with the threshold lowered to one
    node by :func:`use_min_nodes`).

    Results are the same as with the serial builds (module docstring); what changes is only
    which build runs.  ``cartan warm`` uses it to compile the threaded builds into numba's
    cache from its small verification problems, so that a later threaded run loads them.

    Raises
    ------
    ValueError
        When ``k`` is not an integer in ``2..NUMBA_NUM_THREADS`` (one thread would run the
        serial builds).
    """
    top = max_threads()
    if isinstance(k, bool) or not isinstance(k, int) or not 2 <= k <= top:
        raise ValueError(f"threads must be an integer in 2..{top} (NUMBA_NUM_THREADS = {top}), got {k!r}")
    with use_threads(k), use_min_nodes(1):
        yield


def threaded_twins(namespace: dict[str, Any], names: Sequence[str]) -> dict[str, Any]:
    """Threaded variants of the numba kernels ``names`` of a module (pass its ``globals()``).

    Each twin compiles the same Python function with ``parallel=True`` when it uses
    ``prange`` (a serial kernel runs ``prange`` as ``range``), under the qualified name
    ``<name>__threaded`` (its own numba cache file), and with globals in which every name in
    ``names`` is the twin: a twin loop calls twin passes.  Call it after the module has
    defined every kernel it lists.
    """
    from numba import njit

    twin_globals = dict(namespace)
    twins: dict[str, Any] = {}
    for name in names:
        serial = namespace[name]
        py = serial.py_func
        fn = types.FunctionType(py.__code__, twin_globals, py.__name__, py.__defaults__, py.__closure__)
        fn.__qualname__ = f"{py.__qualname__}__threaded"
        fn.__doc__ = py.__doc__
        fn.__kwdefaults__ = py.__kwdefaults__
        options = {k: v for k, v in serial.targetoptions.items() if k != "nopython"}
        if "prange" in py.__code__.co_names:
            options["parallel"] = True
        twins[name] = twin_globals[name] = njit(cache=True, **options)(fn)
    return twins


@contextlib.contextmanager
def numba_threads(k: int) -> Iterator[None]:
    """Run the body with numba's thread count set to ``k`` (restored afterwards)."""
    import numba

    previous = numba.get_num_threads()
    numba.set_num_threads(k)
    try:
        yield
    finally:
        numba.set_num_threads(previous)
