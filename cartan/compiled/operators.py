"""The operator set a scheme hands to the integrators' compiled loops.

A scheme's ``compiled_operators()`` returns an :class:`OperatorSet`: the source fragments
that define its operators (``op_force``, ``op_drift``, ``op_velocity`` … — the list and their
signatures are in :mod:`cartan.schemes._lattice_ops`) together with the group's and the
medium's point kernels, the problem as data, and how to move a
:class:`~cartan.schemes.base.State`'s configuration in and out of the flat arrays the loops
step.  An integrator adds its loop (:mod:`cartan.integrators.loops`) and runs the generated
module; it never sees more of the scheme than this.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from .codegen import Fragment, generate

__all__ = ["LOOP_SOURCES", "OperatorSet"]

#: the modules whose ``loop_fragment()`` joins every generated module, by name (the loops and
#: the diagnostics that run over an operator set); the functions of a generated module compile
#: on first call only, so one module serves every loop and the operators compile once
LOOP_SOURCES = ("cartan.integrators.loops", "cartan.integrators.newton", "cartan.integrators.rattle_loop",
                "cartan.compiled.diagnostics")


@dataclass
class OperatorSet:
    """A scheme's compiled operators for one problem.

    Attributes
    ----------
    label : str
        What the operators serve, for messages (``"lattice × SO(n=4) × sigma-model"``).
    key : str
        A file-name stem for the generated module.
    fragments : list of Fragment
        The group's kernels, the medium's kernels and the operators' source.
    data : tuple
        The problem as data (the operators' first argument ``D``).
    pack : callable ``state -> C``
        The configuration as the tuple of arrays the operators step.
    unpack : callable ``(state, C) -> None``
        Write a stepped configuration back into ``state.arrays``.
    accepts : callable ``state -> bool``
        Whether ``state`` holds the configuration ``pack`` expects.
    nodes : int
        Number of nodes (rows of S).
    reason : str or None
        Why the scheme declined (then every other field is empty).
    module : module or None
        The generated module of these operators and the integrators' loops, once imported.
    threaded : list of Fragment
        The operators' threaded build (empty: none): fragments that define ``prange`` variants
        of the passes over nodes and edges and rebind the operators' names to them (see
        :meth:`generated`).
    threaded_module : module or None
        The generated module of the threaded build, once imported.
    late : list of Fragment
        Fragments that follow the loops in the set's module (empty: none): operators that wrap
        the shared ones and take their names there (a module global bound last is the one numba
        compiles into a loop), e.g. the lattice's driven ends
        (:func:`cartan.schemes._lattice_ops.driven_fragment`).
    loops : tuple of str
        With a :attr:`reason` (the set does not serve every loop), the loops of
        :mod:`cartan.integrators.loops` that run it all the same (:meth:`serves`); empty for a
        set that serves every loop or none.
    accumulates : tuple of str
        The loops of :mod:`cartan.integrators.loops` that integrate the medium's per-node
        accumulators (:mod:`cartan.accumulators`) in the loop, the set's ``op_accumulate``
        rebound (:attr:`late`), its ``pack``/``unpack`` moving them between the state and the
        data; empty: the medium declares none, or they step on the numpy path
        (:func:`cartan.simulate`'s ``_advance``).
    """

    label: str = ""
    key: str = ""
    fragments: list[Fragment] = field(default_factory=list)
    data: Any = None
    pack: Callable | None = None
    unpack: Callable | None = None
    accepts: Callable | None = None
    nodes: int = 0
    reason: str | None = None
    module: Any = None
    threaded: list[Fragment] = field(default_factory=list)
    threaded_module: Any = None
    late: list[Fragment] = field(default_factory=list)
    loops: tuple[str, ...] = ()
    accumulates: tuple[str, ...] = ()

    @classmethod
    def declined(cls, reason: str) -> OperatorSet:
        """An empty set that says why the problem is not covered."""
        return cls(reason=reason)

    @property
    def ok(self) -> bool:
        """Whether the set serves every loop (the implicit midpoint's, the diagnostics' …)."""
        return self.reason is None

    def serves(self, loop: str) -> bool:
        """Whether the generated loop ``loop`` (a function name of the set's module) runs this
        set: every loop when :attr:`ok`, else those of :attr:`loops`."""
        return self.reason is None or loop in self.loops

    def generated(self, threaded: bool = False):
        """The generated module of these operators with every loop of :data:`LOOP_SOURCES`
        (written and imported once per operator set; its functions compile on first call).

        The fragments of :attr:`late` come last.  With ``threaded`` (and a set that has a
        threaded build, :attr:`threaded`), the module of the threaded build: the same fragments
        with :attr:`threaded` after the loops, whose functions
        replace the operators the loops call (a module global bound last is the one numba
        compiles into a loop), in a module of its own (its own file and numba cache).  The
        serial module's text does not change with it.
        """
        import importlib

        if threaded and self.threaded:
            if self.threaded_module is None:
                loops = [importlib.import_module(name).loop_fragment() for name in LOOP_SOURCES]
                self.threaded_module = generate(f"ops-threaded-{self.key}",
                                                [*self.fragments, *loops, *self.threaded, *self.late])
            return self.threaded_module
        if self.module is None:
            loops = [importlib.import_module(name).loop_fragment() for name in LOOP_SOURCES]
            self.module = generate(f"ops-{self.key}", [*self.fragments, *loops, *self.late])
        return self.module
