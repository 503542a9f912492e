"""Speed of one compiled ``lie-verlet`` step loop of the plugin media.

Cost per node-step on the ``lattice`` scheme, ``STEPS`` steps per sample (no saves), each
medium run by the first compiled path :func:`cartan.simulate` would take (the integrator's
own blocks, the scheme's hand-written loops, the integrator's generated loop):

====================  ==============================================================  ==============
case                  problem                                                         nodes
====================  ==============================================================  ==============
``surface-plate``     ``cosserat-surface`` flat plate 1 × 1, h = 0.05, clamped along  32 × 32
                      u = 0, under gravity
``solid-block``       ``cosserat-solid`` block 1 × 1 × 1 (default constants), clamped  12 × 12 × 12
                      at u = 0, released from a 0.1 % stretch along u
``relativistic-loop`` ``relativistic-rod`` circular Nambu–Goto loop (c = μ = 1),      256
                      periodic, released from rest
====================  ==============================================================  ==============

``setup`` builds the scheme and runs two steps, so that numba compilation (or loading its
on-disk cache) never lands inside a timing; Δt is a tenth of the integrator's CFL estimate
(``dt_max``), so that the state stays smooth over every repeat.  ``MediaStep.time_steps`` times
``STEPS`` steps; ``MediaStep.track_node_step`` reports the median cost per node-step in
nanoseconds over ``SAMPLES`` samples (a number comparable across media and sizes: the
performance goals are stated per node, PERFORMANCE.md).

``python benchmarks/bench_media.py --t9`` measures T9 in one process (:func:`t9`): the T1 rod
(n = 1000) on its hand-written structure-of-arrays loop and on the generated loop, the
cosserat-surface plate at 64², the cosserat-solid periodic box at 16³
(:func:`bench_solid.solid_problem`) and the relativistic Nambu–Goto loop at 512 nodes, each on
the generated ``lie-verlet`` loop, timed in turn (CPU time) for ``--rounds`` rounds; it prints
the medians over the rounds and their ratios to the rod's SoA loop.
"""

from __future__ import annotations

import math

import cartan

try:  # a module of the benchmarks package (asv)
    from . import bench_generated as _generated
except ImportError:  # run as a script
    import bench_generated as _generated

STEPS = _generated.STEPS
SAMPLES = 5
CASES = ["surface-plate", "solid-block", "relativistic-loop"]


def _problem(case: str, size: int | None = None) -> cartan.Problem:
    """The case's problem (``size``: nodes per axis instead of the table's)."""
    from cartan.problem import Clamped

    if case == "surface-plate":
        medium = cartan.medium("cosserat-surface", E=1.0, poisson=0.3, thickness=0.05, density=1.0)
        grid = cartan.Grid((size or 32, size or 32), length=(1.0, 1.0))
        loads = [medium.make_load("gravity", g=[0.0, 0.0, -1e-3])]
        return cartan.Problem(medium, grid, medium.initial_state(grid, "flat"), {"u-start": Clamped()}, loads)
    if case == "solid-block":
        medium = cartan.medium("cosserat-solid")
        grid = cartan.Grid((12, 12, 12), length=(1.0, 1.0, 1.0))
        return cartan.Problem(medium, grid, medium.initial_state(grid, "stretch", stretch=(1.001, 1.0, 1.0)),
                              {"u-start": Clamped()})
    if case == "relativistic-loop":
        medium = cartan.medium("relativistic-rod")
        grid = cartan.Grid(size or 256, length=2 * math.pi, periodic=True)
        return cartan.Problem(medium, grid, medium.initial_state(grid, "loop"))
    raise ValueError(f"unknown case {case!r}; allowed: {', '.join(CASES)}")


class _Run(_generated._Run):
    """``STEPS`` compiled ``lie-verlet`` steps of a case, by the first compiled path that runs it."""

    def __init__(self, case: str):
        super().__init__(case, _problem(case))

    def start(self, case: str) -> None:
        """Δt = 0.1 of the CFL estimate; the first compiled path that runs two steps."""
        self.dt = 0.1 * float(self.integrator.dt_max(self.scheme, self.state))
        if not 0 < self.dt < math.inf:
            raise NotImplementedError(f"{case}: no finite CFL estimate ({self.dt / 0.1!r})")
        paths = []
        own = getattr(self.integrator, "compiled_advance", None)
        if own is not None:
            paths.append(("integrator", lambda n: own(self.scheme, self.state, self.dt, n, math.inf)))
        fast = getattr(self.scheme, "compiled_advance", None)
        if fast is not None:
            paths.append(("hand-written", lambda n: fast(self.integrator, self.state, self.dt, n)))
        generic = getattr(self.integrator, "run_compiled_loop", None)
        if generic is not None:
            paths.append(("generated", lambda n: generic(self.scheme, self.state, self.dt, n, math.inf)))
        for name, advance in paths:
            if advance(2):  # compile or load the loop
                self.path, self.advance = name, advance
                break
        else:
            raise NotImplementedError(f"{case}: no compiled loop runs this problem")

    def __call__(self, steps: int = STEPS) -> None:
        before = self.state.scalars.get("nstep", 0)
        self.advance(steps)
        done = self.state.scalars.get("nstep", 0) - before
        if done != steps:
            raise RuntimeError(f"the compiled loop stopped after {done} of {steps} steps (a blow-up)")


class MediaStep(_generated.GeneratedLoops):
    """One compiled step loop per medium: ``STEPS`` steps (the asv settings and ``time_steps`` of
    the generated-loop benchmarks), and the cost per node-step."""

    params = [CASES]

    def setup(self, case):
        self.run = _Run(case)

    def track_node_step(self, case):
        return _generated._median_time(self.run, SAMPLES) * 1e9

    track_node_step.unit = "ns"


def t9(rounds: int = 5) -> dict[str, float]:  # pragma: no cover - a report for the terminal
    """T9 in one process: ns per node-step (CPU time) of the T1 rod on its SoA loop and on the
    generated loop, the 64² surface plate, the 16³ solid box and the 512-node Nambu–Goto loop
    (generated ``lie-verlet`` loops), each the median over ``rounds`` rounds in which every case
    runs in turn (``bench_solid.Run.node_step``: the median of its samples); printed with the
    ratios to the rod's SoA loop, and returned."""
    import bench_solid

    rod, rod_dt = bench_solid.rod_problem()
    runs = {"rod SoA": bench_solid.Run(rod, rod_dt, hand_written=True), "rod generated": bench_solid.Run(rod, rod_dt),
            "surface 64^2": bench_solid.Run(_problem("surface-plate", 64)),
            "solid 16^3": bench_solid.Run(bench_solid.solid_problem(16)),
            "relativistic 512": bench_solid.Run(_problem("relativistic-loop", 512))}
    steps = {"rod SoA": 200, "rod generated": 50, "relativistic 512": 40}
    samples: dict[str, list[float]] = {name: [] for name in runs}
    for _ in range(rounds):
        for name, run in runs.items():
            samples[name].append(run.node_step(steps.get(name, 10), 3))
    cost = {name: float(sorted(v)[len(v) // 2]) for name, v in samples.items()}
    for name, v in cost.items():
        rounds_ = ", ".join(f"{x:.0f}" for x in samples[name])
        print(f"{name:18s} {runs[name].nodes:6d} nodes  {v:8.1f} ns per node-step  "
              f"{v / cost['rod SoA']:5.2f}× the rod's SoA loop  (rounds: {rounds_})")
    return cost


def main() -> None:  # pragma: no cover - a report for the terminal
    """Print the compiled path and the cost per node-step of every case (``--t9``: :func:`t9`)."""
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--t9", action="store_true", help="T9 in one process (see the module docstring)")
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    if args.t9:
        t9(args.rounds)
        return
    for case in CASES:
        run = _Run(case)
        cost = _generated._median_time(run, SAMPLES) * 1e9
        print(f"{case:20s} {run.nodes:6d} nodes  {run.path:12s} {cost:8.1f} ns per node-step")


if __name__ == "__main__":
    main()
