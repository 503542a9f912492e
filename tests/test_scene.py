"""Scenes: TOML schema, one-line errors, registered scenes, and the ``cartan run`` CLI.

The small ``toy-rod`` medium below (a quadratic-energy SE(3) rod with a gravity load) is
shared with ``test_simulate.py`` and ``test_io.py`` through :func:`toy_registry`.
"""

from __future__ import annotations

import math
import pathlib
import re
import textwrap
import types

import click
import numpy as np
import pytest
from click.testing import CliRunner
from toys import QuadraticMedium

import cartan
from cartan.api import Scene, SceneError, load_scene, scene
from cartan.cli_run import register
from cartan.medium import check_positive
from cartan.plugins import reset_registry
from cartan.problem import InitialState, PotentialLoad


# ---------------------------------------------------------------------------- toy plugin
class ToyGravity(PotentialLoad):
    """U(x) = −ρ g·x per unit length (a uniform gravity field)."""

    def __init__(self, g, density=1.0):
        self.g = np.asarray(g, dtype=float)
        if self.g.shape != (3,):
            raise ValueError(f"g must have 3 components, got {self.g.shape}")
        self.density = float(density)

    def potential_energy(self, q):
        return -self.density * (q[..., 1:, 0] @ self.g)

    def potential_gradient(self, q):
        grad = np.zeros(q.shape)
        grad[..., 1:, 0] = -self.density * self.g
        return grad

    def to_dict(self):
        return {"kind": "gravity", "g": self.g.tolist(), "density": self.density}


class ToyRod(QuadraticMedium):
    """Quadratic SE(3) rod: K = ½Σ m_k N_k², U = ½Σ C_k (X_k − X0_k)², X0 = (1, 0, 0, 0, 0, 0)."""

    name = "toy-rod"
    material_dim = 1
    load_kinds = ("gravity",)
    initial_kinds = ("straight", "arc")

    def __init__(self, stiffness=(10.0, 10.0, 10.0, 1.0, 1.0, 1.0), inertia=(1.0, 1.0, 1.0, 0.1, 0.1, 0.2)):
        super().__init__(
            "SE3",
            mass=check_positive("inertia", inertia, shape=(6,)),
            stiffness=check_positive("stiffness", stiffness, shape=(6,)),
        )
        self.space = cartan.space("frame-E3")

    def parameters(self):
        return {"stiffness": self.C.tolist(), "inertia": self.m.tolist()}

    def make_load(self, kind, **params):
        if kind == "gravity":
            return ToyGravity(**params)
        return super().make_load(kind, **params)

    def initial_state(self, grid, kind, curvature=0.0, twist=0.0, velocity=None):
        if kind not in self.initial_kinds:
            return super().initial_state(grid, kind)
        u = grid.coordinates(0)
        xi = np.array([1.0, 0, 0, twist, 0, curvature if kind == "arc" else 0.0])
        Phi = self.group.exp(u[:, None] * xi)
        N = (
            None
            if velocity is None
            else np.broadcast_to(np.asarray(velocity, float), (grid.shape[0], 6)).copy()
        )
        return InitialState(Phi=Phi, N=N)


SCENE = textwrap.dedent(
    """
    name = "toy-butterfly"
    description = "free bent toy rod"
    medium = "toy-rod"
    [parameters]
    stiffness = [10.0, 10.0, 10.0, 1.0, 1.0, 1.0]
    [grid]
    n = 11
    length = 1.0
    [initial]
    kind = "arc"
    curvature = 2.0
    [run]
    integrator = "lie-verlet"
    scheme = "lattice"
    dt = 0.01
    t_end = 0.2
    save_every = 5
    """
)

CANTILEVER = {
    "name": "toy-cantilever",
    "medium": "toy-rod",
    "grid": {"n": 9, "length": 1.0},
    "boundaries": {"start": {"kind": "clamped"}, "end": {"kind": "free", "load": [0, 0, -0.1, 0, 0, 0]}},
    "loads": [{"kind": "gravity", "g": [0, 0, -1.0]}, {"kind": "damping", "coefficients": 0.5}],
    "initial": {"kind": "straight"},
    "run": {"dt": 0.01, "t_end": 0.1, "save_every": 2},
}


def toy_registry(tmp_dir: pathlib.Path | None = None):
    """Rebuild the registries with the toy plugin (medium ``toy-rod``, scenes
    ``toy-butterfly`` (a TOML file, written to ``tmp_dir``) and ``toy-cantilever`` (a dict))."""
    hooks = types.SimpleNamespace()

    @cartan.hookimpl
    def cartan_register_media(register):
        register("toy-rod", ToyRod)

    @cartan.hookimpl
    def cartan_register_scenes(register):
        if tmp_dir is not None:
            path = pathlib.Path(tmp_dir) / "toy-butterfly.toml"
            path.write_text(SCENE)
            register("toy-butterfly", path)
        register("toy-cantilever", dict(CANTILEVER))

    hooks.cartan_register_media = cartan_register_media
    hooks.cartan_register_scenes = cartan_register_scenes
    return reset_registry([("toy", hooks)])


@pytest.fixture
def toy(tmp_path):
    toy_registry(tmp_path)
    yield tmp_path
    reset_registry()


def cli():
    """A fresh CLI group with the run and plot commands registered."""

    @click.group()
    def main():
        pass

    register(main)
    return main


def write(tmp_path, text, name="scene.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


# ---------------------------------------------------------------------------- loading
def test_load_scene_file(toy):
    sc = load_scene(write(toy, SCENE))
    assert isinstance(sc, Scene)
    assert sc.name == "toy-butterfly" and sc.description == "free bent toy rod"
    assert sc.problem.medium.name == "toy-rod" and sc.problem.grid.shape == (11,)
    assert sc.run_settings() == {
        "integrator": "lie-verlet",
        "scheme": "lattice",
        "dt": 0.01,
        "t_end": 0.2,
        "save_every": 5,
    }
    assert sc.source["medium"] == "toy-rod" and sc.path.name == "scene.toml"


def test_load_scene_dict_with_boundaries_and_loads(toy):
    sc = load_scene(CANTILEVER)
    p = sc.problem
    assert type(p.boundaries["start"]).__name__ == "Clamped"
    assert p.boundaries["end"].follower is False
    np.testing.assert_array_equal(p.boundaries["end"].load, [0, 0, -0.1, 0, 0, 0])
    assert [type(ld).__name__ for ld in p.loads] == ["ToyGravity", "Damping"]
    np.testing.assert_array_equal(p.loads[1].coefficients, np.full(6, 0.5))
    assert p.needs_structure_field


def test_registered_scenes(toy):
    assert scene("toy-butterfly").name == "toy-butterfly"
    assert scene("toy-cantilever").problem.grid.shape == (9,)
    with pytest.raises(SceneError, match="unknown scene 'nope'"):
        scene("nope")


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (lambda s: s.replace('medium = "toy-rod"', 'medium = "jelly"'), "medium: unknown medium 'jelly'"),
        (
            lambda s: s.replace("stiffness = [10.0,", "stiffness = [-10.0,"),
            "parameters: stiffness must be > 0",
        ),
        (lambda s: s.replace("[parameters]", "[parameters]\nfoo = 1"), "parameters.foo: unknown parameter"),
        (lambda s: s.replace("n = 11", "n = 1"), "grid.n: must be an integer ≥ 2"),
        (lambda s: s.replace("n = 11", "nn = 11"), "grid.nn: unknown key"),
        (
            lambda s: s.replace('kind = "arc"', 'kind = "knot"'),
            "initial.kind: unknown initial state kind 'knot'",
        ),
        (
            lambda s: s.replace('integrator = "lie-verlet"', 'integrator = "magic"'),
            "run.integrator: unknown integrator 'magic'",
        ),
        (lambda s: s.replace('scheme = "lattice"', 'scheme = "fem"'), "run.scheme: unknown scheme 'fem'"),
        (lambda s: s.replace("dt = 0.01", "dt = -0.01"), "run.dt: must be > 0"),
        (lambda s: s.replace("save_every = 5", "save_every = 0.5"), "run.save_every: must be an integer"),
        (lambda s: s.replace("[initial]", "[initial_state]"), "initial_state: unknown key"),
        (lambda s: s.replace("[initial]\nkind", "[initial]\nkindd"), "initial.kind: missing key"),
        (lambda s: s + '[[loads]]\nkind = "wind"\n', "loads[0].kind: unknown load kind 'wind'"),
        (lambda s: s + '[[loads]]\nkind = "gravity"\ng = [0, 1]\n', "loads[0] (gravity): g must have 3"),
        (
            lambda s: s + '[[loads]]\nkind = "damping"\ncoefficients = -1\n',
            "loads[0] (damping): coefficients must be ≥ 0",
        ),
        (
            lambda s: s + '[boundaries]\nmiddle = { kind = "clamped" }\n',
            "scene.toml: boundaries: unknown end 'middle'",
        ),
        (
            lambda s: s + '[boundaries]\nend = { kind = "glued" }\n',
            "boundaries.end.kind: unknown boundary kind",
        ),
        (
            lambda s: s.replace("t_end = 0.2", "t_end = 0.2\n[run.integrator_options]\nfoo = 1"),
            "run.integrator_options: lie-verlet: integrator 'lie-verlet' takes no option",
        ),
        (lambda s: s.replace("[grid]", "[grid\n"), "invalid TOML"),
    ],
)
def test_scene_errors_are_one_line(toy, edit, expected):
    path = write(toy, edit(SCENE))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert "\n" not in msg
    assert msg.startswith(f"{path}: "), msg
    assert expected in msg, msg


def test_missing_file():
    with pytest.raises(SceneError, match=r"nowhere\.toml: no such file"):
        load_scene("nowhere.toml")


def test_dict_errors_name_the_scene(toy):
    bad = {**CANTILEVER, "grid": {"n": 9, "length": -1.0}}
    with pytest.raises(
        SceneError, match=r"^scene 'toy-cantilever': grid: length\[0\] must be finite and > 0"
    ):
        load_scene(bad)


# ---------------------------------------------------------------------------- CLI
@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (lambda s: s.replace("[grid]", "[grid"), "invalid TOML"),
        (lambda s: s.replace('medium = "toy-rod"', 'medium = "jelly"'), "unknown medium 'jelly'"),
        (lambda s: s.replace("stiffness = [10.0,", "stiffness = [-10.0,"), "stiffness must be > 0"),
    ],
)
def test_cli_run_scene_errors(toy, edit, expected):
    path = write(toy, edit(SCENE))
    out = toy / "out.nc"
    res = CliRunner().invoke(cli(), ["run", str(path), "-o", str(out)])
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("cartan: error: "), res.output
    assert expected in lines[0]
    assert "Traceback" not in res.output
    assert not out.exists()
    assert sorted(p.name for p in toy.iterdir()) == sorted(["scene.toml", "toy-butterfly.toml"])


def test_cli_run_unknown_names(toy):
    out = toy / "out.nc"
    for args in (
        ["--scene", "nope"],
        [str(write(toy, SCENE)), "--integrator", "magic"],
        [str(write(toy, SCENE)), "--dt", "-1"],
    ):
        res = CliRunner().invoke(cli(), ["run", *args, "-o", str(out)])
        assert res.exit_code == 2, res.output
        assert res.output.count("\n") == 1 and res.output.startswith("cartan: error: "), res.output
        assert not out.exists()


def test_cli_run_and_plot(toy):
    out = toy / "run.nc"
    res = CliRunner().invoke(cli(), ["run", str(write(toy, SCENE)), "-o", str(out), "--t-end", "0.1"])
    assert res.exit_code == 0, res.output
    assert str(out) in res.output
    ds = cartan.api.open(out)
    assert ds.sizes["time"] == 3 and float(ds.time[-1]) == pytest.approx(0.1)
    png = toy / "run.png"
    res = CliRunner().invoke(cli(), ["plot", str(out), "-o", str(png)])
    assert res.exit_code == 0, res.output
    assert png.stat().st_size > 1000 and str(png) in res.output


def test_cli_run_registered_scene_and_restart(toy):
    out = toy / "cant.nc"
    res = CliRunner().invoke(
        cli(), ["run", "--scene", "toy-cantilever", "-o", str(out), "--checkpoint-every", "1"]
    )
    assert res.exit_code == 0, res.output
    first = cartan.api.open(out)
    res = CliRunner().invoke(cli(), ["run", "--restart", str(out), "--t-end", "0.2"])
    assert res.exit_code == 0, res.output
    longer = cartan.api.open(out)
    assert float(longer.time[-1]) == pytest.approx(0.2)
    np.testing.assert_array_equal(longer.position.values[: first.sizes["time"]], first.position.values)


def test_cli_plot_missing_file(tmp_path):
    res = CliRunner().invoke(cli(), ["plot", str(tmp_path / "nothing.nc")])
    assert res.exit_code == 2
    assert res.output.startswith("cartan: error: ") and res.output.count("\n") == 1


# ---------------------------------------------------------------------------- hardening: values and limits
@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (lambda s: s.replace("n = 11", 'n = "11"'), "grid.n: must be a number, not the string '11'"),
        (lambda s: s.replace("length = 1.0", "length = true"), "grid.length: must be a number > 0"),
        (lambda s: s.replace("length = 1.0", "length = 1.0\nperiodic = \"false\""),
         "grid.periodic: must be true or false, not the string 'false'"),
        (lambda s: s.replace("length = 1.0", "length = 1.0\nperiodic = 0"), "grid.periodic: must be true or false"),
        (lambda s: s.replace("stiffness = [10.0,", "stiffness = [true,"), "parameters.stiffness[0]: must be a number"),
        (lambda s: s.replace("stiffness = [10.0, 10.0, 10.0, 1.0, 1.0, 1.0]", "stiffness = true"),
         "parameters.stiffness: must be a number, got True (a boolean is not a number"),
        (lambda s: s.replace("curvature = 2.0", 'curvature = "2.0"'), "initial.curvature: must be a number, not"),
        (lambda s: s.replace("curvature = 2.0", "curvature = inf"), "initial.curvature: must be a finite number"),
        (lambda s: s.replace("curvature = 2.0", "curvature = nan"), "initial.curvature: must be a finite number"),
        (lambda s: s.replace("dt = 0.01", 'dt = "1e-3"'), "run.dt: must be a number, not the string '1e-3'"),
        (lambda s: s.replace("dt = 0.01", "dt = true"), "run.dt: must be a finite number, got True"),
        (lambda s: s.replace("n = 11", "n = 99999999999999999999"), "grid.n: integer out of range (64 bits)"),
        (lambda s: s.replace("n = 11", "n = 1000000000"), "grid: a grid of 1000000000 nodes needs ≈"),
        (lambda s: s.replace("n = 11", "shape = [100000, 100000, 100000]"), "1000000000000000 nodes"),
        (lambda s: s + '[[loads]]\nkind = "damping"\ncoefficients = [1, 1, 1, 1, 1, false]\n',
         "loads[0].coefficients[5]: must be a number"),
        (lambda s: s + '[[loads]]\nkind = "damping"\ncoefficients = true\n',
         "loads[0] (damping): coefficients must be a real number or an array of real numbers"),
        (lambda s: s + '[boundaries]\nend = { kind = "free", follower = "no" }\n',
         "boundaries.end.follower: must be true or false, not the string 'no'"),
        (lambda s: s + '[boundaries]\nstart = { kind = "clamped" }\nu-start = { kind = "free" }\n',
         "boundaries: 'start' and 'u-start' name the same end"),
        (lambda s: s + "x = " + "[" * 900 + "]" * 900 + "\n", "nested deeper than 32 levels"),
        (lambda s: s + "x = " + "[" * 40 + "]" * 40 + "\n", "x[0][0][0]"),
        (lambda s: s.replace("[run]", "[run.integrator_options]\nfoo = \"1\"\n[run]"), "must be a number, not"),
    ],
)
def test_scene_values_are_strict(toy, edit, expected):
    path = write(toy, edit(SCENE))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith(f"{path}: "), msg
    assert expected in msg, msg


def test_free_text_may_spell_numbers(toy):
    sc = load_scene(write(toy, SCENE.replace('description = "free bent toy rod"', 'description = "1e5"')
                          .replace('name = "toy-butterfly"', 'name = "true"')))
    assert sc.name == "true" and sc.description == "1e5"


def test_byte_order_mark_is_accepted(toy):
    path = toy / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + SCENE.encode())
    assert load_scene(path).name == "toy-butterfly"


def test_scene_files_must_be_small_regular_files(toy):
    with pytest.raises(SceneError, match=r"^/dev/zero: not a regular file \(a device"):
        load_scene("/dev/zero")
    with pytest.raises(SceneError, match="not a regular file .a directory"):
        load_scene(toy)
    big = write(toy, SCENE + "#" * (1 << 20), "big.toml")
    with pytest.raises(SceneError, match="larger than 1048576 bytes"):
        load_scene(big)
    path = toy / "latin1.toml"
    path.write_bytes(SCENE.replace("free bent", "fr\u00fch").encode("latin-1"))
    with pytest.raises(SceneError, match="not a UTF-8 text file"):
        load_scene(path)


def test_booleans_where_the_constructor_declares_them(toy):
    """true/false for the options declared as booleans, not for numbers."""
    text = SCENE.replace("save_every = 5", "save_every = 5\n[run.scheme_options]\ntrack_frames = true")
    assert load_scene(write(toy, text)).scheme_options == {"track_frames": True}
    implicit = SCENE.replace('"lie-verlet"', '"implicit-midpoint"')
    text = implicit.replace("save_every = 5", "save_every = 5\n[run.integrator_options]\nreuse_jacobian = false")
    assert load_scene(write(toy, text)).integrator_options == {"reuse_jacobian": False}
    text = implicit.replace("save_every = 5", "save_every = 5\n[run.integrator_options]\ntol = true")
    with pytest.raises(SceneError, match="run.integrator_options.tol: must be a number, got True .* reuse_jacobian"):
        load_scene(write(toy, text))


def test_overflowing_parameters_name_the_parameter():
    base = {"name": "x", "medium": "cosserat-rod", "grid": {"n": 5}, "initial": {"kind": "straight"},
            "parameters": {"E": 1e4, "poisson": 0.5, "radius": 0.25, "density": 5000.0}}
    for radius in (1e77, 1e100, 1e308):
        with pytest.raises(SceneError, match=re.escape(f"parameters: radius = {radius:g} is out of range")):
            load_scene({**base, "parameters": {**base["parameters"], "radius": radius}})
    ring = {**base, "grid": {"n": 6, "periodic": True}, "initial": {"kind": "ring", "mode": math.inf}}
    with pytest.raises(SceneError, match="initial.mode: must be a finite number, got inf"):
        load_scene(ring)


def test_static_and_continuation_work_is_bounded(toy):
    static = textwrap.dedent(
        """
        name = "s"
        mode = "static"
        medium = "toy-rod"
        [grid]
        n = 5
        [initial]
        kind = "straight"
        [static]
        """
    )
    from cartan.scene import MAX_ITERATIONS, MAX_LOAD_STEPS

    for key, limit in (("load_steps", MAX_LOAD_STEPS), ("max_iterations", MAX_ITERATIONS)):
        with pytest.raises(SceneError, match=rf"static.{key}: must be an integer in 1..{limit}, got 1000000000"):
            load_scene(write(toy, static + f"{key} = 1000000000\n"))
    assert load_scene(write(toy, static + f"load_steps = {MAX_LOAD_STEPS}\n")).solver_options["load_steps"] == 10000


def test_limits_from_the_environment(monkeypatch):
    from cartan.scene import check_memory, memory_limit, step_limit

    monkeypatch.delenv("CARTAN_MAX_STEPS", raising=False)
    assert step_limit() == 10**9 and step_limit(5) == 5
    for bad in (0, True, 1.5, "3"):
        with pytest.raises(ValueError, match="max_steps must be an integer ≥ 1"):
            step_limit(bad)
    monkeypatch.setenv("CARTAN_MAX_STEPS", "1e6")
    assert step_limit() == 10**6
    monkeypatch.setenv("CARTAN_MAX_STEPS", "lots")
    with pytest.raises(ValueError, match="CARTAN_MAX_STEPS must be an integer ≥ 1, got 'lots'"):
        step_limit()
    for text, value in (("8G", 8 << 30), ("512M", 512 << 20), ("1.5k", 1536), ("1000000", 10**6), ("2GiB", 2 << 30)):
        monkeypatch.setenv("CARTAN_MAX_MEMORY", text)
        assert memory_limit() == value
    monkeypatch.setenv("CARTAN_MAX_MEMORY", "a lot")
    with pytest.raises(ValueError, match="CARTAN_MAX_MEMORY must be a size in bytes"):
        memory_limit()
    monkeypatch.setenv("CARTAN_MAX_MEMORY", "1M")
    with pytest.raises(ValueError, match=r"^the grid needs ≈ 2 MiB of memory, above the limit of 1 MiB; use fewer "
                                         r"nodes, or raise the limit with the environment variable CARTAN_MAX_MEMORY"):
        check_memory("the grid", 2 << 20, "use fewer nodes")
    monkeypatch.delenv("CARTAN_MAX_MEMORY")
    assert memory_limit() >= 1 << 20


# ---------------------------------------------------------------------------- hardening: the Python API
def _toy_problem(**kw):
    medium = ToyRod()
    grid = cartan.Grid(5)
    return dict(medium=medium, grid=grid, initial=medium.initial_state(grid, "straight")) | kw


@pytest.mark.parametrize(
    ("kw", "error", "expected"),
    [
        ({"medium": "toy-rod"}, TypeError, "medium must be a Medium"),
        ({"grid": 5}, TypeError, "grid must be a Grid, got int"),
        ({"initial": np.eye(4)}, TypeError, "initial must be an InitialState"),
        ({"boundaries": [cartan.Clamped()]}, TypeError, "boundaries must be a dict"),
        ({"boundaries": {0: cartan.Clamped()}}, TypeError, "ends are named by strings"),
        ({"loads": cartan.Damping(1.0)}, TypeError, "loads must be a list of Load instances"),
        ({"name": 3}, TypeError, "name must be a string"),
        ({"boundaries": {"start": cartan.Clamped(), "u-start": cartan.Free()}}, ValueError,
         "'start' and 'u-start' name the same end"),
        ({"loads": [cartan.Damping("1")]}, ValueError, "coefficients must be a real number"),
        ({"initial": InitialState(Phi=np.full((5, 4, 4), "1"))}, ValueError, "initial.Phi must be a real number"),
    ],
)
def test_problem_arguments_are_checked(kw, error, expected):
    with pytest.raises(error, match=expected):
        cartan.Problem(**_toy_problem(**kw))


def test_free_end_arguments_are_checked():
    for follower in ("yes", 1, None):
        with pytest.raises(ValueError, match="follower must be True or False"):
            cartan.Free(follower=follower)
    assert cartan.Free(follower=np.bool_(True)).follower is True
    for load in ("1", [0, 0, "1", 0, 0, 0], [True] * 6, [[1.0]], [np.nan] * 6):
        with pytest.raises(ValueError, match="load must be"):
            cartan.Free(load=load)


def test_api_medium_with_an_overflowing_parameter_is_a_value_error():
    """The Python API, like scene files: a parameter so large that a derived quantity overflows
    is a ValueError naming it, not an OverflowError from inside the medium."""
    import cartan

    with pytest.raises(ValueError, match=r"medium 'cosserat-rod': radius = 1e\+100 is out of range"):
        cartan.medium("cosserat-rod", E=1e6, G=1e6 / 3, radius=1e100, density=1000.0)
    with pytest.raises(ValueError, match="E must be a real number"):
        cartan.medium("cosserat-rod", E="1e5", G=1e6 / 3, radius=0.02, density=1000.0)


@pytest.mark.parametrize(
    ("velocity", "expected"),
    [
        ('"no_colon_here"', "name a function as 'module:name'"),
        ('"cartan_nowhere.module:f"', "cannot be imported"),
        ('"math:not_there"', "cannot be imported"),
        ('"math:pi"', "is not callable"),
    ],
)
def test_kinematic_velocity_named_in_a_scene_is_checked(toy, velocity, expected):
    """A scene names a ``kinematic`` velocity as ``"module:name"``; a bad name is one line."""
    text = SCENE.replace('integrator = "lie-verlet"', 'integrator = "kinematic"') + (
        f"\n[run.integrator_options]\nvelocity = {velocity}\n")
    out = toy / "out.nc"
    res = CliRunner().invoke(cli(), ["run", str(write(toy, text)), "-o", str(out)])
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("cartan: error: ") and expected in lines[0], res.output
    assert not out.exists()


def test_kinematic_velocity_options_need_a_named_factory():
    kin = cartan.registry("integrators")["kinematic"]
    with pytest.raises(ValueError, match="named velocity factory"):
        kin(velocity=lambda t, u, X: 0.0 * X[..., 0, :], velocity_options={})
    named = kin(velocity="cartan_filament.binormal:binormal_velocity", velocity_options={"coefficient": 2.0})
    assert named.options() == {"order": 4, "velocity": "cartan_filament.binormal:binormal_velocity",
                               "velocity_options": {"coefficient": 2.0}}
    with pytest.raises(ValueError, match="velocity_options of"):
        kin(velocity="cartan_filament.binormal:binormal_velocity", velocity_options={"speed": 2.0})
