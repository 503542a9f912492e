"""The state of a run: time, momentum density, configuration arrays and accumulators.

:class:`State` is the one object every layer shares: schemes create and update it, integrators
advance it, :func:`cartan.simulate` copies it between saves, and :mod:`cartan.io` writes it to
checkpoints and reads it back.  It lives in its own module, below all of them, so that none of
them has to import another to name it (``cartan.schemes.base`` re-exports it).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["State"]


@dataclass
class State:
    """Everything a run needs to continue exactly: time, momentum, configuration arrays.

    Attributes
    ----------
    t : float
    S : array ``[*shape, r]``
        Momentum density on the nodes.
    arrays : dict of str → ndarray
        Scheme-specific configuration (e.g. ``"Phi"`` node frames, ``"G_u"`` edge elements,
        ``"X"`` nodal strains).  Saved verbatim in checkpoints.
    scalars : dict of str → float
        Accumulators (``"dissipated_energy"``, ``"external_work"``) and the step counter.
    memory : dict of str → ndarray
        What an integrator carries from one step to the next and its next step depends on
        (``rattle``'s multiplier offset, :mod:`cartan.integrators.constrained`); empty for
        the others.  Saved verbatim in checkpoints, so that a restart continues exactly.
    """

    t: float
    S: np.ndarray
    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    scalars: dict[str, float] = field(default_factory=lambda: {"dissipated_energy": 0.0, "external_work": 0.0})
    memory: dict[str, np.ndarray] = field(default_factory=dict)

    def copy(self) -> State:
        """An independent copy (arrays and scalars copied).

        Returns
        -------
        State
        """
        return State(self.t, self.S.copy(), {k: v.copy() for k, v in self.arrays.items()}, dict(self.scalars),
                     {k: v.copy() for k, v in self.memory.items()})

    def is_finite(self) -> bool:
        """Whether the momentum and every configuration array are finite.

        Returns
        -------
        bool
        """
        return bool(np.all(np.isfinite(self.S)) and all(np.all(np.isfinite(a)) for a in self.arrays.values()))
