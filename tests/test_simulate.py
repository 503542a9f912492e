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
    ds = simulate(sc, integrator="rkmk4", dt=0.005, t_end=0.05, save_every=2, compiled=False)  # settings only
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
        ds = simulate(sc, compiled=False)  # the overdamped loops compile in make test-slow
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
    good_path = cartan.io.lastgood_path(path)  # beside the output, which a blow-up never replaces
    assert "Δt = 0.1 exceeds the CFL estimate 0.03" in msg and f"saved to {good_path}" in msg
    assert (
        err.dt == 0.1
        and 0 < err.dt_max < 0.1
        and err.path == good_path
        and err.time == pytest.approx(0.1 * err.step)
    )
    good = cartan.api.open(good_path)
    assert good.sizes["time"] >= 1 and float(good.time[-1]) < err.time
    assert f"(t = {float(good.time[-1]):.6g}) saved" in msg
    assert np.all(np.isfinite(good.S.values))
    assert np.all(np.isfinite(good.kinetic_energy)) and np.all(np.isfinite(good.potential_energy))
    # the last good state is a checkpoint: continue it with a stable step
    cont = simulate(sc, restart=good_path, dt=0.01, t_end=float(good.time[-1]) + 0.05)
    assert float(cont.time[-1]) == pytest.approx(float(good.time[-1]) + 0.05)


def test_instability_error_pickles():
    import pickle

    err = InstabilityError("unstable", step=3, time=0.3, dt=0.1, dt_max=0.05, path=None)
    back = pickle.loads(pickle.dumps(err))
    assert str(back) == "unstable" and (back.step, back.time, back.dt, back.dt_max) == (3, 0.3, 0.1, 0.05)


def test_instability_without_output_uses_a_temporary_file(toy):
    with pytest.warns(StabilityWarning), pytest.raises(InstabilityError) as info:
        simulate(scene("toy-butterfly"), integrator="forward-euler", dt=0.01, t_end=50.0, compiled=False)
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


def test_release_from_rest_is_not_a_blow_up(toy):
    """Released from rest (initial energy at round-off), explicit Euler's step 1 has K = ½m(gΔt)²
    and W = 0: an energy-balance error of 100 % of a state that holds only what the loads put
    there, not growth; the run's scale is that first state's energy.  Four steps of explicit
    Euler at Δt = 0.002 grow each rod mode by at most (1 + (ωΔt)²)² — a blow-up by 1000× takes
    far longer."""
    reset_registry()  # the installed media: the rod's straight state has V ≈ 1e-28, not 0
    with pytest.warns(StabilityWarning, match="no stable Δt for undamped motion"):
        ds = simulate(scene("rod-cantilever-gravity"), integrator="lie-euler", dt=0.002, t_end=0.008,
                      save_every=1, compiled=False)
    assert ds.sizes["time"] == 5
    e_start = abs(float(ds.kinetic_energy[0])) + abs(float(ds.potential_energy[0]))
    assert 0 < e_start < 1e-20 < float(ds.kinetic_energy[1])


def test_progress_is_silent_off_terminal(toy, capsys):
    simulate(scene("toy-butterfly"), t_end=0.05)
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == ""
    simulate(scene("toy-butterfly"), t_end=0.05, progress=True)
    assert "step" in capsys.readouterr().err


def test_integrator_instances_and_options(toy):
    sc = load_scene({**CANTILEVER, "loads": [{"kind": "damping", "coefficients": 1.0}]})
    # the Python path: the overdamped loops compile in make test-slow
    a = simulate(sc, integrator=Overdamped(order=2), dt=5e-4, t_end=0.002, save_every=2, compiled=False)
    b = simulate(
        sc, integrator="overdamped", integrator_options={"order": 2}, dt=5e-4, t_end=0.002, save_every=2,
        compiled=False,
    )
    assert_same_run(a, b)
    assert json.loads(a.attrs["cartan_config"])["run"]["integrator_options"] == {"order": 2}
    with pytest.raises(ValueError, match="order must be 1 or 2"):
        simulate(sc, integrator="overdamped", integrator_options={"order": 3}, dt=5e-4, t_end=0.002)


# ---------------------------------------------------------------------------- work around the steps
def _dense_lambda_max(scheme, state, inv: np.ndarray) -> float:
    """max |eig(M⁻¹K)| (or Γ⁻¹K) of the stiffness assembled column by column with the numpy probe,
    on the free degrees of freedom (live components of nodes that are not clamped)."""
    scheme.compiled_diagnostics = False
    probe = scheme.stiffness_probe(state)
    scheme.compiled_diagnostics = True
    shape, dof = state.S.shape, state.S.size
    J = np.zeros((dof, dof))
    for k in range(dof):
        v = np.zeros(dof)
        v[k] = 1.0
        J[:, k] = (inv * probe(v.reshape(shape))).ravel()
    keep = np.outer(~scheme._clamped, inv > 0).ravel()
    return float(np.max(np.abs(np.linalg.eigvals(J[np.ix_(keep, keep)]))))


def _t1_rod(n: int) -> cartan.Problem:
    """A straight free rod with the Timoshenko-beam material of benchmarks/compare.py (T1)."""
    rod = cartan.medium("cosserat-rod", E=1e6, G=1e4, radius=0.25, density=5000.0)
    grid = cartan.Grid(n, length=3.0)
    return cartan.Problem(rod, grid, rod.initial_state(grid, "straight"))


@pytest.mark.parametrize("kind", ["straight", "dead", "ring"])
def test_cfl_estimate_against_the_exact_eigenvalue(kind):
    """dt_max = 1/√λ_max(M⁻¹K) (and 1/λ_max(Γ⁻¹K) overdamped) against a dense eigensolver.

    The power iteration stops when two Rayleigh quotients agree to 1e-3; the quotient
    approaches λ_max from below, so the estimate lies above the exact value, measured by
    0.2–0.8 % (inertial, √ of the quotient) and 0.2–1.7 % (overdamped) on these rods: the
    bounds 1 % and 2 % leave room for the stopping rule, not for a wrong operator."""
    from test_lattice_compiled import rod_problem

    problem = _t1_rod(16) if kind == "straight" else rod_problem(kind)
    scheme = Lattice(problem)
    state = scheme.initial_state()
    exact = 1.0 / np.sqrt(_dense_lambda_max(scheme, state, 1.0 / scheme.mass))
    assert 1.0 <= scheme.dt_max(state) / exact <= 1.01
    if kind != "straight":
        exact = 1.0 / _dense_lambda_max(scheme, state, 1.0 / scheme.drag())
        assert 1.0 <= scheme.dt_max(state, rate="overdamped") / exact <= 1.02


def test_compiled_diagnostics_only_for_large_problems():
    """Small problems keep the numpy CFL estimate (its compiled kernels would compile for longer
    than the estimate takes); from ``compiled_diagnostics_from`` unknowns on, the compiled one."""
    scheme = Lattice(_t1_rod(40))
    state = scheme.initial_state()
    assert not scheme.uses_compiled_diagnostics()
    assert scheme.stiffness_probe(state).__module__ == "cartan.schemes.base"
    scheme.compiled_diagnostics_from = 40 * 6
    assert scheme.uses_compiled_diagnostics()
    scheme.compiled_diagnostics = False
    assert not scheme.uses_compiled_diagnostics()


@pytest.mark.slow  # the probe's compiled drift and force: ≈ 76 s on a fresh cache
@pytest.mark.parametrize("kind", ["straight", "dead", "follower", "ring", "planar"])
def test_compiled_cfl_estimate_matches_the_numpy_one(kind):
    """The compiled stiffness probe gives the numpy estimate — SE(3) rods on the passes of their
    hand-written loops, the planar (SE(2)) rod on the generated operators —: the same power
    iteration on the same operator, round-off apart.  The central difference divides
    force round-off (≈ 1e-16 of the stress scale) by ε = 1e-7, so the two estimates may differ
    by ≈ 1e-9 relative (measured ≤ 2e-12)."""
    from test_lattice_compiled import rod_problem

    problem = {"straight": lambda: _t1_rod(40), "planar": lambda: rod_problem("dead", planar=True)}.get(
        kind, lambda: rod_problem(kind))()
    scheme = Lattice(problem)
    scheme.compiled_diagnostics_from = 0  # the small rods of the tests run it too
    state = scheme.initial_state()
    before = state.copy()
    expected = "cartan.compiled.diagnostics" if kind == "planar" else "cartan.schemes._lattice_diagnostics"
    assert scheme.stiffness_probe(state).__module__ == expected
    for rate in ("inertial", "overdamped") if kind != "straight" else ("inertial",):
        fast = scheme.dt_max(state, rate=rate)
        scheme.compiled_diagnostics = False
        ref = scheme.dt_max(state, rate=rate)
        scheme.compiled_diagnostics = True
        assert abs(fast / ref - 1.0) <= 1e-9, (rate, fast, ref)
    assert state.t == before.t and np.array_equal(state.S, before.S)
    assert all(np.array_equal(state.arrays[k], before.arrays[k]) for k in before.arrays)


def test_cfl_estimate_rejects_bad_settings():
    scheme = Lattice(_t1_rod(8))
    state = scheme.initial_state()
    with pytest.raises(ValueError, match="rate must be 'inertial' or 'overdamped'"):
        scheme.dt_max(state, rate="viscous")
    with pytest.raises(ValueError, match="iterations must be an integer ≥ 1"):
        scheme.dt_max(state, iterations=0)
    with pytest.raises(ValueError, match="eps must be finite and > 0"):
        scheme.dt_max(state, eps=0.0)


def test_compiled_false_runs_the_reference_cfl_estimate():
    """simulate(compiled=False) computes dt_max with the numpy forces (the reference path)."""
    problem = _t1_rod(12)
    scheme = Lattice(problem)
    scheme.compiled_diagnostics = False
    ref = float(LieVerlet().dt_max(scheme, scheme.initial_state()))
    ds = simulate(problem, dt=1e-4, t_end=2e-4, compiled=False)
    assert json.loads(ds.attrs["cartan_config"])["run"]["dt_max"] == ref


def test_prefix_products_compiled_against_doubling():
    """The compiled sequential frame rebuild against numpy's doubling scan, for a chain and a
    batch of chains: products of n ≤ 400 SE(3) factors of norm ≈ 1 (positions up to ≈ 30)
    agree to round-off, a few ulps times √n (measured ≤ 4e-15 absolute)."""
    from cartan.schemes.base import prefix_products

    g = cartan.group("SE3")
    rng = np.random.default_rng(3)
    for shape in ((399,), (99, 3)):
        steps = g.exp(0.1 * rng.standard_normal((*shape, 6)))
        first = g.exp(rng.standard_normal((*shape[1:], 6)))
        fast = prefix_products(first, steps)
        with cartan.use_backend("numpy"):
            ref = prefix_products(first, steps)
        assert fast.shape == ref.shape == (shape[0] + 1, *shape[1:], 4, 4)
        assert np.max(np.abs(fast - ref)) <= 1e-13 * max(1.0, float(np.max(np.abs(ref))))
        assert np.array_equal(fast[0], first)


@pytest.mark.parametrize("kind", ["dead", "ring", "planar"])
def test_guard_energies_match_the_reference(kind):
    """The guard's compiled energies against Scheme.kinetic_energy/Lattice.potential_energy
    (the same sums in another order: round-off, ≤ 1e-12 relative) on moving, loaded rods: the
    SE(3) rods' plan energies, the planar (SE(2)) rod's generated ones."""
    from test_lattice_compiled import rod_problem
    from toys import advance_compiled

    from cartan.compiled import diagnostics
    from cartan.schemes import _lattice_diagnostics

    problem = rod_problem("dead", planar=True) if kind == "planar" else rod_problem(kind)
    scheme = Lattice(problem)
    state = scheme.initial_state()
    assert advance_compiled(scheme, LieVerlet(), state, 1e-3, 20)
    guard_energies = (diagnostics if kind == "planar" else _lattice_diagnostics).guard_energies
    K, V = guard_energies(scheme, state)
    assert K > 0 and V != 0
    assert K == pytest.approx(scheme.kinetic_energy(state), rel=1e-12)
    assert V == pytest.approx(scheme.potential_energy(state), rel=1e-12)
    scheme.compiled_diagnostics = False
    assert guard_energies(scheme, state) is None


def test_frame_record_total_momentum_with_the_built_frames():
    """frame_record reuses its rebuilt frames for the total momentum: equal to the scheme's own."""
    from test_lattice_compiled import rod_problem

    from cartan import io

    scheme = Lattice(rod_problem("ring"))
    state = scheme.initial_state()
    scheme.compiled_advance(LieVerlet(), state, 1e-3, 10)
    rec = io.frame_record(scheme, LieVerlet(), state)
    assert np.array_equal(rec["total_momentum"], scheme.total_momentum(state))
