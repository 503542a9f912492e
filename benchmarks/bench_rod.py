"""Speed of the Cosserat rod step (``lie-verlet`` on the ``lattice`` scheme, SE(3)) and the
accuracy history of its energy error.

Speed: the T1 scene of ``benchmarks/compare.py`` (a free straight rod with PyElastica's
Timoshenko-beam material, a small smooth initial velocity, Δt = 0.5·dx/c), ``STEPS`` steps
per sample, along each path cartan offers:

* ``simulate`` — ``cartan.simulate`` whole (setup, blow-up guard, one saved frame);
* ``simulate-uncompiled`` — ``cartan.simulate(..., compiled=False)``, skipped (n/a) while
  ``simulate`` has no ``compiled`` option;
* ``step-loop`` — a bare loop of ``LieVerlet.step`` on a ``Lattice``;
* ``compiled-advance`` — ``Lattice.compiled_advance`` over all the steps (the scheme's
  compiled loop without ``simulate`` around it), skipped (n/a) when the scheme has none or
  declines the problem.

``RodStep`` runs every path at n = 10², 10³, 10⁴ and 10⁵ elements.  ``setup`` runs every
path once on the same rod, so that numba compilation (or loading its on-disk cache) never
lands inside a timing.

Work around the steps: ``SimulateSaves`` times ``cartan.simulate`` of the same rod at
n = 1000 over 2000 steps with ``save_every`` = 20, 100, 1000 and 2000 (the per-save cost
against the steps), and ``CFLEstimate`` the CFL estimate each run starts with, compiled and
numpy, at n = 10³ … 10⁵.

Accuracy: the butterfly rod (PyElastica's butterfly material, n = 11, an arc of curvature
0.5 released from rest): max relative energy error of ``lie-verlet`` over t ∈ [0, 1.2] and
the ratio of that error between Δt = 4e-3 and 2e-3 (≈ 4 for a second-order method).
"""

from __future__ import annotations

import inspect

import cartan

from .compare import cartan_problem, step_size, t1_velocity

STEPS = 20
#: :class:`SimulateSaves`: rod size and steps per run
SAVE_N = 1000
SAVE_STEPS = 2000

PATHS = ["simulate", "simulate-uncompiled", "step-loop", "compiled-advance"]

#: PyElastica's butterfly material (E, ν, radius, density)
BUTTERFLY = {"E": 1e4, "poisson": 0.5, "radius": 0.25, "density": 5000.0}


def _simulate(problem, dt: float, nsteps: int, **options):
    return cartan.simulate(problem, integrator="lie-verlet", scheme="lattice", dt=dt, t_end=nsteps * dt,
                           save_every=nsteps, progress=False, **options)


class RodStep:
    """``STEPS`` steps of ``lie-verlet`` on a free straight rod of ``n`` elements."""

    params = ([100, 1000, 10000, 100000], PATHS)
    param_names = ["n", "path"]
    number = 1
    repeat = (3, 10, 20.0)
    warmup_time = 0.0
    timeout = 600.0

    def setup(self, n, path):
        options = {}
        if path == "simulate-uncompiled":
            if "compiled" not in inspect.signature(cartan.simulate).parameters:
                raise NotImplementedError("cartan.simulate has no 'compiled' option")
            options["compiled"] = False
        self.problem = cartan_problem(n, t1_velocity(n))
        self.dt = step_size(n)
        self.options = options
        if path in ("step-loop", "compiled-advance"):
            self.scheme = cartan.registry("schemes")["lattice"](self.problem)
            self.integrator = cartan.registry("integrators")["lie-verlet"]()
            self.state = self.scheme.initial_state()
            if path == "compiled-advance":
                advance = getattr(self.scheme, "compiled_advance", None)
                if advance is None:
                    raise NotImplementedError("the lattice scheme has no compiled_advance")
                if not advance(self.integrator, self.state, self.dt, 2):  # compile or load the loop
                    raise NotImplementedError("Lattice.compiled_advance declines this problem")
            else:
                for _ in range(2):  # compile or load every kernel
                    self.integrator.step(self.scheme, self.state, self.dt)
        else:
            _simulate(self.problem, self.dt, 2, **options)

    def time_steps(self, n, path):
        if path == "step-loop":
            step, scheme, state, dt = self.integrator.step, self.scheme, self.state, self.dt
            for _ in range(STEPS):
                step(scheme, state, dt)
        elif path == "compiled-advance":
            self.scheme.compiled_advance(self.integrator, self.state, self.dt, STEPS)
        else:
            _simulate(self.problem, self.dt, STEPS, **self.options)


class SimulateSaves:
    """``cartan.simulate`` of the T1 rod at n = 1000 over ``SAVE_STEPS`` steps, saving every
    ``save_every`` steps: the per-save work (frame output, the guard's energy tests at the
    steps 1, 2, 4, 8, … of every save block) against the steps themselves."""

    params = ([20, 100, 1000, SAVE_STEPS],)
    param_names = ["save_every"]
    number = 1
    repeat = (3, 10, 20.0)
    warmup_time = 0.0

    def setup(self, save_every):
        self.problem = cartan_problem(SAVE_N, t1_velocity(SAVE_N))
        self.dt = step_size(SAVE_N)
        _simulate(self.problem, self.dt, 4)  # compile or load every kernel

    def time_simulate(self, save_every):
        cartan.simulate(self.problem, integrator="lie-verlet", scheme="lattice", dt=self.dt,
                        t_end=SAVE_STEPS * self.dt, save_every=save_every, progress=False)


class CFLEstimate:
    """The CFL estimate ``simulate`` computes once per run (``Scheme.dt_max``: a power iteration
    of force evaluations, compiled for lattice problems with a compiled plan; ``numpy``: the
    same with ``compiled_diagnostics = False``) on the T1 rod of ``n`` elements."""

    params = ([1000, 10000, 100000], ["compiled", "numpy"])
    param_names = ["n", "path"]
    number = 1
    repeat = (3, 10, 20.0)
    warmup_time = 0.0
    timeout = 600.0

    def setup(self, n, path):
        self.scheme = cartan.registry("schemes")["lattice"](cartan_problem(n, t1_velocity(n)))
        self.scheme.compiled_diagnostics = path == "compiled"
        self.state = self.scheme.initial_state()
        self.scheme.dt_max(self.state, iterations=1)  # compile or load the kernels

    def time_dt_max(self, n, path):
        self.scheme.dt_max(self.state)


# ---------------------------------------------------------------------------- butterfly energy
def _butterfly_energy_error(dt: float, t_end: float = 1.2) -> float:
    """max over the steps of |E(t) − E(0)| / E(0), lie-verlet on the lattice."""
    rod = cartan.medium("cosserat-rod", **BUTTERFLY)
    grid = cartan.Grid(11, length=3.0)
    problem = cartan.Problem(medium=rod, grid=grid,
                             initial=rod.initial_state(grid, "arc", curvature=0.5, centered=True))
    scheme = cartan.registry("schemes")["lattice"](problem)
    integrator = cartan.registry("integrators")["lie-verlet"]()
    state = scheme.initial_state()

    def energy():
        return scheme.kinetic_energy(state) + scheme.potential_energy(state)

    e0 = energy()
    worst = 0.0
    for _ in range(round(t_end / dt)):
        integrator.step(scheme, state, dt)
        worst = max(worst, abs(energy() - e0))
    return float(worst / e0)


def track_butterfly_energy_error():
    """Max relative energy error of lie-verlet on the butterfly rod, Δt = 4e-3, t ≤ 1.2."""
    return _butterfly_energy_error(4e-3)


track_butterfly_energy_error.unit = "relative"


def track_butterfly_energy_error_ratio():
    """e(Δt)/e(Δt/2) of that error, Δt = 4e-3: ≈ 4 for a second-order method."""
    return _butterfly_energy_error(4e-3) / _butterfly_energy_error(2e-3)


track_butterfly_energy_error_ratio.unit = "ratio"
