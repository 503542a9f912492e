"""T4 scaling: cost per element-step of the compiled step loops against the problem size,
with 1 and 2 threads (PERFORMANCE.md §2, T4).

Run it as a script::

    python benchmarks/scaling.py [--out DIR] [--quick]

Media and sizes (defaults):

rod    the free straight SE(3) rod of T1 (``benchmarks/compare.py``: PyElastica's
       Timoshenko-beam material, a small smooth initial velocity, Δt = 0.5·dx/c), n = 10⁴,
       10⁵, 10⁶ elements; the vectorised ``lie-verlet`` loop.
sigma  the sigma model on S² (SO(3) frames) on a periodic N × N grid, N = 128, 256, 512,
       1024, a smooth random field with a velocity (``"random-smooth"``), ``lie-verlet`` at a
       Courant number of 0.25; elements are the N² nodes.

Every case is advanced by ``Lattice.compiled_advance`` (the compiled loop, no saves) with
each thread count in turn (``cartan.use_threads``; a thread count above 1 takes effect only
from :data:`cartan._threads.MIN_NODES` nodes, or from ``--min-nodes``).  The cost per step is
the slope between a call of k steps and a call of 3k steps, so that what a call does once
(the rod loop's copies of the state into structure-of-arrays form and back) is left out;
k is chosen so that the short call takes about ``--seconds``.  Medians (and extremes) over
``--repeats`` alternating repetitions go to ``DIR/scaling.nc`` (every sample, CF attributes)
and ``DIR/scaling.png`` (cost per element-step against n, one line per medium × threads); a
table with the 2-thread speed-up and the cost relative to the smallest size is printed.
"""

from __future__ import annotations

import argparse
import datetime
import gc
import math
import os
import pathlib
import platform
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script from anywhere
    sys.path.insert(0, str(ROOT))

from benchmarks.compare import cartan_problem, step_size, t1_velocity  # noqa: E402

ROD_SIZES = (10_000, 100_000, 1_000_000)
SIGMA_SIDES = (128, 256, 512, 1024)
QUICK_ROD_SIZES = (10_000, 100_000)
QUICK_SIGMA_SIDES = (128, 256)
#: Courant number of the sigma-model runs (c = 1 on a unit box: Δt = 0.25·h)
SIGMA_COURANT = 0.25


# ---------------------------------------------------------------------------- cases
def rod_case(n: int):
    """``(scheme, state, integrator, Δt, elements)`` of the T1 rod with n elements."""
    import cartan

    scheme = cartan.registry("schemes")["lattice"](cartan_problem(n, t1_velocity(n)))
    return scheme, scheme.initial_state(), cartan.registry("integrators")["lie-verlet"](), step_size(n), n


def sigma_case(side: int):
    """``(scheme, state, integrator, Δt, elements)`` of the sigma model on a periodic
    ``side × side`` grid."""
    import cartan

    medium = cartan.medium("sigma-model", n=2, d=2)
    grid = cartan.Grid((side, side), 1.0, periodic=True)
    initial = medium.initial_state(grid, "random-smooth", amplitude=0.5, velocity_amplitude=0.3, seed=0)
    scheme = cartan.registry("schemes")["lattice"](cartan.Problem(medium, grid, initial))
    dt = SIGMA_COURANT * grid.spacing[0] / medium.wave_speed()
    return scheme, scheme.initial_state(), cartan.registry("integrators")["lie-verlet"](), dt, side * side


CASES: dict[str, Callable[[int], tuple]] = {"rod": rod_case, "sigma": sigma_case}


# ---------------------------------------------------------------------------- measurement
def _advance(scheme, integrator, state, dt: float, steps: int, threads: int) -> float:
    import cartan

    with cartan.use_threads(threads):
        t0 = time.perf_counter()
        # the compiled path cartan.simulate takes: the SE(3) rod's hand-written loop, else the
        # integrator's generated loop (the sigma model: its threaded build with threads > 1)
        if not (scheme.compiled_advance(integrator, state, dt, steps)
                or integrator.run_compiled_loop(scheme, state, dt, steps)):
            raise RuntimeError("no compiled loop runs the problem")
        return time.perf_counter() - t0


def measure_case(medium: str, size: int, threads: Sequence[int], repeats: int, seconds: float,
                 log=print) -> dict[str, Any]:
    """Seconds per step ``[threads, repeat]`` (the slope between k and 3k steps) and per call of
    k steps for one medium and size."""
    scheme, state, integrator, dt, elements = CASES[medium](size)
    for k in threads:  # compile or load the loops of every thread count
        _advance(scheme, integrator, state, dt, 2, k)
    one = min(_advance(scheme, integrator, state, dt, 2, threads[0]) for _ in range(2)) / 2
    steps = max(2, int(math.ceil(seconds / max(one, 1e-9))))
    slope = np.full((len(threads), repeats), np.nan)
    call = np.full((len(threads), repeats), np.nan)
    for rep in range(repeats):
        order = range(len(threads)) if rep % 2 == 0 else reversed(range(len(threads)))
        for j in order:
            short = _advance(scheme, integrator, state, dt, steps, threads[j])
            long = _advance(scheme, integrator, state, dt, 3 * steps, threads[j])
            slope[j, rep] = (long - short) / (2 * steps)
            call[j, rep] = short
    med = np.median(slope, axis=-1)
    log(f"  {medium} {elements:>9d} elements, {steps} + {3 * steps} steps: "
        + "; ".join(f"{k} thread{'s' if k > 1 else ''} {1e9 * m / elements:.1f} ns/element-step"
                    for k, m in zip(threads, med)))
    del scheme, state
    gc.collect()
    return {"seconds_per_step": slope, "seconds_per_call": call, "elements": elements, "steps": steps}


def build_dataset(results: list[tuple[str, int, dict[str, Any]]], threads: Sequence[int], repeats: int,
                  command: str, load: tuple[float, float]):
    import numba
    import xarray as xr

    import cartan
    from cartan import _threads

    per_step = np.stack([r["seconds_per_step"] for _, _, r in results])
    elements = np.array([r["elements"] for _, _, r in results])
    ds = xr.Dataset(
        {
            "seconds_per_step": (("case", "threads", "repeat"), per_step,
                                 {"long_name": "wall time per step (slope between k and 3k steps)", "units": "s"}),
            "seconds_per_call": (("case", "threads", "repeat"),
                                 np.stack([r["seconds_per_call"] for _, _, r in results]),
                                 {"long_name": "wall time of a call of k steps", "units": "s"}),
            "cost": (("case", "threads", "repeat"), per_step / elements[:, None, None],
                     {"long_name": "wall time per element-step", "units": "s"}),
        },
        coords={
            "case": [f"{m} {r['elements']}" for m, _, r in results],
            "medium": ("case", [m for m, _, _ in results]),
            "elements": ("case", elements, {"long_name": "elements (rod) or nodes (sigma model)"}),
            "size": ("case", np.array([s for _, s, _ in results]),
                     {"long_name": "rod elements or sigma-model grid side"}),
            "steps": ("case", np.array([r["steps"] for _, _, r in results]), {"long_name": "k"}),
            "threads": ("threads", np.asarray(threads)),
            "repeat": ("repeat", np.arange(repeats)),
        },
        attrs={
            "title": "cartan T4 scaling: compiled lie-verlet loops, cost per element-step",
            "Conventions": "CF-1.8",
            "history": f"{datetime.datetime.now(datetime.UTC).isoformat(timespec='seconds')}: {command}",
            "cartan_version": cartan.__version__,
            "numba_version": numba.__version__,
            "numba_threading_layer": _threading_layer(),
            "numba_num_threads": int(numba.config.NUMBA_NUM_THREADS),
            "min_nodes": int(_threads.MIN_NODES),
            "python": platform.python_version(),
            "machine": f"{platform.machine()} {platform.processor() or ''}".strip(),
            "load_average": f"{load[0]:.2f} at the start, {load[1]:.2f} at the end (1-minute averages)",
        },
    )
    return ds


def _threading_layer() -> str:
    import numba

    try:
        return str(numba.threading_layer())
    except ValueError:  # no parallel region has run
        return str(numba.config.THREADING_LAYER)


def plot(ds, path: pathlib.Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.0, 4.5))
    styles = {"rod": "o", "sigma": "s"}
    labels = {"rod": "SE(3) rod", "sigma": "sigma model on S², 2D"}
    for medium in dict.fromkeys(ds.medium.values):
        sel = ds.where(ds.medium == medium, drop=True)
        x = sel.elements.values
        for k in ds.threads.values:
            ns = 1e9 * sel.cost.sel(threads=k).values
            med = np.median(ns, axis=-1)
            err = [med - ns.min(axis=-1), ns.max(axis=-1) - med]
            ax.errorbar(x, med, yerr=err, marker=styles.get(str(medium), "o"), capsize=3,
                        linestyle="-" if k == 1 else "--",
                        label=f"{labels.get(str(medium), medium)}, {k} thread{'s' if k > 1 else ''}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("elements (rod) / nodes (sigma model)")
    ax.set_ylabel("ns per element-step")
    ax.set_title("T4: compiled lie-verlet step loops (median, min–max)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def table(ds, log=print) -> None:
    threads = [int(k) for k in ds.threads.values]
    head = ["medium", "elements"] + [f"ns/element-step, {k} thr" for k in threads]
    if len(threads) > 1:
        head.append(f"speed-up {threads[-1]}/{threads[0]}")
    head.append("cost / smallest (1 thr)")
    log("| " + " | ".join(head) + " |")
    log("|" + "---|" * len(head))
    for medium in dict.fromkeys(ds.medium.values):
        sel = ds.where(ds.medium == medium, drop=True)
        med = 1e9 * sel.cost.median("repeat")
        base = float(med.isel(case=0).sel(threads=threads[0]))
        for c in range(sel.sizes["case"]):
            row = [str(medium), f"{int(sel.elements.values[c]):,}"]
            row += [f"{float(med.isel(case=c).sel(threads=k)):.1f}" for k in threads]
            serial = float(med.isel(case=c).sel(threads=threads[0]))
            if len(threads) > 1:
                row.append(f"{serial / float(med.isel(case=c).sel(threads=threads[-1])):.2f}")
            row.append(f"{serial / base:.2f}")
            log("| " + " | ".join(row) + " |")


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=str(ROOT / "docs" / "performance"),
                    help="output directory (default: docs/performance)")
    ap.add_argument("--quick", action="store_true", help="the two smaller sizes of each medium, 3 repetitions")
    ap.add_argument("--rod-sizes", type=int, nargs="*", default=None, help="rod elements (default 1e4 1e5 1e6)")
    ap.add_argument("--sigma-sides", type=int, nargs="*", default=None,
                    help="sigma-model grid sides (default 128 256 512 1024)")
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2], help="thread counts (default 1 2)")
    ap.add_argument("--repeats", type=int, default=None, help="alternating repetitions (default 5; --quick 3)")
    ap.add_argument("--seconds", type=float, default=0.15, help="target duration of the short call (default 0.15 s)")
    ap.add_argument("--min-nodes", type=int, default=None,
                    help="threads from this many nodes (default: cartan._threads.MIN_NODES)")
    args = ap.parse_args(argv)
    import cartan
    from cartan import _threads

    if args.min_nodes is not None:
        _threads.MIN_NODES = int(args.min_nodes)
    for k in args.threads:
        _threads._validate(k, "--threads")
    rods = args.rod_sizes if args.rod_sizes is not None else (QUICK_ROD_SIZES if args.quick else ROD_SIZES)
    sides = args.sigma_sides if args.sigma_sides is not None else (QUICK_SIGMA_SIDES if args.quick else SIGMA_SIDES)
    repeats = args.repeats or (3 if args.quick else 5)
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    command = "python benchmarks/scaling.py " + " ".join(sys.argv[1:] if argv is None else argv)
    print(f"cartan {cartan.__version__}, Python {platform.python_version()}, {platform.machine()}; "
          f"threads {args.threads} from {_threads.MIN_NODES} nodes, {repeats} repetitions")
    start = time.perf_counter()
    load0 = os.getloadavg()[0]
    results = []
    for medium, sizes in (("rod", rods), ("sigma", sides)):
        for size in sizes:
            results.append((medium, int(size), measure_case(medium, int(size), args.threads, repeats, args.seconds)))
    ds = build_dataset(results, args.threads, repeats, command, (load0, os.getloadavg()[0]))
    ds.to_netcdf(out / "scaling.nc")
    plot(ds, out / "scaling.png")
    print()
    table(ds)
    print(f"\nthreading layer {ds.attrs['numba_threading_layer']}; load average {ds.attrs['load_average']} "
          "(threads pay only on idle cores)")
    print(f"wrote {out / 'scaling.nc'} and {out / 'scaling.png'} ({time.perf_counter() - start:.0f} s in all)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
