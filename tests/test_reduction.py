"""Exact reductions (``cartan.reduction``): planar SE(3) problems run on SE(2) and give the full run's output.

Tolerances: the SE(2) and SE(3) kernels compute the same planar motion with different
round-off (≈ 1e-16 per operation); a few hundred steps of these damped motions keep the
difference ≲ 1e-13 of each variable's scale (the verification case ``rod-planar-se3-se2``
measures 5e-15 for positions, 1e-13 for momenta), so every variable must agree to 1e-12 of its
scale: its largest magnitude, the strain scale for the integrability residual (a difference of
strains), 1 for the dimensionless closure residual and group defect.  The implicit-midpoint
runs agree to the Newton tolerance in principle (``tol = 1e-10``); on these small rods the
iterations converge far below it and the observed differences are ≤ 3e-14.

The reduction is made only where it pays (``cartan.reduction.reduction_pays``); on the
lattice's hand-written compiled loops, where it does not, the tests force it (``forced``)
to check the lift on the default path.
"""

from __future__ import annotations

import importlib
import json
import math
import warnings

import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner

import cartan
import cartan.reduction as reduction
from cartan.cli import main
from cartan.problem import Load
from cartan.reduction import IN_PLANE, PLANAR, planar_reduction
from cartan.simulate import InstabilityError, StabilityWarning

ROD = {"E": 1e5, "poisson": 0.5, "radius": 0.05, "density": 1000.0}
DAMPING = [2.0, 2.0, 2.0, 1e-3, 1e-3, 1e-3]
TOL = 1e-12
#: the scale of the variables that are not measured against their own size
SCALE_OF = {"integrability_residual": "X", "closure_residual": 1.0, "group_defect": 1.0}


def rod():
    return cartan.medium("cosserat-rod", **ROD)


def cantilever(*, velocity=None, g=(0.0, -9.81, 0.0), end_load=(0.0, -0.05, 0.0, 0.0, 0.0, 0.01), loads=(),
               medium=None, **initial) -> cartan.Problem:
    """A cantilever along x, clamped at s = 0, under gravity, a dead end load and damping (the x–y plane)."""
    r = rod() if medium is None else medium
    grid = cartan.Grid(21, length=1.0)
    init = r.initial_state(grid, "straight", velocity=velocity, **initial)
    return cartan.Problem(
        r, grid, init, {"start": cartan.Clamped(), "end": cartan.Free(load=list(end_load))},
        [r.make_load("gravity", g=list(g)), cartan.Damping(DAMPING), *loads], name="cantilever",
    )


def ring(**initial) -> cartan.Problem:
    """A closed ring (rest curvature 1 about e₃) started ovalled, spinning and moving in its plane."""
    r = cartan.medium("cosserat-rod", stretch_shear=[50.0, 50.0, 50.0], bend_twist=[1.0, 1.0, 1.0], mass=1.0,
                      rotational_inertia=[0.02, 0.01, 0.01], rest_curvature=[0.0, 0.0, 1.0])
    grid = cartan.Grid(24, length=2 * math.pi, periodic=True)
    params = {"amplitude": 0.1, "mode": 2, "rigid_velocity": [0.2, -0.1, 0.0, 0.0, 0.0, 0.5], **initial}
    return cartan.Problem(r, grid, r.initial_state(grid, "ring", **params),
                          loads=[cartan.Damping([0.1, 0.1, 0.1, 0.01, 0.01, 0.01])], name="ring")


#: the default path (lie-verlet on the lattice's compiled loops), where the reduction is forced
CANTILEVER_RUN = {"dt": 1e-3, "t_end": 0.3, "save_every": 30, "progress": False}
#: implicit midpoint, where the reduction pays and is made without forcing
RING_RUN = {"dt": 2e-3, "t_end": 0.6, "save_every": 50, "progress": False, "integrator": "implicit-midpoint"}


@pytest.fixture
def forced(monkeypatch):
    """The reduction made wherever it is exact, also where it would not pay (``reduction_pays``)."""
    monkeypatch.setattr(reduction, "reduction_pays", lambda run: True)


@pytest.fixture(scope="module")
def cantilever_runs():
    p = cantilever()
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(reduction, "reduction_pays", lambda run: True)
        reduced = cartan.simulate(p, **CANTILEVER_RUN)
    return reduced, cartan.simulate(p, **CANTILEVER_RUN, reduce=False)


@pytest.fixture(scope="module")
def ring_runs():
    p = ring()
    return cartan.simulate(p, **RING_RUN), cartan.simulate(p, **RING_RUN, reduce=False)


def config(ds: xr.Dataset) -> dict:
    cfg = json.loads(ds.attrs["cartan_config"])
    cfg.pop("counters")  # force evaluations and wall time: what was run
    return cfg


def assert_same_run(reduced: xr.Dataset, full: xr.Dataset) -> None:
    """The reduced run's Dataset is the full run's: variables, dimensions, coordinates, attributes, values."""
    assert reduced.attrs["cartan_reduction"] == PLANAR
    assert "cartan_reduction" not in full.attrs
    assert list(reduced.data_vars) == list(full.data_vars)
    assert list(reduced.coords) == list(full.coords)
    assert dict(reduced.sizes) == dict(full.sizes)
    assert set(reduced.attrs) == set(full.attrs) | {"cartan_reduction"}
    for key, value in full.attrs.items():
        if key not in ("history", "cartan_config"):
            assert reduced.attrs[key] == value, key
    assert config(reduced) == config(full)
    for name in full.variables:
        a, b = reduced[name], full[name]
        assert a.dims == b.dims and a.shape == b.shape and a.attrs == b.attrs, name
        if b.dtype.kind not in "fiu":
            assert np.array_equal(a.values, b.values), name
            continue
        scale = SCALE_OF.get(name)
        if scale is None:
            scale = float(np.max(np.abs(b.values)))
        elif isinstance(scale, str):
            scale = float(np.max(np.abs(full[scale].values)))
        err = float(np.max(np.abs(a.values - b.values))) if b.size else 0.0
        assert err <= TOL * max(scale, 1e-300), (name, err, scale)
    assert float(np.max(np.abs(full.position.values[..., 2]))) <= 1e-14  # the full run stays planar


# ---------------------------------------------------------------------------- planar runs
def test_cantilever_reduced_equals_full(cantilever_runs):
    reduced, full = cantilever_runs
    assert_same_run(reduced, full)
    assert float(np.ptp(full.position.values[:, -1, 1])) > 1e-3  # the tip moved in the plane


@pytest.mark.slow  # compiles the implicit blocks on SE(3) and SE(2) (60-90 s on a fresh cache); the
# cantilever above keeps the reduction's equality in the fast suite
def test_ring_reduced_equals_full(ring_runs):
    reduced, full = ring_runs
    assert_same_run(reduced, full)
    assert float(np.max(np.abs(full.N.values[..., IN_PLANE[2]]))) > 0.1  # it spins


@pytest.mark.slow  # the implicit loop of the planar rod: ≈ 70 s to compile on a fresh cache
def test_reduced_only_where_it_pays():
    """The lattice's hand-written compiled loops run SE(3) rods (``lie-verlet``) faster than the
    generated loops run SE(2) ones: no reduction there; the Python loop, implicit midpoint and
    the integrators whose steps go to the generated loops on both groups (``rkmk4``) are reduced."""
    p = cantilever()
    short = {**CANTILEVER_RUN, "t_end": 0.01, "save_every": 5}
    assert "cartan_reduction" not in cartan.simulate(p, **short).attrs
    assert cartan.simulate(p, **short, compiled=False).attrs["cartan_reduction"] == PLANAR
    assert cartan.simulate(p, **short, integrator="implicit-midpoint").attrs["cartan_reduction"] == PLANAR
    assert cartan.simulate(p, **{**short, "dt": 1e-4}, integrator="rkmk4").attrs["cartan_reduction"] == PLANAR


def test_reduced_problem_maps_the_data():
    p = cantilever(velocity=[0.1, 0.2, 0.0, 0.0, 0.0, 0.3])
    red = planar_reduction(p)
    assert red is not None and red.kind == PLANAR
    q = red.reduced
    assert q.medium.name == "planar-cosserat-rod" and q.medium.group.name == "SE2"
    np.testing.assert_array_equal(q.initial.Phi, p.initial.Phi[..., :3, :3])
    np.testing.assert_array_equal(q.initial.N, p.initial.N[..., list(IN_PLANE)])
    np.testing.assert_array_equal(q.boundaries["end"].load, [0.0, -0.05, 0.01])
    np.testing.assert_array_equal(q.loads[0].field, [0.0, -9.81])
    np.testing.assert_array_equal(q.loads[1].coefficients, [2.0, 2.0, 1e-3])
    np.testing.assert_array_equal(q.medium.inertia(), p.medium.inertia()[list(IN_PLANE)])


# ---------------------------------------------------------------------------- not planar: not reduced
class Pull(Load):
    """A load the reduction does not know (even though it is planar)."""

    def force(self, Phi, N, t):
        return np.zeros(np.shape(N))


class NoTwin(type(rod())):
    def planar_reduction(self):
        return None


class WrongTwin(type(rod())):
    """Declares a twin that is not its restriction (another bending stiffness)."""

    def planar_reduction(self):
        return cartan.medium("planar-cosserat-rod", **{**ROD, "E": 2e5})


class Sampled(type(rod())):
    """Hides its quadratic data: the twin is checked at sample strains."""

    def quadratic_energy(self):
        return None


class SampledWrongTwin(Sampled):
    def planar_reduction(self):
        return cartan.medium("planar-cosserat-rod", **{**ROD, "poisson": 0.3})  # another shear modulus


NOT_PLANAR = {
    "out-of-plane velocity": lambda: cantilever(velocity=[0.0, 0.0, 1e-3, 0.0, 0.0, 0.0]),
    "out-of-plane angular velocity": lambda: cantilever(velocity=[0.0, 0.0, 0.0, 1e-3, 0.0, 0.0]),
    "gravity out of the plane": lambda: cantilever(g=(0.0, -9.81, -1.0)),
    "end force out of the plane": lambda: cantilever(end_load=(0.0, 0.0, 0.1, 0.0, 0.0, 0.0)),
    "end moment out of the plane": lambda: cantilever(end_load=(0.0, 0.0, 0.0, 0.0, 0.1, 0.0)),
    "uniform force out of the plane": lambda: cantilever(loads=[cartan.UniformForce([0, 0, 0, 0.1, 0, 0])]),
    "unknown load class": lambda: cantilever(loads=[Pull()]),
    "rod above the plane": lambda: cantilever(origin=[0.0, 0.0, 0.1]),
    "rod out of the plane": lambda: cantilever(direction=[1.0, 0.0, 0.1]),
    "e3 along -z": lambda: cantilever(normal=[0.0, 0.0, -1.0]),
    "e3 along y (x–z plane)": lambda: cantilever(normal=[0.0, 1.0, 0.0]),
    "out-of-plane rest curvature": lambda: cantilever(medium=cartan.medium("cosserat-rod", **ROD,
                                                                           rest_curvature=[0.0, 0.3, 0.0])),
    "medium without a twin": lambda: cantilever(medium=NoTwin(**ROD)),
    "twin that is not the restriction": lambda: cantilever(medium=WrongTwin(**ROD)),
    "twin that is not the restriction (sampled)": lambda: cantilever(medium=SampledWrongTwin(**ROD)),
    "ring out of its plane": lambda: ring(out_of_plane=0.05),
}


@pytest.mark.parametrize("case", sorted(NOT_PLANAR))
def test_not_planar_is_not_reduced(case):
    assert planar_reduction(NOT_PLANAR[case]()) is None


def test_planar_variants_are_reduced():
    """The controls of the cases above: the same problems with planar data are reduced."""
    for p in (cantilever(loads=[cartan.UniformForce([0.1, 0, 0, 0, 0, 0.2])]), cantilever(origin=[0.3, -0.2, 0.0]),
              cantilever(direction=[1.0, 0.5, 0.0]), ring(), cantilever(medium=Sampled(**ROD)),
              cantilever(medium=cartan.medium("cosserat-rod", **ROD, rest_curvature=[0.0, 0.0, 0.3]))):
        assert planar_reduction(p) is not None


def test_holonomy_and_reference_are_restricted():
    """A periodic straight rod (holonomy: the translation by L along x) and a rest shape given
    as a reference configuration are planar data too; out of the plane they are not."""
    r = rod()
    grid = cartan.Grid(16, length=2.0, periodic=True)
    p = cartan.Problem(r, grid, r.initial_state(grid, "straight", direction=[0.6, 0.8, 0.0]))
    red = planar_reduction(p)
    assert red is not None
    np.testing.assert_array_equal(red.reduced.initial.holonomy, p.initial.holonomy[:3, :3])
    assert red.reduced.initial.holonomy[1, 0] == p.initial.holonomy[1, 0] != 0.0
    grid = cartan.Grid(16, length=1.0)
    bent = r.initial_state(grid, "arc", curvature=1.5)
    p = cartan.Problem(r, grid, r.initial_state(grid, "straight"), {"start": cartan.Clamped()}, reference=bent.Phi)
    red = planar_reduction(p)
    assert red is not None
    np.testing.assert_array_equal(red.reduced.reference.Phi, bent.Phi[..., :3, :3])
    tilted = r.initial_state(grid, "straight", direction=[1.0, 0.0, 0.2])
    assert planar_reduction(cartan.Problem(r, grid, r.initial_state(grid, "straight"), reference=tilted.Phi)) is None


def test_not_planar_run_has_no_attribute(forced):
    p = cantilever(velocity=[0.0, 0.0, 1e-3, 0.0, 0.0, 0.0])
    ds = cartan.simulate(p, **{**CANTILEVER_RUN, "t_end": 0.03, "save_every": 10})
    assert "cartan_reduction" not in ds.attrs
    assert float(np.max(np.abs(ds.position.values[-1, :, 2]))) > 0.0  # it does leave the plane


def test_prescribed_velocity_is_not_reduced(forced):
    """``kinematic`` prescribes the velocity: data the planar test cannot see (this one turns
    the rod out of its plane), so the run steps on SE(3) as given."""
    def out_of_plane(t, u, X):
        N = np.zeros((*u.shape[:-1], 6))
        N[..., :] = [0.3, 0.2, 0.1, 0.0, 0.0, 0.5]
        return N

    p = cantilever(g=(0.0, 0.0, 0.0))
    ds = cartan.simulate(p, integrator=cartan.registry("integrators")["kinematic"](velocity=out_of_plane, order=2),
                         dt=1e-2, t_end=0.1, save_every=10, progress=False, compiled=False)
    assert "cartan_reduction" not in ds.attrs
    assert float(np.max(np.abs(ds.position.values[-1, :, 2]))) > 1e-3


# ---------------------------------------------------------------------------- files, restarts, checkpoints
def test_runs_written_to_a_file_are_not_reduced_and_restart_bit_for_bit(tmp_path, forced):
    """A run that writes a file steps on the group it was given: its restart (on that group)
    continues it bit for bit, which a reduced first half would not give."""
    p = cantilever()
    whole = cartan.simulate(p, **CANTILEVER_RUN, output=tmp_path / "whole.nc")
    half = cartan.simulate(p, **{**CANTILEVER_RUN, "t_end": 0.15}, output=tmp_path / "half.nc")
    assert "cartan_reduction" not in whole.attrs and "cartan_reduction" not in half.attrs
    cont = cartan.simulate(p, **CANTILEVER_RUN, restart=tmp_path / "half.nc", output=tmp_path / "cont.nc")
    for name in ("position", "frame", "X", "N", "S", "kinetic_energy", "potential_energy"):
        assert np.array_equal(cont[name].values, whole[name].values), name


def test_checkpoints_are_not_reduced(tmp_path, forced):
    p = cantilever()
    ds = cartan.simulate(p, **{**CANTILEVER_RUN, "t_end": 0.03, "save_every": 10}, output=tmp_path / "ck.nc",
                         checkpoint_every=1)
    assert "cartan_reduction" not in ds.attrs


def test_blow_up_is_reported_by_the_full_problem(tmp_path, monkeypatch, forced):
    """A reduced run that blows up is run in full: the error and the last good state are the SE(3) run's."""
    lifted = []
    monkeypatch.setattr(reduction, "lift_records", lambda *a: lifted.append(a) or {})
    unstable = []
    sim = importlib.import_module("cartan.simulate")
    execute = sim._execute_run

    def spy(run):
        try:
            return execute(run)
        except InstabilityError:
            unstable.append(run.problem.medium.group.name)
            raise

    monkeypatch.setattr(sim, "_execute_run", spy)
    p = cantilever()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StabilityWarning)
        with pytest.raises(InstabilityError) as info:
            cartan.simulate(p, dt=5e-2, t_end=5.0, save_every=5, progress=False)
    assert unstable == ["SE2", "SE3"] and not lifted  # the reduced run blew up, then the full one
    last = cartan.open(info.value.path)
    assert last.sizes["row"] == 3 and last.sizes["component"] == 6
    assert "cartan_reduction" not in last.attrs


def test_reduce_must_be_a_bool():
    with pytest.raises(ValueError, match="reduce"):
        cartan.simulate(cantilever(), **CANTILEVER_RUN, reduce="yes")


# ---------------------------------------------------------------------------- command line
SCENE = """
name = "planar-cantilever"
medium = "cosserat-rod"

[parameters]
E = 1e5
poisson = 0.5
radius = 0.05
density = 1000.0

[grid]
n = 21
length = 1.0

[boundaries]
start = { kind = "clamped" }
end = { kind = "free" }

[[loads]]
kind = "gravity"
g = [0.0, -9.81, 0.0]

[[loads]]
kind = "damping"
coefficients = [2.0, 2.0, 2.0, 1e-3, 1e-3, 1e-3]

[initial]
kind = "straight"

[run]
integrator = "implicit-midpoint"
dt = 1e-3
t_end = 0.05
save_every = 10
"""


@pytest.mark.slow  # the implicit loops of the planar and the SE(3) rod: ≈ 50 s to compile
def test_cli_runs_write_a_file_and_are_not_reduced(tmp_path):
    """``cartan run`` writes its result, so it steps on the scene's own group (restarts exact)."""
    scene = tmp_path / "planar.toml"
    scene.write_text(SCENE)
    out = tmp_path / "out.nc"
    res = CliRunner().invoke(main, ["run", str(scene), "-o", str(out), "--no-progress"])
    assert res.exit_code == 0, res.output
    ds = cartan.open(out)
    assert "cartan_reduction" not in ds.attrs
    in_memory = cartan.simulate(cartan.load_scene(scene), progress=False)
    assert in_memory.attrs["cartan_reduction"] == PLANAR
    assert_same_run(in_memory, ds)
