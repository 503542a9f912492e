"""The pressure load of the ``cosserat-surface`` medium: normal to the deformed surface, p per unit deformed area."""

from __future__ import annotations

import math
import pathlib

import cartan_cosserat_surface
import numpy as np
import pytest
from cartan_cosserat_surface.cases_pressure import (
    CASES,
    closed_cylinder_problem,
    inflation_pressure,
    inflation_stretch,
    mean_stretch,
    polygon_factor,
)
from cartan_cosserat_surface.surface import Pressure
from click.testing import CliRunner

import cartan
from cartan.cli import main
from cartan.scene import SceneError, load_scene


@pytest.fixture(scope="module")
def medium():
    return cartan.medium("cosserat-surface", E=1.0, poisson=0.0, thickness=0.05)


# ---------------------------------------------------------------------------- construction
def test_bad_parameters(medium):
    grid = cartan.Grid((5, 4))
    with pytest.raises(ValueError, match="pressure"):
        Pressure(float("nan"), grid)
    with pytest.raises(ValueError, match="grid"):
        Pressure(1.0, cartan.Grid(5))
    with pytest.raises(ValueError, match="grid"):
        Pressure(1.0, cartan.Grid((5, 2)))
    with pytest.raises(ValueError, match="holonomy"):
        Pressure(1.0, grid, holonomy={0: np.eye(4)})           # axis 0 is open
    with pytest.raises(ValueError, match="holonomy"):
        Pressure(1.0, cartan.Grid((5, 4), periodic=(True, False)), holonomy={0: 2 * np.eye(4)})
    assert isinstance(medium.make_load("pressure", pressure=1.0, grid=grid), Pressure)
    # without a grid: the problem's, attached when a Problem is built (a scene's pressure)
    free = medium.make_load("pressure", pressure=1.0)
    with pytest.raises(ValueError, match="no grid"):
        free.force(np.zeros((5, 4, 4, 4)), None, 0.0)
    with pytest.raises(ValueError, match="holonomy needs the grid"):
        Pressure(1.0, holonomy={1: np.eye(4)})
    prob = cartan.Problem(medium, grid, medium.initial_state(grid, "flat"), loads=[free])
    assert prob.loads[0].grid is grid and free.holonomy == {}
    with pytest.raises(ValueError, match=r"loads\[0\]: grid: an open axis needs ≥ 3 nodes"):
        g2 = cartan.Grid((5, 2))
        cartan.Problem(medium, g2, medium.initial_state(g2, "flat"), loads=[Pressure(1.0)])
    with pytest.raises(ValueError, match=r"loads\[0\]: pressure: grid has shape \(5, 4\)"):
        g3 = cartan.Grid((6, 4))
        cartan.Problem(medium, g3, medium.initial_state(g3, "flat"), loads=[Pressure(1.0, grid)])
    with pytest.raises(ValueError, match="surface"):
        Pressure(1.0, grid).bind(cartan.medium("cosserat-solid"))


# ---------------------------------------------------------------------------- the force
def _bump(u, v):
    """A doubly curved chart r = (u + v²/4, v, sin 2u cos v)."""
    return np.stack([u + 0.25 * v * v, v, np.sin(2 * u) * np.cos(v)], axis=-1)


def _bump_normal(grid):
    """The exact r_u × r_v of :func:`_bump` at the nodes."""
    u, v = np.meshgrid(grid.coordinates(0), grid.coordinates(1), indexing="ij")
    ru = np.stack([np.ones_like(u), np.zeros_like(u), 2 * np.cos(2 * u) * np.cos(v)], axis=-1)
    rv = np.stack([0.5 * v, np.ones_like(u), -np.sin(2 * u) * np.sin(v)], axis=-1)
    return np.cross(ru, rv)


def test_force_is_pressure_times_area_normal_second_order(medium):
    """On an open doubly curved patch the nodal force converges to p r_u × r_v at O(dx²), edges
    included (one-sided second-order differences); it is normal to the difference tangents to
    round-off and carries no moment; its body components are Rᵀf."""
    p, errors = 0.7, []
    for n in (9, 17, 33):
        grid = cartan.Grid((n, n), length=(1.0, 0.8))
        exact = _bump_normal(grid)
        state = medium.initial_state(grid, "surface", position=_bump)
        load = Pressure(p, grid)
        load.bind(medium)
        f = load.spatial_force(state.Phi)
        errors.append(np.abs(f - p * exact).max() / p)
        ru, rv = load.tangents(state.Phi)
        scale = np.linalg.norm(f, axis=-1) * np.maximum(np.linalg.norm(ru, axis=-1), np.linalg.norm(rv, axis=-1))
        assert np.abs(np.einsum("...i,...i->...", f, ru)).max() < 1e-14 * scale.max()
        assert np.abs(np.einsum("...i,...i->...", f, rv)).max() < 1e-14 * scale.max()
        T = load.force(state.Phi, np.zeros((n, n, 6)), 0.0)
        assert np.all(T[..., 3:] == 0.0)
        np.testing.assert_allclose(np.einsum("...ij,...j->...i", state.Phi[..., 1:, 1:], T[..., :3]), f,
                                   atol=1e-14 * np.abs(f).max())
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(orders > 1.8), (errors, orders)


def test_sign_convention(medium):
    """p > 0 pushes along +e₃: +z on a flat plate, outward on a cylinder (body force (0, 0, p·area))."""
    grid = cartan.Grid((5, 4), length=(1.0, 0.5))
    load = Pressure(2.0, grid)
    load.bind(medium)
    T = load.force(medium.initial_state(grid, "flat").Phi, np.zeros((5, 4, 6)), 0.0)
    np.testing.assert_allclose(T, np.broadcast_to([0, 0, 2.0, 0, 0, 0], T.shape), atol=1e-13)
    cyl = cartan.Grid((16, 4), length=(2 * math.pi, 0.5), periodic=(True, False))
    load = Pressure(2.0, cyl)
    T = load.force(medium.initial_state(cyl, "cylinder").Phi, np.zeros((16, 4, 6)), 0.0)
    # the polygon's central difference: |r_u| = sin φ/φ, along e₁; the force along +e₃ (outward)
    np.testing.assert_allclose(T, np.broadcast_to([0, 0, 2.0 * polygon_factor(16), 0, 0, 0], T.shape), atol=1e-13)


# ---------------------------------------------------------------------------- the closed cylinder
def test_inflation_closed_form_is_consistent(medium):
    """p(λ) inverts, and linearises to (1 − ν²)pR²/(Eh)/(1 + h²/(12R²))."""
    shell = cartan.medium("cosserat-surface", thickness=0.05, rest_curvature=(1.0, 0.0))
    for lam in (0.9, 1.3, 2.5):
        assert abs(inflation_stretch(shell, 1.0, inflation_pressure(shell, 1.0, lam)) - lam) < 1e-13
    p = 1e-9
    w = inflation_stretch(shell, 1.0, p) - 1.0
    lin = (1 - shell.nu ** 2) * p / (shell.E * shell.h) / (1 + shell.h ** 2 / 12)
    assert abs(w / lin - 1) < 1e-6   # the quadratic term: O(w/R)


@pytest.mark.parametrize("stretch", [1.0 + 1e-6, 1.3, 1.8])
def test_lattice_inflation_is_exact(stretch):
    """The lattice's uniformly inflated polygon is the continuum equilibrium at p·sin φ/φ, at any
    load: λ_lattice = λ(p sin φ/φ) to the solver's tolerance; the state is uniform."""
    n = 16
    shell = cartan.medium("cosserat-surface", thickness=0.05, rest_curvature=(1.0, 0.0))
    p = inflation_pressure(shell, 1.0, stretch)
    problem = closed_cylinder_problem(n, p)
    # an 80 % inflation in one load step from rest takes Newton (exact Jacobian) to the degenerate
    # collapsed equilibrium (radius ≈ 0); two load steps follow the inflation branch
    ds = cartan.solve_static(problem, tol=1e-10, load_steps=2 if stretch > 1.5 else 1)
    lam = mean_stretch(ds, problem)
    exact = inflation_stretch(problem.medium, 1.0, p * polygon_factor(n))
    assert abs((lam - 1) / (exact - 1) - 1) < 1e-7
    x = ds.position.values[0]
    r = np.hypot(x[..., 0], x[..., 2] + 1.0)
    assert (r.max() - r.min()) < 1e-8 * (exact - 1)
    # the lattice's error against the continuum is the pressure it applies, 1 − sin φ/φ ≈ φ²/6
    err = (lam - 1) / (stretch - 1) - 1
    assert -0.05 < err < -0.2 * (2 * math.pi / n) ** 2 / 6


@pytest.mark.parametrize("case", CASES, ids=lambda c: c.name)
def test_registered_cases_second_order(case):
    """The registered cases converge at O(du²) in the circumferential spacing (n = 16, 32)."""
    errors = []
    for level in case.quick_levels:
        problem, settings = case.problem(level)
        errors.append(case.error(case.run(problem, settings), problem))
    assert errors[-1] < case.tolerance
    assert abs(math.log2(errors[0] / errors[1]) - case.space_order) < 0.1, errors


# ---------------------------------------------------------------------------- follower: a cantilever strip
@pytest.fixture(scope="module")
def strip(medium):
    grid = cartan.Grid((17, 3), length=(1.0, 0.25))
    return grid, medium.initial_state(grid, "flat")


def _cantilever(medium, strip, load):
    grid, init = strip
    return cartan.Problem(medium, grid, init, boundaries={"u-start": cartan.Clamped()}, loads=[load])


def test_cantilever_linear_and_follower(medium, strip):
    """Small p: the Timoshenko cantilever under a uniform load, w = qL⁴/(8D) + qL²/(2κGh) (ν = 0, the
    lattice exact to round-off for this polynomial); large p: the pressure stays normal to the
    deformed strip and bends it more than the dead load of the same magnitude (its moment at a
    section is p c²/2, c the chord to the tip, against the dead load's p x²/2, x ≤ c)."""
    grid, _ = strip
    D = medium.bending_stiffness
    q = 1e-6 * D
    ds = cartan.solve_static(_cantilever(medium, strip, Pressure(q, grid)), tol=1e-10)
    w = ds.position.values[0][-1, 1, 2]
    ref = q / (8 * D) + q / (2 * medium.ks * medium.shear_modulus * medium.h)
    assert abs(w / ref - 1) < 1e-9
    q = 2.0 * D
    pressure = Pressure(q, grid)
    ds = cartan.solve_static(_cantilever(medium, strip, pressure), tol=1e-10)
    Phi = np.zeros((*grid.shape, 4, 4))
    Phi[..., 0, 0] = 1.0
    Phi[..., 1:, 0] = ds.position.values[0]
    Phi[..., 1:, 1:] = ds.frame.values[0]
    f = pressure.spatial_force(Phi)
    ru, rv = pressure.tangents(Phi)
    for t in (ru, rv):
        cos = np.einsum("...i,...i->...", f, t) / (np.linalg.norm(f, axis=-1) * np.linalg.norm(t, axis=-1))
        assert np.abs(cos).max() < 1e-14
    tilt = np.degrees(np.arccos(f[-1, 1, 2] / np.linalg.norm(f[-1, 1])))
    assert tilt > 15.0    # the tip's load turned with the strip (19° measured)
    dead = cartan.solve_static(_cantilever(medium, strip, medium.make_load("dead-load", force=[0, 0, q])), tol=1e-10)
    w_follower, w_dead = ds.position.values[0][-1, 1, 2], dead.position.values[0][-1, 1, 2]
    assert w_follower > w_dead * (1 + 1e-2), (w_follower, w_dead)


def test_energy_balance_lie_verlet(medium):
    """A non-potential load: its power goes to external_work, and K + V − W stays constant to the
    integrator's O(Δt²) (a clamped strip released under a large pressure, 9 × 3 nodes)."""
    grid = cartan.Grid((9, 3), length=(1.0, 0.25))
    load = Pressure(20 * medium.bending_stiffness, grid)
    assert not load.conservative
    problem = cartan.Problem(medium, grid, medium.initial_state(grid, "flat"),
                             boundaries={"u-start": cartan.Clamped()}, loads=[load])
    drift = []
    for dt in (0.02, 0.01):
        ds = cartan.simulate(problem, "lie-verlet", dt=dt, t_end=10.0, save_every=int(round(1 / dt)))
        K, V, W = (ds[k].values for k in ("kinetic_energy", "potential_energy", "external_work"))
        assert W[-1] > 0.1 * K.max() > 0
        drift.append(np.abs(K + V - W - (K[0] + V[0] - W[0])).max() / W[-1])
    assert drift[0] < 1e-5
    assert 3.0 < drift[0] / drift[1] < 5.0, drift   # O(Δt²)


def test_work_is_pressure_times_volume_change():
    """On the closed cylinder (no supports, zero initial velocity) a sudden pressure makes it
    breathe; the work of the load is p·L·ΔA, A the area of each ring's polygon (the nodal forces of
    a uniform inflation are p times the polygon area's gradient), to the O(Δt²) of the quadrature."""
    base = closed_cylinder_problem(16, 0.005)
    problem = cartan.Problem(base.medium, base.grid, base.initial, loads=[base.loads[0]])
    p, L = base.loads[0].pressure, base.grid.length[1]

    def ring_area(x):
        X, Z = x[..., 0], x[..., 2]
        return float(np.mean(0.5 * np.abs(np.sum(X * np.roll(Z, -1, 0) - np.roll(X, -1, 0) * Z, axis=0))))

    errors = []
    for dt in (0.02, 0.01):
        ds = cartan.simulate(problem, "lie-verlet", dt=dt, t_end=3.0, save_every=int(round(0.5 / dt)))
        W = ds["external_work"].values
        A = np.array([ring_area(x) for x in ds["position"].values])
        assert W[-1] > 0
        errors.append(np.abs(W - p * L * (A - A[0])).max() / W[-1])
    assert errors[0] < 5e-4
    assert 3.0 < errors[0] / errors[1] < 5.0, errors   # O(Δt²)


# ---------------------------------------------------------------------------- the scene
def test_inflation_scene_is_the_registered_case():
    """``cartan run --scene shell-cylinder-inflation`` is the case shell-cylinder-inflation at level 2: the
    pressure, the grid and the axial holonomy come from the scene's problem (Load.attach); the same
    equilibrium to round-off."""
    sc = cartan.scene("shell-cylinder-inflation")
    case = next(c for c in CASES if c.name == "shell-cylinder-inflation")
    problem, settings = case.problem(2)
    assert sc.problem.loads[0].pressure == problem.loads[0].pressure
    assert sc.problem.loads[0].holonomy.keys() == {1}
    assert np.array_equal(sc.problem.loads[0].holonomy[1], problem.loads[0].holonomy[1])
    assert np.array_equal(sc.problem.loads[1].K, problem.loads[1].K)
    ours = sc.run()
    ref = case.run(problem, settings)
    x, y = ours["position"].values[-1], ref["position"].values[-1]
    assert np.max(np.abs(x - y)) < 1e-12 * np.max(np.abs(y)), np.max(np.abs(x - y))
    assert abs(case.error(ours, sc.problem) - case.error(ref, problem)) < 1e-10


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        ("pressure = 0.01895868554522401", 'pressure = "high"', "loads[0] (pressure): pressure must be"),
        ("pressure = 0.01895868554522401", "pressure = [1.0, 2.0]", "loads[0] (pressure): pressure must"),
        ("pressure = 0.01895868554522401", "p = 0.01", "load 'pressure' takes the parameter 'pressure'"),
        ("pressure = 0.01895868554522401", "", "load 'pressure' takes the parameter 'pressure'"),
        ("[8, 0, 2]", "[8, 0, 3]", "loads[1] (node-springs): springs: component must be 0, 1 or 2"),
        ("[8, 0, 2]", "[32, 0, 2]", "loads[1]: springs: node [32, 0] is not a node of the grid of shape [32, 3]"),
        ("stiffness = 1296.9111506219235", "stiffness = -1.0", "loads[1] (node-springs): stiffness must be"),
        ("shape = [32, 3]", "shape = [32, 2]", "loads[0]: grid: an open axis needs ≥ 3 nodes"),
    ],
)
def test_bad_pressure_scenes_are_refused(tmp_path, old, new, expected):
    """One line ``cartan: error: ...`` naming the load, status 2, nothing written."""
    text = (pathlib.Path(cartan_cosserat_surface.__file__).parent / "scenes"
            / "shell-cylinder-inflation.toml").read_text()
    assert old in text
    if old == "shape = [32, 3]":  # an open axial direction of 2 nodes
        text = text.replace("periodic = [true, true]", "periodic = [true, false]")
    path = tmp_path / "scene.toml"
    path.write_text(text.replace(old, new))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert "\n" not in msg and expected in msg, msg
    res = CliRunner().invoke(main, ["run", str(path), "-o", str(tmp_path / "out.nc")])
    assert res.exit_code == 2, res.output
    assert res.output.startswith("cartan: error: ") and res.output.count("\n") == 1, res.output
    assert expected in res.output and "Traceback" not in res.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.toml"]
