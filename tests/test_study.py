"""Convergence and stability studies (cartan.study), their scale-out and the verify/converge commands."""

from __future__ import annotations

import json
import math
import os
import pathlib
import signal
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
    ds1 = study.converge(case, integrators=["lie-verlet", "lie-euler"], levels=3, refine="time", store=tmp_path)
    first = SpinningArc.problem_calls
    assert first == 6
    files = sorted(p.name for p in tmp_path.glob("*.json"))
    assert len(files) == 6
    # lose one result: only that task runs again
    (tmp_path / files[0]).unlink()
    ds2 = study.converge(case, integrators=["lie-verlet", "lie-euler"], levels=3, refine="time", store=tmp_path)
    assert SpinningArc.problem_calls == first + 1
    xr.testing.assert_allclose(ds1["error"], ds2["error"])
    study.converge(case, integrators=["lie-verlet", "lie-euler"], levels=3, refine="time", store=tmp_path)
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


# ---------------------------------------------------------------------------- distributed
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
        # the bracket starts at CFL/4: far below the limit a 300-step window sees only part of
        # the (bounded) O(Δt²) energy oscillation, which the drift test would misread
        ds = study.stability(functools.partial(thin_rod, r), "lie-verlet", [11], steps=300, rtol=0.02,
                             bracket=(0.25, 4.0))
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
    finer = study.stability(functools.partial(thin_rod, 0.01), "lie-verlet", [21], steps=300, rtol=0.02,
                            bracket=(0.25, 4.0))
    assert float(finer["h"].squeeze()) > 0.01
    assert float(finer["dt_max"].squeeze()) == pytest.approx(dt_max[2], rel=0.2)
    # forward-euler: unstable at every Δt tried, down to 1/64 of the leapfrog estimate
    for r in (0.04, 0.005):
        fe = study.stability(functools.partial(thin_rod, r), "forward-euler", [11], steps=300)
        assert float(fe["dt_max"].squeeze()) == 0.0
        assert int(fe["bracketed"].squeeze()) == 1
