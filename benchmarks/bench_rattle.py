"""Speed of the constrained step: ``rattle`` on the inextensible filament (lattice, SE(3)).

``RattleStep`` times ``STEPS`` steps of the filament of ``benchmarks/filament_speed.py`` (clamped,
3-D tip wrench, Δt = half the CFL estimate) at n = 11, 21, 41, 81 nodes along two paths:

* ``compiled`` — the generated ``rattle_loop`` (``Rattle.run_compiled_loop``);
* ``python`` — a bare loop of ``Rattle.step`` (sparse LU solves), ``PY_STEPS`` steps.

``RattleRelaxation`` times the first ``RELAX_STEPS`` compiled steps of the damped relaxation
to the elastica (the scene ``filament-elastica``, n = 41, Γ as in ``filament_speed.py``).  Both
track the trial free flows per step (1 + the multipliers' iterations per step), the quantity
the multipliers' predictor acts on.

``setup`` runs each path once, so that compilation (or loading its cache) never lands inside a
timing.  The comparison with the stiff cosserat-rod, including the relaxation to the elastica,
is the script ``benchmarks/filament_speed.py``.
"""

from __future__ import annotations

from .filament_speed import TIP, _filament, _problem, _setup

STEPS = 200
PY_STEPS = 5
RELAX_STEPS = 2000
#: the relaxation's damping (filament_speed.relaxation's default)
DAMPING = [7.0, 7.0, 7.0, 0.07, 0.07, 0.07]


def _flows(integ, before: int, steps: int) -> float:
    return 1.0 + (integ.niter - before) / steps


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

    def _run(self, path) -> int:
        if path == "compiled":
            self.integrator.run_compiled_loop(self.scheme, self.state, self.dt, STEPS)
            return STEPS
        for _ in range(PY_STEPS):
            self.integrator.step(self.scheme, self.state, self.dt)
        return PY_STEPS

    def time_steps(self, n, path):
        self._run(path)

    def track_trial_flows(self, n, path):
        before = self.integrator.niter
        return _flows(self.integrator, before, self._run(path))

    track_trial_flows.unit = "flows/step"


class RattleRelaxation:
    """The first ``RELAX_STEPS`` compiled steps of the damped relaxation to the elastica (n = 41)."""

    number = 1
    repeat = (3, 5, 20.0)
    warmup_time = 0.0
    timeout = 600.0

    def setup(self):
        import cartan
        from cartan.integrators import Rattle

        base = cartan.scene("filament-elastica").problem
        load = base.boundary(0, "end").load
        self.problem = _problem(base.medium, int(base.grid.shape[0]), load, loads=[cartan.Damping(DAMPING)])
        integ = Rattle()
        sch, state, dt = _setup(self.problem, integ)
        if not integ.run_compiled_loop(sch, state, dt, 2):
            raise NotImplementedError(f"no compiled rattle loop ({integ.compiled_declined})")
        self._fresh()

    def _fresh(self):
        from cartan.integrators import Rattle

        self.integrator = Rattle()
        self.scheme, self.state, self.dt = _setup(self.problem, self.integrator)

    def time_steps(self):
        self._fresh()
        self.integrator.run_compiled_loop(self.scheme, self.state, self.dt, RELAX_STEPS)

    def track_trial_flows(self):
        self._fresh()
        self.integrator.run_compiled_loop(self.scheme, self.state, self.dt, RELAX_STEPS)
        return _flows(self.integrator, 0, RELAX_STEPS)

    track_trial_flows.unit = "flows/step"
