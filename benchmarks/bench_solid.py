"""Speed of the Cosserat solid's compiled lattice ``lie-verlet`` step against the SE(3) rod (T9).

The solid is ``cosserat-solid`` with the default constants on a periodic unit box of n³ nodes,
undeformed, with a smooth velocity field (a standing shear wave in every component, amplitude
10⁻³); the rod is the T1 rod of :mod:`benchmarks.compare` (n = 1000 elements).  Both run the
generated ``lie-verlet`` loop (``integrator.run_compiled_loop``); the rod also runs its
hand-written structure-of-arrays loop (``Lattice.compiled_advance``), the peer of T9.  Times
are CPU time of the process (``time.process_time``: steadier than wall time on a shared
machine), except the first call and the set-up (wall time).

Reported, in ns per node and step (the rod: per node-step of its n + 1 nodes):

* ``step`` — the whole loop, the median over ``SAMPLES`` blocks of ``STEPS`` steps;
* the operators one by one (:func:`profile`, as :mod:`benchmarks.profile_generated` calls them):
  ``force`` (edge logarithms, corner stresses, edge stresses to the nodes), ``free flow``
  (which ends with a ``move``), ``move`` and ``velocity``;
* for the solid, the three passes of the coupled ``op_force`` timed apart (:func:`force_passes`:
  the same arithmetic compiled here with the operator set's kernels): ``logs`` (3 edge
  logarithms per node), ``corners`` (8 corners per node: gather the strains, the medium's stress
  kernel, scatter the stresses to the edges), ``to nodes`` (3 dexp⁻¹ᵀ pairs per node); ``kernel``
  — the medium's ``m_stress`` alone at the corners' strains; ``corners, one X0`` — the corner
  pass reading one rest strain instead of each corner's copy.

::

    python benchmarks/bench_solid.py [--sizes 16 24 32] [--steps 20] [--compile]

and the peak resident memory of the process.  ``--compile`` times building an 8³ solid and its
first two steps in a fresh process (run it with an empty ``NUMBA_CACHE_DIR`` for the compile
time).
"""

from __future__ import annotations

import argparse
import math
import pathlib
import resource
import subprocess
import sys
import time

import numpy as np

import cartan

ROOT = pathlib.Path(__file__).resolve().parents[1]
for _p in (ROOT / "tests", ROOT / "benchmarks"):
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))

STEPS = 20
SAMPLES = 5
ROD_N = 1000


def solid_problem(n: int, amplitude: float = 1e-3) -> cartan.Problem:
    """The periodic n³ box of the default solid, undeformed, with a smooth velocity field."""
    medium = cartan.medium("cosserat-solid")
    grid = cartan.Grid((n, n, n), length=(1.0, 1.0, 1.0), periodic=True)
    u = np.stack(np.meshgrid(*[grid.coordinates(a) for a in range(3)], indexing="ij"), axis=-1)
    wave = np.sin(2 * np.pi * u[..., [1, 2, 0, 1, 2, 0]]) * np.linspace(1.0, 0.5, 6)
    return cartan.Problem(medium, grid, medium.initial_state(grid, "undeformed", velocity=amplitude * wave))


def rod_problem() -> tuple[cartan.Problem, float]:
    """The T1 rod of :mod:`benchmarks.compare` and its Δt."""
    import compare

    return compare.cartan_problem(ROD_N, compare.t1_velocity(ROD_N)), compare.step_size(ROD_N)


class Run:
    """A problem on the lattice with ``lie-verlet``, one compiled loop, warmed up (two steps)."""

    def __init__(self, problem: cartan.Problem, dt: float | None = None, hand_written: bool = False):
        self.scheme = cartan.registry("schemes")["lattice"](problem)
        self.integrator = cartan.registry("integrators")["lie-verlet"]()
        self.state = self.scheme.initial_state()
        self.nodes = int(np.prod(problem.grid.shape))
        self.dt = 0.1 * float(self.integrator.dt_max(self.scheme, self.state)) if dt is None else dt
        self.hand_written = hand_written
        t0, c0 = time.perf_counter(), time.process_time()
        if not self(2):
            raise NotImplementedError("no compiled loop runs this problem")
        self.first_call = time.perf_counter() - t0  # wall time
        self.first_call_cpu = time.process_time() - c0

    def __call__(self, steps: int) -> bool:
        if self.hand_written:
            return self.scheme.compiled_advance(self.integrator, self.state, self.dt, steps)
        return self.integrator.run_compiled_loop(self.scheme, self.state, self.dt, steps, math.inf)

    def node_step(self, steps: int = STEPS, samples: int = SAMPLES) -> float:
        """ns per node-step, the median over ``samples`` blocks of ``steps`` steps."""
        times = []
        for _ in range(samples):
            t0 = time.process_time()
            self(steps)
            times.append(time.process_time() - t0)
        return float(np.median(times)) / (steps * self.nodes) * 1e9


def _median(call, reps: int = 7, inner: int = 3) -> float:
    times = []
    for _ in range(reps):
        t0 = time.process_time()
        for _ in range(inner):
            call()
        times.append((time.process_time() - t0) / inner)
    return float(np.median(times))


def profile(run: Run) -> dict[str, float]:
    """ns per node of each operator of one generated ``lie-verlet`` step of ``run``
    (:func:`profile_generated.profile_run`, in CPU time)."""
    import profile_generated

    profile_generated.CLOCK = time.process_time
    return profile_generated.profile_run(run.scheme, run.integrator, run.state, run.dt, inner=3)


_PASSES = """
def pass_logs(D, C, K):
    G = C[0]
    XI, QE = K[2], K[3]
    xi = np.empty(R_)
    for e in range(G.shape[0]):
        g_log(G[e], xi)
        for k in range(R_):
            XI[e, k] = xi[k]
            QE[e, k] = 0.0


def pass_corners(D, K, uniform):
    XI, QE = K[2], K[3]
    X = np.empty((D_, R_))
    Q = np.empty((D_, R_))
    for c in range(D.cw.shape[0]):
        for b in range(D_):
            e = D.cedge[c, b]
            for k in range(R_):
                X[b, k] = XI[e, k] * D.einvh[e]
        m_stress(X, D.cX0[0 if uniform else c], D.params, Q)
        for b in range(D_):
            e = D.cedge[c, b]
            f = D.cw[c] * D.einvh[e]
            for k in range(R_):
                QE[e, k] += f * Q[b, k]


def pass_kernel(D, Xc, Qc):
    for c in range(Xc.shape[0]):
        m_stress(Xc[c], D.cX0[c], D.params, Qc[c])


def pass_nodes(D, W, K):
    XI, QE = K[2], K[3]
    xi = np.empty(R_)
    q = np.empty(R_)
    vec = np.empty(R_)
    vec2 = np.empty(R_)
    for i in range(W.shape[0]):
        for k in range(R_):
            W[i, k] = 0.0
    for e in range(XI.shape[0]):
        for k in range(R_):
            xi[k] = XI[e, k]
            q[k] = QE[e, k]
        i, j = D.tail[e], D.head[e]
        g_dexp_inv_T_pair(xi, q, vec, vec2)
        for k in range(R_):
            W[i, k] += vec[k]
            W[j, k] -= vec2[k]
"""


def force_passes(run: Run) -> dict[str, float]:
    """ns per node of the three passes of the coupled ``op_force`` (the edge logarithms, the
    corner stresses gathered from and scattered to the edges, the edge stresses to the nodes),
    compiled here with the operator set's fragments (the same kernels, sizes as constants), and
    of the medium's stress kernel alone at the corners' strains (``kernel``); for a uniform rest
    strain also the corner pass reading one rest strain instead of each corner's copy
    (``corners, one X0``: what the copies ``D.cX0`` cost in memory traffic)."""
    from cartan.compiled.codegen import Fragment, generate

    ops = run.scheme.compiled_operators()
    module = ops.generated()
    D = ops.data
    if not D.coupled:
        return {}
    C = ops.pack(run.state)
    K = module.op_work(D)
    passes = generate(f"bench-solid-passes-{ops.key}", [*ops.fragments, Fragment(source=_PASSES)])
    n = ops.nodes
    W = np.empty((n, D.r))
    passes.pass_logs(D, C, K)
    Xc = np.ascontiguousarray(K[2][D.cedge] * D.einvh[D.cedge][..., None])  # [corners, d, r]
    Qc = np.empty_like(Xc)
    cost = {
        "logs": _median(lambda: passes.pass_logs(D, C, K)),
        "corners": _median(lambda: passes.pass_corners(D, K, False)),
        "to nodes": _median(lambda: passes.pass_nodes(D, W, K)),
        "kernel": _median(lambda: passes.pass_kernel(D, Xc, Qc)),
    }
    if not D.cX0.size or np.all(D.cX0 == D.cX0[0]):  # what a rest strain read once would save
        cost["corners, one X0"] = _median(lambda: passes.pass_corners(D, K, True))
    return {k: v / n * 1e9 for k, v in cost.items()}


def report(sizes: list[int], steps: int) -> list[dict]:
    """Measure the rod and the solid at ``sizes`` in this process; print and return the rows."""
    rows = []
    rod_problem_, rod_dt = rod_problem()
    rod_soa = Run(rod_problem_, rod_dt, hand_written=True)
    rod_gen = Run(rod_problem_, rod_dt)
    peers = {"rod SoA": rod_soa, "rod generated": rod_gen}
    peer_cost = {}
    for name, run in peers.items():
        peer_cost[name] = run.node_step(steps * 10)
        rows.append({"case": name, "nodes": run.nodes, "ns": peer_cost[name]})
        print(f"{name:16s} {run.nodes:8d} nodes  {peer_cost[name]:8.1f} ns per node-step")
    ops = profile(rod_gen)
    print(f"{'':16s} generated ops: " + "  ".join(f"{k} {v:.1f}" for k, v in ops.items()))
    for n in sizes:
        t0 = time.perf_counter()
        run = Run(solid_problem(n))
        setup = time.perf_counter() - t0
        cost = run.node_step(steps)
        ops = profile(run)
        ops |= force_passes(run)
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        row = {"case": f"solid {n}^3", "nodes": run.nodes, "ns": cost, "ops": ops, "setup_s": setup,
               "first_call_s": run.first_call, "max_rss_MB": rss,
               "ratio_soa": cost / peer_cost["rod SoA"], "ratio_generated": cost / peer_cost["rod generated"]}
        rows.append(row)
        print(f"solid {n}^3{'':9s} {run.nodes:8d} nodes  {cost:8.1f} ns per node-step  "
              f"({row['ratio_soa']:.0f}× the rod's SoA loop, {row['ratio_generated']:.1f}× its generated loop); "
              f"setup {setup:.1f} s, first call {run.first_call:.2f} s, max RSS {rss:.0f} MB")
        print(f"{'':16s} ops: " + "  ".join(f"{k} {v:.1f}" for k, v in ops.items()))
    return rows


def compile_time(n: int = 8) -> tuple[float, float]:
    """(wall, CPU) seconds to build the solid's n³ run and take its first two steps in a fresh
    process: with an empty numba cache, the compilation of everything it needs (the generated
    loop, the CFL estimate's kernels, the group's and the medium's kernels); with a warm one,
    loading them."""
    code = (f"import sys, time; sys.path.insert(0, {str(ROOT / 'benchmarks')!r}); import bench_solid as b; "
            f"t0, c0 = time.perf_counter(), time.process_time(); b.Run(b.solid_problem({n})); "
            f"print(time.perf_counter() - t0, time.process_time() - c0)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    wall, cpu = out.stdout.strip().splitlines()[-1].split()
    return float(wall), float(cpu)


def main(argv: list[str] | None = None) -> None:  # pragma: no cover - a report for the terminal
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="*", default=[16, 24, 32])
    parser.add_argument("--steps", type=int, default=STEPS)
    parser.add_argument("--compile", action="store_true", help="time a first call in a fresh process")
    args = parser.parse_args(argv)
    if args.compile:
        wall, cpu = compile_time()
        print(f"build and first two steps (fresh process): {wall:.1f} s wall, {cpu:.1f} s CPU")
        return
    report(args.sizes, args.steps)


if __name__ == "__main__":
    main(sys.argv[1:])
