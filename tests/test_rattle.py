"""``rattle``: time integration of media with constrained strains (paper §III.E, §IV.E).

The inextensible, unshearable filament (θ = (1, 0, 0) on every lattice edge) run in time: the
constraints held to round-off, the velocities tangent to them, the energy balance closing to
the method's second order, the observed order in Δt, exact restarts, and the statics'
equilibrium reached by a damped run.  Without constraints the step is lie-verlet's.

The fast tests run the Python step (``compiled=False``), the reference of the compiled loop,
which compiles for minutes on a fresh cache: its agreement with the Python step, its restarts
and the long runs are in ``make test-slow`` (and ``tests/test_rattle_compiled.py``).
"""

from __future__ import annotations

import numpy as np
import pytest

import cartan
from cartan.constraints import StrainConstraints
from cartan.integrators import LieVerlet, Rattle
from cartan.schemes import Lattice

#: a 3-D tip wrench: bending about both axes and twist
TIP = [0.0, -2.0, 0.5, 0.2, 0.0, 0.0]


def _filament(n: int = 11, load=TIP, loads=(), initial=None):
    rod = cartan.medium("filament", bending=(1.0, 1.5), twist=0.8, rotational_inertia=0.01)
    grid = cartan.Grid(n, length=1.0)
    return cartan.Problem(rod, grid, initial or rod.initial_state(grid, "straight"),
                          {"start": cartan.Clamped(), "end": cartan.Free(load=list(load))}, loads=list(loads))


@pytest.fixture(scope="module")
def run():
    """200 steps of Δt = 5e-3 (the bending waves' limit at n = 11 is ≈ 1e-2)."""
    integ = Rattle()
    ds = cartan.simulate(_filament(), integrator=integ, dt=5e-3, t_end=1.0, save_every=20, progress=False,
                         compiled=False)
    return ds, integ


def test_constraints_hold_to_round_off(run):
    """θ = (1, 0, 0) on every edge at every save, to round-off (the iteration stops at 1e-13)."""
    ds, integ = run
    theta = ds["X"].values[..., :3]
    assert np.max(np.abs(theta - [1.0, 0.0, 0.0])) < 1e-12
    assert float(ds["constraint_residual"].max()) < 1e-12
    # the filament moved (bent by several tenths of its length): there was something to hold
    assert float(np.abs(ds["position"].values[-1, -1, 1])) > 0.1
    assert integ.niter / integ.nstep < 8  # the multipliers' iteration converges in a few steps


def test_energy_balance_is_second_order(run):
    """K + V − W (W the work of the dead end load) stays at the method's O(Δt²) error, and the
    constraint forces do no work: halving Δt divides the balance error by ≈ 4."""
    ds, _ = run
    balance = ds["kinetic_energy"] + ds["potential_energy"] - ds["external_work"]
    err_coarse = float(np.max(np.abs(balance)))
    assert err_coarse < 2e-3 * float(ds["external_work"].max())
    fine = cartan.simulate(_filament(), integrator="rattle", dt=2.5e-3, t_end=1.0, save_every=40, progress=False,
                           compiled=False)
    err_fine = float(np.max(np.abs(fine["kinetic_energy"] + fine["potential_energy"] - fine["external_work"])))
    assert 2.8 < err_coarse / err_fine < 5.7  # 4 = 2², within the spread of a max over 50 saves


def test_observed_order_is_two():
    """Tip position at t = 0.4 for Δt = 8, 4, 2 × 1e-3: the ratio of successive differences
    gives the order, 2 ± 0.25."""
    tips = []
    for dt in (8e-3, 4e-3, 2e-3):
        ds = cartan.simulate(_filament(n=9), integrator="rattle", dt=dt, t_end=0.4, save_every=int(round(0.4 / dt)),
                             progress=False, compiled=False)
        tips.append(ds["position"].values[-1, -1])
    d1, d2 = np.linalg.norm(tips[0] - tips[1]), np.linalg.norm(tips[1] - tips[2])
    order = np.log2(d1 / d2)
    assert 1.75 < order < 2.25, order


def test_chord_iteration_and_its_newton_fallback_agree(monkeypatch):
    """The position multipliers' chord iteration (the matrix ½Δt·Δt B₀PB₀ᵀ the predictor
    factors, the flow's Jacobian to O(Δt|N|): each iteration gains about three digits) and the
    quasi-Newton matrix it turns to when an iteration gains less than ``_SLOW`` (forced here
    from the second trial on, ``_SLOW = 0``) converge to the same steps: 12 Python steps of
    Δt = 5e-3 under the tip wrench, the constraints at round-off in both, the states equal to
    1e-11 (both stop at |c| ≤ 1e-13).  Near the time step's limit (the CFL estimate allows
    Δt ≈ 1e-2 here) the chord costs little: measured 5.0 trial flows per step (at most 6)
    against 4.97 (at most 5) with the quasi-Newton matrix."""
    import cartan.integrators.constrained as constrained

    def run():
        sch = Lattice(_filament())
        state = sch.initial_state()
        integ = Rattle()
        trials = []
        for _ in range(12):
            before = integ.niter
            integ.step(sch, state, 5e-3)
            trials.append(1 + integ.niter - before)
        return sch, state, integ, trials

    sch, chord, integ, trials = run()
    monkeypatch.setattr(constrained, "_SLOW", 0.0)
    _, newton, integ_n, trials_n = run()
    assert min(trials_n) >= 3  # it iterated past the first chord iteration: the fallback's matrix was used
    assert np.mean(trials) <= np.mean(trials_n) + 0.5 and max(trials) <= max(trials_n) + 1
    for st, it in ((chord, integ), (newton, integ_n)):
        assert it.constraint_residual(sch, st) < 1e-13
    assert np.max(np.abs(chord.S - newton.S)) < 1e-11
    for key in chord.arrays:
        assert np.max(np.abs(chord.arrays[key] - newton.arrays[key])) < 1e-11, key
    assert np.max(np.abs(sch.velocity(chord))) > 0.1  # it moved


def test_offset_predictor_moves_the_start_only(monkeypatch):
    """The predictor λ + (ν − λ)* (the force-level multiplier plus the offset ν − λ of the last
    three steps extrapolated quadratically, kept in ``State.memory``) changes where the
    multipliers' iteration starts, not where it ends: 40 damped Python steps of Δt = 4e-3 under
    the tip wrench, with the extrapolated offset, with the last offset alone and without an
    offset, agree to 1e-11 (all stop at |c| ≤ 1e-13: round-off apart, as the chord and Newton
    matrices above; measured 2e-13), with fewer trial flows each (measured per step near the
    time step's limit, Δt ≈ 0.4 of the CFL estimate: 4.88 without, 4.55 with the last offset,
    4.30 with the extrapolated one)."""
    import cartan.integrators.constrained as constrained

    prob = _filament(loads=[cartan.Damping([7.0, 7.0, 7.0, 0.07, 0.07, 0.07])])

    def run():
        sch = Lattice(prob)
        state = sch.initial_state()
        integ = Rattle()
        for _ in range(40):
            integ.step(sch, state, 4e-3)
        return sch, state, integ

    sch, fast, integ = run()
    assert fast.memory["rattle_offset"].shape == (3, 10 * 3)
    assert fast.memory["rattle_offset_dt"].tolist() == [4e-3] * 3
    extrapolated = constrained._offset

    def last_only(state, ncon, dt):
        off, k = extrapolated(state, ncon, dt)
        return (None, 0) if k == 0 else (state.memory["rattle_offset"][0], 1)

    monkeypatch.setattr(constrained, "_offset", last_only)
    _, last, integ_last = run()
    monkeypatch.setattr(constrained, "_offset", lambda *args: (None, 0))
    _, slow, integ_slow = run()
    assert integ.niter < integ_last.niter < integ_slow.niter
    assert integ.constraint_residual(sch, fast) < 1e-13
    for other in (last, slow):
        assert np.max(np.abs(fast.S - other.S)) < 1e-11
        for key in fast.arrays:
            assert np.max(np.abs(fast.arrays[key] - other.arrays[key])) < 1e-11, key
    assert np.max(np.abs(sch.velocity(fast))) > 0.1  # it moved


def test_rows_rate_in_closed_form():
    """The predictor's Ḃ_c N (``Rattle._rows_rate``: the rows' second derivative along the drift
    Φ ← Φ exp(εN), from the series of dexp⁻¹ to its second term) against a fourth-order central
    difference of the rows along exp(εN): from a bent, moving filament (40 steps under the tip
    wrench, n = 11: |hX_e| up to ≈ 0.2, the series' remainder ≈ (4/720)|hX_e|³), measured 4e-6
    of the largest rate; the difference's own error (ε = 1e-3/max|N|) is ≈ 1e-10."""
    from cartan.schemes.base import State

    sch = Lattice(_filament())
    state = sch.initial_state()
    integ = Rattle()
    for _ in range(40):
        integ.step(sch, state, 5e-3)
    con = integ._constraints(sch, state)[0]
    N = sch.velocity(state)

    def rows(eps):
        moved = State(state.t, state.S, {k: v.copy() for k, v in state.arrays.items()})
        sch.drift(moved, eps, N, exact=True)
        return con.values(moved)

    eps = 1e-3 / float(np.max(np.abs(N)))
    fd = (-rows(2 * eps) + 16 * rows(eps) - 30 * rows(0.0) + 16 * rows(-eps) - rows(-2 * eps)) / (12 * eps**2)
    rate = integ._rows_rate(sch, state, N, con)
    assert float(np.max(np.abs(fd))) > 1.0  # the filament turns: the rows curve along the drift
    assert float(np.max(np.abs(rate - fd))) < 2e-5 * float(np.max(np.abs(fd)))


def test_velocity_is_tangent_after_a_step():
    """An initial velocity that stretches the filament is projected: after one step
    B_c N = 0 to round-off and the stretch rate is gone."""
    prob = _filament(n=7, load=[0.0] * 6)
    rod = prob.medium
    grid = prob.grid
    N0 = np.zeros((7, 6))
    N0[:, 0] = np.linspace(0.0, 1.0, 7)  # axial velocity growing along the rod: a stretch rate
    N0[:, 1] = 0.3 * np.linspace(0.0, 1.0, 7)
    prob = cartan.Problem(rod, grid, cartan.InitialState(prob.initial.Phi, N0), prob.boundaries)
    sch = Lattice(prob)
    state = sch.initial_state()
    integ = Rattle()
    integ.step(sch, state, 1e-3)
    unknown = np.broadcast_to(sch.live, (7, 6)).copy()
    unknown[sch._clamped] = False
    con = StrainConstraints(sch, unknown, state)
    N = sch.velocity(state)[unknown]
    assert np.max(np.abs(con.matrix(state) @ N)) < 1e-12 * max(1.0, np.max(np.abs(N)))
    assert np.max(np.abs(con.values(state))) < 1e-13
    assert np.max(np.abs(N)) > 0.01  # the transverse motion is kept


def test_without_constraints_rattle_is_lie_verlet():
    """On a medium that holds nothing fixed the step is lie-verlet's, bit for bit."""
    rod = cartan.medium("cosserat-rod", stretch_shear=[100.0, 50.0, 50.0], bend_twist=[1.0, 2.0, 2.0], mass=1.0,
                        rotational_inertia=[0.02, 0.01, 0.01])
    grid = cartan.Grid(9, length=1.0)
    prob = cartan.Problem(rod, grid, rod.initial_state(grid, "arc", curvature=2.0),
                          {"start": cartan.Clamped(), "end": cartan.Free(load=[0.5, 0.3, 0.1, 0.2, 0.0, 0.1])})
    a = cartan.simulate(prob, integrator=Rattle(), dt=1e-3, t_end=0.02, compiled=False, progress=False)
    b = cartan.simulate(prob, integrator=LieVerlet(), dt=1e-3, t_end=0.02, compiled=False, progress=False)
    assert np.array_equal(a["position"].values, b["position"].values)
    assert np.array_equal(a["S"].values, b["S"].values)
    assert float(a["constraint_residual"].max()) == 0.0


def test_simulate_picks_rattle_and_refuses_the_others():
    """A medium with constrained strains runs with ``rattle`` by default; an integrator that does
    not hold the constraints is refused with a clear error; the collocation scheme holds them on
    its nodal strains (``tests/test_rattle_collocation.py``)."""
    prob = _filament(n=5)
    ds = cartan.simulate(prob, dt=5e-3, t_end=0.01, progress=False, compiled=False)
    assert "constraint_residual" in ds and float(ds["constraint_residual"].max()) < 1e-12
    with pytest.raises(ValueError, match="integrator='rattle'"):
        cartan.simulate(prob, integrator="lie-verlet", dt=5e-3, t_end=0.01, progress=False)
    dc = cartan.simulate(prob, scheme="collocation", dt=5e-3, t_end=0.01, progress=False, compiled=False)
    assert float(dc["constraint_residual"].max()) < 1e-12


@pytest.mark.parametrize("compiled", [False, pytest.param(True, marks=pytest.mark.slow)])
def test_restart_is_bit_for_bit(tmp_path, compiled):
    """A run continued from its checkpoint is the uninterrupted run, bit for bit: the
    multipliers' iteration starts from the state and the last step's offset ν − λ in
    ``State.memory``, which the checkpoint carries (without it the continued run differs by
    round-off, 2e-16 in the positions), in the Python step and the compiled loop (which
    compiles for minutes on a fresh cache: ``make test-slow``)."""
    from cartan import io

    prob = _filament(n=7)
    kw = dict(integrator="rattle", dt=4e-3, save_every=5, checkpoint_every=1, progress=False, compiled=compiled)
    whole = cartan.simulate(prob, t_end=0.08, output=tmp_path / "whole.nc", **kw)
    cartan.simulate(prob, t_end=0.04, output=tmp_path / "part.nc", **kw)
    memory = io.read_checkpoint(tmp_path / "part.nc")[0].memory
    assert memory["rattle_offset"].shape == (3, 6 * 3) and np.max(np.abs(memory["rattle_offset"])) > 0.0
    assert memory["rattle_offset_dt"].tolist() == [4e-3] * 3
    cont = cartan.simulate(prob, restart=tmp_path / "part.nc", t_end=0.08, progress=False, compiled=compiled)
    for name in ("position", "frame", "S", "X", "kinetic_energy", "external_work", "constraint_residual"):
        assert np.array_equal(whole[name].values, cont[name].values), name


def parabola_problem(rod, n: int, end_load=None) -> cartan.Problem:
    """``rod`` clamped at x = 0, sampled on the parabola y = ½x² at n equal x steps with frames
    along its tangent: the edges stretch and shear (the arclength is not x), off the constraints."""
    grid = cartan.Grid(n, length=1.0)
    x = grid.coordinates(0)
    angle = np.arctan(x)  # the tangent of y = ½x²
    c, sn = np.cos(angle), np.sin(angle)
    Phi = np.zeros((n, 4, 4))
    Phi[:, 0, 0] = 1.0
    Phi[:, 1, 0], Phi[:, 2, 0] = x, 0.5 * x**2
    Phi[:, 1:, 1:] = np.stack([np.stack([c, -sn, 0 * x], -1), np.stack([sn, c, 0 * x], -1),
                               np.stack([0 * x, 0 * x, 1 + 0 * x], -1)], axis=-2)
    end = cartan.Free() if end_load is None else cartan.Free(load=list(end_load))
    return cartan.Problem(rod, grid, cartan.InitialState(Phi, np.zeros((n, 6))),
                          {"start": cartan.Clamped(), "end": end})


def test_initial_configuration_is_projected():
    """A sampled shape that misses θ = (1, 0, 0) (nodes on the parabola y = ½x² at equal x
    steps, frames along its tangent: the edges stretch and shear) is brought onto the
    constraints before the first step."""
    n = 9
    prob = parabola_problem(cartan.medium("filament"), n)
    sch = Lattice(prob)
    state = sch.initial_state()
    unknown = np.broadcast_to(sch.live, (n, 6)).copy()
    unknown[sch._clamped] = False
    con = StrainConstraints(sch, unknown, state)
    assert np.max(np.abs(con.values(state))) > 1e-2  # the parabola's arclength is not x
    Rattle().step(sch, state, 1e-3)
    assert np.max(np.abs(con.values(state))) < 1e-13


@pytest.mark.slow
def test_length_and_constraints_over_ten_thousand_steps():
    """10⁴ steps (t = 50, a tip wrench swinging the filament through large 3-D motion): the
    constraint residual stays at round-off and the energy balance bounded (no drift)."""
    integ = Rattle()
    ds = cartan.simulate(_filament(), integrator=integ, dt=5e-3, t_end=50.0, save_every=500, progress=False)
    assert integ.nstep == 10_000
    assert float(ds["constraint_residual"].max()) < 1e-12
    balance = ds["kinetic_energy"] + ds["potential_energy"] - ds["external_work"]
    assert float(np.max(np.abs(balance))) < 2e-3 * float(ds["external_work"].max())


@pytest.mark.slow
def test_damped_run_settles_on_the_static_elastica():
    """A damped run of the planar cantilever under a tip dead load α = PL²/B = 2 settles on the
    equilibrium ``solve_static`` finds with the same constraints (same lattice): the dynamics'
    multipliers and the statics' are the same fictitious stresses."""
    damping = cartan.Damping([4.0, 4.0, 4.0, 0.04, 0.04, 0.04])
    prob = _filament(n=11, load=[0.0, -2.0, 0.0, 0.0, 0.0, 0.0], loads=[damping])
    rod = cartan.medium("filament", bending=(1.0, 1.0), twist=0.8, rotational_inertia=0.01)
    prob = cartan.Problem(rod, prob.grid, prob.initial, prob.boundaries, loads=[damping])
    static = cartan.Problem(rod, prob.grid, prob.initial, prob.boundaries)
    target = cartan.solve_static(static, load_steps=2)["position"].values[0, -1]
    ds = cartan.simulate(prob, integrator="rattle", dt=5e-3, t_end=12.0, save_every=400, progress=False)
    tip = ds["position"].values[-1, -1]
    assert float(ds["kinetic_energy"][-1]) < 1e-10
    assert np.linalg.norm(tip - target) < 1e-6


@pytest.mark.slow
def test_stiff_cosserat_rod_tends_to_the_filament_in_time():
    """Cross-medium limit in time: cosserat-rod with EA = GA = ratio·B/L² (lie-verlet, compiled)
    against the filament (rattle) from the same start under the same tip wrench; the tip
    difference at t = 0.4 falls like 1/ratio (the axial and shear strains are F/EA): fitted
    slope −1 ± 0.1 over ratio = 1e3 … 1e5 (measured −1.00; 1e2 is pre-asymptotic)."""
    T, dt = 0.4, 5e-4
    grid = cartan.Grid(11, length=1.0)
    bc = {"start": cartan.Clamped(), "end": cartan.Free(load=TIP)}
    fil = cartan.medium("filament", bending=(1.0, 1.5), twist=0.8, rotational_inertia=0.01)
    ref = cartan.simulate(cartan.Problem(fil, grid, fil.initial_state(grid, "straight"), bc), integrator="rattle",
                          dt=dt, t_end=T, save_every=int(round(T / dt)), progress=False)["position"].values[-1, -1]
    ratios, diffs = [1e3, 1e4, 1e5], []
    for ratio, sub in zip(ratios, (1, 2, 8), strict=True):  # the rod's step below its axial waves' limit
        rod = cartan.medium("cosserat-rod", stretch_shear=[ratio] * 3, bend_twist=[0.8, 1.0, 1.5], mass=1.0,
                            rotational_inertia=[0.01] * 3)
        prob = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"), bc)
        ds = cartan.simulate(prob, integrator="lie-verlet", dt=dt / sub, t_end=T, save_every=int(round(T * sub / dt)),
                             progress=False)
        diffs.append(np.linalg.norm(ds["position"].values[-1, -1] - ref))
    slope = np.polyfit(np.log(ratios), np.log(diffs), 1)[0]
    assert -1.1 < slope < -0.9, (slope, diffs)


def test_swing_scene_runs_with_rattle():
    """The registered scene ``filament-swing`` (released under gravity, damped) names rattle; a
    short run holds the constraints and closes the energy balance E + D − W."""
    sc = cartan.scene("filament-swing")
    assert sc.run_settings()["integrator"] == "rattle"
    ds = cartan.simulate(sc, t_end=0.4, progress=False, compiled=False)
    assert float(ds["constraint_residual"].max()) < 1e-12
    assert float(ds["kinetic_energy"][-1]) > 0.1  # it is swinging
    E = ds["kinetic_energy"] + ds["potential_energy"] + ds["dissipated_energy"] - ds["external_work"]
    assert float(np.max(np.abs(E))) < 1e-3 * float(ds["kinetic_energy"].max())


def test_frame_record_takes_the_reference_numbers():
    """A saved frame computes the edge strains once (for X and the held rows' residual) and
    the kinetic energy from the velocity it records: the same numbers, bit for bit, as the
    scheme's and the integrator's own methods (a few Python steps of a damped, bending run,
    so that nothing is zero)."""
    from cartan import io

    prob = _filament(n=7, loads=[cartan.Damping([1.0, 1.0, 1.0, 0.01, 0.01, 0.01])])
    integ = Rattle()
    sch = Lattice(prob)
    state = sch.initial_state()
    for _ in range(4):
        integ.step(sch, state, 4e-3)
    rec = io.frame_record(sch, integ, state)
    assert rec["kinetic_energy"] > 0.0
    assert rec["kinetic_energy"] == float(sch.kinetic_energy(state))
    assert rec["constraint_residual"] == integ.constraint_residual(sch, state)  # from StrainConstraints.values
    assert np.array_equal(rec["X"], np.asarray(sch.strains(state))[..., 0, :])


def test_compiled_loop_arguments_are_built_once_per_step_size():
    """The loop's fixed arguments (free-flow pieces, closing matrix, held components) are built
    at the first call for a (scheme, problem, Δt) and shared by the later calls; a new Δt builds
    them again (the damped closing matrix depends on it); the force carried between calls and
    the status arrays are new at every call.  (Building the arguments compiles nothing.)"""
    prob = _filament(n=7, loads=[cartan.Damping([1.0, 1.0, 1.0, 0.01, 0.01, 0.01])])
    integ = Rattle()
    sch = Lattice(prob)
    state = sch.initial_state()
    name, a = integ.compiled_loop(sch, state, 4e-3)
    _, b = integ.compiled_loop(sch, state, 4e-3)
    _, c = integ.compiled_loop(sch, state, 2e-3)
    _, fresh = Rattle().compiled_loop(sch, state, 2e-3)
    assert name == "rattle_loop" and len(a) == 13
    assert all(x is y for x, y in zip(a[3:9], b[3:9], strict=True))  # pieces … scale: shared
    assert a[0] is not b[0] and a[-2] is not b[-2] and a[-1] is not b[-1]  # W, status, info: new
    assert not np.array_equal(a[5], c[5])  # the closing matrix (I + ½ΔtΓM⁺)⁻¹ follows Δt
    for x, y in zip(c, fresh, strict=True):
        assert np.array_equal(np.asarray(x), np.asarray(y))
