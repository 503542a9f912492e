"""The inextensible filament (``rattle``) against the stiff Cosserat rod (``lie-verlet``).

Run it as a script::

    python benchmarks/filament_speed.py [--quick]

Two tables, from a warm numba cache (a first run compiles the loops, untimed):

Step cost
    µs per step of the filament (B₂ = 1, B₃ = 1.5, C = 0.8, ρA = 1, ρI = 0.01, L = 1, clamped,
    3-D tip wrench) with ``rattle`` compiled (:mod:`cartan.integrators.rattle_loop`; with its
    trial free flows per step over the timed steps) and in Python (``Rattle.step``), and of
    the cosserat-rod with the same bending, twist and inertia
    and EA = GA = 1e6·B with ``lie-verlet`` compiled (the lattice's hand-written loop, what
    ``cartan.simulate`` runs), at n = 11, 21, 41, 81 nodes; and each medium's time step, half
    its CFL estimate (``simulate``'s default).

Relaxation to the elastica
    The registered scene ``filament-elastica`` (n = 41, B = C = 1, L = 1, clamped, dead tip
    force 2B/L² along −y) reached by damped dynamic relaxation from the straight rod: the
    filament with compiled ``rattle`` against the cosserat-rod with EA = GA = 1e6·B with
    compiled ``lie-verlet``, the same inertia (ρA = 1, ρI = ρJ = 0.01) and the same damping Γ
    (the default, 7 on the translations and 0.07 on the rotations: ≈ twice the lowest
    bending frequency times the inertia, near critical for the slowest mode), each at half its
    CFL estimate.  The error is the relative tip error ``|x_tip − x*|/|x* − x_tip,0|``, x* the
    filament's static equilibrium on the same lattice (``cartan.solve_static``; the stiff rod's
    own equilibrium differs from it by O(P/EA) = 2e-6).  A first, untimed run records the
    error every ``CHECK`` time units and finds the step count after which it stays below 1e-4;
    then timed runs, ``--repeat`` of each medium taken in turn (filament, rod, filament, …), take
    exactly that many steps in one compiled call (warm cache, no saves, no guard): the wall
    time and the process CPU time of the steps alone, their medians, and the ratios of the
    medians.  On a shared machine the CPU time is the steadier measure (a process waiting for
    a core accrues none); the load average (``os.getloadavg``) is printed with the table, and
    ``rattle``'s trial free flows per step (1 + the multipliers' iterations per step).
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

import cartan
from cartan.integrators import LieVerlet, Rattle
from cartan.schemes import Lattice

TIP = [0.0, -2.0, 0.5, 0.2, 0.0, 0.0]
#: the error is recorded every CHECK time units of the untimed run
CHECK = 0.02


def _filament(bending=(1.0, 1.5), twist=0.8):
    return cartan.medium("filament", bending=bending, twist=twist, rotational_inertia=0.01)


def _stiff_rod(bending=(1.0, 1.5), twist=0.8, ratio=1e6):
    b = np.broadcast_to(np.asarray(bending, dtype=float), (2,))
    ea = ratio * float(np.min(b))
    return cartan.medium("cosserat-rod", stretch_shear=[ea, ea, ea], bend_twist=[twist, b[0], b[1]], mass=1.0,
                         rotational_inertia=[0.01] * 3)


def _problem(medium, n: int, load, loads=()):
    grid = cartan.Grid(n, length=1.0)
    return cartan.Problem(medium, grid, medium.initial_state(grid, "straight"),
                          {"start": cartan.Clamped(), "end": cartan.Free(load=list(load), follower=False)},
                          loads=list(loads))


def _advance(sch, integ, state, dt: float, nsteps: int) -> None:
    """``nsteps`` compiled steps, the way ``cartan.simulate`` takes them (the scheme's
    hand-written loop, else the integrator's generated loop)."""
    if sch.compiled_advance(integ, state, dt, nsteps):
        return
    if not integ.run_compiled_loop(sch, state, dt, nsteps):
        raise RuntimeError(f"{integ.name} on {sch.medium.name}: no compiled loop "
                           f"({getattr(integ, 'compiled_declined', None)})")


def _setup(prob, integ):
    sch = Lattice(prob)
    state = sch.initial_state()
    state.scalars["nstep"] = 0
    dt = 0.5 * float(integ.dt_max(sch, state))
    return sch, state, dt


def _per_step(make, integ_cls, compiled: bool, steps: int, repeat: int = 3) -> tuple[float, float, float]:
    """(µs per step, Δt, trial free flows per step): the median over ``repeat`` blocks of
    ``steps`` steps after a warm-up; the trial flows (1 + the multipliers' iterations per step,
    ``rattle`` only, else 1) over all the timed steps."""
    integ = integ_cls()
    sch, state, dt = _setup(make(), integ)
    run = (lambda k: _advance(sch, integ, state, dt, k)) if compiled else (
        lambda k: [integ.step(sch, state, dt) for _ in range(k)])
    run(2)
    times = []
    niter0 = getattr(integ, "niter", 0)
    for _ in range(repeat):
        t0 = time.perf_counter()
        run(steps)
        times.append((time.perf_counter() - t0) / steps)
    flows = 1.0 + (getattr(integ, "niter", 0) - niter0) / (repeat * steps)
    return 1e6 * float(np.median(times)), dt, flows


def step_costs(sizes) -> list[dict]:
    rows = []
    for n in sizes:
        fil = lambda n=n: _problem(_filament(), n, TIP)  # noqa: E731
        rod = lambda n=n: _problem(_stiff_rod(), n, TIP)  # noqa: E731
        c, dt_f, flows = _per_step(fil, Rattle, True, steps=2000)
        p, _, _ = _per_step(fil, Rattle, False, steps=max(5, 400 // n), repeat=2)
        r, dt_r, _ = _per_step(rod, LieVerlet, True, steps=20000)
        rows.append({"n": n, "rattle_compiled_us": c, "flows": flows, "rattle_python_us": p, "speedup": p / c,
                     "rod_lie_verlet_us": r, "dt_filament": dt_f, "dt_rod": dt_r, "dt_ratio": dt_f / dt_r})
    return rows


def _tip(sch, state) -> np.ndarray:
    return np.asarray(sch.frames(state))[-1, 1:4, 0]


def relaxation(damping=(7.0, 7.0, 7.0, 0.07, 0.07, 0.07), tol: float = 1e-4, t_max: float = 15.0,
               repeat: int = 3) -> list[dict]:
    sc = cartan.scene("filament-elastica")
    base = sc.problem
    load = np.asarray(base.boundary(0, "end").load, dtype=float)
    fil = base.medium
    n = int(base.grid.shape[0])
    static = cartan.solve_static(_problem(fil, n, load), load_steps=2, tol=1e-12)
    x_ref = np.asarray(static["position"].values[-1, -1])
    x0 = np.array([1.0, 0.0, 0.0])
    scale = float(np.linalg.norm(x_ref - x0))
    rod = _stiff_rod(bending=fil.parameters()["bending"], twist=fil.parameters()["twist"])
    cases = []
    for name, medium, integ_cls in (("filament, rattle", fil, Rattle),
                                    ("cosserat-rod EA=GA=1e6·B, lie-verlet", rod, LieVerlet)):
        prob = _problem(medium, n, load, loads=[cartan.Damping(list(damping))])
        integ = integ_cls()
        sch, state, dt = _setup(prob, integ)
        # untimed: the error every CHECK time units up to t_max; the last crossing of tol
        every = max(1, int(round(CHECK / dt)))
        nmax = int(t_max / dt) // every * every
        last_bad = 0
        k = 0
        while k < nmax:
            _advance(sch, integ, state, dt, every)
            k += every
            err = float(np.linalg.norm(_tip(sch, state) - x_ref)) / scale
            if err > tol:
                last_bad = k
        final_err = err
        if final_err > tol or last_bad >= nmax:
            raise RuntimeError(f"{name}: the tip error is {final_err:.2e} at t = {t_max} (not settled)")
        cases.append((name, prob, integ_cls, last_bad + every))
    # timed: exactly `steps` steps in one compiled call, from a fresh state (warm cache), the
    # media in turn, `repeat` times
    walls: dict = {name: [] for name, *_ in cases}
    cpus: dict = {name: [] for name, *_ in cases}
    errs: dict = {}
    for _ in range(max(1, repeat)):
        for name, prob, integ_cls, steps in cases:
            integ = integ_cls()
            sch, state, dt = _setup(prob, integ)
            t0, c0 = time.perf_counter(), time.process_time()
            _advance(sch, integ, state, dt, steps)
            walls[name].append(time.perf_counter() - t0)
            cpus[name].append(time.process_time() - c0)
            trials = 1.0 + integ.niter / steps if hasattr(integ, "niter") else 1.0
            errs[name] = (dt, float(np.linalg.norm(_tip(sch, state) - x_ref)) / scale, trials)
    rows = []
    for name, _, _, steps in cases:
        dt, err, trials = errs[name]
        wall, cpu = float(np.median(walls[name])), float(np.median(cpus[name]))
        rows.append({"case": name, "dt": dt, "steps": steps, "t": steps * dt, "wall_s": wall, "cpu_s": cpu,
                     "tip_error": err, "us_per_step": 1e6 * wall / steps, "walls": walls[name], "flows": trials})
    rows.append({"case": "speed-up (rod / filament), wall", "ratio": rows[1]["wall_s"] / rows[0]["wall_s"]})
    rows.append({"case": "speed-up (rod / filament), CPU", "ratio": rows[1]["cpu_s"] / rows[0]["cpu_s"]})
    return rows


def _load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="n = 11, 21 only for the step costs")
    ap.add_argument("--repeat", type=int, default=3, help="timed relaxation runs of each medium (medians)")
    ap.add_argument("--relaxation-only", action="store_true", help="skip the step-cost table")
    args = ap.parse_args(argv)
    sizes = (11, 21) if args.quick else (11, 21, 41, 81)
    if args.relaxation_only:
        sizes = ()
    if sizes:
        print(f"step cost (µs per step; Δt = half the CFL estimate); load average {_load()}")
        print(f"{'n':>4} {'rattle compiled':>16} {'flows/step':>10} {'rattle Python':>14} {'speed-up':>9} "
              f"{'rod lie-verlet':>15} "
              f"{'Δt filament':>12} {'Δt rod':>10} {'Δt ratio':>9}")
        for r in step_costs(sizes):
            print(f"{r['n']:>4} {r['rattle_compiled_us']:>16.1f} {r['flows']:>10.2f} {r['rattle_python_us']:>14.0f} "
                  f"{r['speedup']:>9.0f} {r['rod_lie_verlet_us']:>15.2f} {r['dt_filament']:>12.3e} "
                  f"{r['dt_rod']:>10.3e} {r['dt_ratio']:>9.1f}")
        print()
    print("damped relaxation to the elastica (filament-elastica, n = 41), relative tip error 1e-4; "
          f"medians of {args.repeat} timed runs each; load average {_load()}")
    print(f"{'case':<38} {'Δt':>10} {'steps':>8} {'t':>7} {'wall [s]':>9} {'CPU [s]':>8} {'µs/step':>8} "
          f"{'tip error':>10} {'flows/step':>10}")
    for r in relaxation(repeat=args.repeat):
        if "ratio" in r:
            print(f"{r['case']:<38} {r['ratio']:>10.1f}")
            continue
        print(f"{r['case']:<38} {r['dt']:>10.3e} {r['steps']:>8d} {r['t']:>7.2f} {r['wall_s']:>9.4f} "
              f"{r['cpu_s']:>8.4f} {r['us_per_step']:>8.2f} {r['tip_error']:>10.2e} {r['flows']:>10.2f}")
    print(f"load average after: {_load()}")

if __name__ == "__main__":
    main()
