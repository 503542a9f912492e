"""The generated compiled loops against the hand-written ones (T8 of PERFORMANCE.md §2).

Cost per node-step of ``lie-verlet`` on the lattice, ``STEPS`` steps per sample (no saves),
for the problems the generated loops bring to compiled code and their quadratic twins on the
same group and grid, which the hand-written loops run:

=====================  ==========================================  =====================
case                   medium                                      loop
=====================  ==========================================  =====================
``so3-quadratic``      quadratic SO(3) chain, n = 1000, periodic   hand-written
``so3-quadratic-gen``  the same                                    generated
``so3-quartic``        ½DᵀCD + ¼β(DᵀD)², n = 1000                  generated
``se3-quadratic``      quadratic SE(3) surface, 64², periodic      hand-written
``se3-quadratic-gen``  the same                                    generated
``se3-coupled``        axis-coupled quartic SE(3) surface, 64²     generated
``s2-sigma``           sigma model on S² (SO(3)), 64²              hand-written
``so4-quadratic``      quadratic SO(4) medium, 64², periodic       generated
``s3-sigma``           sigma model on S³ (SO(4)), 64²              generated
=====================  ==========================================  =====================

The hand-written loops of these cases are retired (docs/design.md, "Decision (lattice)"):
the ``hand-written`` cases now fall through to the generated loop, so each measures what its
``-gen`` twin measures.  T8 compares a medium with a quadratic medium on the same group and grid, run the fastest
way cartan runs it: the hand-written loop where there is one (SO(3), SE(3)), else the
generated loop (SO(4) has only generated loops; its twin is ``so4-quadratic``).  The ratios
against the generated quadratic twins (``*-quadratic-gen``) separate what the medium costs
from what the generated loop costs.  ``track_ratio`` times a case and its twin in the same
process, alternating, and reports the ratio of medians (PERFORMANCE.md: ratios from one
run).  The toy media are those of the test suite (``tests/toys.py``).
"""

from __future__ import annotations

import pathlib
import sys
import time

import numpy as np

import cartan

ROOT = pathlib.Path(__file__).resolve().parents[1]
if str(ROOT / "tests") not in sys.path:
    sys.path.insert(0, str(ROOT / "tests"))

STEPS = 20
CASES = ["so3-quadratic", "so3-quadratic-gen", "so3-quartic", "se3-quadratic", "se3-quadratic-gen", "se3-coupled",
         "s2-sigma", "so4-quadratic", "s3-sigma"]
#: (case, twin) pairs of T8
PAIRS = (("so3-quadratic-gen", "so3-quadratic"), ("so3-quartic", "so3-quadratic"), ("so3-quartic", "so3-quadratic-gen"),
         ("se3-coupled", "se3-quadratic"), ("se3-coupled", "se3-quadratic-gen"), ("s3-sigma", "so4-quadratic"),
         ("s3-sigma", "s2-sigma"))


def _problem(case: str):
    from toys import CoupledQuartic, QuadraticMedium

    from cartan.problem import InitialState

    if case.startswith("s2") or case.startswith("s3"):
        medium = cartan.medium("sigma-model", n=2 if case.startswith("s2") else 3, d=2)
        grid = cartan.Grid((64, 64), 1.0, periodic=True)
        return cartan.Problem(medium, grid, medium.initial_state(grid, "random-smooth", seed=0))
    if case.startswith("so3"):
        medium = CoupledQuartic("SO3", d=1) if case == "so3-quartic" else QuadraticMedium("SO3")
        grid = cartan.Grid(1000, 1.0, periodic=True)
    elif case == "so4-quadratic":
        medium = QuadraticMedium("SO4")
        medium.material_dim, medium.separable_axes = 2, True
        medium._set_energy(np.eye(6)[:2], medium.C)
        grid = cartan.Grid((64, 64), 1.0, periodic=True)
    else:
        if case == "se3-coupled":
            medium = CoupledQuartic("SE3", d=2)
        else:
            medium = QuadraticMedium("SE3")
            medium.material_dim, medium.separable_axes = 2, True
            medium._set_energy(np.eye(6)[:2], medium.C)
        grid = cartan.Grid((64, 64), 1.0, periodic=True)
    G = medium.group
    u = np.stack(np.meshgrid(*[grid.coordinates(a) for a in range(grid.d)], indexing="ij"), axis=-1)
    wave = np.prod(np.sin(2 * np.pi * u), axis=-1)[..., None] * np.linspace(1.0, 0.5, G.dim)
    Phi = G.exp(0.01 * wave)  # a smooth wave on a uniformly prestrained body (periodic axes)
    return cartan.Problem(medium, grid, InitialState(Phi=Phi))


class _Run:
    """``STEPS`` compiled ``lie-verlet`` steps of a case, by the loop the case names."""

    def __init__(self, case: str, problem: cartan.Problem | None = None):
        problem = _problem(case) if problem is None else problem
        self.nodes = int(np.prod(problem.grid.shape))
        self.scheme = cartan.registry("schemes")["lattice"](problem)
        self.integrator = cartan.registry("integrators")["lie-verlet"]()
        self.state = self.scheme.initial_state()
        self.start(case)

    def start(self, case: str) -> None:
        """Choose the case's loop and run two steps (compiling it, or loading it from the cache)."""
        self.dt = 1e-5
        self.generated = case.endswith("-gen") or case in ("so3-quartic", "se3-coupled", "so4-quadratic", "s3-sigma")
        if not self():
            raise NotImplementedError(f"{case}: no compiled loop")

    def __call__(self, steps: int = 2) -> bool:
        if self.generated:
            return self.integrator.run_compiled_loop(self.scheme, self.state, self.dt, steps)
        # the hand-written loops take SE(3) rods only: the other cases fall through to the
        # generated loop (the twin then measures the same loop as its ``-gen`` case)
        return self.scheme.compiled_advance(self.integrator, self.state, self.dt, steps) or (
            self.integrator.run_compiled_loop(self.scheme, self.state, self.dt, steps))


class GeneratedLoops:
    """Time of ``STEPS`` steps per case (divide by nodes × STEPS for the cost per node-step)."""

    params = [CASES]
    param_names = ["case"]
    number = 1
    repeat = (3, 10, 20.0)
    warmup_time = 0.0
    timeout = 900.0

    def setup(self, case):
        self.run = _Run(case)

    def time_steps(self, case):
        self.run(STEPS)


def _median_time(run: _Run, samples: int) -> float:
    times = []
    for _ in range(samples):
        t0 = time.perf_counter()
        run(STEPS)
        times.append(time.perf_counter() - t0)
    return float(np.median(times)) / (STEPS * run.nodes)


class GeneratedRatio:
    """T8: cost per node-step of a generated case over its hand-written quadratic twin."""

    params = [[f"{case}/{twin}" for case, twin in PAIRS]]
    param_names = ["pair"]
    number = 1
    repeat = 1
    timeout = 900.0
    unit = "ratio"

    def setup(self, pair):
        case, twin = pair.split("/")
        self.pair = (_Run(case), _Run(twin))

    def track_ratio(self, pair):
        generated, handwritten = self.pair
        ratios = [_median_time(generated, 3) / _median_time(handwritten, 3) for _ in range(3)]
        return float(np.median(ratios))


def main() -> None:  # pragma: no cover - a report for the terminal
    """Print the cost per node-step of every case and the T8 ratios, from one process."""
    runs = {case: _Run(case) for case in CASES}
    cost = {case: _median_time(run, 5) * 1e9 for case, run in runs.items()}
    for case in CASES:
        print(f"{case:20s} {cost[case]:8.1f} ns per node-step")
    for gen, twin in PAIRS:
        print(f"T8 {gen} / {twin}: {cost[gen] / cost[twin]:.2f}")


if __name__ == "__main__":
    main()
