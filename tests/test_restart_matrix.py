"""Restarts are bit for bit for every integrator × scheme × ``compiled`` setting.

A run to t₁ continued to t₂ from its checkpoint (``simulate(..., restart=path)``) gives the
same frames, series, coordinates and final checkpoint as one uninterrupted run to t₂, and the
same ``cartan_config`` (the scene it came from included) apart from the force and wall-time
counters.  The state after a number of steps does not depend on how the steps were grouped
into blocks (save blocks, the compiled loops' sub-blocks, separate calls).
"""

from __future__ import annotations

import importlib
import json
import pathlib
import tomllib
import warnings

import netCDF4
import numpy as np
import pytest
from toys import advance_compiled, params_of, wave

import cartan
from cartan import io
from cartan.api import load_scene, simulate
from cartan.integrators import Integrator
from cartan.integrators.explicit import Kinematic, Overdamped
from cartan.integrators.implicit import ImplicitMidpoint
from cartan.plugins import get_registry
from cartan.schemes import Collocation, Lattice

#: a clamped Cosserat rod, bent, moving, under gravity, a dead end load and damping on every
#: component (the overdamped integrator needs drag on all of them)
SCENE = """\
name = "restart-matrix-rod"
description = "A clamped, bent and moving Cosserat rod for the restart tests."
medium = "cosserat-rod"

[parameters]
stretch_shear = [100.0, 50.0, 50.0]
bend_twist = [1.0, 2.0, 2.0]
mass = 1.0
rotational_inertia = [0.02, 0.01, 0.01]

[grid]
n = 9
length = 1.0

[boundaries.start]
kind = "clamped"

[boundaries.end]
kind = "free"
load = [0.5, 0.6, 0.7, 0.8, 0.9, 1.0]

[[loads]]
kind = "damping"
coefficients = [2.0, 2.0, 2.0, 0.05, 0.05, 0.05]

[[loads]]
kind = "gravity"
g = [0.0, -9.81, 0.0]

[initial]
kind = "arc"
curvature = 2.0
velocity = [0.1, 0.15, 0.2, 0.25, 0.3, 0.35]
"""

#: steps of the first part and of the whole run; frames every SAVE steps, so that a save block
#: holds several of the compiled loops' sub-blocks (steps 1, 2, 4 of the block)
SAVE, PART, WHOLE = 6, 12, 24
SCENE_DICT = tomllib.loads(SCENE)


#: id → (integrator, options, Δt); the explicit Euler methods have no stable Δt without
#: damping (a StabilityWarning, ignored here: the runs are short)
INTEGRATORS = {
    "lie-verlet": ("lie-verlet", {}, 1e-3),
    "lie-euler": ("lie-euler", {}, 1e-3),
    "forward-euler": ("forward-euler", {}, 1e-3),
    "rkmk4": ("rkmk4", {}, 1e-3),
    "overdamped-1": ("overdamped", {"order": 1}, 1e-4),
    "overdamped-2": ("overdamped", {"order": 2}, 1e-4),
    "implicit-midpoint": ("implicit-midpoint", {}, 1e-3),
    "kinematic": ("kinematic", {"velocity": wave, "order": 2}, 1e-3),
}
SCHEMES = ["lattice", "collocation"]


def slow_when(item) -> bool:
    """``make test`` runs the Python paths and the ``lie-verlet`` loops of the rod; the other
    compiled loops (and the d = 2 sigma model's) in ``make test-slow`` (tests/conftest.py)."""
    p = params_of(item)
    if item.originalname == "test_compiled_steps_do_not_depend_on_the_blocks":
        return p["key"] != "lie-verlet" or p["problem"] != "rod"
    compiled = p.get("compiled", False)
    return compiled and (p.get("key") != "lie-verlet" or item.originalname != "test_restart_is_bit_for_bit")
#: counters that legitimately differ between an uninterrupted and a restarted run
VOLATILE_COUNTERS = ("nforce", "wall_time")


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory) -> pathlib.Path:
    path = tmp_path_factory.mktemp("restart-matrix") / "rod.toml"
    path.write_text(SCENE)
    return path


def _config(ds) -> dict:
    cfg = json.loads(ds.attrs["cartan_config"])
    for key in VOLATILE_COUNTERS:
        cfg["counters"].pop(key)
    return cfg


def assert_same_run(a, b) -> None:
    """Every variable bit for bit, the same attributes (the history apart) and the same
    ``cartan_config`` (the force and wall-time counters apart)."""
    assert set(a.variables) == set(b.variables)
    assert dict(a.sizes) == dict(b.sizes)
    for name in a.variables:
        assert a[name].dims == b[name].dims, name
        assert np.array_equal(a[name].values, b[name].values), name
    assert {k: v for k, v in a.attrs.items() if k not in ("history", "cartan_config")} == {
        k: v for k, v in b.attrs.items() if k not in ("history", "cartan_config")
    }
    assert _config(a) == _config(b)


def assert_same_checkpoint(path_a: pathlib.Path, path_b: pathlib.Path) -> None:
    """The final checkpoints of two run files hold the same state, bit for bit, and the same
    run information (the force and wall-time counters apart)."""
    (sa, ia, ra, _), (sb, ib, rb, _) = io.read_checkpoint(path_a), io.read_checkpoint(path_b)
    assert sa.t == sb.t and sa.scalars == sb.scalars
    assert np.array_equal(sa.S, sb.S)
    assert set(sa.arrays) == set(sb.arrays)
    for key in sa.arrays:
        assert np.array_equal(sa.arrays[key], sb.arrays[key]), key
    for info in (ia, ib):
        for key in VOLATILE_COUNTERS:
            info["counters"].pop(key)
    assert ia == ib
    assert ra.keys() == rb.keys()
    for key in ra:
        assert np.array_equal(np.asarray(ra[key]), np.asarray(rb[key])), key


@pytest.fixture
def python_steps(monkeypatch):
    """How many steps the Python loop (``step`` of the integrators) takes."""
    calls = {"n": 0}
    for cls in (Integrator, ImplicitMidpoint):
        real = cls.__dict__["step"]

        def counted(self, scheme, state, dt, real=real):
            calls["n"] += 1
            return real(self, scheme, state, dt)

        monkeypatch.setattr(cls, "step", counted)
    return calls


#: the kinematic loop on collocation compiles a generated module of its own (30-100 s on a fresh cache)
SLOW_RUNS = {("kinematic", "collocation", True)}
MATRIX = [pytest.param(key, scheme, compiled, id=f"{key}-{scheme}-{'compiled' if compiled else 'python'}",
                       marks=[pytest.mark.slow] if (key, scheme, compiled) in SLOW_RUNS else [])
          for key in INTEGRATORS for scheme in SCHEMES for compiled in (True, False)]


@pytest.mark.parametrize(("key", "scheme", "compiled"), MATRIX)
def test_restart_is_bit_for_bit(key, scheme, compiled, scene_file, tmp_path, python_steps):
    """A run of the scene file to t₁ (PART steps), continued to t₂ (WHOLE steps) from its
    checkpoint given the Problem, is the uninterrupted run to t₂: frames, series, coordinates,
    the run file and its final checkpoint bit for bit, the same configuration (scene file
    included).  A combination the integrator or the scheme refuses is skipped, with its error."""
    integrator, options, dt = INTEGRATORS[key]
    settings = dict(integrator=integrator, integrator_options=options, scheme=scheme, dt=dt, save_every=SAVE,
                    checkpoint_every=1, compiled=compiled)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", cartan.StabilityWarning)
        try:
            whole = simulate(load_scene(scene_file), t_end=WHOLE * dt, output=tmp_path / "whole.nc", **settings)
        except (NotImplementedError, ValueError, TypeError) as exc:  # the combination is refused
            pytest.skip(f"{key} on {scheme} is not supported: {exc}")
        simulate(load_scene(scene_file), t_end=PART * dt, output=tmp_path / "part.nc", **settings)
        steps_before = python_steps["n"]
        # continued from the file, given the Problem (not the scene): integrator, scheme, Δt,
        # options and intervals come from the checkpoint; a callable option is given again
        again = {"velocity": wave} if integrator == "kinematic" else None
        continued = simulate(load_scene(scene_file).problem, restart=tmp_path / "part.nc", t_end=WHOLE * dt,
                             integrator_options=again, compiled=compiled)
    assert whole.sizes["time"] == WHOLE // SAVE + 1 and int(whole.step[-1]) == WHOLE
    assert_same_run(whole, continued)
    assert_same_run(cartan.open(tmp_path / "whole.nc"), cartan.open(tmp_path / "part.nc"))
    assert_same_checkpoint(tmp_path / "whole.nc", tmp_path / "part.nc")
    cfg = json.loads(continued.attrs["cartan_config"])
    assert cfg["scene_path"] == str(scene_file) and cfg["scene"]["name"] == "restart-matrix-rod"
    assert (cfg["run"]["integrator"], cfg["run"]["scheme"]) == (integrator, scheme)
    # the continuation ran on the path asked for: the compiled loops take every step, or none
    assert python_steps["n"] - steps_before == (0 if compiled else WHOLE - PART)
    # the run moved: the restart had something to reproduce
    assert not np.array_equal(whole.position.values[0], whole.position.values[-1])


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "python"])
@pytest.mark.parametrize("mode", ["extended", "interrupted"])
def test_overdamped_ring_restart_is_bit_for_bit(mode, compiled, tmp_path, monkeypatch):
    """The registered scene ``rod-ring-relax`` (overdamped, lattice), continued after a finished
    part or after an interruption, given its Problem: the same run, and the scene's file kept."""
    simulate_module = importlib.import_module("cartan.simulate")  # the module, not the function
    sc = cartan.scene("rod-ring-relax")
    settings = dict(save_every=50, checkpoint_every=2, compiled=compiled)
    whole = simulate(sc, t_end=0.12, output=tmp_path / "whole.nc", **settings)
    path = tmp_path / "part.nc"
    if mode == "extended":
        simulate(sc, t_end=0.06, output=path, **settings)
    else:
        calls = {"n": 0}
        real = simulate_module._advance

        def interrupted(*args, **kwargs):
            calls["n"] += 1
            if calls["n"] == 4:
                raise KeyboardInterrupt
            return real(*args, **kwargs)

        monkeypatch.setattr(simulate_module, "_advance", interrupted)
        with pytest.raises(KeyboardInterrupt):
            simulate(sc, t_end=0.12, output=path, **settings)
        monkeypatch.setattr(simulate_module, "_advance", real)
        assert cartan.open(path).sizes["time"] == 3  # the checkpoint after 2 saves
    continued = simulate(sc.problem, restart=path, t_end=0.12, compiled=compiled)
    assert_same_run(whole, continued)
    assert_same_checkpoint(tmp_path / "whole.nc", path)
    assert json.loads(continued.attrs["cartan_config"])["scene_path"] == str(sc.path)


def test_scene_provenance_survives_restarts(scene_file, tmp_path):
    """The scene and its file stay in ``cartan_config`` and in the checkpoint through restarts
    given the Problem, the scene rebuilt from the file (``simulate(None, restart=...)``) or the
    scene again; a run of a bare Problem has neither."""
    settings = dict(integrator="lie-verlet", dt=1e-3, save_every=SAVE)
    path = tmp_path / "run.nc"
    simulate(load_scene(scene_file), t_end=PART * 1e-3, output=path, **settings)
    for i, given in enumerate([lambda: load_scene(scene_file).problem, lambda: None, lambda: load_scene(scene_file)]):
        ds = simulate(given(), restart=path, t_end=(PART + (i + 1) * SAVE) * 1e-3)
        cfg = json.loads(ds.attrs["cartan_config"])
        assert cfg["scene_path"] == str(scene_file), i
        assert cfg["scene"]["name"] == "restart-matrix-rod", i
        _, info, _, _ = io.read_checkpoint(path)
        assert info["scene_path"] == str(scene_file) and info["scene"]["name"] == "restart-matrix-rod"
    # a bare Problem: no scene before or after a restart
    bare = tmp_path / "bare.nc"
    simulate(load_scene(scene_file).problem, t_end=PART * 1e-3, output=bare, **settings)
    ds = simulate(load_scene(scene_file).problem, restart=bare, t_end=WHOLE * 1e-3)
    cfg = json.loads(ds.attrs["cartan_config"])
    assert cfg["scene_path"] is None and cfg["scene"] is None


def _edit_checkpoint(path: pathlib.Path, edit) -> None:
    """Rewrite the JSON attribute of the checkpoint group of a run file with ``edit(meta)``."""
    with netCDF4.Dataset(path, "a") as nc:
        group = nc.groups["checkpoint"]
        meta = json.loads(group.getncattr("cartan_checkpoint"))
        edit(meta)
        group.setncattr("cartan_checkpoint", json.dumps(meta))


def test_scene_path_of_a_checkpoint_without_it(scene_file, tmp_path):
    """A checkpoint without ``scene_path`` (files written before it was kept there) takes it
    from the run file's ``cartan_config``; a ``scene_path`` that is not a path is a damaged
    checkpoint."""
    path = tmp_path / "run.nc"
    simulate(load_scene(scene_file), integrator="lie-verlet", dt=1e-3, t_end=PART * 1e-3, save_every=SAVE,
             output=path)
    _edit_checkpoint(path, lambda meta: meta.pop("scene_path"))
    ds = simulate(load_scene(scene_file).problem, restart=path, t_end=WHOLE * 1e-3)
    assert json.loads(ds.attrs["cartan_config"])["scene_path"] == str(scene_file)
    assert io.read_checkpoint(path)[1]["scene_path"] == str(scene_file)
    _edit_checkpoint(path, lambda meta: meta.update(scene_path=42))
    with pytest.raises(ValueError, match="damaged checkpoint: scene_path must be a path or null, got 42"):
        simulate(None, restart=path, t_end=(WHOLE + SAVE) * 1e-3)


# ---------------------------------------------------------------------------- blocks
def sigma_problem():
    """The sigma model on S² over a periodic 6 × 5 grid (d = 2; SO(3) with a gauge component),
    moving, with its harmonic-map drag."""
    medium = cartan.medium("sigma-model", n=2, d=2)
    grid = cartan.Grid((6, 5), 1.0, periodic=(True, True))
    init = medium.initial_state(grid, "random-smooth", amplitude=0.6, gauge_amplitude=0.3, velocity_amplitude=0.4,
                                seed=1)
    return cartan.Problem(medium, grid, init, {}, [medium.make_load("drag", gamma=0.7)])


PROBLEMS = {"rod": lambda: load_scene(SCENE_DICT).problem, "sigma-2d": sigma_problem}

#: id → integrator factory
BLOCK_INTEGRATORS = {
    "lie-verlet": cartan.integrators.LieVerlet,
    "lie-euler": cartan.integrators.LieEuler,
    "forward-euler": cartan.integrators.ForwardEuler,
    "rkmk4": cartan.integrators.RKMK4,
    "overdamped-1": lambda: Overdamped(order=1),
    "overdamped-2": lambda: Overdamped(order=2),
    "implicit-midpoint": ImplicitMidpoint,
    "kinematic": lambda: Kinematic(velocity=wave, order=2),
}


def _advance_in_blocks(scheme, make, dt: float, blocks, saved: bool):
    """``sum(blocks)`` compiled steps (the integrator's own blocks, else the scheme's hand-written
    loops, else the generated loop) in calls of ``blocks`` steps, or None when the compiled
    path declines; with ``saved``, the
    integrator's velocity is asked for before every call, as a saved frame asks for it."""
    state = scheme.initial_state()
    state.scalars.setdefault("nstep", 0)
    integ = make()
    own = getattr(integ, "compiled_advance", None)
    for size in blocks:
        if saved:
            integ.velocity(scheme, state)
        ran = own(scheme, state, dt, size) if own is not None else advance_compiled(scheme, integ, state, dt, size)
        if not ran:
            return None
    return state


#: (integrator, problem) pairs; ``kinematic`` on the rod only (its generated loop, one module per
#: velocity function, scheme and grid dimension, compiles in seconds per combination)
BLOCK_CASES = [(key, problem) for problem in PROBLEMS for key in BLOCK_INTEGRATORS
               if key != "kinematic" or problem == "rod"]
#: combinations whose loop module no other fast test compiles (25-55 s each on a fresh cache): the
#: kinematic loop on collocation, the implicit blocks of the d = 2 sigma model on collocation,
#: the first-order loops of the d = 2 sigma model on the lattice; their blocks stay covered by
#: the same integrators on the rod
SLOW_BLOCK_CASES = {("kinematic", "rod", "collocation"), ("implicit-midpoint", "sigma-2d", "collocation"),
                    ("implicit-midpoint", "sigma-2d", "lattice"),
                    ("lie-euler", "sigma-2d", "lattice"), ("forward-euler", "sigma-2d", "lattice"),
                    ("rkmk4", "sigma-2d", "lattice")}


@pytest.mark.parametrize(("key", "problem", "scheme_type"), [
    pytest.param(key, problem, scheme_type, id=f"{key}-{problem}-{sid}",
                 marks=[pytest.mark.slow] if (key, problem, sid) in SLOW_BLOCK_CASES else [])
    for key, problem in BLOCK_CASES for scheme_type, sid in ((Lattice, "lattice"), (Collocation, "collocation"))])
def test_compiled_steps_do_not_depend_on_the_blocks(key, problem, scheme_type):
    """The compiled loops give the same state after 13 steps in one call as in calls of
    1, 2, 4 and 6 steps, with or without the integrator's velocity asked for in between (the
    reference path's value, which agrees with the compiled one to round-off only)."""
    scheme = scheme_type(PROBLEMS[problem]())
    make = BLOCK_INTEGRATORS[key]
    dt_max = make().dt_max(scheme, scheme.initial_state())
    dt = 0.4 * dt_max if 0 < dt_max < np.inf else 1e-3
    one = _advance_in_blocks(scheme, make, dt, [13], saved=False)
    if one is None:
        pytest.skip(f"no compiled loop runs {key} on {scheme.name} for {problem} (d = {scheme.grid.d})")
    assert one.scalars["nstep"] == 13
    for blocks, saved in (([1, 2, 4, 6], False), ([1, 2, 4, 6], True), ([13], True)):
        split = _advance_in_blocks(scheme, make, dt, blocks, saved)
        assert split.t == one.t and split.scalars == one.scalars, (blocks, saved)
        assert np.array_equal(split.S, one.S), (blocks, saved)
        for name in one.arrays:
            assert np.array_equal(split.arrays[name], one.arrays[name]), (name, blocks, saved)


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "python"])
@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("key", ["lie-verlet", "overdamped-1", "overdamped-2"])
def test_restart_on_a_surface_is_bit_for_bit(key, scheme, compiled, tmp_path):
    """A d = 2 problem (the sigma model), given as a Problem: the same run, and no scene."""
    integrator, options, _ = INTEGRATORS[key]
    problem = sigma_problem()
    scheme_obj = {"lattice": Lattice, "collocation": Collocation}[scheme](problem)
    dt = 0.4 * get_registry().get("integrators", integrator)(**options).dt_max(scheme_obj, scheme_obj.initial_state())
    settings = dict(integrator=integrator, integrator_options=options, scheme=scheme, dt=dt, save_every=SAVE,
                    compiled=compiled)
    whole = simulate(sigma_problem(), t_end=WHOLE * dt, **settings)
    simulate(sigma_problem(), t_end=PART * dt, output=tmp_path / "part.nc", **settings)
    continued = simulate(sigma_problem(), restart=tmp_path / "part.nc", t_end=WHOLE * dt, compiled=compiled)
    assert int(continued.step[-1]) == WHOLE
    assert_same_run(whole, continued)
    cfg = json.loads(continued.attrs["cartan_config"])
    assert cfg["scene"] is None and cfg["scene_path"] is None
