"""Speed of the ``relativistic-rod`` step against the SE(3) rod's (docs/media/relativistic-rod.md, "Speed").

The goal: a compiled relativistic-rod step costs at most 2× per element what the SE(3) rod's
step costs, with the same integrator and n.  Cost per node-step on the ``lattice`` scheme,
``STEPS`` steps per sample (no saves), each problem run by the first compiled path
:func:`cartan.simulate` would take (the integrator's own blocks, the scheme's hand-written
loops, the integrator's generated loop):

================  ==================================================================  =========
case              problem                                                             nodes
================  ==================================================================  =========
``nambu-goto``    ``relativistic-rod`` circular Nambu–Goto loop (c = μ = 1), periodic,  n
                  released from rest (Poincaré group, r = 10)
``se3-rod``       ``cosserat-rod``: the T1 rod of ``benchmarks/compare.py`` (a free      n
                  straight rod, a small smooth velocity; SE(3), r = 6)
================  ==================================================================  =========

for the integrators with a compiled loop for the Nambu–Goto string (``lie-verlet``,
``lie-euler``, ``rkmk4``; ``implicit-midpoint`` needs a positive kinetic metric).  For
``lie-verlet`` the SE(3) rod has two compiled loops, the hand-written one
(``Lattice.compiled_advance``, what :func:`cartan.simulate` takes) and the generated one
(``se3-rod-gen``, the loop every other group runs): both are timed.  Δt = 0.1 of the
``lie-verlet`` CFL estimate for every case (the state stays smooth over all the repeats; the
cost of an explicit step does not depend on Δt).  ``RelativisticRatio.track_ratio`` times the
two cases in the same process, alternating, and reports the ratio of medians (PERFORMANCE.md:
ratios from one run).

The elastic string (``energy="elastic"``, a Lagrangian that couples N and X) runs on the
numpy path only (the compiled loops decline it): ``ElasticStep`` times one step of
``rkmk4`` and of ``implicit-midpoint`` on a spinning, stretched ring of ``n`` nodes.

``python benchmarks/bench_relativistic.py`` prints every number from one process.
"""

from __future__ import annotations

import math
import os
import time

import numpy as np

import cartan

STEPS = 20
#: samples per median
SAMPLES = 5
#: samples per case in :func:`main` (alternating between the cases)
MAIN_SAMPLES = 15
#: the integrators with a compiled loop for the Nambu–Goto string (``implicit-midpoint`` declines
#: its indefinite kinetic metric μ diag(−1, 1, 1, 1, 0₆))
INTEGRATORS = ["lie-verlet", "lie-euler", "rkmk4"]
CASES = ["nambu-goto", "se3-rod"]
SIZES = [1000, 10000]
#: the elastic string: ring sizes and integrators (numpy path)
ELASTIC_SIZES = [16, 64]
ELASTIC_INTEGRATORS = ["rkmk4", "implicit-midpoint"]


def _problem(case: str, n: int) -> cartan.Problem:
    """The case's problem with ``n`` nodes."""
    if case == "nambu-goto":
        medium = cartan.medium("relativistic-rod")
        grid = cartan.Grid(n, length=2 * math.pi, periodic=True)
        return cartan.Problem(medium, grid, medium.initial_state(grid, "loop"))
    if case == "se3-rod":
        try:
            from .compare import cartan_problem, t1_velocity
        except ImportError:  # run as a script
            from compare import cartan_problem, t1_velocity
        return cartan_problem(n - 1, t1_velocity(n - 1))  # n - 1 elements: n nodes
    if case == "elastic":
        medium = cartan.medium("relativistic-rod", energy="elastic", stiffness=0.1)
        grid = cartan.Grid(n, length=2 * math.pi, periodic=True)
        return cartan.Problem(medium, grid, medium.initial_state(grid, "ring", radius=1.3, spin=0.3076923076923077))
    raise ValueError(f"unknown case {case!r}; allowed: {', '.join([*CASES, 'elastic'])}")


class _Run:
    """``STEPS`` steps of ``integrator`` on a case, by the first compiled path that runs it
    (``generated``: skipping the scheme's hand-written loops; ``compiled=False``: the numpy
    path, one ``integrator.step`` at a time)."""

    def __init__(self, case: str, integrator: str, n: int, compiled: bool = True, generated: bool = False):
        problem = _problem(case, n)
        self.nodes = int(np.prod(problem.grid.shape))
        self.scheme = cartan.registry("schemes")["lattice"](problem)
        self.integrator = cartan.registry("integrators")[integrator]()
        self.state = self.scheme.initial_state()
        dt = float(cartan.registry("integrators")["lie-verlet"]().dt_max(self.scheme, self.state))
        if not 0 < dt < math.inf:
            raise NotImplementedError(f"{case}: no finite CFL estimate ({dt!r})")
        self.dt = 0.1 * dt
        if not compiled:
            self.path = "numpy"
            self.advance = self._numpy
            self.advance(2)
            return
        paths = []
        own = getattr(self.integrator, "compiled_advance", None)
        if own is not None:
            paths.append(("integrator", lambda k: own(self.scheme, self.state, self.dt, k, math.inf)))
        fast = getattr(self.scheme, "compiled_advance", None)
        if fast is not None and not generated:
            paths.append(("hand-written", lambda k: fast(self.integrator, self.state, self.dt, k)))
        generic = getattr(self.integrator, "run_compiled_loop", None)
        if generic is not None:
            paths.append(("generated", lambda k: generic(self.scheme, self.state, self.dt, k, math.inf)))
        for name, advance in paths:
            if advance(2):  # compile or load the loop
                self.path, self.advance = name, advance
                break
        else:
            raise NotImplementedError(f"{case} × {integrator}: no compiled loop runs this problem")

    def _numpy(self, steps: int) -> bool:
        for _ in range(steps):
            self.integrator.step(self.scheme, self.state, self.dt)
        return True

    def __call__(self, steps: int = STEPS) -> None:
        before = self.state.scalars.get("nstep", 0)
        self.advance(steps)
        done = self.state.scalars.get("nstep", 0) - before
        if done != steps:
            raise RuntimeError(f"the loop stopped after {done} of {steps} steps (a blow-up)")


def _median_time(run: _Run, samples: int = SAMPLES, steps: int = STEPS) -> float:
    """Median seconds per node-step over ``samples`` samples of ``steps`` steps."""
    times = []
    for _ in range(samples):
        t0 = time.perf_counter()
        run(steps)
        times.append(time.perf_counter() - t0)
    return float(np.median(times)) / (steps * run.nodes)


class RelativisticStep:
    """``STEPS`` compiled steps of one integrator on one case (divide by n × STEPS)."""

    params = (SIZES, CASES, INTEGRATORS)
    param_names = ["n", "case", "integrator"]
    number = 1
    repeat = (3, 10, 20.0)
    warmup_time = 0.0
    timeout = 900.0

    def setup(self, n, case, integrator):
        self.run = _Run(case, integrator, n)

    def time_steps(self, n, case, integrator):
        self.run(STEPS)


class RelativisticRatio:
    """Cost per node-step of the Nambu–Goto string over the SE(3) rod's, same integrator and n
    (the goal: ≤ 2)."""

    params = (SIZES, INTEGRATORS)
    param_names = ["n", "integrator"]
    number = 1
    repeat = 1
    timeout = 900.0
    unit = "ratio"

    def setup(self, n, integrator):
        self.pair = (_Run("nambu-goto", integrator, n), _Run("se3-rod", integrator, n))

    def track_ratio(self, n, integrator):
        string, rod = self.pair
        ratios = [_median_time(string, 3) / _median_time(rod, 3) for _ in range(3)]
        return float(np.median(ratios))


class ElasticStep:
    """One step of the elastic string on the numpy path (the compiled loops decline it)."""

    params = (ELASTIC_SIZES, ELASTIC_INTEGRATORS)
    param_names = ["n", "integrator"]
    number = 1
    repeat = (3, 5, 20.0)
    warmup_time = 0.0
    timeout = 900.0

    def setup(self, n, integrator):
        self.run = _Run("elastic", integrator, n, compiled=False)

    def time_step(self, n, integrator):
        self.run(1)

    def track_node_step(self, n, integrator):
        return _median_time(self.run, 3, 2) * 1e9

    track_node_step.unit = "ns"


def main() -> None:  # pragma: no cover - a report for the terminal
    """Print the cost per node-step of every case and the ratios, from one process."""
    print(f"load average at start: {os.getloadavg()}")
    for n in SIZES:
        for integ in INTEGRATORS:
            runs = {"nambu-goto": _Run("nambu-goto", integ, n), "se3-rod": _Run("se3-rod", integ, n)}
            if runs["se3-rod"].path == "hand-written":
                runs["se3-rod-gen"] = _Run("se3-rod", integ, n, generated=True)
            samples: dict[str, list[float]] = {k: [] for k in runs}
            for _ in range(MAIN_SAMPLES):  # alternate, so that all see the same load
                for k, run in runs.items():
                    samples[k].append(_median_time(run, 1))
            for stat, f in (("median", np.median), ("min", np.min)):  # (the minimum: least disturbed by load)
                cost = {k: float(f(v)) * 1e9 for k, v in samples.items()}
                line = f"n = {n:6d} {integ:11s} {stat:6s}"
                for k, run in runs.items():
                    line += f" {k} {cost[k]:8.1f} ns ({run.path})"
                ratios = "  ".join(f"nambu-goto/{k} {cost['nambu-goto'] / cost[k]:.2f}" for k in runs
                                   if k != "nambu-goto")
                print(f"{line}  {ratios}", flush=True)
    for n in ELASTIC_SIZES:
        for integ in ELASTIC_INTEGRATORS:
            run = _Run("elastic", integ, n, compiled=False)
            cost = _median_time(run, 3, 2)
            print(f"elastic n = {n:4d} {integ:18s} {cost * n * 1e3:8.2f} ms per step, {cost * 1e9:10.0f} ns per "
                  f"node-step (numpy path)", flush=True)
    print(f"load average at end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
