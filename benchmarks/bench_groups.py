"""Speed of the batched group operations, numba kernels against the numpy reference path.

Every benchmark is parameterised over the group, the backend and the number of points; the
ratio ``numpy / numba`` at 10⁵ points is the figure of merit (docs/benchmarks.md).  Inputs
are drawn with a fixed seed; ``setup`` calls every operation once on the active backend so
that numba compilation (or loading the on-disk cache) never lands inside a timing.
"""

from __future__ import annotations

import importlib

import numpy as np

from cartan._backend import set_backend

#: registry name -> (module, class)
GROUPS = {
    "SO3": ("cartan.groups.so3", "SO3"),
    "SE3": ("cartan.groups.se3", "SE3"),
    "SO2": ("cartan.groups.so2", "SO2"),
    "SE2": ("cartan.groups.se2", "SE2"),
    "SO13": ("cartan.groups.so13", "SO13"),
    "Poincare": ("cartan.groups.poincare", "Poincare"),
}
SEED = 20240611
#: algebra elements are N(0, SCALE²) per component: rotation angles stay well inside the
#: injectivity radius π, boosts are moderate (rapidities of order one).
SCALE = 0.4
DT = 0.01


def load_group(name: str):
    """Instantiate a group by registry name; ``NotImplementedError`` (asv: skip) if absent."""
    module, cls = GROUPS[name]
    try:
        return getattr(importlib.import_module(module), cls)()
    except (ImportError, AttributeError) as exc:
        raise NotImplementedError(f"group {name} is not available: {exc}") from exc


class GroupOps:
    """exp, log, Ad and 𝓔(Δt, Y) on batches of ``n`` points."""

    params = (list(GROUPS), ["numba", "numpy"], [10**3, 10**5])
    param_names = ["group", "backend", "n"]
    timeout = 300.0

    def setup(self, group, backend, n):
        self.group = load_group(group)
        rng = np.random.default_rng(SEED)
        self.xi = SCALE * rng.standard_normal((n, self.group.dim))
        set_backend("numpy")
        self.g = self.group.exp(self.xi)  # same inputs for both backends
        set_backend(backend)
        # Compile (or load from the numba cache) every kernel on a few points.
        few_xi, few_g = self.xi[:8], self.g[:8]
        self.group.exp(few_xi)
        self.group.log(few_g)
        self.group.Ad(few_g)
        self.group.E(DT, few_xi)

    def teardown(self, group, backend, n):
        set_backend(None)

    def time_exp(self, group, backend, n):
        self.group.exp(self.xi)

    def time_log(self, group, backend, n):
        self.group.log(self.g)

    def time_Ad(self, group, backend, n):
        self.group.Ad(self.g)

    def time_E(self, group, backend, n):
        self.group.E(DT, self.xi)
