"""The registered verification cases (VERIFICATION.md §4) and the invariant checks (§1).

Every registered case runs at its two finest quick levels with each default integrator and
scheme (a static case's "integrator" is ``newton``; in ``make test`` with the first of each, the
others in ``make test-slow``): the error at the finest meets the case's
tolerance and, where the case states an expected order, the observed order
log₂(e_coarse/e_fine) lies in [p − 0.2, p + 0.3].
"""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest
from cartan_verification import (
    Case,
    StaticCase,
    check_invariants,
    dissipation_balance,
    dissipation_rate,
    energy_balance,
    group_membership,
    momentum_drift,
    observed_orders,
    ring_closure,
    run_case,
    spatial_integrability,
    temporal_integrability,
)
from cartan_verification import references as ref
from cartan_verification.case import NEWTON
from cartan_verification.plugin import all_cases

import cartan

CASES = cartan.registry("cases")
RUNS = [(name, integ, scheme) for name, case in sorted(CASES.items()) if case.kind == "convergence"
        for integ in case.default_integrators for scheme in case.default_schemes]
#: every level of these takes several seconds (continuation paths at four resolutions)
SLOW_ALL_LEVELS = {"rod-euler-buckling", "rod-cantilever-elastica", "plate-buckling-column",
                   "plate-buckling-wide-column", "plate-navier-thick", "plate-navier-thin", "solid-uniaxial-stress",
                   "plate-buckling-column-kl", "shell-scordelis-lo", "shell-pinched-cylinder", "solid-cylinder-torsion",
                   "relativistic-newtonian-limit", "shell-sphere-breathing",
                   # about 75 continuation steps per level (the twist-buckling path, 7-13 s a run)
                   "filament-greenhill",
                   # Willmore flows of 10-16 steps to the Clifford torus, nv = 12 … 96 (15-70 s each)
                   "willmore-clifford-torus"}
#: cases whose every level runs in their own test file already (tests/test_kirchhoff_love_modes.py,
#: tests/test_kirchhoff_love_gauge.py: the same runs, minutes each in Python rattle on 2D grids)
OWN_ALL_LEVELS = {"plate-modes-kl", "principal-gauge-kl"}
#: cases whose quick levels alone take tens of seconds (the shells' grids of 33² – 65² nodes):
#: their coarse levels run in the fast suite in their own files (tests/test_cosserat_surface_shells.py)
SLOW_QUICK = {"shell-scordelis-lo", "shell-pinched-cylinder",
              # 33² × 3 and 65² × 3 micropolar slabs, finite-difference Jacobians (minutes; its own test file)
              "solid-cylinder-torsion",
              # the periodic string with a translation holonomy compiles a Poincaré loop of its own (≈ 40 s)
              "relativistic-newtonian-limit",
              # rattle in Python on 2D plates and tubes of 16² – 64² nodes (≈ 30 s each; test_kirchhoff_love_*.py)
              "plate-modes-kl", "principal-gauge-kl",
              # the closed sphere in Python (glued grids decline the compiled loops), 512 nodes (≈ 30 s)
              "shell-sphere-breathing",
              # two Willmore flows of 11 steps (nv = 24, 48: about 15 s and 30 s)
              "willmore-clifford-torus"}


def _slow_poincare(run: tuple) -> bool:
    """Runs whose generated Poincaré loops compile for 30-70 s each on a fresh cache: the
    relativistic string keeps lie-verlet on the lattice in the fast suite, its other methods
    (and its kinematic cases, tests/test_relativistic_rod.py) in ``make test-slow``."""
    return run[0].startswith("relativistic-") and run[1:] != ("lie-verlet", "lattice")


def _other_method(run: tuple) -> bool:
    """Runs with a method other than the case's first default integrator and scheme: each
    compiles a loop of its own (10-70 s on a fresh cache: the rigid body's RKMK4, the ring's
    collocation loops), and the methods themselves are verified by their own cases in the fast
    suite; they run in ``make test-slow``."""
    case = CASES[run[0]]
    return run[1:] != (case.default_integrators[0], case.default_schemes[0])


def _own_loop(run: tuple) -> bool:
    """Dynamic cases whose loop ``make test`` does not compile (tests/conftest.py): the micropolar
    solid's and the relativistic string's generated loops (40-70 s each on a fresh cache) and the
    lattice's hand-written RKMK loop (overdamped); they run in ``make test-slow``, the static
    cases in both."""
    case = CASES[run[0]]
    if case.static:
        return False
    return case.medium in ("cosserat-solid", "relativistic-rod") or run[1] in ("overdamped", "rkmk4", "lie-euler")


QUICK_RUNS = [pytest.param(*run, marks=pytest.mark.slow)
              if _slow_poincare(run) or _other_method(run) or _own_loop(run) or run[0] in SLOW_QUICK else run
              for run in RUNS]
ALL_LEVEL_RUNS = [pytest.param(*run, marks=pytest.mark.slow)
                  if run[0] in SLOW_ALL_LEVELS or _slow_poincare(run) or _other_method(run) or _own_loop(run)
                  else run for run in RUNS if run[0] not in OWN_ALL_LEVELS]


# ---------------------------------------------------------------------------- registry and metadata
def test_every_case_is_registered_and_described():
    # the verification package's cases, and those the media plugins register beside their media
    assert {c.name for c in all_cases()} <= set(CASES)
    media = cartan.registry("media")
    for name, case in CASES.items():
        assert isinstance(case, Case) and case.name == name
        assert case.medium in media, name
        for field in ("description", "reference", "quantity", "norm", "tolerance_reason"):
            assert getattr(case, field).strip(), (name, field)
        assert 0 < case.tolerance < math.inf, name
        assert len(case.levels) >= 2 and set(case.quick()) <= set(case.levels)
        if case.static:  # equilibria: Newton's method on the lattice, refined in space
            assert isinstance(case, StaticCase) and case.default_integrators == (NEWTON,)
            assert case.default_schemes == ("lattice",) and case.space_order is not None and case.refine == "space"
        else:
            assert case.default_integrators and set(case.default_integrators) <= set(cartan.registry("integrators"))
        assert case.refine in (None, "space", "time", "both")
        for integ in case.default_integrators:
            assert 0 < case.tolerance_for(integ) < math.inf
        if case.time_order_of is not None:
            for integ in case.default_integrators:
                assert case.expected_time_order(integ) is not None, (name, integ)
        with pytest.raises(AttributeError):
            case.tolerance = 1.0


def test_expected_order_precedence():
    cases = CASES
    assert cases["free-rigid-body"].expected_order("rkmk4") == 4.0
    assert cases["free-rigid-body"].expected_order() == 2.0
    assert cases["rod-axial-wave"].expected_order() == 2.0
    assert cases["rod-planar-se3-se2"].expected_order() is None
    # met to round-off at every level: no order, whatever the integrator's
    slide = cases["sphere-rod-great-circle-slide"]
    assert slide.roundoff and slide.expected_order("rkmk4") is None
    from cartan.study import expected_order

    assert math.isnan(expected_order(slide, "rkmk4", "both"))
    assert expected_order(cases["rod-euler-buckling"], "newton", "space") == 2.0
    limit = cases["sphere-rod-large-radius"]
    assert limit.expected_order() == 2.0 and limit.space_order is None
    assert limit.limit_levels() == {0: 10.0, 1: 20.0, 2: 40.0, 3: 80.0}


def test_problem_settings_are_simulate_arguments():
    import inspect

    from cartan.continuation import continuation
    from cartan.statics import solve_static

    solver_keys = set(inspect.signature(solve_static).parameters) | set(inspect.signature(continuation).parameters)
    for case in CASES.values():
        problem, settings = case.problem(case.levels[0])
        if case.kind == "stability":
            continue
        assert isinstance(problem, cartan.Problem)
        if case.static:  # the solver's keyword arguments
            keys = solver_keys if case.solver is None else set(inspect.signature(case.solver).parameters)
            assert "dt" not in settings and set(settings) <= keys, (case.name, settings)
            continue
        assert {"dt", "t_end", "save_every"} <= set(settings) <= {"dt", "t_end", "save_every", "integrator_options",
                                                                  "scheme_options"}
        assert settings["dt"] > 0 and settings["t_end"] > 0


def test_static_case_runs_with_newton_only():
    case = CASES["rod-timoshenko-static"]
    problem, settings = case.problem(0)
    with pytest.raises(ValueError, match=r"integrator must be 'newton'.*'lie-verlet'"):
        case.run(problem, settings, "lie-verlet")
    with pytest.raises(ValueError, match=r"scheme must be 'lattice'.*'collocation'"):
        case.run(problem, settings, NEWTON, "collocation")
    err, ds = run_case(case, 0)
    config = json.loads(ds.attrs["cartan_config"])
    assert config["run"]["integrator"] == NEWTON and config["counters"]["nstep"] == ds.attrs["newton_iterations"] >= 2
    assert err == pytest.approx(abs(-float(ds.position[0, -1, 2]) - case.exact()) / case.exact())


# ---------------------------------------------------------------------------- the cases converge
@pytest.mark.parametrize(("name", "integrator", "scheme"), QUICK_RUNS)
def test_case_meets_tolerance_and_order(name, integrator, scheme):
    case = CASES[name]
    errors = []
    with warnings.catch_warnings():
        if integrator == "lie-euler":  # unconditionally unstable for undamped motion (CFL 0), but
            warnings.simplefilter("ignore", cartan.StabilityWarning)  # resolved over this short run
        for level in case.quick():
            errors.append(run_case(case, level, integrator, scheme)[0])
    assert np.all(np.isfinite(errors))
    tol = case.tolerance_for(integrator, scheme)
    assert errors[-1] <= tol, (errors, tol)
    p = case.expected_order(integrator)
    if p is not None:
        observed = observed_orders(errors)[-1]
        assert p - 0.2 <= observed <= p + 0.3, (errors, observed, p)


@pytest.mark.parametrize(("name", "integrator", "scheme"), ALL_LEVEL_RUNS)
def test_case_all_levels(name, integrator, scheme):
    """Every default level: the observed orders of the asymptotic (last two) pairs."""
    case = CASES[name]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", cartan.StabilityWarning)
        errors = [run_case(case, level, integrator, scheme)[0] for level in case.levels]
    assert errors[-1] <= case.tolerance_for(integrator, scheme)
    p = case.expected_order(integrator)
    if p is not None:
        assert np.all(np.abs(observed_orders(errors)[-2:] - p) <= 0.3), errors


def test_planar_case_detects_a_difference():
    """The SE(3) ≡ SE(2) error is not vacuous: a displaced node or an out-of-plane offset shows."""
    case = CASES["rod-planar-se3-se2"]
    err, ds = run_case(case, 0)
    assert err <= case.tolerance
    for k in (0, 2):
        moved = ds.copy(deep=True)
        moved.position.values[-1, 5, k] += 1e-6
        # the move, to the rounding of the addition (positions of order 1: 1e-16)
        assert case.error(moved, case.problem(0)[0]) >= 1e-6 - 1e-12


# ---------------------------------------------------------------------------- invariant checks
def _ring(n=10):
    rod = cartan.medium("cosserat-rod", E=1e4, poisson=0.5, radius=0.25, density=5000.0)
    grid = cartan.Grid(n, length=2.0, periodic=True)
    u = 2 * math.pi * np.arange(n) / n
    vel = np.stack([0.3 * np.cos(2 * u), 0.2 * np.sin(u), 0.4 * np.sin(2 * u), np.cos(u), 0.5 * np.sin(3 * u),
                    0.7 + 0 * u], axis=-1)
    init = rod.initial_state(grid, "ring", amplitude=0.2, mode=2, out_of_plane=0.15, velocity=vel,
                             rigid_velocity=[0, 0, 0, 0.5, 1.0, 2.0])
    return cartan.Problem(rod, grid, init)


def test_invariants_round_off_for_lattice_lie_verlet():
    ds = cartan.simulate(_ring(), integrator="lie-verlet", scheme="lattice", dt=2e-3, t_end=0.4, save_every=20,
                         progress=False)
    assert temporal_integrability(ds) <= 1e-12
    assert ring_closure(ds) <= 1e-12
    assert group_membership(ds) <= 1e-12
    assert spatial_integrability(ds) == 0.0  # d = 1: void
    assert 0 < energy_balance(ds) < 1e-3
    assert momentum_drift(ds) <= 1e-10  # free ring: Lie–Verlet conserves the momentum map
    report = check_invariants(ds)
    assert report["passed"] and all(v["passed"] in (True, None) for k, v in report.items() if k != "passed")


@pytest.mark.slow  # the lattice's forward-euler loop: ≈ 20 s to compile on a fresh cache
def test_invariants_large_for_forward_euler():
    with pytest.warns(cartan.StabilityWarning):
        ds = cartan.simulate(_ring(), integrator="forward-euler", scheme="lattice", dt=5e-4, t_end=0.1,
                             save_every=20, progress=False)
    assert group_membership(ds) > 1e-6
    assert ring_closure(ds) > 1e-6
    report = check_invariants(ds)
    assert not report["passed"] and report["group_membership"]["passed"] is False
    assert check_invariants(ds, tolerances={"group_membership": None, "ring_closure": None,
                                            "temporal_integrability": None, "energy_balance": None})["passed"]
    with pytest.raises(ValueError, match="unknown invariant"):
        check_invariants(ds, tolerances={"holonomy": 1.0})


@pytest.mark.slow  # the d = 2 lattice loops: ≈ 15 s to compile on a fresh cache
def test_spatial_integrability_d2_and_dissipative_balance():
    m = cartan.medium("sigma-model", n=2, d=2)
    grid = cartan.Grid((12, 12), 1.0, periodic=True)
    problem = cartan.Problem(m, grid, m.initial_state(grid, "random-smooth", amplitude=1.0, velocity_amplitude=1.0))
    ds = cartan.simulate(problem, dt=0.004, t_end=0.04, save_every=5, progress=False)
    assert "spatial_residual" in ds
    assert spatial_integrability(ds) <= 1e-12
    assert ring_closure(ds) <= 1e-12
    # dissipative: E + D − E₀ closes to the integrator's order (second-order overdamped, small Δt)
    case = CASES["sphere-rod-latitude-order2"]
    _, ds1 = run_case(case, 2, save_every=8)
    _, ds2 = run_case(case, 3, save_every=16)
    b1, b2 = energy_balance(ds1), energy_balance(ds2)
    assert float(ds1.dissipated_energy[-1]) > 0 and b1 < 1e-2
    assert 1.6 <= math.log2(b1 / b2) <= 2.4, (b1, b2)


@pytest.mark.slow  # the overdamped loops: ≈ 20 s to compile on a fresh cache
def test_dissipation_balance_is_the_gradient_flow_law():
    """dE/dt = −⟨N, ΓN⟩ recomputed from the saved velocities: O(Δt) for Lie–Euler, O(Δt²) for RKMK2
    (every step saved), on the overdamped rod on a sphere (drag) — any overdamped run."""
    case = CASES["sphere-rod-latitude"]
    problem, settings = case.problem(0)
    defects = {}
    for order in (1, 2):
        runs = []
        for steps in (40, 80):
            ds = cartan.simulate(problem, integrator="overdamped", dt=settings["t_end"] / steps,
                                 t_end=settings["t_end"], save_every=1, integrator_options={"order": order},
                                 progress=False)
            runs.append(dissipation_balance(ds, problem))
        defects[order] = runs
        assert order - 0.2 <= math.log2(runs[0] / runs[1]) <= order + 0.3, (order, runs)
    assert defects[2][1] < 1e-2 * defects[1][1]
    # the rate is the drag's power, positive; check_invariants reports it when given the problem
    rate = dissipation_rate(ds, problem)
    assert np.all(rate > 0)
    report = check_invariants(ds, problem=problem, tolerances={"dissipation_balance": 1e-4})
    assert report["dissipation_balance"]["passed"] and report["dissipation_balance"]["value"] == defects[2][1]
    assert "dissipation_balance" not in check_invariants(ds)
    # not vacuous: a velocity field 1 % off breaks the balance
    wrong = ds.copy(deep=True)
    wrong["N"].values[...] *= 1.01
    assert dissipation_balance(wrong, problem) > 100 * defects[2][1]
    # no dissipative load: nothing to balance
    assert dissipation_balance(ds, cartan.Problem(problem.medium, problem.grid, problem.initial)) == 0.0


# ---------------------------------------------------------------------------- shared references
def test_elastica_references_agree():
    """Two independent computations of the inextensible cantilever (elliptic integrals; shooting on
    the boundary-value problem) agree to round-off and reproduce the tabulated five digits."""
    for alpha, (v_tab, s_tab) in ref.ELASTICA_TABLE.items():
        v, s = ref.cantilever_elastica(alpha)
        assert abs(v - v_tab) <= 5e-6 and abs(s - s_tab) <= 5e-6, (alpha, v, s)
        v2, s2 = ref.cantilever_exact_tip(1.0, alpha, 1.0)
        assert abs(v2 - v) < 1e-11 and abs(s2 - s) < 1e-11, (alpha, v - v2, s - s2)
    with pytest.raises(ValueError, match="alpha must be a finite number > 0"):
        ref.cantilever_elastica(0.0)


def test_timoshenko_reference_against_linear_theory():
    """The geometrically exact tip deflection tends to the linear Timoshenko value as F → 0 (the
    relative gap is O(F²)) and lies 3.23e-4 below it at F = 15."""
    case = CASES["rod-timoshenko-static"]
    k = case.stiffnesses()
    gaps = []
    for force in (15.0, 7.5):
        exact = ref.cantilever_exact_tip(case.length, force, k["EI"], k["EA"], k["shear_stiffness"])[0]
        gaps.append(exact / ref.timoshenko_linear_tip(case.length, force, k["EI"], k["shear_stiffness"]) - 1)
    assert -3.3e-4 < gaps[0] < -3.1e-4
    assert 3.8 < gaps[0] / gaps[1] < 4.2
    assert case.exact() == pytest.approx(0.0677484208, rel=1e-9)


def test_pinned_elastica_reference():
    """Near onset w/L ≈ (2√2/π)√(P/P_cr − 1); the shortening follows from the same modulus."""
    for excess in (1e-4, 1e-3):
        w, s = ref.pinned_elastica(1.0 + excess)
        assert w == pytest.approx(2 * math.sqrt(2) / math.pi * math.sqrt(excess), rel=2 * excess)
        assert s == pytest.approx(2 * excess, rel=10 * excess)  # Δ/L ≈ π²(w/L)²/4 = 2(P/P_cr − 1)
    assert ref.pinned_elastica(1.5)[0] == pytest.approx(0.394288, abs=1e-6)
    with pytest.raises(ValueError, match="load_ratio must be a finite number > 1"):
        ref.pinned_elastica(0.9)
    assert ref.euler_critical_load(2.0, 2.0) == pytest.approx(math.pi**2 / 2)


def test_rod_dispersion_is_timoshenko_for_a_straight_rod():
    """Straight rod: the axial and torsional branches are c·k; the flexural branches solve the
    Timoshenko beam's frequency equation det[[κGAk² − ρAω², iκGAk], [−iκGAk, EIk² + κGA − ρIω²]] = 0."""
    rod = cartan.medium("cosserat-rod", E=1e4, poisson=0.5, radius=0.25, density=5000.0)
    C = np.asarray(rod.stiffness_diagonal(), float).ravel()
    M = np.asarray(rod.inertia(), float)
    for k in (0.5, 3.0, 20.0):
        omega, modes = ref.rod_dispersion(k, [1, 0, 0, 0, 0, 0], C, M)
        assert np.any(np.isclose(omega, math.sqrt(C[0] / M[0]) * k, rtol=1e-12))
        assert np.any(np.isclose(omega, math.sqrt(C[3] / M[3]) * k, rtol=1e-12))
        ga, ei, rho_a, rho_i = C[1], C[4], M[0], M[4]
        for w in omega:
            det = (ga * k**2 - rho_a * w**2) * (ei * k**2 + ga - rho_i * w**2) - (ga * k) ** 2
            if not (np.isclose(w, math.sqrt(C[0] / M[0]) * k) or np.isclose(w, math.sqrt(C[3] / M[3]) * k)):
                assert abs(det) <= 1e-9 * (ga * k**2 + ei * k**2 + ga) ** 2, (k, w, det)
        assert np.allclose(modes.conj().T @ np.diag(M) @ modes, np.eye(6), atol=1e-12)
    with pytest.raises(ValueError, match="stiffness must be 6 finite numbers"):
        ref.rod_dispersion(1.0, np.zeros(6), C[:3], M)


# ---------------------------------------------------------------------------- static cases
def test_euler_buckling_critical_load_and_branch():
    """P_cr within 1e-3 of π²B/L² and second order in dx (π²h²/12); the post-buckled point at
    P = 1.5 P_cr matches the elastica's deflection and shortening."""
    case = CASES["rod-euler-buckling"]
    parts = []
    for level in case.quick():
        _, ds = run_case(case, level)
        assert list(ds["critical_kind"].values) == ["bifurcation"]
        assert ds["load_factor"].values[-1] == pytest.approx(1.5 * math.pi**2, rel=1e-12)
        parts.append(case.parts(ds))
        h = 1.0 / (case.problem(level)[0].grid.shape[0] - 1)
        assert parts[-1]["critical_load"] == pytest.approx(math.pi**2 * h**2 / 12, rel=0.01)
    assert parts[-1]["critical_load"] < 1e-3
    for key in ("critical_load", "deflection", "shortening"):
        assert 1.8 <= math.log2(parts[0][key] / parts[1][key]) <= 2.3, (key, parts)
    assert max(parts[-1].values()) <= case.tolerance


def test_cantilever_elastica_every_load():
    case = CASES["rod-cantilever-elastica"]
    _, ds = run_case(case, case.quick()[-1])
    parts = case.parts(ds)
    assert set(parts) == {f"{w} {a:g}" for a in case.loads for w in ("vertical", "shortening")}
    assert max(abs(v) for v in parts.values()) <= 1e-4, parts
    assert np.all(np.diff(ds["monitor"].values) > 0)


# ---------------------------------------------------------------------------- integrability contrast
def test_ring_wave_integrability_lattice_round_off_collocation_drifts():
    """On the flexural ring wave (translations and rotations that do not commute) the lattice keeps
    the stored strains integrable to round-off while collocation's drift by O(h²) per unit time."""
    case = CASES["rod-ring-flexural-wave"]
    resid = {}
    for scheme in ("lattice", "collocation"):
        _, ds = run_case(case, 1, "lie-verlet", scheme)
        resid[scheme] = float(ds["integrability_residual"].max())
        assert float(ds["integrability_residual"][0]) <= 1e-12  # both start integrable
    assert resid["lattice"] <= 1e-12, resid
    assert resid["collocation"] >= 1e3 * max(resid["lattice"], 1e-16), resid


def test_great_circle_slide_detects_stress():
    """The slide's error is not vacuous: a strain off the great circle's shows."""
    case = CASES["sphere-rod-great-circle-slide"]
    err, ds = run_case(case, 1)
    assert err <= case.tolerance
    bent = ds.copy(deep=True)
    bent["X"].values[-1, 3, ..., 2] += 1e-6
    assert case.error(bent, case.problem(1)[0]) >= 1e-7


# ---------------------------------------------------------------------------- stability cases
def test_stability_case_is_not_a_convergence_study():
    from cartan.study import StudyError, converge

    case = CASES["rod-stiff-stability"]
    assert case.kind == "stability" and not case.compare_methods
    with pytest.raises(StudyError, match=r"stability study.*cartan verify --case rod-stiff-stability"):
        converge(case, levels=2)


@pytest.mark.slow
def test_stiff_rod_stability_section(tmp_path):
    """The report section of the stiff rod: implicit-midpoint stable at ≥ 10× the explicit CFL
    estimate at every dx, lie-verlet's bisected limit within a factor 2 of that estimate."""
    case = CASES["rod-stiff-stability"]
    text, parts, checks, failed = case.report_section(tmp_path, quick=True)
    assert (checks, failed) == (2 * len(case.n_values), 0), text
    assert (tmp_path / "rod-stiff-stability.png").stat().st_size > 0
    ds = parts[0]
    ratio = ds["dt_max"] / ds["dt_reference"]
    assert float(ratio.sel(integrator="implicit-midpoint").min()) >= 10.0
    explicit = ratio.sel(integrator="lie-verlet")
    assert 0.5 <= float(explicit.min()) <= float(explicit.max()) <= 2.0
