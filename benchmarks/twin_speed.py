"""A stiff Cosserat rod against its held-strain twin, the filament with ``rattle``: whole runs.

Run it as a script::

    python benchmarks/twin_speed.py [--sizes 11 41] [--repeat 9]

What ``cartan advise examples/stiff-rod-swing.toml --check`` times (docs/advise.md): the scene
``stiff-rod-swing`` (a clamped cosserat-rod, EA = GA = 1e6·B, released under gravity with light
damping) run with ``lie-verlet`` to t = 0.5, and its twin (``cartan.advise.held_strain_problem``,
the filament) run with ``rattle`` to the same time, each at half its CFL estimate (``simulate``'s
default), each saving the scene's own output as the check does: the rod every ``save_every`` steps
of the scene (1000), the twin at the same interval in time, to its nearest whole number of steps
(``--frames N`` saves N frames per run instead, the pilots' analysis sampling), through the
check's own runner (``cartan.advise._simulate``: ``cartan.simulate`` with ``reduce=False``, no
file).  A whole run
is the call to ``simulate``, from the problem to the Dataset: resolution of the run, steps,
frame records and Dataset assembly.  Each medium runs once untimed (a warm numba cache; the
first run of a machine compiles the loops), then ``--repeat`` rod/twin pairs in turn; the wall
and process CPU times of each run, their medians, the ratio of the medians (rod / twin) and the
range of the pairs' ratios.  On a shared machine the CPU time is the steadier measure; the load
average is printed with each table.  ``--sizes`` sets the grid (``[grid] n``) of the scene.
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

import numpy as np

import cartan
from cartan.advise import _simulate, held_strain_problem
from cartan.simulate import StabilityWarning, _resolve_run

SCENE = os.path.join(os.path.dirname(__file__), os.pardir, "examples", "stiff-rod-swing.toml")
#: the pilot's end time (the scene's t_end)
T_END = 0.5


def _dt(problem, integrator: str, scheme: str) -> float:
    """Half the CFL estimate of ``integrator`` on ``problem``: the Δt ``simulate`` picks."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StabilityWarning)
        run = _resolve_run(problem, integrator, scheme, None, T_END, None, None, None, None, None, None, False, 1e3,
                           compiled=True, command="", max_steps=None)
    return float(run.dt)


def cases(n: int) -> tuple:
    """``(rod problem, rod settings, twin problem, twin settings)`` of ``stiff-rod-swing`` on ``n`` nodes."""
    import tomllib

    with open(SCENE, "rb") as fh:
        spec = tomllib.load(fh)
    spec["grid"]["n"] = int(n)
    scene = cartan.load_scene(spec)
    rod = scene.problem
    settings = scene.run_settings()
    twin = held_strain_problem(rod)
    rs = {"integrator": settings["integrator"], "scheme": settings["scheme"]}
    rs["dt"] = _dt(rod, rs["integrator"], rs["scheme"])
    rs["save_every"] = int(settings.get("save_every") or 1)
    ts = {"integrator": "rattle", "scheme": "lattice"}
    ts["dt"] = _dt(twin, "rattle", "lattice")
    ts["save_every"] = max(1, round(rs["save_every"] * rs["dt"] / ts["dt"]))  # the same interval in time
    return rod, rs, twin, ts


def _timed(problem, settings) -> tuple[float, float, object]:
    s = dict(settings)
    every = s.pop("save_every", None)
    t0, c0 = time.perf_counter(), time.process_time()
    ds = _simulate(problem, s, T_END, save_every=every)
    return time.perf_counter() - t0, time.process_time() - c0, ds


def measure(n: int, repeat: int, frames: int | None = None) -> dict:
    """The whole runs' times at ``n`` nodes: medians, ratios (rod / twin) and steps; ``frames``
    saved frames per run (None: the scene's own output, as the check saves it)."""
    rod, rs, twin, ts = cases(n)
    if frames:
        for s in (rs, ts):
            s["save_every"] = max(1, round(T_END / s["dt"]) // int(frames))
    _timed(rod, rs)  # warm-up: compiled loops loaded, CFL estimates cached
    _timed(twin, ts)
    wall: dict = {"rod": [], "twin": []}
    cpu: dict = {"rod": [], "twin": []}
    for _ in range(max(1, repeat)):
        for name, prob, s in (("rod", rod, rs), ("twin", twin, ts)):
            w, c, ds = _timed(prob, s)
            wall[name].append(w)
            cpu[name].append(c)
            steps = int(ds["step"].values[-1])
            nframes = int(ds.sizes["time"])
    pairs_w = [a / b for a, b in zip(wall["rod"], wall["twin"], strict=True)]
    pairs_c = [a / b for a, b in zip(cpu["rod"], cpu["twin"], strict=True)]
    med = {f"{k}_{m}": float(np.median(v[k])) for m, v in (("wall", wall), ("cpu", cpu)) for k in v}
    return {"n": n, **med, "ratio_wall": med["rod_wall"] / med["twin_wall"],
            "ratio_cpu": med["rod_cpu"] / med["twin_cpu"], "range_wall": (min(pairs_w), max(pairs_w)),
            "range_cpu": (min(pairs_c), max(pairs_c)), "dt_rod": rs["dt"], "dt_twin": ts["dt"],
            "steps_twin": steps, "steps_rod": int(round(T_END / rs["dt"])), "frames": nframes}


def _load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[11, 41], help="grid sizes n of the scene")
    ap.add_argument("--repeat", type=int, default=9, help="timed rod/twin pairs (medians)")
    ap.add_argument("--frames", type=int, default=None,
                    help="saved frames per run (default: the scene's own output, as the check saves it)")
    args = ap.parse_args(argv)
    saves = f"{args.frames} frames per run" if args.frames else "the scene's own output"
    print(f"stiff-rod-swing (lie-verlet) against its filament twin (rattle), whole runs to t = {T_END} saving "
          f"{saves}; medians of {args.repeat} pairs")
    print(f"{'n':>4} {'steps rod/twin':>15} {'twin wall':>10} {'twin CPU':>9} {'rod wall':>9} {'rod CPU':>8} "
          f"{'ratio wall (range)':>20} {'ratio CPU (range)':>19} {'frames':>6} {'load':>16}")
    for n in args.sizes:
        load = _load()
        r = measure(n, args.repeat, args.frames)
        print(f"{n:>4} {r['steps_rod']:>8d}/{r['steps_twin']:<6d} {r['twin_wall']:>10.4f} {r['twin_cpu']:>9.4f} "
              f"{r['rod_wall']:>9.4f} {r['rod_cpu']:>8.4f} "
              f"{r['ratio_wall']:>6.2f} ({r['range_wall'][0]:.2f}–{r['range_wall'][1]:.2f}) "
              f"{r['ratio_cpu']:>6.2f} ({r['range_cpu'][0]:.2f}–{r['range_cpu'][1]:.2f}) {r['frames']:>6d} {load:>16}")
    print(f"load average after: {_load()}")


if __name__ == "__main__":
    main()
