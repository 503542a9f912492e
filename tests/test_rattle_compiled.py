"""The compiled ``rattle`` loop (:mod:`cartan.integrators.rattle_loop`) against the Python step.

The fast tests use one compiled loop, the filament (SE(3), its quadratic kernels) on an open
chain, which ``tests/test_rattle.py`` compiles too (its runs take the compiled path by default):
the compiled and Python runs agree to round-off, the constraints hold, the initial projection
and the failure of the multipliers' iteration behave as in Python, and the problems the loop
does not cover fall back to the Python step with a reason.
"""

from __future__ import annotations

import numpy as np
import pytest

# the filament, its tip wrench and the parabola off the constraints, as in the Python step's tests
from test_rattle import TIP, _filament, parabola_problem

import cartan
from cartan.integrators import Rattle
from cartan.schemes import Lattice


def _python_steps_forbidden(monkeypatch):
    """Make the Python step fail: a run that passes took only compiled steps."""
    def refuse(*args, **kwargs):
        raise AssertionError("the Python step ran")
    monkeypatch.setattr(Rattle, "_step", refuse)


@pytest.mark.slow  # compiles the rattle loop (minutes on a fresh cache)
def test_compiled_run_matches_the_python_step(monkeypatch):
    """120 steps of Δt = 5e-3 under a 3-D tip wrench (the filament bends by tenths of its
    length): the compiled loop and the Python step agree to round-off.  Both converge the
    multipliers to |c| ≤ 1e-13 and differ in the order of their sums only; measured 2e-15 in
    the positions and 1e-14 in S after 120 steps (2e-14 after 300): 1e-11 leaves room for the
    growth of round-off in a bending motion."""
    kw = dict(dt=5e-3, t_end=0.6, save_every=40, progress=False)
    py_integ = Rattle()
    ref = cartan.simulate(_filament(), integrator=py_integ, compiled=False, **kw)
    integ = Rattle()
    with monkeypatch.context() as m:
        _python_steps_forbidden(m)
        ds = cartan.simulate(_filament(), integrator=integ, **kw)
    assert integ.compiled_declined is None
    assert integ.nstep == py_integ.nstep == 120
    assert integ.niter == py_integ.niter  # the same iterations, step by step
    assert integ.nforce == py_integ.nforce
    assert float(np.abs(ref["position"].values[-1, -1, 1])) > 0.05  # it moved
    for name in ("position", "frame", "S", "X", "kinetic_energy", "potential_energy", "external_work"):
        scale = max(1.0, float(np.max(np.abs(ref[name].values))))
        assert float(np.max(np.abs(ds[name].values - ref[name].values))) < 1e-11 * scale, name
    assert float(ds["constraint_residual"].max()) < 1e-12


@pytest.mark.slow  # compiles the rattle loop (minutes on a fresh cache)
def test_compiled_initial_projection_matches_python():
    """A sampled shape off the constraints (nodes on y = ½x² at equal x steps, the edges
    stretch and shear) is projected by the compiled loop's first step as by the Python step:
    residual at round-off and the same state to round-off."""
    rod = cartan.medium("filament", bending=(1.0, 1.5), twist=0.8, rotational_inertia=0.01)
    prob = parabola_problem(rod, 9, end_load=TIP)
    sch = Lattice(prob)
    a, b = sch.initial_state(), sch.initial_state()
    a.scalars["nstep"] = b.scalars["nstep"] = 0
    integ = Rattle()
    assert integ.run_compiled_loop(sch, a, 1e-3, 3)
    py = Rattle()
    for _ in range(3):
        py.step(sch, b, 1e-3)
    con = integ._constraints(sch, a)[0]
    assert np.max(np.abs(con.values(a))) < 1e-13
    assert np.max(np.abs(con.values(sch.initial_state()))) > 1e-2  # there was something to project
    for key in a.arrays:
        assert np.max(np.abs(a.arrays[key] - b.arrays[key])) < 1e-12, key
    assert np.max(np.abs(a.S - b.S)) < 1e-11


@pytest.mark.slow  # compiles the rattle loop (minutes on a fresh cache)
def test_failed_iteration_raises_and_keeps_the_last_state():
    """A time step far beyond the bending waves' limit: the multipliers' iteration fails at
    the first step, the loop raises the Python step's ConvergenceError and the state is the
    one the step started from."""
    from cartan.statics import ConvergenceError

    sch = Lattice(_filament())
    state = sch.initial_state()
    state.scalars["nstep"] = 0
    before = {k: v.copy() for k, v in state.arrays.items()}
    with pytest.raises(ConvergenceError, match="reduce dt"):
        Rattle().run_compiled_loop(sch, state, 2.0, 5)
    assert state.scalars["nstep"] == 0
    for key, value in before.items():
        assert np.array_equal(state.arrays[key], value), key
    assert np.array_equal(state.S, sch.initial_state().S)


def test_uncovered_problems_fall_back_with_a_reason():
    """d = 2 (the Kirchhoff–Love surface) and a periodic chain are left to the Python step,
    with the reason; nothing is compiled to find out."""
    rod = cartan.medium("filament")
    grid = cartan.Grid(8, length=1.0, periodic=True)
    ring = cartan.Problem(rod, grid, rod.initial_state(grid, "ring"))
    integ = Rattle()
    sch = Lattice(ring)
    assert integ.compiled_loop(sch, sch.initial_state(), 1e-3) is None
    assert "periodic" in integ.compiled_declined
    plate = cartan.medium("kirchhoff-love", thickness=0.1)
    grid2 = cartan.Grid((5, 3), length=(1.0, 0.5))
    sch2 = Lattice(cartan.Problem(plate, grid2, plate.initial_state(grid2, "flat"), {"u-start": cartan.Clamped()}))
    assert integ.compiled_loop(sch2, sch2.initial_state(), 1e-3) is None
    assert "d = 2" in integ.compiled_declined


@pytest.mark.slow
def test_damped_gravity_run_matches_the_python_step():
    """The damped branch (the closing kick implicit in the damping, μ solved with it) and a
    constant field: the scene ``filament-swing`` over 300 steps, compiled against Python."""
    sc = cartan.scene("filament-swing")
    kw = dict(t_end=300 * 2e-3, dt=2e-3, save_every=100, progress=False)
    ref = cartan.simulate(sc, compiled=False, **kw)
    ds = cartan.simulate(sc, **kw)
    for name in ("position", "S", "kinetic_energy", "dissipated_energy", "external_work"):
        scale = max(1.0, float(np.max(np.abs(ref[name].values))))
        assert float(np.max(np.abs(ds[name].values - ref[name].values))) < 1e-10 * scale, name
    assert float(ds["constraint_residual"].max()) < 1e-12


@pytest.mark.slow  # the rattle loop (minutes on a fresh cache)
@pytest.mark.parametrize("damping", [[2.0, 2.0, 2.0, 0.02, 0.02, 0.02], [2.0, 1.0, 3.0, 0.05, 0.01, 0.02]],
                         ids=["proportional", "general"])
def test_damped_runs_match_python_and_restart_bit_for_bit(tmp_path, damping):
    """Damping proportional to the inertia (Γ_k/M_kk the same on every component: the closing
    kick's projection reuses the factors of B P Bᵀ) and general damping (its own factors): the
    compiled loop agrees with the Python step to round-off (1e-11, as the undamped run above),
    and a compiled run continued from its checkpoint is the uninterrupted one bit for bit (the
    force a step starts from is W(N = 0) − ΓN however the steps are grouped into calls)."""
    prob = _filament(n=7, loads=[cartan.Damping(damping)])
    kw = dict(integrator="rattle", dt=4e-3, save_every=5, progress=False)
    ref = cartan.simulate(prob, t_end=0.12, compiled=False, **kw)
    whole = cartan.simulate(prob, t_end=0.12, output=tmp_path / "whole.nc", checkpoint_every=1, **kw)
    for name in ("position", "S", "kinetic_energy", "dissipated_energy", "external_work"):
        scale = max(1.0, float(np.max(np.abs(ref[name].values))))
        assert float(np.max(np.abs(whole[name].values - ref[name].values))) < 1e-11 * scale, name
    assert float(whole["dissipated_energy"].values[-1]) > 0.0
    assert float(whole["constraint_residual"].max()) < 1e-12
    cartan.simulate(prob, t_end=0.06, output=tmp_path / "part.nc", checkpoint_every=1, **kw)
    cont = cartan.simulate(prob, restart=tmp_path / "part.nc", t_end=0.12, progress=False)
    for name in ("position", "frame", "S", "X", "kinetic_energy", "dissipated_energy", "constraint_residual"):
        assert np.array_equal(whole[name].values, cont[name].values), name
