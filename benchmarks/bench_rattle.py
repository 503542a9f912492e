"""Speed of the constrained step: ``rattle`` on the inextensible filament (lattice, SE(3)).

``RattleStep`` times ``STEPS`` steps of the filament of ``benchmarks/filament_speed.py`` (clamped,
3-D tip wrench, Δt = half the CFL estimate) at n = 11, 21, 41, 81 nodes along two paths:

* ``compiled`` — the generated ``rattle_loop`` (``Rattle.run_compiled_loop``);
* ``python`` — a bare loop of ``Rattle.step`` (sparse LU solves), ``PY_STEPS`` steps.

``setup`` runs each path once, so that compilation (or loading its cache) never lands inside a
timing.  The comparison with the stiff cosserat-rod, including the relaxation to the elastica,
is the script ``benchmarks/filament_speed.py``.
"""

from __future__ import annotations

from .filament_speed import TIP, _filament, _problem, _setup

STEPS = 200
PY_STEPS = 5


class RattleStep:
    """``STEPS`` (compiled) or ``PY_STEPS`` (Python) steps of ``rattle`` on the filament of ``n`` nodes."""

    params = ([11, 21, 41, 81], ["compiled", "python"])
    param_names = ["n", "path"]
    number = 1
    repeat = (3, 10, 20.0)
    warmup_time = 0.0
    timeout = 600.0

    def setup(self, n, path):
        from cartan.integrators import Rattle

        self.integrator = Rattle()
        self.scheme, self.state, self.dt = _setup(_problem(_filament(), n, TIP), self.integrator)
        if path == "compiled":
            if not self.integrator.run_compiled_loop(self.scheme, self.state, self.dt, 2):
                raise NotImplementedError(f"no compiled rattle loop ({self.integrator.compiled_declined})")
        else:
            self.integrator.step(self.scheme, self.state, self.dt)

    def time_steps(self, n, path):
        if path == "compiled":
            self.integrator.run_compiled_loop(self.scheme, self.state, self.dt, STEPS)
        else:
            for _ in range(PY_STEPS):
                self.integrator.step(self.scheme, self.state, self.dt)
