"""``simulate``: settings, restart bit for bit, blow-up detection, stability warning."""

from __future__ import annotations

import importlib
import json
import warnings

import numpy as np
import pytest
import xarray as xr
from test_scene import CANTILEVER, toy_registry
from toys import arc_problem

import cartan
from cartan.api import InstabilityError, StabilityWarning, load_scene, scene, simulate
from cartan.integrators import LieVerlet, Overdamped
from cartan.plugins import reset_registry
from cartan.schemes import Lattice

simulate_module = importlib.import_module("cartan.simulate")  # the module, not the function

#: attributes that legitimately differ between an uninterrupted and a restarted run
VOLATILE = ("history", "cartan_config")


@pytest.fixture
def toy(tmp_path):
    toy_registry(tmp_path)
    yield tmp_path
    reset_registry()


def assert_same_run(a: xr.Dataset, b: xr.Dataset) -> None:
    """Identical data, coordinates and attributes except the history and the counters."""
    xr.testing.assert_identical(a.drop_attrs(deep=False), b.drop_attrs(deep=False))
    for name in a.variables:
        assert np.array_equal(a[name].values, b[name].values), name
    assert {k: v for k, v in a.attrs.items() if k not in VOLATILE} == {
        k: v for k, v in b.attrs.items() if k not in VOLATILE
    }
    ca, cb = json.loads(a.attrs["cartan_config"]), json.loads(b.attrs["cartan_config"])
    assert ca["problem"] == cb["problem"] and ca["run"] == cb["run"]
    assert ca["counters"]["nstep"] == cb["counters"]["nstep"]


def test_scene_settings_and_overrides(toy):
    sc = scene("toy-butterfly")
    ds = simulate(sc)
    assert ds.sizes["time"] == 5 and float(ds.time[-1]) == pytest.approx(0.2)
    cfg = json.loads(ds.attrs["cartan_config"])["run"]
    assert (cfg["integrator"], cfg["scheme"], cfg["dt"], cfg["save_every"]) == (
        "lie-verlet",
        "lattice",
        0.01,
        5,
    )
    ds = simulate(sc, integrator="rkmk4", dt=0.005, t_end=0.05, save_every=2)
    assert list(ds.step.values) == [0, 2, 4, 6, 8, 10]
    assert json.loads(ds.attrs["cartan_config"])["run"]["integrator"] == "rkmk4"
    # conservative run: lie-verlet keeps the energy to O(dt²)
    E = ds.kinetic_energy + ds.potential_energy
    assert float(abs(E - E[0]).max()) < 1e-3 * float(E[0])


def test_names_classes_and_files(toy):
    path = toy / "toy-butterfly.toml"
    by_name = simulate(str(path), t_end=0.05)
    by_class = simulate(load_scene(path), integrator=LieVerlet, scheme=Lattice, t_end=0.05)
    assert_same_run(by_name, by_class)
    assert_same_run(by_name, simulate("toy-butterfly", t_end=0.05))


def test_problem_defaults_dt_and_frames():
    prob = arc_problem(n=9, curvature=1.0)
    ds = simulate(prob, t_end=0.5)
    cfg = json.loads(ds.attrs["cartan_config"])["run"]
    assert 0.4 * cfg["dt_max"] <= cfg["dt"] <= 0.5 * cfg["dt_max"]
    assert cfg["save_every"] == max(1, cfg["nsteps"] // 100)
    assert float(ds.time[-1]) >= 0.5 - 1e-12
    with pytest.raises(ValueError, match="t_end is required"):
        simulate(prob)
    with pytest.raises(ValueError, match="checkpoint_every needs an output"):
        simulate(prob, t_end=0.1, checkpoint_every=1)


def test_overdamped_relaxation(toy):
    sc = load_scene(
        {
            "medium": "toy-rod",
            "grid": {"n": 9},
            "initial": {"kind": "arc", "curvature": 2.0},
            "loads": [{"kind": "damping", "coefficients": 1.0}],
            "run": {"integrator": "overdamped", "dt": 5e-4, "t_end": 0.01, "save_every": 5},
        }
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error", StabilityWarning)
        ds = simulate(sc)
    assert np.all(ds.kinetic_energy.values == 0) and np.all(np.diff(ds.potential_energy.values) <= 0)
    assert float(np.abs(ds.N.isel(time=-1)).max()) > 0  # N of the gradient flow is recorded


def test_restart_after_finishing_is_bit_for_bit(toy):
    sc = load_scene({**CANTILEVER, "run": {"dt": 0.01, "t_end": 0.2, "save_every": 3}})
    full = simulate(sc, output=toy / "full.nc")
    simulate(sc, t_end=0.09, output=toy / "part.nc")
    cont = simulate(sc, restart=toy / "part.nc", t_end=0.2)
    assert_same_run(full, cont)
    assert_same_run(cartan.api.open(toy / "full.nc"), cartan.api.open(toy / "part.nc"))
    # a scene run can be continued from the file alone
    again = simulate(None, restart=toy / "part.nc")
    assert_same_run(full, again)


@pytest.mark.parametrize("integrator", ["lie-verlet", "rkmk4"])
def test_restart_after_interruption_is_bit_for_bit(toy, monkeypatch, integrator):
    sc = load_scene({**CANTILEVER, "run": {"dt": 0.01, "t_end": 0.3, "save_every": 2}})
    full = simulate(sc, integrator=integrator, output=toy / "full.nc", checkpoint_every=3)

    calls = {"n": 0}
    real = simulate_module._advance

    def interrupted(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 9:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(simulate_module, "_advance", interrupted)
    path = toy / "run.nc"
    with pytest.raises(KeyboardInterrupt):
        simulate(sc, integrator=integrator, output=path, checkpoint_every=3)
    saved = cartan.api.open(path)
    assert saved.sizes["time"] == 7  # the checkpoint after 6 saves (plus the initial frame)
    monkeypatch.setattr(simulate_module, "_advance", real)
    cont = simulate(sc, restart=path)
    assert_same_run(full, cont)
    assert_same_run(full, cartan.api.open(path))
    assert cont.attrs["history"].count("\n") == 1  # both commands are recorded


def test_restart_rejects_another_problem(toy):
    sc = load_scene(CANTILEVER)
    simulate(sc, output=toy / "a.nc")
    other = load_scene({**CANTILEVER, "grid": {"n": 7, "length": 1.0}})
    with pytest.raises(ValueError, match="different problem"):
        simulate(other, restart=toy / "a.nc", t_end=0.2)


def test_stability_warning_before_the_run(toy):
    sc = scene("toy-butterfly")
    with pytest.warns(StabilityWarning, match=r"Δt = 0.04 exceeds the CFL estimate 0.03\d+ of 'lie-verlet'"):
        simulate(sc, dt=0.04, t_end=0.04)
    with warnings.catch_warnings():
        warnings.simplefilter("error", StabilityWarning)
        simulate(sc, dt=0.02, t_end=0.04)


def test_instability_error_keeps_last_good_state(toy):
    sc = scene("toy-butterfly")
    path = toy / "blow.nc"
    with pytest.warns(StabilityWarning), pytest.raises(InstabilityError) as info:
        simulate(sc, dt=0.1, t_end=20.0, save_every=2, output=path)
    err = info.value
    msg = str(err)
    assert msg.startswith(f"unstable at step {err.step} (t = ")
    assert "Δt = 0.1 exceeds the CFL estimate 0.03" in msg and f"saved to {path}" in msg
    assert (
        err.dt == 0.1
        and 0 < err.dt_max < 0.1
        and err.path == path
        and err.time == pytest.approx(0.1 * err.step)
    )
    good = cartan.api.open(path)
    assert good.sizes["time"] >= 1 and float(good.time[-1]) < err.time
    assert f"(t = {float(good.time[-1]):.6g}) saved" in msg
    assert np.all(np.isfinite(good.S.values))
    assert np.all(np.isfinite(good.kinetic_energy)) and np.all(np.isfinite(good.potential_energy))
    # the last good state is a checkpoint: continue it with a stable step
    cont = simulate(sc, restart=path, dt=0.01, t_end=float(good.time[-1]) + 0.05)
    assert float(cont.time[-1]) == pytest.approx(float(good.time[-1]) + 0.05)


def test_instability_error_pickles():
    import pickle

    err = InstabilityError("unstable", step=3, time=0.3, dt=0.1, dt_max=0.05, path=None)
    back = pickle.loads(pickle.dumps(err))
    assert str(back) == "unstable" and (back.step, back.time, back.dt, back.dt_max) == (3, 0.3, 0.1, 0.05)


def test_instability_without_output_uses_a_temporary_file(toy):
    with pytest.warns(StabilityWarning), pytest.raises(InstabilityError) as info:
        simulate(scene("toy-butterfly"), integrator="forward-euler", dt=0.01, t_end=50.0)
    err = info.value
    assert err.dt_max == 0 and "CFL estimate 0" in str(err)
    try:
        assert err.path.name.startswith("cartan-unstable-")
        assert cartan.api.open(err.path).sizes["time"] >= 1
    finally:
        err.path.unlink()


def test_in_block_detection_names_the_step(toy):
    """With rare saves the per-step guard stops the run inside the save block."""
    with pytest.warns(StabilityWarning), pytest.raises(InstabilityError) as info:
        simulate(scene("toy-butterfly"), dt=0.06, t_end=100.0, save_every=10, output=toy / "x.nc")
    assert info.value.step % 10 != 0 or "non-finite" in str(info.value)


def test_progress_is_silent_off_terminal(toy, capsys):
    simulate(scene("toy-butterfly"), t_end=0.05)
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == ""
    simulate(scene("toy-butterfly"), t_end=0.05, progress=True)
    assert "step" in capsys.readouterr().err


def test_integrator_instances_and_options(toy):
    sc = load_scene({**CANTILEVER, "loads": [{"kind": "damping", "coefficients": 1.0}]})
    a = simulate(sc, integrator=Overdamped(order=2), dt=5e-4, t_end=0.002, save_every=2)
    b = simulate(
        sc, integrator="overdamped", integrator_options={"order": 2}, dt=5e-4, t_end=0.002, save_every=2
    )
    assert_same_run(a, b)
    assert json.loads(a.attrs["cartan_config"])["run"]["integrator_options"] == {"order": 2}
    with pytest.raises(ValueError, match="order must be 1 or 2"):
        simulate(sc, integrator="overdamped", integrator_options={"order": 3}, dt=5e-4, t_end=0.002)
