"""``cartan warm`` and the threaded builds of the compiled loops.

The threaded builds (``prange`` twins, ``cartan._threads.threaded_twins``) run only with
``CARTAN_THREADS`` > 1 on grids of at least ``MIN_NODES`` nodes; ``cartan warm`` compiles them
on its small verification problems inside ``cartan._threads.threaded_everywhere`` (the node
threshold lowered to one node).  A process started afterwards with ``CARTAN_THREADS=2`` on a
grid of ``MIN_NODES`` nodes must then load every kernel it uses from numba's cache.
"""

from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys
import textwrap

import pytest
from click.testing import CliRunner

import cartan
from cartan import _threads
from cartan.cli import main
from cartan.cli_cache import PARTS, kernel_inventory, warm

ROOT = pathlib.Path(__file__).resolve().parents[1]
CARTAN = [sys.executable, "-c", "from cartan.cli import main; main()"]
#: the warm-up workload of these tests: one SE(3) rod case with lie-verlet on the lattice
SUBSET = ["--group", "SE3", "--case", "rod-axial-wave-free", "--integrator", "lie-verlet", "--scheme", "lattice"]
two_threads = pytest.mark.skipif(_threads.max_threads() < 2, reason="numba has a single thread here")

#: a first threaded run in a new process (CARTAN_THREADS=2): a free SE(3) rod of MIN_NODES
#: nodes, 10 lie-verlet steps, then numba's cache misses over every cached cartan kernel and
#: the threaded kernels that ran
THREADED_RUN = textwrap.dedent(
    """
    import json
    import cartan
    from cartan import _threads
    from cartan.cli_cache import kernel_inventory

    rod = cartan.medium("cosserat-rod", E=1e6, G=1e4, radius=0.25, density=5000.0)
    grid = cartan.Grid(_threads.MIN_NODES, length=3.0)
    init = rod.initial_state(grid, "straight", velocity=[0.01, 0.0, 0.0, 0.0, 0.0, 0.0])
    ds = cartan.simulate(cartan.Problem(rod, grid, init), dt=1e-6, t_end=1e-5, save_every=5, progress=False)
    kernels = kernel_inventory()
    print(json.dumps({"threads": cartan.get_threads(), "steps": int(ds.step[-1]),
                      "misses": {f"{k.module}.{k.name}": k.misses for k in kernels if k.misses},
                      "hits": sum(k.hits for k in kernels),
                      "threaded": sorted(k.name for k in kernels if k.name.endswith("__threaded") and k.signatures)}))
    """
)


def _run(args, **kw):
    return subprocess.run(args, capture_output=True, text=True, cwd=ROOT, timeout=1800, **kw)


# ---------------------------------------------------------------------------- the threshold
def test_use_min_nodes_sets_and_restores_the_threshold():
    before = _threads.MIN_NODES
    with _threads.use_min_nodes(5):
        assert _threads.MIN_NODES == 5
        with _threads.use_min_nodes(7):
            assert _threads.MIN_NODES == 7
        assert _threads.MIN_NODES == 5
    assert _threads.MIN_NODES == before
    with pytest.raises(RuntimeError), _threads.use_min_nodes(3):
        raise RuntimeError("restored on error too")
    assert _threads.MIN_NODES == before


@pytest.mark.parametrize("bad", [0, -4, 2.5, True, "8", None])
def test_use_min_nodes_validates(bad):
    with pytest.raises(ValueError, match=r"min_nodes must be an integer ≥ 1"), _threads.use_min_nodes(bad):
        pass  # pragma: no cover


@pytest.mark.parametrize("bad", [1, 0, 2.0, True, "2"])
def test_threaded_everywhere_validates(bad):
    with pytest.raises(ValueError, match=r"threads must be an integer in 2\.\.\d+"), _threads.threaded_everywhere(bad):
        pass  # pragma: no cover
    with pytest.raises(ValueError, match="threads must be an integer in 2"), _threads.threaded_everywhere(
            _threads.max_threads() + 1):
        pass  # pragma: no cover


@two_threads
def test_threaded_everywhere_reaches_every_grid(monkeypatch):
    monkeypatch.delenv(_threads.ENV, raising=False)
    threshold = _threads.MIN_NODES
    assert _threads.loop_threads(1) == 1
    with _threads.threaded_everywhere(2):
        assert cartan.get_threads() == 2 and _threads.MIN_NODES == 1
        assert _threads.loop_threads(1) == 2 and _threads.loop_threads(threshold) == 2
    assert cartan.get_threads() == 1 and _threads.loop_threads(threshold) == 1
    assert _threads.MIN_NODES == threshold


def test_thread_queries_count_the_loops_asking():
    before = _threads.thread_queries()
    _threads.loop_threads(10)
    _threads.loop_threads(10**6)
    assert _threads.thread_queries() == before + 2


# ---------------------------------------------------------------------------- warm
def test_inventory_lists_the_threaded_twins():
    from cartan.schemes import _lattice_compiled as lc

    names = {(k.module, k.name) for k in kernel_inventory()}
    twins = {(f.py_func.__module__, f.py_func.__qualname__) for f in lc.soa.THREADED.values()}
    assert ("cartan.schemes._lattice_compiled_soa", "lie_verlet_se3_loop__threaded") in twins
    assert twins <= names
    # each kernel once: the twins are not also listed under their serial names' entries
    listed = [(k.module, k.name) for k in kernel_inventory()]
    assert len(listed) == len(set(listed))


@two_threads
@pytest.mark.slow
def test_warm_runs_the_threaded_builds():
    """The ``threads`` part runs the case again through the threaded loop (it gains a compiled
    signature), and reports its own steps."""
    from cartan.schemes import _lattice_compiled as lc

    assert "threads" in PARTS
    threshold = _threads.MIN_NODES
    lines: list[str] = []
    steps = warm(["threads"], cases=["rod-axial-wave-free"], integrators=["lie-verlet"], schemes=["lattice"],
                 log=lines.append)
    assert [(s.part, s.name, s.status) for s in steps] == [
        ("threads", "rod-axial-wave-free / lie-verlet / lattice", "ok")]
    assert lines and lines[0].startswith("threads rod-axial-wave-free")
    assert lc.soa.THREADED["lie_verlet_se3_loop"].signatures
    assert _threads.MIN_NODES == threshold and cartan.get_threads() == 1  # restored


@pytest.mark.slow
@two_threads
def test_threads_part_reruns_only_the_runs_that_reach_a_threaded_loop():
    """After the ``cases`` part, only the runs during which a compiled loop asked for its thread
    count run again threaded; a combination the case rejects before stepping (``overdamped``
    without drag) is not rerun."""
    steps = warm(["cases", "threads"], cases=["rod-axial-wave-free"], integrators=["lie-verlet", "overdamped"],
                 schemes=["lattice"])
    status = {(s.part, s.name): s.status for s in steps}
    assert status[("cases", "rod-axial-wave-free / lie-verlet / lattice")] == "ok"
    assert status[("cases", "rod-axial-wave-free / overdamped / lattice")] == "skipped"
    assert [name for part, name in status if part == "threads"] == ["rod-axial-wave-free / lie-verlet / lattice"]
    assert status[("threads", "rod-axial-wave-free / lie-verlet / lattice")] == "ok"


@pytest.mark.slow
def test_warm_without_threads_part(monkeypatch):
    """``--no-threads`` leaves the threaded builds out; alone with ``--part threads`` it leaves
    nothing to do (a usage error)."""
    result = CliRunner().invoke(main, ["warm", "--no-threads", "--part", "threads"])
    assert result.exit_code == 2 and "--no-threads leaves no workload" in result.output
    seen = []
    real = warm

    def spy(parts, **kw):
        seen.append(list(parts))
        return real(parts, **kw)

    monkeypatch.setattr("cartan.cli_cache.warm", spy)
    result = CliRunner().invoke(main, ["warm", "--no-threads", *SUBSET, "-v"])
    assert result.exit_code == 0, result.output
    assert seen == [["groups", "cases", "grids"]]
    assert "cases   rod-axial-wave-free / lie-verlet / lattice" in result.output
    assert "threads rod-axial-wave-free" not in result.output


def test_single_thread_numba_skips_the_threads_part(monkeypatch):
    monkeypatch.setattr(_threads, "max_threads", lambda: 1)
    steps = warm(["threads"], cases=["rod-axial-wave-free"], integrators=["lie-verlet"], schemes=["lattice"])
    assert [(s.part, s.status) for s in steps] == [("threads", "skipped")]
    assert "NUMBA_NUM_THREADS" in steps[0].message


@two_threads
@pytest.mark.slow
def test_a_threaded_process_after_warm_compiles_nothing():
    """``cartan warm`` (threaded builds included, the default) on the SE(3) rod case, then a
    new process with ``CARTAN_THREADS=2`` on a rod of ``MIN_NODES`` nodes: the threaded loop
    runs and every kernel comes from numba's cache."""
    first = _run([*CARTAN, "warm", *SUBSET, "--strict"])
    assert first.returncode == 0, first.stderr
    env = dict(os.environ, CARTAN_THREADS="2", NUMBA_NUM_THREADS="2")
    run = _run([sys.executable, "-c", THREADED_RUN], env=env)
    assert run.returncode == 0, run.stderr
    out = json.loads(run.stdout.strip().splitlines()[-1])
    assert out["threads"] == 2 and out["steps"] == 10
    assert "lie_verlet_se3_loop__threaded" in out["threaded"], out
    assert out["misses"] == {} and out["hits"] >= 1, out
