"""Driven ends (``cartan.Driven``: a clamp moving with a constant body velocity ξ) in the exact
planar reduction and in the advice's held-strain twin.

A planar SE(3) rod whose driven end's ξ lies in the plane (translation along e₁, e₂, rotation
about e₃) moves in the plane: the end's frame Φ(0)·exp(tξ) stays in the embedded SE(2), and the
reduced run is the full run to round-off (tolerance 1e-12 of each variable's scale, as in
``tests/test_reduction.py``, where it is argued).  A ξ with a component V₃, Ω₁ or Ω₂ takes the end
out of the plane: no reduction, and the reason names the driven end.
"""

from __future__ import annotations

import pathlib

import numpy as np
import pytest
from test_reduction import assert_same_run

import cartan
import cartan.reduction as reduction
from cartan import advise as adv
from cartan.reduction import IN_PLANE, PLANAR, planar_obstacle, planar_reduction

ROD = {"E": 1e5, "poisson": 0.5, "radius": 0.05, "density": 1000.0}
#: in-plane translation and rotation about the normal, in the end's body frame
PLANAR_XI = [0.1, 0.2, 0.0, 0.0, 0.0, 0.5]
#: the stiff swing of ``examples/`` (EA = GA = 1e6 B/L², n = 11)
STIFF_SWING = pathlib.Path(__file__).resolve().parents[1] / "examples" / "stiff-rod-swing.toml"
#: a short run on the numpy path (driven ends are stepped there): 200 steps, 5 frames
#: the numpy path: the compiled driven loops (checked against it in tests/test_driven_compiled.py) compile
#: for ≈ 45 s each on an empty cache
RUN = {"dt": 1e-4, "t_end": 0.02, "save_every": 50, "progress": False, "integrator": "rkmk4", "compiled": False}


def driven_rod(xi, *, n: int = 21) -> cartan.Problem:
    """A rod along x driven at s = 0 with body velocity ``xi``, free end loaded in the plane, under
    gravity along −y and damping (every other datum in the x–y plane)."""
    r = cartan.medium("cosserat-rod", **ROD)
    grid = cartan.Grid(n, length=1.0)
    return cartan.Problem(
        r,
        grid,
        r.initial_state(grid, "straight"),
        {"start": cartan.Driven(velocity=list(xi)), "end": cartan.Free(load=[0.0, -0.05, 0.0, 0.0, 0.0, 0.01])},
        [r.make_load("gravity", g=[0.0, -9.81, 0.0]), cartan.Damping([2.0, 2.0, 2.0, 1e-3, 1e-3, 1e-3])],
        name="driven-rod",
    )


def test_planar_driven_end_is_mapped_to_se2():
    p = driven_rod(PLANAR_XI)
    red = planar_reduction(p)
    assert red is not None and planar_obstacle(p) is None
    b = red.reduced.boundaries["start"]
    assert isinstance(b, cartan.Driven)
    assert np.array_equal(b.velocity, np.asarray(PLANAR_XI)[list(IN_PLANE)])
    assert red.reduced.medium.group.name == "SE2"


def test_planar_driven_rod_runs_reduced_equal_to_full(monkeypatch):
    """Reduced and full runs agree to 1e-12 of each variable's scale, and the driven node follows
    Φ(0)·exp(tξ) (the end moved and turned in the plane)."""
    p = driven_rod(PLANAR_XI)
    full = cartan.simulate(p, **RUN, reduce=False)
    monkeypatch.setattr(reduction, "reduction_pays", lambda run: True)  # made wherever it is exact
    reduced = cartan.simulate(p, **RUN)
    assert_same_run(reduced, full)
    g = p.medium.group
    Phi0 = np.asarray(p.initial.Phi, dtype=float)[0]
    for t, pos, E in zip(reduced.time.values, reduced.position.values[:, 0], reduced.frame.values[:, 0], strict=True):
        expected = Phi0 @ g.exp(t * np.asarray(PLANAR_XI))
        assert np.max(np.abs(pos - expected[1:, 0])) <= 1e-12  # round-off of exp over 200 steps
        assert np.max(np.abs(E - expected[1:, 1:])) <= 1e-12
    assert np.linalg.norm(reduced.position.values[-1, 0]) > 1e-3  # it moved
    assert abs(float(full.external_work.values[-1])) > 0.0  # the support did work


@pytest.mark.parametrize("component", [2, 3, 4])
def test_out_of_plane_driven_end_is_not_reduced(component, monkeypatch):
    xi = np.zeros(6)
    xi[component] = 0.5
    p = driven_rod(xi, n=11)
    assert planar_reduction(p) is None
    reason = planar_obstacle(p)
    assert reason is not None and "boundary 'start'" in reason and "driven velocity" in reason
    if component == 3:  # a twist about the tangent (lie-verlet moves it exactly): the run is the full one
        monkeypatch.setattr(reduction, "reduction_pays", lambda run: True)
        ds = cartan.simulate(p, dt=1e-4, t_end=2e-3, save_every=10, progress=False, compiled=False)
        assert "cartan_reduction" not in ds.attrs
        assert float(np.max(np.abs(ds.frame.values[-1, 0, 2, :2]))) > 0.0  # e₃ left +z


def test_advice_reports_why_the_planar_reduction_is_blocked():
    """The advice's exact planar reduction names the driven end (no run is needed to say so)."""
    p = driven_rod([0.0, 0.0, 0.0, 0.5, 0.0, 0.0], n=11)
    sub = adv._Subject(p, "driven-rod", "static", {}, {})
    out = adv._advise_planar(sub, None, 0.0, None, None, False)
    assert not out.admitted and out.indicator == 0.0
    assert "boundary 'start'" in out.note and "driven velocity" in out.note


def test_twin_carries_a_driven_end():
    """The filament twin keeps the driven end (same group, same ξ), the estimate integrates from it,
    and a ξ that rattle cannot move exactly declines the twin with the integrator's reason."""
    p = driven_rod([0.0, 0.0, 0.0, 0.0, 0.0, 0.5], n=11)
    held, _ = adv.held_strain_twin(p)
    b = held.boundaries["start"]
    assert isinstance(b, cartan.Driven) and np.array_equal(b.velocity, p.boundaries["start"].velocity)
    sub = adv._Subject(p, "driven-rod", "dynamic", {}, {"integrator": "lie-verlet", "scheme": "lattice"})
    assert adv._anchor(sub) == "start"
    assert adv._driven_obstacle(held, sub.run_settings) is None  # a rotation about one body axis
    mixed, _ = adv.held_strain_twin(driven_rod(PLANAR_XI, n=11))  # translation and rotation: no exact split step
    reason = adv._driven_obstacle(mixed, sub.run_settings)
    assert reason is not None and "rattle" in reason and "commute" in reason
    declined = adv._advise_held(
        adv._Subject(driven_rod(PLANAR_XI, n=11), "d", "dynamic", {}, sub.run_settings), None, 1e-3, False, 0.0, None
    )
    assert not declined.admitted and "declined" in declined.note and "commute" in declined.note
    assert planar_reduction(driven_rod(PLANAR_XI)).kind == PLANAR


@pytest.mark.slow  # (the check runs both models compiled: 27 s warm, the driven loops compile on a fresh cache)
def test_dynamic_check_runs_the_twin_with_the_driven_end():
    """The stiff swing with its clamp turning about e₃: the filament (rattle) runs with the driven
    end, both timed runs save the scene's output (``save_every`` = 1000 rod steps: the initial and
    the last frame of this 200-step pilot), and the check measures a difference of the size the
    held strains carry (the model difference plus the two runs' time-step errors, predicted)."""
    import tomllib

    spec = tomllib.loads((STIFF_SWING).read_text())
    spec["boundaries"]["start"] = {"kind": "driven", "velocity": [0.0, 0.0, 0.0, 0.0, 0.0, 0.5]}
    spec["run"]["t_end"] = 0.01
    fil = adv.advise(spec, check=True, pilot_steps=200)[adv.HELD_STRAINS]
    assert fil.admitted, fil.note
    assert np.isfinite(fil.measured_difference) and np.isfinite(fil.time_ratio) and fil.time_ratio > 0.0
    assert 0.0 < fil.model_difference <= fil.predicted_difference
    assert fil.measured_difference < fil.error_scale  # the two runs follow the same driven clamp
    assert "saving the scene's output (the full run every 1000 steps, 2 frames" in fil.check_note
    assert "timed pair" in fil.check_note
