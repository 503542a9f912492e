"""Convergence and stability studies (cartan.study), their scale-out and the verify/converge commands."""

from __future__ import annotations

import json
import math
import os
import pathlib
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner

import cartan
from cartan import study
from cartan.grid import Grid
from cartan.problem import InitialState, Problem

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from toys import QuadraticMedium, arc_problem  # noqa: E402


class SpinningArc:
    """A spinning, bent toy rod (SE(3) quadratic medium), final strain against an rkmk4 run with Δt/256."""

    name = "toy-spinning-arc"
    medium = "toy-quadratic"
    description = "bent quadratic SE(3) rod released with a velocity field"
    reference = "rkmk4 with 1/256 of the coarsest time step"
    quantity = "X"
    norm = "max"
    space_order = None
    time_order_of = {"lie-verlet": 2, "rkmk4": 4, "lie-euler": 1}
    tolerance = 1e-2
    tolerance_reason = "coarse time steps of a toy study"
    default_integrators = ("lie-verlet",)
    levels = 4
    dt0 = 0.02
    problem_calls = 0
    delay = 0.0
    _reference: dict = {}

    def problem(self, level: int, scheme: str = "lattice"):
        type(self).problem_calls += 1
        if self.delay:
            time.sleep(self.delay)
        p = arc_problem(n=9, velocity=np.array([0.0, 0.3, 0.0, 0.1, 0.0, 0.2]))
        return p, dict(dt=self.dt0, t_end=0.4, save_every=None)

    def _exact(self, scheme):
        if scheme not in self._reference:
            p, run = self.problem(0, scheme)
            type(self).problem_calls -= 1
            ds = cartan.simulate(p, integrator="rkmk4", scheme=scheme, dt=self.dt0 / 256, t_end=run["t_end"],
                                 save_every=256 * 20)
            self._reference[scheme] = ds["X"].isel(time=-1).values
        return self._reference[scheme]

    def error(self, ds, problem):
        scheme = json.loads(ds.attrs["cartan_config"])["run"]["scheme"]
        return float(np.max(np.abs(ds["X"].isel(time=-1).values - self._exact(scheme))))


class SlowSpinningArc(SpinningArc):
    """The same case, with a pause in every task (for the worker-kill test)."""

    name = "toy-spinning-arc-slow"
    space_order = 2  # refined in time against a fine-Δt run (no exact reference needed)
    delay = 0.6


class StrainEnergy:
    """Lattice energy of a sinusoidal strain field: midpoint rule of ¼ C₀ b² L, second order in dx."""

    name = "toy-strain-energy"
    medium = "toy-quadratic"
    description = "X₀(u) = 1 + b sin 2πu along one generator (commuting: Φ exact)"
    reference = "V = ¼ C₀ b² L"
    quantity = "potential_energy"
    norm = "relative"
    space_order = 2
    time_order_of = None
    tolerance = 1e-2
    tolerance_reason = "midpoint rule at 8 nodes per wavelength"
    default_integrators = ("lie-verlet",)
    levels = 4
    b = 0.1

    def problem(self, level: int, scheme: str = "lattice"):
        n = 8 * 2**level + 1
        medium = QuadraticMedium("SE3")
        grid = Grid(n, 1.0)
        u = grid.coordinates(0)
        xi = np.zeros((n, 6))
        xi[:, 0] = u - self.b * (np.cos(2 * np.pi * u) - 1) / (2 * np.pi)
        return Problem(medium, grid, InitialState(Phi=medium.group.exp(xi))), dict(dt=1e-3, t_end=2e-3, save_every=2)

    def error(self, ds, problem):
        exact = 0.25 * problem.medium.C[0] * self.b**2
        return abs(float(ds["potential_energy"].isel(time=0)) - exact) / exact


# ---------------------------------------------------------------------------- converge
def test_converge_time_order():
    ds = study.converge(SpinningArc(), integrators=["lie-verlet", "rkmk4"], schemes=["lattice"], levels=4,
                        refine="time")
    assert dict(ds.sizes) == {"integrator": 2, "scheme": 1, "level": 4}
    for v in ("error", "wall_time", "nforce", "nstep", "dt", "n", "observed_order"):
        assert v in ds, v
    assert ds["nstep"].sel(integrator="lie-verlet").values.ravel().tolist() == [20, 40, 80, 160]
    p = ds["observed_order"]
    assert abs(float(p.sel(integrator="lie-verlet", scheme="lattice")) - 2) < 0.2
    assert abs(float(p.sel(integrator="rkmk4", scheme="lattice")) - 4) < 0.5
    assert ds["passed"].values.all()
    assert ds.attrs["Conventions"].startswith("CF")


def test_converge_space_order():
    ds = study.converge(StrainEnergy(), integrators=["lie-verlet"], levels=4)
    assert ds.attrs["refine"] == "space"
    assert ds["n"].values.ravel().tolist() == [9, 17, 33, 65]
    assert abs(float(ds["observed_order"].squeeze()) - 2) < 0.1
    assert float(ds["expected_order"].squeeze()) == 2


def test_converge_takes_the_levels_themselves():
    """levels=(1, 2, 3): the case's own levels (a case need not start at level 0, e.g.
    filament-greenhill's (1, 2)), the same errors as those levels of a 4-level study; the coordinate
    ``level`` holds them; levels that do not increase are refused."""
    listed = study.converge(StrainEnergy(), integrators=["lie-verlet"], levels=(1, 2, 3))
    assert listed["level"].values.tolist() == [1, 2, 3]
    assert listed["n"].values.ravel().tolist() == [17, 33, 65]
    full = study.converge(StrainEnergy(), integrators=["lie-verlet"], levels=4)
    np.testing.assert_array_equal(listed["error"].values.ravel(), full["error"].values.ravel()[1:])
    with pytest.raises(study.StudyError, match="increasing"):
        study.converge(StrainEnergy(), integrators=["lie-verlet"], levels=(2, 1))


def test_converge_self_referenced_time(tmp_path):
    case = SlowSpinningArc()
    case.delay = 0.0
    ds = study.converge(case, integrators=["lie-verlet"], levels=3, refine="time", store=tmp_path)
    assert ds.attrs["error_reference"].startswith("run with the finest dt")
    assert abs(float(ds["observed_order"].squeeze()) - 2) < 0.25
    assert len(list(tmp_path.glob("*.json"))) == 4  # three levels and the reference


def test_observed_order_fit():
    h = 0.1 / 2.0 ** np.arange(5)
    e = 3 * h**2
    e[0] *= 5  # pre-asymptotic coarsest level: dropped
    assert study.observed_order(h, e) == pytest.approx(2)
    e2 = np.array([1e-2, 2.5e-3, 1e-15, 1e-16])  # round-off plateau left out
    assert study.observed_order(h[:4], e2) == pytest.approx(2)
    assert math.isnan(study.observed_order([1.0], [1.0]))


def test_bad_refine_and_missing_dask(monkeypatch):
    with pytest.raises(study.StudyError, match="refine"):
        study.converge(SpinningArc(), refine="diagonal")
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(study.StudyError, match=r"pip install 'cartan\[dist\]'"):
        study.converge(SpinningArc(), levels=2, refine="time", client="local")


def test_store_rerun_skips_finished_tasks(tmp_path):
    case = SpinningArc()
    SpinningArc.problem_calls = 0
    ds1 = study.converge(case, integrators=["lie-verlet", "rkmk4"], levels=3, refine="time", store=tmp_path)
    first = SpinningArc.problem_calls
    assert first == 6
    files = sorted(p.name for p in tmp_path.glob("*.json"))
    assert len(files) == 6
    # lose one result: only that task runs again
    (tmp_path / files[0]).unlink()
    ds2 = study.converge(case, integrators=["lie-verlet", "rkmk4"], levels=3, refine="time", store=tmp_path)
    assert SpinningArc.problem_calls == first + 1
    xr.testing.assert_allclose(ds1["error"], ds2["error"])
    study.converge(case, integrators=["lie-verlet", "rkmk4"], levels=3, refine="time", store=tmp_path)
    assert SpinningArc.problem_calls == first + 1


def test_write_once(tmp_path):
    path = tmp_path / "k.json"
    study._write_once(path, {"a": 1})
    study._write_once(path, {"a": 2})
    assert json.loads(path.read_text()) == {"a": 1}
    assert [p.name for p in tmp_path.iterdir()] == ["k.json"]


def test_plots(tmp_path):
    ds = study.converge(SpinningArc(), integrators=["lie-verlet", "rkmk4"], levels=3, refine="time")
    for fn in (study.plot_work_precision, study.plot_error_vs_h):
        out = fn(ds, tmp_path / f"{fn.__name__}.png")
        assert out.read_bytes()[:4] == b"\x89PNG"


def test_traces_and_plot(tmp_path):
    tr = study.traces(SpinningArc(), ["lie-verlet", "rkmk4"], ["lattice"], level=0, frames=10)
    assert dict(tr.sizes) == {"integrator": 2, "scheme": 1, "frame": 11}
    assert (tr["status"] == "ok").all()
    assert np.isfinite(tr["energy_error"]).all() and float(tr["energy_error"].max()) < 0.1  # coarse Δt
    assert float(tr["integrability_residual"].max()) < 1e-10  # the lattice: round-off
    out = study.plot_traces(tr, tmp_path / "traces.png")
    assert out.read_bytes()[:4] == b"\x89PNG"


def test_converge_static_case():
    """A static case (equilibria by Newton; "integrator" newton) is refined in space: no Δt, the
    Newton iterations as nstep, the per-scheme tolerance and the integrability residual recorded."""
    ds = study.converge("rod-timoshenko-static", levels=3)
    assert ds.attrs["refine"] == "space" and list(ds["integrator"].values) == ["newton"]
    assert ds["n"].values.ravel().tolist() == [13, 25, 49]
    assert np.isnan(ds["dt"]).all() and np.isnan(ds["nforce"]).all()
    assert ((ds["nstep"] >= 2) & (ds["nstep"] <= 10)).all()
    assert (ds["integrability_residual"] <= 1e-12).all()  # the lattice: round-off
    assert abs(float(ds["observed_order"].squeeze()) - 2.0) < 0.05
    assert float(ds["tolerance"].squeeze()) == 1e-4 and bool(ds["passed"].squeeze())
    with pytest.raises(study.StudyError, match=r"refined in space only.*'time'"):
        study.converge("rod-timoshenko-static", levels=2, refine="time")


def test_converge_per_scheme_tolerance():
    """tolerances keyed "integrator/scheme" judge each scheme by its own threshold."""
    case = cartan.registry("cases")["rod-ring-flexural-wave"]
    assert case.tolerance_for("lie-verlet", "collocation") == 6e-2
    assert case.tolerance_for("lie-verlet", "lattice") == case.tolerance_for("lie-verlet") == 5e-3
    ds = study.converge(StrainEnergy(), integrators=["lie-verlet"], schemes=["lattice"], levels=2)
    assert float(ds["tolerance"].squeeze()) == StrainEnergy.tolerance  # a case without tolerance_for


def test_converge_order_band():
    """``passed`` needs the observed order in [p − 0.2, p + 0.3]: an error falling faster than
    claimed fails too (a reference or a level that is not what the case says)."""

    class Understated(StrainEnergy):
        space_order = 1  # the midpoint rule is second order: observed 2.0 > 1 + 0.3

    ds = study.converge(Understated(), levels=3)
    assert abs(float(ds["observed_order"].squeeze()) - 2.0) < 0.1
    assert not bool(ds["passed"].squeeze()) and ds.attrs["order_slack"] == [0.2, 0.3]
    assert bool(study.converge(Understated(), levels=3, order_slack=(0.2, 1.5))["passed"].squeeze())
    with pytest.raises(ValueError, match="order_slack must be ≥ 0"):
        study.converge(Understated(), levels=2, order_slack=-0.1)


# ---------------------------------------------------------------------------- stability
def straight_rod(n):
    rng = np.random.default_rng(1)
    return arc_problem(n=n, curvature=0.0, velocity=1e-3 * rng.standard_normal((n, 6)))


def test_stability_bisection(tmp_path):
    ds = study.stability(straight_rod, ["lie-verlet", "forward-euler"], [9, 17], steps=400, rtol=0.02)
    assert dict(ds.sizes) == {"integrator": 2, "n": 2}
    lv = ds.sel(integrator="lie-verlet")
    ratio = lv["dt_max"] / lv["dt_cfl"]
    assert ((ratio > 1 / 1.2) & (ratio < 1.2)).all(), ratio.values
    assert lv["bracketed"].values.all()
    # Δt_max ∝ dx for the wave-like toy
    assert float(lv["dt_max"][0] / lv["dt_max"][1]) == pytest.approx(float(lv["h"][0] / lv["h"][1]), rel=0.15)
    fe = ds.sel(integrator="forward-euler")
    assert (fe["dt_cfl"] == 0).all()
    assert (fe["dt_max"] == 0).all()  # unstable at every Δt tried
    out = study.plot_stability(ds, tmp_path / "stab.png")
    assert out.stat().st_size > 0


def test_stability_criterion_covers_a_fixed_time():
    """Far below the limit (Δt = CFL/64) a fixed 300-step window sees only the rising part of the
    bounded energy oscillation of a thin rod; the drift test then reads it as growth and calls
    every Δt unstable.  Trials over a fixed physical time (300 × the CFL estimate) find the limit."""
    import functools

    problem = functools.partial(thin_rod, 0.005)
    old = study.stability(problem, "lie-verlet", [11], steps=300, rtol=0.02, trend=1.5, horizon=1e-12)
    assert float(old["dt_max"].squeeze()) == 0.0  # misread: "unstable" at the bottom of the bracket
    new = study.stability(problem, "lie-verlet", [11], steps=300, rtol=0.02)
    assert float(new["dt_max"].squeeze() / new["dt_cfl"].squeeze()) == pytest.approx(1.0, abs=0.1)
    assert new.attrs["trend"] == "off"
    with pytest.raises(ValueError, match="horizon must be a finite time > 0"):
        study.stability(problem, "lie-verlet", [11], horizon=-1.0)
    with pytest.raises(ValueError, match="bracket must be two numbers 0 < low < high"):
        study.stability(problem, "lie-verlet", [11], bracket=(4.0, 1.0))
    with pytest.raises(ValueError, match="steps must be an integer ≥ 1"):
        study.stability(problem, "lie-verlet", [11], steps=0)


# ---------------------------------------------------------------------------- distributed
def test_scheduler_address_string(tmp_path):
    """``--scheduler tcp://HOST:PORT``: the study's tasks run on the workers of a running scheduler
    reached by its address string (here a LocalCluster's), results stored once per task."""
    distributed = pytest.importorskip("distributed")
    from cartan import cli_verify

    out, store = tmp_path / "wp.nc", tmp_path / "store"
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        address = cluster.scheduler_address
        assert isinstance(address, str) and address.startswith("tcp://")
        res = CliRunner().invoke(cli_verify.converge_cmd, ["rod-timoshenko-static", "--levels", "2", "--scheduler",
                                                           address, "--store", str(store), "-o", str(out)])
        assert res.exit_code == 0, res.output
        with distributed.Client(address) as client:  # the tasks ran there, not in this process
            keys = client.run_on_scheduler(lambda dask_scheduler: {str(t[0]) for t in dask_scheduler.transition_log})
            assert sum(k.startswith("cartan-study-rod-timoshenko-static") for k in keys) == 2, keys
        ds = study.converge("sphere-rod-latitude", levels=2, client=address)  # from Python: the same string
        assert abs(float(ds["observed_order"].squeeze()) - 1.0) < 0.2  # Lie–Euler overdamped
    assert len(list(store.glob("*.json"))) == 2
    with xr.open_dataset(out) as wp:
        assert wp.sizes["level"] == 2 and list(wp["integrator"].values) == ["newton"]


@pytest.mark.slow
def test_documented_dask_commands(tmp_path):
    """The documented commands: ``dask scheduler``, ``dask worker ADDRESS --nworkers N --nthreads 1``
    and ``cartan converge CASE --scheduler ADDRESS --store DIR`` (random ports, no dashboards)."""
    pytest.importorskip("distributed")
    bindir = pathlib.Path(sys.executable).parent
    info = tmp_path / "scheduler.json"
    procs = [subprocess.Popen([str(bindir / "dask"), "scheduler", "--port", "0", "--no-dashboard",
                               "--scheduler-file", str(info)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        deadline = time.monotonic() + 60
        while not info.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        address = json.loads(info.read_text())["address"]
        procs.append(subprocess.Popen([str(bindir / "dask"), "worker", address, "--nworkers", "2", "--nthreads", "1",
                                       "--no-dashboard"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        out, store = tmp_path / "wp.nc", tmp_path / "study"
        res = subprocess.run([str(bindir / "cartan"), "converge", "sphere-rod-latitude", "--levels", "3",
                              "--scheduler", address, "--store", str(store), "-o", str(out)],
                             capture_output=True, text=True, timeout=300)
        assert res.returncode == 0, res.stderr
        assert "sphere-rod-latitude  overdamped / lattice" in res.stdout
        assert len(list(store.glob("*.json"))) == 3
        with xr.open_dataset(out) as wp:
            assert abs(float(wp["observed_order"].squeeze()) - 1.0) < 0.2
    finally:
        for proc in reversed(procs):
            proc.terminate()
        for proc in procs:
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()


@pytest.mark.slow  # starts a dask cluster and kills a worker (≈ 11 s)
def test_local_cluster_worker_killed(tmp_path):
    distributed = pytest.importorskip("distributed")
    case = SlowSpinningArc()
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        client.wait_for_workers(2)
        victim = sorted(client.scheduler_info()["workers"])[0]
        pid = client.run(os.getpid, workers=[victim])[victim]
        killed = []

        def kill():  # the worker process this test started, mid-way through the sweep
            deadline = time.monotonic() + 120
            while len(list(tmp_path.glob("*.json"))) < 2 and time.monotonic() < deadline:
                time.sleep(0.05)
            killed.append(len(list(tmp_path.glob("*.json"))))
            os.kill(pid, signal.SIGKILL)

        t = threading.Thread(target=kill)
        t.start()
        ds = study.converge(case, integrators=["lie-verlet", "rkmk4"], schemes=["lattice", "collocation"],
                            levels=2, refine="time", client=client, store=tmp_path)
        t.join()
    assert 0 < killed[0] < 12  # the kill came mid-way
    files = sorted(tmp_path.glob("*.json"))
    assert len(files) == 12  # 2 × 2 × (2 levels + reference): each exactly once
    assert len({json.loads(p.read_text())["key"] for p in files}) == 12
    assert not list(tmp_path.glob(".*.tmp"))
    assert np.isfinite(ds["error"].values).all()


# ---------------------------------------------------------------------------- commands
@pytest.fixture
def registered_case(monkeypatch):
    from cartan import cli_verify

    monkeypatch.setattr(cli_verify, "_cases", lambda: {"toy-strain-energy": StrainEnergy})


def test_cli_verify_quick(tmp_path, registered_case):
    from cartan import cli_verify

    out = tmp_path / "report"
    res = CliRunner().invoke(cli_verify.verify_cmd, ["--quick", "--case", "toy-strain-energy", "--out", str(out)])
    assert res.exit_code == 0, res.output
    text = (out / "README.md").read_text()
    assert "| toy-strain-energy |" in text and "pass" in text
    assert list(out.glob("*.png"))
    ds = xr.open_dataset(out / "verification.nc")
    assert "toy-strain-energy__error" in ds
    ds.close()


def test_cli_converge(tmp_path, registered_case):
    from cartan import cli_verify

    out = tmp_path / "wp.nc"
    res = CliRunner().invoke(cli_verify.converge_cmd, ["toy-strain-energy", "-i", "lie-verlet", "--levels", "3",
                                                       "-o", str(out)])
    assert res.exit_code == 0, res.output
    ds = xr.open_dataset(out)
    assert dict(ds.sizes)["level"] == 3
    ds.close()
    res = CliRunner().invoke(cli_verify.converge_cmd, ["no-such-case", "-o", str(out)])
    assert res.exit_code == 2
    assert res.output.count("\n") == 1 and "no-such-case" in res.output


def test_cli_verify_method_section(tmp_path, monkeypatch):
    """The report's schemes-and-integrators section on the ring wave (here with lie-verlet only):
    the text quotes the lattice's round-off residual against collocation's O(h²) one, level by level."""
    import re

    from cartan import cli_verify

    monkeypatch.setattr(cli_verify, "METHOD_INTEGRATORS", ("lie-verlet",))
    case = cartan.registry("cases")["rod-ring-flexural-wave"]
    assert case.compare_methods
    out = tmp_path
    text, parts, total, failed = cli_verify._method_study(case, True, out, None, None)
    assert (total, failed) == (2, 0)
    assert "## Schemes and integrators on one analytic case: `rod-ring-flexural-wave`" in text
    m = re.search(r"`lattice` stays at round-off — at most (\S+) over every level — while the strains "
                  r"`collocation` stores leave those of its frames: (.*?) from n = 16 to n = 128 "
                  r"\(observed order (\S+) in dx\)", text)
    assert m, text
    lattice = float(m.group(1))
    colloc = [float(v) for v in m.group(2).split(" → ")]
    assert lattice <= 1e-12 and len(colloc) == 4
    assert min(colloc) >= 1e3 * lattice and np.all(np.diff(colloc) < 0)
    assert abs(float(m.group(3)) - 2.0) < 0.2
    assert "| lie-verlet / collocation | 5." in text  # the residual table, level by level
    for name in ("methods-work-precision", "methods-error", "methods-invariants"):
        assert (out / f"rod-ring-flexural-wave-{name}.png").stat().st_size > 0
    assert "rod-ring-flexural-wave-methods__integrability_residual" in parts[0]


# ---------------------------------------------------------------------------- thin-rod stability
def thin_rod(radius, n):
    """A straight free Cosserat rod (L = 1) of the given radius, small random velocities."""
    rod = cartan.medium("cosserat-rod", E=1e6, G=4e5, radius=radius, density=1000.0)
    grid = Grid(n, length=1.0)
    initial = rod.initial_state(grid, "straight")
    initial.N = 1e-3 * np.random.default_rng(1).standard_normal((n, 6))
    return Problem(medium=rod, grid=grid, initial=initial)


def test_thin_rod_stability_limit():
    """dx = 0.1 > radius: the shear/rotary-inertia mode ω ~ √(G/ρ)/r sets Δt_max ∝ radius, not dx."""
    import functools

    radii = [0.04, 0.02, 0.01, 0.005]
    dt_max, dt_cfl = [], []
    for r in radii:
        # the default bracket (1/64, 4) × CFL: every trial covers the same physical time,
        # 300 × the CFL estimate (19 200 steps at the bottom of the bracket)
        ds = study.stability(functools.partial(thin_rod, r), "lie-verlet", [11], steps=300, rtol=0.02)
        assert tuple(ds.attrs["bracket"]) == (1 / 64, 4.0)
        assert float(ds["horizon"].squeeze()) == pytest.approx(300 * float(ds["dt_reference"].squeeze()))
        assert float(ds["h"].squeeze()) > r
        assert int(ds["bracketed"].squeeze()) == 1
        dt_max.append(float(ds["dt_max"].squeeze()))
        dt_cfl.append(float(ds["dt_cfl"].squeeze()))
    dt_max, dt_cfl = np.array(dt_max), np.array(dt_cfl)
    # halving the radius halves Δt_max (± 20 %)
    assert np.all(np.abs(dt_max[:-1] / dt_max[1:] / 2.0 - 1.0) < 0.2), dt_max
    # Δt_max tracks the integrator's CFL estimate within a factor 1.5
    assert np.all((dt_max / dt_cfl > 1 / 1.5) & (dt_max / dt_cfl < 1.5)), dt_max / dt_cfl
    # refining dx (still > radius) leaves Δt_max set by the radius
    finer = study.stability(functools.partial(thin_rod, 0.01), "lie-verlet", [21], steps=300, rtol=0.02)
    assert float(finer["h"].squeeze()) > 0.01
    assert float(finer["dt_max"].squeeze()) == pytest.approx(dt_max[2], rel=0.2)
    # forward-euler: unstable at every Δt tried, down to 1/64 of the leapfrog estimate
    for r in (0.04, 0.005):
        fe = study.stability(functools.partial(thin_rod, r), "forward-euler", [11], steps=300)
        assert float(fe["dt_max"].squeeze()) == 0.0
        assert int(fe["bracketed"].squeeze()) == 1
