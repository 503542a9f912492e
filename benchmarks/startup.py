"""T6: start-up time of a cached install — ``import cartan`` and a first simulation.

Target (PERFORMANCE.md §2, T6): importing cartan and running a first simulation in a new
Python process takes ≤ 3 s when numba's cache is warm (``cartan warm``, run by
``make install``), i.e. no kernel is compiled.

Each sample is a fresh interpreter (``python -c ...``) that measures, with
``time.perf_counter``:

``import``
    ``import cartan`` (numpy, numba, xarray, the plugin registry, the numba kernels'
    dispatchers; nothing is compiled at import);
``first simulation``
    building the T1 rod of ``benchmarks/compare.py`` (n = 100 elements, PyElastica's
    Timoshenko-beam material, a small smooth velocity) and ``cartan.simulate`` of 100
    ``lie-verlet`` steps with the default saves (one frame per step) — loading every kernel
    it uses from the cache;

and reports the numba cache hits and misses over all cartan kernels (misses = signatures
compiled in that process; 0 from a warm cache).  The wall time of the whole child process
(interpreter start-up included) is measured by the parent.  One unmeasured child runs first,
so that a cold cache is filled before the samples.

Run it as a script::

    python benchmarks/startup.py [--reps 5] [--n 100] [--steps 100]

``benchmarks/compare.py`` reports the same measurement as T6, and the asv suite tracks it
(:class:`Startup`).
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib
import subprocess
import sys
import textwrap
import time
from collections.abc import Sequence

import numpy as np

TARGET = 3.0
ROOT = pathlib.Path(__file__).resolve().parents[1]

#: the child: import, build the T1 rod, simulate, report (JSON on the last line of stdout)
CHILD = textwrap.dedent(
    """
    import json, math, time
    t0 = time.perf_counter()
    import numpy as np
    import cartan
    t1 = time.perf_counter()
    n, steps = {n}, {steps}
    L, c = 3.0, math.sqrt(1e6 / 5000.0)
    rod = cartan.medium("cosserat-rod", E=1e6, G=1e4, radius=0.25, density=5000.0)
    grid = cartan.Grid(n + 1, length=L)
    s = np.linspace(0.0, 1.0, n + 1)
    v = 1e-2 * np.stack([np.cos(np.pi * s), 0.5 * np.cos(2 * np.pi * s), 0.25 * np.cos(3 * np.pi * s)], -1)
    init = rod.initial_state(grid, "straight")
    N = np.zeros((n + 1, 6))
    N[:, :3] = np.einsum("nji,nj->ni", np.asarray(init.Phi)[:, 1:, 1:], v)
    problem = cartan.Problem(rod, grid, cartan.InitialState(Phi=init.Phi, N=N))
    dt = 0.5 * (L / n) / c
    ds = cartan.simulate(problem, dt=dt, t_end=steps * dt, progress=False)
    t2 = time.perf_counter()
    assert int(ds.step[-1]) == steps
    from cartan.cli_cache import kernel_inventory
    kernels = kernel_inventory()
    print(json.dumps({{"import": t1 - t0, "simulation": t2 - t1, "frames": int(ds.sizes["time"]),
                      "hits": sum(k.hits for k in kernels), "misses": sum(k.misses for k in kernels)}}))
    """
)


def run_child(n: int = 100, steps: int = 100) -> dict[str, float]:
    """One fresh interpreter: its own timings (``import``, ``simulation``), the numba cache
    ``hits``/``misses`` and the parent's wall time of the whole process (``process``)."""
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", CHILD.format(n=int(n), steps=int(steps))],
                          capture_output=True, text=True, cwd=ROOT, timeout=1800)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"start-up child failed:\n{proc.stderr[-2000:]}")
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    out["process"] = wall
    out["total"] = out["import"] + out["simulation"]
    return out


def measure(reps: int = 5, n: int = 100, steps: int = 100, log=None) -> dict[str, np.ndarray]:
    """``reps`` fresh-process samples after one unmeasured child (which fills a cold cache).

    Returns
    -------
    dict of str → ndarray ``(reps,)``
        ``import``, ``simulation``, ``total`` (their sum), ``process`` (the child's wall time
        seen by the parent), ``hits``, ``misses``; plus ``warmup`` (the first child's
        ``process`` time, a 1-element array).
    """
    if reps < 1:
        raise ValueError(f"reps must be ≥ 1, got {reps}")
    first = run_child(n, steps)
    if log is not None:
        log(f"  warm-up child: {first['process']:.2f} s ({first['misses']} signature(s) compiled)")
    rows = []
    for k in range(reps):
        rows.append(run_child(n, steps))
        if log is not None:
            r = rows[-1]
            log(f"  sample {k + 1}/{reps}: import {r['import']:.2f} s, first simulation {r['simulation']:.2f} s, "
                f"process {r['process']:.2f} s, {r['misses']} compiled")
    out = {key: np.array([r[key] for r in rows], dtype=float)
           for key in ("import", "simulation", "total", "process", "hits", "misses")}
    out["warmup"] = np.array([first["process"]])
    return out


def summary(result: dict[str, np.ndarray]) -> str:
    med = {k: float(np.median(v)) for k, v in result.items()}
    verdict = "meets" if med["process"] <= TARGET else "misses"
    return (f"T6 start-up (medians of {len(result['total'])} fresh processes): import cartan {med['import']:.2f} s + "
            f"first simulation {med['simulation']:.2f} s = {med['total']:.2f} s; whole process "
            f"{med['process']:.2f} s ({verdict} the {TARGET:g} s target); numba signatures compiled per process: "
            f"{int(np.max(result['misses']))}")


# ---------------------------------------------------------------------------- asv
class Startup:
    """T6 in the asv suite: fresh-process start-up, medians of 3 samples (seconds)."""

    timeout = 1800.0

    def setup_cache(self):
        result = measure(reps=3)
        return {k: float(np.median(v)) for k, v in result.items()}

    def track_import(self, result):
        """``import cartan`` in a fresh process."""
        return result["import"]

    def track_first_simulation(self, result):
        """Building the T1 rod (n = 100) and 100 ``lie-verlet`` steps with default saves."""
        return result["simulation"]

    def track_process(self, result):
        """The whole fresh process (interpreter start, import, first simulation): T6."""
        return result["process"]

    def track_compiled_signatures(self, result):
        """numba signatures compiled in the process (0 from a warm cache)."""
        return result["misses"]

    track_import.unit = "seconds"
    track_first_simulation.unit = "seconds"
    track_process.unit = "seconds"
    track_compiled_signatures.unit = "signatures"


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reps", type=int, default=5, help="fresh-process samples (default 5)")
    ap.add_argument("--n", type=int, default=100, help="rod elements (default 100)")
    ap.add_argument("--steps", type=int, default=100, help="lie-verlet steps (default 100)")
    args = ap.parse_args(argv)
    for name in ("reps", "n", "steps"):
        if getattr(args, name) < 1:
            ap.error(f"--{name} must be ≥ 1")
    result = measure(args.reps, args.n, args.steps, log=print)
    print(summary(result))
    return 0 if math.isfinite(float(np.median(result["process"]))) else 1


if __name__ == "__main__":
    sys.exit(main())
