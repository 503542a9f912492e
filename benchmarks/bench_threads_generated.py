"""T4 with threads: the generated compiled loops' threaded build against their serial build.

Cost per node-step of compiled ``lie-verlet`` (no saves) with 1 and 2 threads
(``cartan.use_threads``; docs/performance.md, "Threads") for media that run the generated loops
(:mod:`cartan.integrators.loops` over the lattice's operators, :mod:`cartan.schemes._lattice_ops`):

===========  ===============================================================  ====================
case         problem                                                          sizes
===========  ===============================================================  ====================
``surface``  ``cosserat-surface`` plate (E = 1, ν = 0.3, thickness 0.05), a     N × N, N = 128, 256,
             smooth transverse velocity, free edges, Δt = 0.1 h/c             512
``rod``      an SE(3) rod with the axis-coupled quartic energy                n = 10⁴, 10⁵, 10⁶
             ``½DᵀCD + ¼β(DᵀD)²`` (``toys.CoupledQuartic``, d = 1, periodic),
             a smooth wave, Δt = 10⁻⁵ h
===========  ===============================================================  ====================

The cost per step is the slope between a call of k and a call of 3k steps (what a call does
once — packing the state, building the threaded passes' incidence lists — is left out); the
thread counts alternate within each repetition and the medians over ``--repeats`` are
reported with the 2-thread speed-up.  The 1-minute load average before and after is printed:
on a shared machine the speed-up is only meaningful at a low load.

Run it as a script::

    python benchmarks/bench_threads_generated.py [--cases surface,rod] [--sizes ...] [--repeats 5]

The asv class :class:`ThreadedGeneratedLoops` times ``STEPS`` steps of the smallest sizes.
"""

from __future__ import annotations

import argparse
import math
import os
import pathlib
import sys
import time
from collections.abc import Callable, Sequence

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
for _p in (ROOT, ROOT / "tests"):
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))

import cartan  # noqa: E402

SURFACE_SIDES = (128, 256, 512)
ROD_SIZES = (10_000, 100_000, 1_000_000)
STEPS = 10


def surface_case(side: int) -> tuple:
    """``(scheme, state, integrator, Δt, nodes)``: a free ``cosserat-surface`` plate of
    ``side × side`` nodes with a smooth transverse velocity."""
    medium = cartan.medium("cosserat-surface", E=1.0, poisson=0.3, thickness=0.05, density=1.0)
    grid = cartan.Grid((side, side), length=(1.0, 1.0))
    from cartan.problem import InitialState

    flat = medium.initial_state(grid, "flat")
    u = np.stack(np.meshgrid(*[grid.coordinates(a) for a in range(2)], indexing="ij"), axis=-1)
    N = np.zeros((side, side, medium.group.dim))
    N[..., 2] = 1e-3 * np.sin(np.pi * u[..., 0]) * np.sin(np.pi * u[..., 1])  # a transverse velocity
    scheme = cartan.registry("schemes")["lattice"](cartan.Problem(medium, grid, InitialState(Phi=flat.Phi, N=N)))
    state = scheme.initial_state()
    h = min(grid.spacing)
    c = float(np.sqrt(1.0 / 1.0))  # √(E/ρ)
    return scheme, state, cartan.registry("integrators")["lie-verlet"](), 0.1 * h / c, side * side


def rod_case(n: int) -> tuple:
    """``(scheme, state, integrator, Δt, nodes)``: a periodic SE(3) rod of n nodes with the
    axis-coupled quartic energy (a non-quadratic medium: the generated loops)."""
    from toys import CoupledQuartic

    from cartan.problem import InitialState

    medium = CoupledQuartic("SE3", d=1)
    grid = cartan.Grid(n, 1.0, periodic=True)
    G = medium.group
    u = grid.coordinates(0)
    wave = np.sin(2 * np.pi * u)[:, None] * np.linspace(1.0, 0.5, G.dim)
    problem = cartan.Problem(medium, grid, InitialState(Phi=G.exp(0.01 * wave)))
    scheme = cartan.registry("schemes")["lattice"](problem)
    return scheme, scheme.initial_state(), cartan.registry("integrators")["lie-verlet"](), 1e-5 / n, n


CASES: dict[str, Callable[[int], tuple]] = {"surface": surface_case, "rod": rod_case}
SIZES = {"surface": SURFACE_SIDES, "rod": ROD_SIZES}


def _cpu_times() -> tuple[float, float]:
    """(idle, total) jiffies of the machine (``/proc/stat``)."""
    with open("/proc/stat") as fh:
        values = [float(v) for v in fh.readline().split()[1:]]
    return values[3] + values[4], sum(values)


def wait_idle(fraction: float, timeout: float = 120.0, window: float = 0.3) -> float:
    """Wait (up to ``timeout`` s) until the machine's cores were idle for at least ``fraction``
    of a ``window`` (other processes' load), and return the idle fraction last seen (1 where
    ``/proc/stat`` is missing)."""
    if fraction <= 0.0 or not os.path.exists("/proc/stat"):
        return 1.0
    end = time.monotonic() + timeout
    while True:
        i0, t0 = _cpu_times()
        time.sleep(window)
        i1, t1 = _cpu_times()
        idle = (i1 - i0) / max(t1 - t0, 1e-9)
        if idle >= fraction or time.monotonic() > end:
            return idle


def thread_cpu() -> dict[int, float]:
    """CPU seconds (user + system) of each thread of this process (``/proc/self/task``; empty
    where it is missing), at the kernel's clock-tick resolution."""
    tick = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
    out: dict[int, float] = {}
    root = pathlib.Path("/proc/self/task")
    if not root.exists():
        return out
    for task in root.iterdir():
        try:
            fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        out[int(task.name)] = (float(fields[11]) + float(fields[12])) / tick
    return out


def advance(scheme, integrator, state, dt: float, steps: int, threads: int) -> tuple[float, float, float]:
    """``(wall, busiest, total)``: the wall time of ``steps`` steps in the generated loop with
    ``threads`` threads, the CPU time of its busiest thread and of all threads."""
    with cartan.use_threads(threads):
        c0 = thread_cpu()
        t0 = time.perf_counter()
        if not integrator.run_compiled_loop(scheme, state, dt, steps):
            raise RuntimeError("the generated loop does not run this problem")
        wall = time.perf_counter() - t0
        c1 = thread_cpu()
    used = [c1[k] - c0.get(k, 0.0) for k in c1]
    return wall, max(used, default=float("nan")), float(sum(used))


def measure(case: str, size: int, threads: Sequence[int] = (1, 2), repeats: int = 5, seconds: float = 1.0,
            idle: float = 0.0, idle_timeout: float = 30.0, log=print) -> dict:
    """Median seconds per node-step (slopes between k and 3k steps) of a case: ``{"wall": {threads:
    cost}, "busiest": …, "cpu": …}`` — wall time, the busiest thread's CPU time, all threads' CPU time;
    with ``idle`` > 0 each sample waits until the cores were idle for that fraction of a short
    window (:func:`wait_idle`: on a shared machine, samples taken beside other jobs)."""
    scheme, state, integrator, dt, nodes = CASES[case](size)
    for k in threads:  # compile or load each build
        advance(scheme, integrator, state, dt, 2, k)
    one = min(advance(scheme, integrator, state, dt, 2, threads[0])[0] for _ in range(2)) / 2
    steps = max(2, int(math.ceil(seconds / max(one, 1e-9))))
    # [threads, repeat, (wall, busiest thread's CPU, all threads' CPU)] per node-step
    slope = np.full((len(threads), repeats, 3), np.nan)
    seen: list[float] = []
    for rep in range(repeats):
        order = list(range(len(threads))) if rep % 2 == 0 else list(reversed(range(len(threads))))
        for j in order:
            seen.append(wait_idle(idle, idle_timeout))
            short = np.array(advance(scheme, integrator, state, dt, steps, threads[j]))
            long = np.array(advance(scheme, integrator, state, dt, 3 * steps, threads[j]))
            slope[j, rep] = (long - short) / (2 * steps) / nodes
    med = np.median(slope, axis=1)
    cost = {k: float(m) for k, m in zip(threads, med[:, 0])}
    log(f"{case:8s} {nodes:>9d} nodes  k = {steps:4d}  " + "  ".join(
        f"{k} thr {1e9 * cost[k]:8.1f} ns (min {1e9 * np.min(slope[j, :, 0]):.1f}, "
        f"max {1e9 * np.max(slope[j, :, 0]):.1f}; CPU busiest {1e9 * med[j, 1]:.1f}, all {1e9 * med[j, 2]:.1f})"
        for j, k in enumerate(threads))
        + (f"  speed-up {cost[threads[0]] / cost[threads[-1]]:.2f}× (busiest-thread CPU: "
           f"{med[0, 2] / med[-1, 1]:.2f}×)" if len(threads) > 1 else "")
        + (f"  idle before samples {min(seen):.2f}–{max(seen):.2f}" if idle > 0 else ""))
    return {"wall": cost, "busiest": dict(zip(threads, med[:, 1])), "cpu": dict(zip(threads, med[:, 2]))}


class ThreadedGeneratedLoops:
    """asv: ``STEPS`` steps of the smallest case of each medium with 1 and 2 threads (divide by
    nodes × STEPS for the cost per node-step)."""

    params = [["surface", "rod"], [1, 2]]
    param_names = ["case", "threads"]
    number = 1
    repeat = (3, 10, 20.0)
    timeout = 1800.0

    def setup(self, case, threads):
        if threads > cartan._threads.max_threads():
            raise NotImplementedError("numba has fewer threads")
        self.args = CASES[case](SIZES[case][0])
        advance(*self.args[:4], 2, threads)

    def time_steps(self, case, threads):
        advance(*self.args[:4], STEPS, threads)


def main(argv: Sequence[str] | None = None) -> None:  # pragma: no cover - a report for the terminal
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", default="surface,rod")
    parser.add_argument("--sizes", default="", help="comma-separated sizes (default: each case's list)")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=1.0, help="target duration of the short call")
    parser.add_argument("--idle", type=float, default=0.0,
                        help="before each sample, wait until the cores were idle for this fraction of 0.3 s")
    parser.add_argument("--idle-timeout", type=float, default=30.0, help="longest wait for --idle (s)")
    args = parser.parse_args(argv)
    print(f"load average {os.getloadavg()[0]:.2f} (1 min) at the start; numba threads "
          f"{cartan._threads.max_threads()}")
    for case in args.cases.split(","):
        sizes = [int(s) for s in args.sizes.split(",")] if args.sizes else SIZES[case]
        for size in sizes:
            measure(case, size, repeats=args.repeats, seconds=args.seconds, idle=args.idle,
                    idle_timeout=args.idle_timeout)
    print(f"load average {os.getloadavg()[0]:.2f} (1 min) at the end")


if __name__ == "__main__":
    main()
