"""Speed of the sigma-model step on 2D grids (``lie-verlet`` and the harmonic-map flow on the
``lattice`` scheme, SO(3) frames), T4 of PERFORMANCE.md §2.

The O(3) sigma model (n = 2) on a periodic N × N grid, N = 64, 128, 256, a smooth random
field with a velocity (``"random-smooth"``), ``STEPS`` steps per sample of
``Lattice.compiled_advance`` (the compiled loop, no saves) with 1 or 2 threads
(``cartan.use_threads``; threads take effect from :data:`cartan._threads.MIN_NODES` nodes,
so only the 256² grid runs threaded).  ``lie-verlet`` runs at a Courant number of 0.25,
``overdamped`` (γ = K) at Δt = 0.1·h².  ``setup`` advances two steps first, so that numba
compilation (or loading its on-disk cache) never lands inside a timing.
"""

from __future__ import annotations

import cartan

STEPS = 10


class SigmaStep:
    """``STEPS`` compiled steps of the sigma model on an ``N × N`` periodic grid."""

    params = ([64, 128, 256], ["lie-verlet", "overdamped"], [1, 2])
    param_names = ["N", "integrator", "threads"]
    number = 1
    repeat = (3, 10, 20.0)
    warmup_time = 0.0
    timeout = 600.0

    def setup(self, N, integrator, threads):
        from cartan import _threads

        if threads > _threads.max_threads():
            raise NotImplementedError(f"numba has {_threads.max_threads()} thread(s) here")
        medium = cartan.medium("sigma-model", n=2, d=2)
        grid = cartan.Grid((N, N), 1.0, periodic=True)
        initial = medium.initial_state(grid, "random-smooth", amplitude=0.5, velocity_amplitude=0.3, seed=0)
        h = grid.spacing[0]
        if integrator == "overdamped":
            problem = cartan.Problem(medium, grid, initial, loads=[medium.make_load("drag")])
            self.dt = 0.1 * h * h
        else:
            problem = cartan.Problem(medium, grid, initial)
            self.dt = 0.25 * h / medium.wave_speed()
        self.scheme = cartan.registry("schemes")["lattice"](problem)
        self.integrator = cartan.registry("integrators")[integrator]()
        self.state = self.scheme.initial_state()
        self.threads = threads
        with cartan.use_threads(threads):
            if not self._advance(2):
                raise NotImplementedError("no compiled loop runs this problem")

    def _advance(self, steps: int) -> bool:
        """The compiled path ``cartan.simulate`` takes: the scheme's hand-written loops (SE(3)
        rods only), else the integrator's generated loop (the sigma model)."""
        return self.scheme.compiled_advance(self.integrator, self.state, self.dt, steps) or (
            self.integrator.run_compiled_loop(self.scheme, self.state, self.dt, steps))

    def time_steps(self, N, integrator, threads):
        with cartan.use_threads(self.threads):
            self._advance(STEPS)
