"""``rattle`` on the ``collocation`` scheme: the filament's constrained strains held on the nodal
strains (paper §III, §III.E; :class:`cartan.constraints.NodalStrainConstraints`).

The rows are ``X_i[k] − value_k`` per node and held component, their rate along the drift
``B_c δ = [Dδ + ad_X δ]_k`` (the compatibility equation of §III), less the one combination per
open axis that is dependent at a straight configuration (the odd–even mode of the central
difference).  Checked: the rows and their rate against finite differences of the scheme's own
drift; the held rows at round-off along a run; the nodal stretch off only in the odd–even mode;
the energy balance closing at second order in Δt; bad input; and (slow) agreement with the
lattice's ``rattle`` as n grows.  Python step only (no compiled collocation rattle).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from toys import assert_rows_follow_the_drift

import cartan
from cartan.constraints import NodalStrainConstraints
from cartan.integrators import Rattle
from cartan.schemes import Lattice, Scheme
from cartan.schemes.collocation import Collocation

#: the tip wrench of tests/test_rattle.py: bending about both axes and twist
TIP = [0.0, -2.0, 0.5, 0.2, 0.0, 0.0]


def _filament(n: int = 11, initial: str = "straight", end=None):
    rod = cartan.medium("filament", bending=(1.0, 1.5), twist=0.8, rotational_inertia=0.01)
    grid = cartan.Grid(n, length=1.0)
    init = rod.initial_state(grid, "straight") if initial == "straight" else rod.initial_state(grid, "arc",
                                                                                                 curvature=1.0)
    return cartan.Problem(rod, grid, init, {"start": cartan.Clamped(), "end": end or cartan.Free(load=TIP)})


def _steps(scheme, nsteps: int, dt: float):
    state = scheme.initial_state()
    integ = Rattle()
    integ.reset()
    for _ in range(nsteps):
        integ.step(scheme, state, dt)
    return state, integ


def test_rows_are_the_exact_rate_of_the_drift():
    """``B_c δ`` is the derivative of the held rows along the scheme's exact drift and ``Ḃ_c N``
    its second derivative (central differences of step ε = 1e-4, whose truncation ∝ ε²: measured
    1.2e-8 and 1.5e-8 relative, 1.2e-6 and 1.5e-6 at ε = 1e-3)."""
    scheme = Collocation(_filament(initial="arc"), "fd2")
    state, _ = _steps(scheme, 3, 5e-3)  # a curved, moving state
    assert_rows_follow_the_drift(scheme, state, 3, 1e-7, 1e-6)


def test_dependent_row_is_the_odd_even_mode():
    """n nodal rows per component on an open axis, one combination dependent at the straight
    state (the stretch's odd–even mode): 3n − 1 rows held on a clamped–free filament."""
    n = 11
    scheme = Collocation(_filament(n), "fd2")
    con = scheme.constraint_rows(np.broadcast_to(~scheme._clamped[:, None], (n, 6)).copy(), scheme.initial_state())
    assert isinstance(con, NodalStrainConstraints)
    assert con.nrow == 3 * n and con.ncon == 3 * n - 1
    dropped = np.linalg.svd(con.T.toarray(), full_matrices=True)[0][:, -1].reshape(n, 3)  # the complement of T
    assert np.max(np.abs(dropped[:, 1:])) < 1e-12  # the stretch rows only
    signs = np.sign(dropped[:, 0]) * np.sign(dropped[0, 0])
    assert np.array_equal(signs, (-1.0) ** np.arange(n))  # alternating: odd–even


@pytest.fixture(scope="module")
def run():
    """100 steps of Δt = 5e-3 of the straight filament under the tip wrench, n = 11."""
    scheme = Collocation(_filament(), "fd2")
    state = scheme.initial_state()
    integ = Rattle()
    integ.reset()
    con = integ._constraints(scheme, state)[0]
    held, shear, stretch_rest = [], [], []
    mode = np.linalg.svd(con.T.toarray(), full_matrices=True)[0][:, -1]  # the one combination not held
    for _ in range(100):
        integ.step(scheme, state, 5e-3)
        held.append(float(np.max(np.abs(con.values(state)))))
        nodal = con.nodal_values(state)
        shear.append(float(np.max(np.abs(nodal.reshape(-1, 3)[:, 1:]))))
        stretch_rest.append(float(np.max(np.abs(nodal - (mode @ nodal) * mode))))
    return scheme, state, integ, np.array(held), np.array(shear), np.array(stretch_rest)


def test_held_rows_at_round_off(run):
    """The held rows at every step to the iteration's tolerance (|c| ≤ 1e-13 times max(1, |value|)
    = 1e-13: 1e-12 leaves round-off's scatter); the shear nodally, the stretch in every
    combination but the odd–even mode, to the same round-off."""
    scheme, state, integ, held, shear, stretch_rest = run
    assert held.max() < 1e-12
    assert shear.max() < 1e-12
    assert stretch_rest.max() < 1e-12
    assert integ.constraint_residual(scheme, state) == pytest.approx(held[-1])
    assert float(np.abs(scheme.frames(state)[-1, 2, 0])) > 0.1  # it moved: there was something to hold


def test_energy_balance_closes_at_second_order():
    """K + V − W of the run (W the end load's work; the constraint forces do no work) closes to
    the method's O(Δt²): the observed order between Δt = 4e-3 and 2e-3 is 2 ± 0.4."""
    errs = []
    for dt in (4e-3, 2e-3):
        ds = cartan.simulate(_filament(), scheme="collocation", integrator="rattle", dt=dt, t_end=0.2,
                             save_every=int(round(0.02 / dt)), progress=False, compiled=False)
        balance = (ds["kinetic_energy"] + ds["potential_energy"] - ds["external_work"]).values
        errs.append(float(np.max(np.abs(balance - balance[0]))))
        assert float(ds["constraint_residual"].max()) < 1e-12
    order = np.log2(errs[0] / errs[1])
    assert 1.6 < order < 2.4, (errs, order)


def test_damped_swing_balance_closes_at_second_order():
    """E + D − W of the clamped filament released straight under gravity with Rayleigh damping
    (the scene ``filament-swing``'s loads, n = 11, t ≤ 0.5): the closing kick's implicit damping
    and its velocity multipliers are solved together, the dissipation is booked, and the
    balance closes at second order (measured to t = 1: 2.5e-4, 6.3e-5 of a dissipated 0.69 at
    Δt = 4e-3, 2e-3, ratio 4.0; asserted order 2 ± 0.4)."""
    fil = cartan.medium("filament", bending=1.0, twist=0.8, rotational_inertia=0.01)
    grid = cartan.Grid(11, length=1.0)
    problem = cartan.Problem(fil, grid, fil.initial_state(grid, "straight"),
                             {"start": cartan.Clamped(), "end": cartan.Free()},
                             loads=[fil.make_load("gravity", g=[0.0, 0.0, -9.81]),
                                    cartan.Damping([0.5, 0.5, 0.5, 5e-3, 5e-3, 5e-3])])
    errs = []
    for dt in (4e-3, 2e-3):
        ds = cartan.simulate(problem, scheme="collocation", dt=dt, t_end=0.5, save_every=int(round(0.05 / dt)),
                             progress=False)
        balance = (ds["kinetic_energy"] + ds["potential_energy"] + ds["dissipated_energy"]
                   - ds["external_work"]).values
        errs.append(float(np.max(np.abs(balance - balance[0]))))
        assert float(ds["dissipated_energy"][-1]) > 0.05  # the damping did work to book
        assert float(ds["constraint_residual"].max()) < 1e-12
    assert 1.6 < np.log2(errs[0] / errs[1]) < 2.4, errs


def test_free_filament():
    """A free–free helix (no loads; n = 20): the held rows at round-off and the energy error of
    second order in Δt (measured 7.4e-3, 1.7e-3 of E at Δt = 2e-3, 1e-3 to t = 0.2: order 2.15;
    to t = 0.8 7.8e-3, 2.0e-3, the lattice's 8.9e-3, 2.2e-3).  ``simulate``'s default
    (compiled) path runs the Python step for the collocation's rows, and says why."""
    fil = cartan.medium("filament", bending=(1.0, 1.5), twist=0.8, rotational_inertia=0.01)
    grid = cartan.Grid(20, length=1.0)
    problem = cartan.Problem(fil, grid, fil.initial_state(grid, "helix", radius=0.3, pitch=0.5),
                             {"start": cartan.Free(), "end": cartan.Free()})
    errs = []
    for dt in (2e-3, 1e-3):
        ds = cartan.simulate(problem, scheme="collocation", dt=dt, t_end=0.2, save_every=int(round(0.02 / dt)),
                             progress=False)
        energy = (ds["kinetic_energy"] + ds["potential_energy"]).values
        errs.append(float(np.max(np.abs(energy - energy[0])) / energy[0]))
        assert float(ds["constraint_residual"].max()) < 1e-12
    assert 1.6 < np.log2(errs[0] / errs[1]) < 2.4, errs
    scheme = Collocation(problem)
    assert "edge strains" in Rattle().compiled_reason(scheme)


def test_bad_input():
    """A medium whose stress reads a held component is refused with ValueError naming it (Held
    ends run: tests/test_collocation_rattle_reactions.py; Driven ends: tests/test_collocation_driven.py)."""
    grid = cartan.Grid(11, length=1.0)
    params = dict(stretch_shear=[1e3, 1e3, 1e3], bend_twist=[1.0, 1.0, 1.0], mass=1.0,
                  rotational_inertia=[0.02, 0.01, 0.01])
    base = type(cartan.medium("cosserat-rod", **params))

    class Stiff(base):  # a rod whose stress reads the components it claims to hold
        def constrained_strains(self):
            return np.array([0, 1, 2]), np.array([1.0, 0.0, 0.0])

    with pytest.raises(ValueError, match="has none"):  # a scheme without rows (Scheme.constraint_rows)
        Scheme.constraint_rows(SimpleNamespace(name="other"), None, None)

    stiff = Stiff(**params)
    problem = cartan.Problem(stiff, grid, stiff.initial_state(grid, "straight"),
                             {"start": cartan.Clamped(), "end": cartan.Free()})
    scheme = Collocation(problem, "fd2")
    with pytest.raises(ValueError, match="constrained strain component"):
        Rattle()._constraints(scheme, scheme.initial_state())


def test_dense_rank_test_is_announced_and_bounded(capsys, monkeypatch):
    """The rows' rank test is a dense SVD (its cost grows as the rows cubed): above
    ``DENSE_RANK_NOTE_ROWS`` it says so on stderr, above ``DENSE_RANK_MAX_ROWS`` it is refused with
    a ValueError naming the rows and the lattice (limits lowered here to keep the test small)."""
    import cartan.constraints as C

    rod = cartan.medium("filament", bending=(1.0, 1.5), twist=0.8, rotational_inertia=0.01)
    grid = cartan.Grid(11, length=1.0)
    problem = cartan.Problem(rod, grid, rod.initial_state(grid, "arc", curvature=1.0),
                             {"start": cartan.Clamped(), "end": cartan.Free()})
    scheme = Collocation(problem, "fd2")
    monkeypatch.setattr(C, "DENSE_RANK_NOTE_ROWS", 10)
    Rattle()._constraints(scheme, scheme.initial_state())
    assert "dense SVD" in capsys.readouterr().err
    monkeypatch.setattr(C, "DENSE_RANK_MAX_ROWS", 20)
    with pytest.raises(ValueError, match=r"nodal constraint rows, above the 20 .*scheme='lattice'"):
        Rattle()._constraints(Collocation(problem, "fd2"), scheme.initial_state())


@pytest.mark.slow
def test_agrees_with_the_lattice_as_n_grows():
    """The clamped horizontal filament released from rest under gravity (ρAgL³/B = 9.81, the
    scene ``filament-swing`` undamped), t = 0.3 with Δt = 1e-3, on both schemes at the same n:
    the tip positions' difference falls at the schemes' second order in h (measured 7.2e-3,
    2.1e-3, 6.2e-4 at n = 11, 21, 41: ratios 3.4 per halving of h; asserted > 2^1.5, the
    collocation's fd2 boundary rows being of order 1), and so does the stretch's odd–even ripple
    that the rows leave (5.5e-3, 1.3e-3, 3.4e-4 at t = 0.3: a discretization error)."""
    fil = cartan.medium("filament", bending=1.0, twist=0.8, rotational_inertia=0.01)
    dt, nsteps = 1e-3, 300

    ripple = []

    def tip(cls, n):
        grid = cartan.Grid(n, length=1.0)
        problem = cartan.Problem(fil, grid, fil.initial_state(grid, "straight"),
                                 {"start": cartan.Clamped(), "end": cartan.Free()},
                                 loads=[fil.make_load("gravity", g=[0.0, 0.0, -9.81])])
        scheme = cls(problem)
        state, integ = _steps(scheme, nsteps, dt)
        if cls is Collocation:
            ripple.append(float(np.max(np.abs(integ._constraints(scheme, state)[0].nodal_values(state)))))
        return scheme.frames(state)[-1, 1:, 0]

    errs = [float(np.linalg.norm(tip(Collocation, n) - tip(Lattice, n))) for n in (11, 21, 41)]
    assert errs[0] / errs[1] > 2**1.5 and errs[1] / errs[2] > 2**1.5, errs
    assert ripple[0] / ripple[1] > 2**1.5 and ripple[1] / ripple[2] > 2**1.5, ripple
