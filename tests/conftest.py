"""Shared test configuration."""

from __future__ import annotations

import os

# One BLAS thread per test process.  `make test` runs one xdist worker per core; BLAS threads on
# top of them oversubscribe the cores, and OpenBLAS's threads wait by spinning: beside one busy
# core a 120 × 120 solve took 40× and a 199 × 384 SVD 30× longer with two threads than with one.
# The variables reach the workers (started after this file is read); threadpoolctl covers a
# process whose BLAS is loaded already.
for _var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import matplotlib  # noqa: E402
import pytest  # noqa: E402
from hypothesis import HealthCheck, settings  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

threadpool_limits(limits=1, user_api="blas")
matplotlib.use("Agg")

# Deterministic in CI (derandomised), more examples on request: HYPOTHESIS_PROFILE=thorough.
settings.register_profile(
    "default", deadline=None, max_examples=40, suppress_health_check=[HealthCheck.too_slow]
)
settings.register_profile(
    "ci", parent=settings.get_profile("default"), derandomize=True, print_blob=True
)
settings.register_profile("thorough", parent=settings.get_profile("default"), max_examples=1000)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci" if os.environ.get("CI") else "default"))


@pytest.fixture(autouse=True, scope="session")
def _temporary_files_stay_in_the_session(tmp_path_factory):
    """Files a run writes where the user gave no path (the last good state of a blow-up, in
    ``tempfile.gettempdir()``) go to the session's temporary directory, not the machine's."""
    import tempfile

    before = tempfile.tempdir
    tempfile.tempdir = str(tmp_path_factory.mktemp("tempfiles"))
    yield
    tempfile.tempdir = before


def record_returns(monkeypatch, owner, name: str) -> list:
    """Wrap the method ``owner.name`` so that each call's return value is appended to the list
    returned here (a spy: the method still runs)."""
    calls = []
    real = getattr(owner, name)

    def spy(self, *args, **kwargs):
        ran = real(self, *args, **kwargs)
        calls.append(ran)
        return ran

    monkeypatch.setattr(owner, name, spy)
    return calls


@pytest.fixture
def generated_runs(monkeypatch) -> list:
    """What ``Integrator.run_compiled_loop`` returned, call by call (True: the generated loop
    took the steps)."""
    from cartan.integrators import Integrator

    return record_returns(monkeypatch, Integrator, "run_compiled_loop")


# ---------------------------------------------------------------------------- compile profile
# CARTAN_COMPILE_LOG=path: every numba compilation (top level: a function with the functions it
# compiles inline) is written to ``path.<worker>`` as a JSON line ``{test, function, args,
# seconds, cpu_seconds}`` (wall clock and the worker's CPU time: the second does not count the
# other processes on the cores), to find which tests of the fast suite pay for which compiled loops.
_CURRENT_TEST = {"id": "<collection>"}


def _install_compile_log(path: str) -> None:
    import json
    import time

    from numba.core import event

    worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
    out = open(f"{path}.{worker}", "a", buffering=1)  # noqa: SIM115 - open for the session

    class _Log(event.Listener):
        depth = 0

        def on_start(self, ev):
            if self.depth == 0:
                self.t0, self.c0 = time.perf_counter(), time.process_time()
            self.depth += 1

        def on_end(self, ev):
            self.depth -= 1
            if self.depth == 0:
                func = ev.data["dispatcher"].py_func
                out.write(json.dumps({"test": _CURRENT_TEST["id"],
                                      "function": f"{func.__module__}.{func.__qualname__}",
                                      "args": str(ev.data["args"])[:300],
                                      "seconds": round(time.perf_counter() - self.t0, 3),
                                      "cpu_seconds": round(time.process_time() - self.c0, 3)}) + "\n")

    event.register("numba:compile", _Log())


if os.environ.get("CARTAN_COMPILE_LOG"):
    _install_compile_log(os.environ["CARTAN_COMPILE_LOG"])


# ---------------------------------------------------------------------------- the fast suite's loops
# ``make test`` compiles a few loops only: on an empty numba cache every compiled loop costs
# 10-100 s, far more than the tests that run it.  A test module may define
# ``slow_when(item) -> bool``; the items it names are marked ``slow`` (``make test-slow``), so the
# rule that picks them stays beside the tests.  The loops ``make test`` compiles: the demo's
# (the hand-written SE(3) lie-verlet loop of the lattice, and its generic twin for the other
# groups), the generated ``lie-verlet`` loops of the SE(3) rod on both schemes, the hand-written
# RKMK loop (the study tests' reference runs), one implicit-midpoint loop (the lattice's SE(3)
# rod), and the groups' and media's kernels.
#
# With -n (make test), xdist hands a worker one unit of tests at a time; a unit is a file
# (``--dist loadfile``, pyproject.toml) or a group of COMPILE_GROUPS.  numba has no lock across
# processes: two workers that reach an uncompiled loop at once both compile it, and a worker that
# reaches it after the other has finished loads it from the disk cache.  So the units that compile
# the suite's large loops go first, one per worker (COMPILE_FIRST, in order: the first to the
# first worker, the second to the second, ...), and the other units follow, largest first; the
# loops are on disk by the time the other worker's tests reach them.
COMPILE_GROUPS = {
    # the demo's hand-written SE(3) lie-verlet loop (≈ 60-90 s to compile), and the generated
    # lie-verlet loop of the planar rod on SE(2) (≈ 40 s): the planar case runs the same rod on
    # SE(3) too, so it needs the SE(3) loop as well and stays on the worker that compiles it
    "se3-soa-lie-verlet": (
        "tests/test_scene.py::test_cli_run_and_plot",
        "tests/test_verification_cases.py::test_case_meets_tolerance_and_order[free-rigid-body-lie-verlet-lattice]",
        "tests/test_verification_cases.py::test_case_meets_tolerance_and_order[rod-planar-se3-se2-lie-verlet-lattice]",
    ),
    # the generated collocation loop of the SE(3) rod (≈ 30-90 s)
    "collocation-loops": ("tests/test_collocation_compiled.py", "tests/test_generated_collocation.py"),
}
#: the units that start the run, in this order (a group's name or a test file)
COMPILE_FIRST = ("se3-soa-lie-verlet", "collocation-loops",
                 "tests/test_compiled_paths.py")  # (the generated lattice loop of the SE(3) rod)
_GROUP_OF = {key: group for group, keys in COMPILE_GROUPS.items() for key in keys}


def _group(nodeid: str) -> str:
    file = nodeid.split("::", 1)[0]
    return _GROUP_OF.get(nodeid, _GROUP_OF.get(file, file))


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    for item in items:
        rule = getattr(getattr(item, "module", None), "slow_when", None)
        if rule is not None and rule(item):
            item.add_marker(pytest.mark.slow)


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """``--dist loadfile`` with the groups of COMPILE_GROUPS, COMPILE_FIRST's units first."""
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class _LoadFileAndCompileGroups(LoadScopeScheduling):
        _ordered = False

        def _split_scope(self, nodeid: str) -> str:
            return _group(nodeid)

        def _assign_work_unit(self, node) -> None:
            if not self._ordered:  # the first call: the queue is complete
                self._ordered = True
                for scope in reversed(COMPILE_FIRST):
                    if scope in self.workqueue:
                        self.workqueue.move_to_end(scope, last=False)
            super()._assign_work_unit(node)

    return _LoadFileAndCompileGroups(config, log)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    _CURRENT_TEST["id"] = item.nodeid
    yield
