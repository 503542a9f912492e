"""Generated modules: one small Python module per (loop, operators, kernels), compiled once.

A compiled loop reaches the kernels it calls (the group's exp, log, dexp⁻¹ …, the medium's
energy density and stress, the scheme's operators) as **module globals** of a module written
for it: numba then compiles the loop as if it had been written by hand around those kernels,
and caches the machine code on disk like any ``@njit(cache=True)`` function, so a later
process loads it instead of compiling (a jitted function passed as an argument compiles
as fast but is compiled again in every process).

The module's file name carries a hash of its text and of the source files of every kernel
it imports (and of the kernels those call): editing a kernel gives a new module, and the
stale one is never loaded again.  Modules live in ``<cache>/generated`` where ``<cache>`` is
``$NUMBA_CACHE_DIR/cartan`` when numba's cache directory is set, else
``$XDG_CACHE_HOME/cartan`` (``~/.cache/cartan``); ``CARTAN_CACHE_DIR`` overrides both.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import inspect
import os
import sys
import tempfile
import textwrap
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

__all__ = ["Fragment", "cache_dir", "first_call", "generate", "njit_source"]

#: module name prefix of generated modules (``sys.modules`` keys)
PACKAGE = "cartan_generated"
_loaded: dict[str, ModuleType] = {}


@dataclass
class Fragment:
    """A piece of a generated module.

    Attributes
    ----------
    imports : dict of str → (str, str)
        ``alias → (module, name)``: ``from module import name as alias``.
    constants : dict of str → array or float or int
        Module-level constants (numba freezes global arrays into the machine code).
    source : str
        Python source of functions (each is compiled with ``@njit(cache=True)``).
    parallel : tuple of str
        Top-level functions of ``source`` compiled with ``parallel=True`` (their ``prange``
        loops run on numba's threads; the threaded builds, :mod:`cartan._threads`).  A module
        with one imports ``prange`` from numba; the others' text is unchanged by this field.
    """

    imports: dict[str, tuple[str, str]] = field(default_factory=dict)
    constants: dict[str, Any] = field(default_factory=dict)
    source: str = ""
    parallel: tuple[str, ...] = ()


@functools.cache
def njit_source(*functions: Callable) -> str:
    """The source of plain Python functions, to be compiled inside a generated module.

    The functions are written (and linted, and read) as ordinary module-level functions whose
    free names (``g_exp``, ``op_force`` …) are the globals of the generated module.  Read once
    per process (``inspect.getsource`` tokenises the whole file: milliseconds per run).
    """
    return "\n\n".join(textwrap.dedent(inspect.getsource(f)) for f in functions)


def cache_dir() -> Path:
    """Where generated modules are written (see the module docstring)."""
    env = os.environ.get("CARTAN_CACHE_DIR")
    if env:
        return Path(env)
    numba_dir = os.environ.get("NUMBA_CACHE_DIR")
    if numba_dir:
        return Path(numba_dir) / "cartan"
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "cartan"


def _literal(value: Any) -> str:
    """Exact Python source of a constant (float64/int64/bool arrays, floats, ints)."""
    if isinstance(value, (bool, np.bool_)):
        return repr(bool(value))
    if isinstance(value, (int, np.integer)):
        return repr(int(value))
    if isinstance(value, (float, np.floating)):
        return f"float.fromhex({float(value).hex()!r})"
    arr = np.ascontiguousarray(value)
    dtype = {"f": "float64", "i": "int64", "b": "bool_"}[arr.dtype.kind]
    arr = arr.astype(dtype)
    return (f"np.frombuffer(bytes.fromhex({arr.tobytes().hex()!r}), dtype=np.{dtype})"
            f".reshape({tuple(arr.shape)!r}).copy()")


def _kernel_sources(imports: Iterable[tuple[str, str]]) -> list[str]:
    """Source files of the imported kernels and of the jitted functions their modules import."""
    return sorted({f for imp in imports for f in _kernel_files(*imp)})


@functools.cache
def _kernel_files(module_name: str, name: str) -> tuple[str, ...]:
    """:func:`_kernel_sources` of one import, found once per process (``inspect`` looks up every
    function of the module: tens of milliseconds per run of a generated loop); :func:`generate`
    checks their stamps at every call and reads them again when one changed, so that an edited
    kernel still makes a new module."""
    module = importlib.import_module(module_name)
    obj = getattr(module, name)
    # a function, a dispatcher (``py_func``) or an intrinsic (``_defn``)
    func = getattr(obj, "py_func", None) or getattr(obj, "_defn", None) or obj
    try:
        files = {inspect.getsourcefile(func) or ""}
    except TypeError:
        return ()
    for value in vars(module).values():
        inner = getattr(value, "py_func", None)
        if inner is not None:
            try:
                files.add(inspect.getsourcefile(inner) or "")
            except TypeError:
                pass
    return tuple(sorted(f for f in files if f))


def _inline(name: str) -> str:
    """numba's ``inline`` option for a kernel or helper of a generated module.

    IR inlining (``"always"``) types a function's body again at every call site; the group's
    kernels (``g_*``: exp, log, Ad, dexp⁻¹ …) are large and called from many sites, and
    compiling them once (``"never"``, LLVM still inlines them when the caller is optimised)
    takes a third less time to compile a loop (lattice ``lie-verlet``, SE(3) rod: 29 → 17 s;
    sigma model on SO(4): 36 → 21 s of CPU time), at 0–1.6× the cost per step (the SO(4)
    kernels, which fill small work arrays, lose most).  The exceptions, :data:`INLINED_KERNELS`,
    are small kernels called once per node and piece from one call site: an out-of-line call
    costs more than their arithmetic (≈ 16 ns against ≈ 7 ns for SE(3)'s ``g_axis_flow``, and
    ≈ 38 ns when a tuple of work arrays is passed).  (IR-inlining ``g_compose`` and ``g_inverse``
    into the lattice's edge update, ``op_move``, takes it from 112 to 51 ns per node on the SE(3)
    rod but adds ≈ 1.6 s of CPU time to every lattice loop's compile, ≈ 7 %: not taken.  SE(3)'s
    passes over edges and nodes — ``se3_log_chunk_point``, ``se3_move_chunk_point`` … — call
    functions compiled once and cached instead, which no generated module compiles again.)
    """
    return "never" if name.startswith("g_") and name not in INLINED_KERNELS else "always"


#: group kernels compiled into their callers (numba IR inlining) although they are group
#: kernels (see :func:`_inline`)
INLINED_KERNELS = frozenset({"g_axis_flow"})


#: the text of each rendered module by the content of its fragments (:func:`_render_key`)
_rendered: dict[tuple, str] = {}


def _render_key(fragments: list[Fragment]) -> tuple:
    """What the text of :func:`_render` depends on, in order: per fragment its source, imports,
    constants (as their exact literals) and parallel functions (hashable, and cheap beside
    the dedent and decoration of thousands of source lines that it saves at every run)."""
    return tuple((frag.source, tuple(frag.imports.items()),
                  tuple((name, _literal(value)) for name, value in frag.constants.items()), tuple(frag.parallel))
                 for frag in fragments)


def _render(fragments: Iterable[Fragment]) -> str:
    """The module's text (rendered once per content and process, :data:`_rendered`)."""
    fragments = list(fragments)
    key = _render_key(fragments)
    text = _rendered.get(key)
    if text is None:
        if len(_rendered) > 64:
            _rendered.clear()
        text = _rendered[key] = _render_text(fragments)
    return text


def _render_text(fragments: Iterable[Fragment]) -> str:
    imports: dict[str, tuple[str, str]] = {}
    constants: dict[str, Any] = {}
    sources: list[str] = []
    parallel: set[str] = set()
    for frag in fragments:
        imports.update(frag.imports)
        constants.update(frag.constants)
        parallel.update(frag.parallel)
        if frag.source.strip():
            sources.append(textwrap.dedent(frag.source).strip())
    lines = ["# Generated by cartan.compiled.codegen: a compiled loop and the kernels it calls.",
             "import numpy as np", "from numba import njit, prange" if parallel else "from numba import njit", ""]
    for alias, (module, name) in sorted(imports.items()):
        lines.append(f"from {module} import {name} as _{alias}")
    lines.append("")
    # the kernels are compiled from their Python source inside the module: the medium's
    # (``m_``) and the loops' helpers (``_``) inlined into their callers (numba IR inlining),
    # the group's (``g_``) compiled once per signature and left to LLVM to inline
    lines.append("_jit = lambda f, how: (f if isinstance(f, type) or hasattr(f, '_defn')"
                 " else njit(inline=how, error_model='numpy')(getattr(f, 'py_func', f)))")
    for alias in sorted(imports):
        lines.append(f"{alias} = _jit(_{alias}, {_inline(alias)!r})")
    lines.append("")
    for name, value in constants.items():
        lines.append(f"{name} = {_literal(value)}")
    lines.append("")
    body = "\n\n\n".join(sources)
    # every top-level function is compiled and cached; helpers (``_name``) and kernels
    # (``g_name``, ``m_name``) are compiled where they are called (see :func:`_inline`)
    # (the functions named by a fragment's ``parallel`` are compiled with ``parallel=True``)
    inline = ("def _", "def g_", "def m_")
    body = "\n".join((f"@njit(inline={_inline(ln[4:])!r}, error_model='numpy')\n" + ln) if ln.startswith(inline)
                     else ("@njit(cache=True, error_model='numpy', parallel=True)\n" + ln)
                     if ln.startswith("def ") and ln[4:].split("(")[0] in parallel
                     else ("@njit(cache=True, error_model='numpy')\n" + ln) if ln.startswith("def ") else ln
                     for ln in body.splitlines())
    lines.append(body)
    return "\n".join(lines) + "\n"


#: the name hash of a module by (text, the kernels' files and their stamps, :func:`_stamp`)
_digests: dict[tuple, str] = {}


def _stamp(path: str) -> tuple[int, int]:
    """``(modification time in ns, size)`` of a kernel's source file: a file edited in place
    changes it, and :func:`generate` then reads the files again."""
    st = os.stat(path)
    return st.st_mtime_ns, st.st_size


def generate(kind: str, fragments: Iterable[Fragment]) -> ModuleType:
    """Write (once) and import the generated module made of ``fragments``.

    Parameters
    ----------
    kind : str
        A readable stem of the file name (e.g. ``"lie_verlet-lattice-SO4-sigma_model"``).
    fragments : iterable of Fragment

    Returns
    -------
    module
        The imported module; its functions compile on first call and are cached on disk.
    """
    fragments = list(fragments)
    text = _render(fragments)
    sources = _kernel_sources(imp for f in fragments for imp in f.imports.values())
    # the hash of the text and the kernels' files, again only when a file changed (its stat)
    key = (text, tuple((path, *_stamp(path)) for path in sources))
    hexdigest = _digests.get(key)
    if hexdigest is None:
        digest = hashlib.sha256(text.encode())
        for path in sources:
            digest.update(Path(path).read_bytes())
        if len(_digests) > 64:
            _digests.clear()
        hexdigest = _digests[key] = digest.hexdigest()
    stem = "".join(c if c.isalnum() else "_" for c in kind)[:80]
    name = f"{stem}_{hexdigest[:16]}"
    if name in _loaded:
        return _loaded[name]
    folder = cache_dir() / "generated"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.py"
    if not path.exists() or path.read_text() != text:
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{name}.", suffix=".tmp")
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        os.replace(tmp, path)
    spec = importlib.util.spec_from_file_location(f"{PACKAGE}.{name}", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    module.__cartan_marker__ = folder / f"{name}.compiled"
    _loaded[name] = module
    return module


#: the markers :class:`first_call` has seen on disk in this process
_compiled: set[Path] = set()


class first_call:  # noqa: N801 - used as a function: ``with first_call(...):``
    """Around the first call of ``module.function``: announce on stderr that ``what`` compiles,
    and compile it in one process at a time.

    A context manager.  The first time ``function`` of a generated module runs on a machine it
    is compiled and its machine code written to the cache; ``with first_call(...)`` around that
    call says so on stderr (what, and that it happens once) and reports the compile time.
    Processes that reach the same first call meanwhile (parallel runs, test workers) wait on a
    lock file beside the module and then load the machine code from the cache instead of
    compiling it again.  Later calls, and calls in later processes, do nothing.
    """

    def __init__(self, module: ModuleType, function: str, what: str):
        self.marker: Path = module.__cartan_marker__.with_suffix(f".{function}.compiled")
        self.what = what
        self._lock: Any = None
        self._t0 = 0.0

    def __enter__(self) -> first_call:
        if self.marker in _compiled or self.marker.exists():
            _compiled.add(self.marker)  # (a marker once seen stays: no file check at later calls)
            return self
        try:
            import fcntl
        except ImportError:  # no advisory locks on this platform: each process compiles
            fcntl = None
        if fcntl is not None:
            self._lock = open(self.marker.with_suffix(".lock"), "a")  # noqa: SIM115 - held until __exit__
            fcntl.flock(self._lock, fcntl.LOCK_EX)
            if self.marker.exists():  # compiled by another process while this one waited
                self._release()
                return self
        print(f"cartan: compiling {self.what} (once; later runs load it from {self.marker.parent})",
              file=sys.stderr, flush=True)
        self._t0 = time.perf_counter()
        return self

    def __exit__(self, kind: Any, value: Any, tb: Any) -> None:
        if self._t0 and kind is None:
            self.marker.touch()
            print(f"cartan: compiled {self.what} in {time.perf_counter() - self._t0:.1f} s", file=sys.stderr,
                  flush=True)
        self._t0 = 0.0
        self._release()

    def _release(self) -> None:
        if self._lock is not None:
            self._lock.close()  # (closing the file releases the lock)
            self._lock = None
