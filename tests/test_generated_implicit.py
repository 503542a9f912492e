"""``implicit-midpoint`` over a scheme's compiled operator set (:mod:`cartan.integrators.newton`).

The compiled blocks of steps (``ImplicitMidpoint.compiled_advance``) and the Python driver on
the compiled residual (``ImplicitMidpoint.step``) against the numpy reference (the scheme's
``compiled_diagnostics`` cleared): the same Newton iterations and Jacobians, and states
within 1e-12 relative — the project's compiled-vs-reference bound.  The iterates of the two
paths differ by the round-off of the residual (another summation order, Gaussian elimination
instead of LAPACK for ``B(ξ)ᵀW``), which Newton's method does not amplify at these Δt
(observed ≤ 3e-15 over the 16 steps here).  The blocks and the Python driver on the compiled
residual run the same compiled pieces and agree bit for bit (the energy accumulators to
round-off: the blocks sum the midpoint powers with the scheme's ``op_powers``, the driver with
``Scheme.powers``), and a restarted run reproduces the uninterrupted one bit for bit.
"""

from __future__ import annotations

import numpy as np
import pytest
from toys import CoupledQuartic, rel_error, rod_problem

import cartan
from cartan.grid import Grid
from cartan.integrators.implicit import ImplicitMidpoint
from cartan.problem import Clamped, Damping, InitialState, Problem
from cartan.schemes.lattice import Lattice

TOL = 1e-12
#: the sub-blocks cartan.simulate uses (ending at steps 1, 2, 4, 8, …)
BLOCKS = (1, 1, 2, 4, 8)


def _sheet() -> Problem:
    """The coupled quartic medium on SE(3), d = 2 (open × periodic), clamped on u = 0, damped, moving."""
    med = CoupledQuartic("SE3", d=2)
    G = med.group
    grid = Grid((6, 5), (1.0, 0.8), periodic=(False, True))
    U, V = np.meshgrid(grid.coordinates(0), grid.coordinates(1), indexing="ij")
    Phi = G.exp(U[..., None] * np.array([1.0, 0, 0, 0, 0.3, 0]) + V[..., None] * np.array([0, 1.0, 0, 0.5, 0, 0])
                + 0.05 * np.sin(3 * U)[..., None] * np.linspace(-1.0, 1.0, 6))
    N = 0.2 * np.cos(2 * np.pi * V)[..., None] * np.linspace(1.0, 0.5, 6)
    return Problem(med, grid, InitialState(Phi=Phi, N=N), {"u-start": Clamped()}, [Damping(0.2)])


def _sigma() -> Problem:
    """SO(4) (the sigma model on S³), d = 2, a small periodic grid."""
    med = cartan.medium("sigma-model", n=3, d=2)
    grid = Grid((6, 5), 1.0, periodic=True)
    return Problem(med, grid, med.initial_state(grid, "random-smooth"))


#: scheme factories and a Δt at which Newton's method converges in a few iterations
CASES = {
    "rod-SE3-d1-dead-load-gravity": (lambda: Lattice(rod_problem("dead"), track_frames=True), 2e-2),
    "coupled-SE3-d2": (lambda: Lattice(_sheet()), 5e-3),
    "sigma-SO4-d2": (lambda: Lattice(_sigma()), 5e-2),
}


def _start(scheme):
    state = scheme.initial_state()
    state.scalars["nstep"] = 0
    return state


def _counters(integ) -> tuple:
    return integ.nstep, integ.nforce, integ.newton_iterations, integ.jacobians


#: the coupled sheet and the S³ sigma model compile implicit blocks no other fast test needs (25-50 s
#: each on a fresh cache); SO(4) loops stay in the fast suite through the sigma model's gauge test
SLOW_CASES = {"coupled-SE3-d2", "sigma-SO4-d2"}


@pytest.mark.parametrize("name", [pytest.param(name, marks=[pytest.mark.slow] if name in SLOW_CASES else [])
                                  for name in sorted(CASES)])
def test_blocks_agree_with_the_numpy_reference_and_the_python_driver(name):
    make, dt = CASES[name]
    ref_scheme, drv_scheme, scheme = make(), make(), make()
    assert scheme.compiled_operators().ok
    ref_scheme.compiled_diagnostics = False
    ref, drv, fast = _start(ref_scheme), _start(drv_scheme), _start(scheme)
    ri, di, fi = ImplicitMidpoint(), ImplicitMidpoint(), ImplicitMidpoint()
    assert not ri.compiled_advance(ref_scheme, ref, dt, 1)  # declined: the numpy path
    for _ in range(sum(BLOCKS)):
        ri.step(ref_scheme, ref, dt)
        di.step(drv_scheme, drv, dt)
    assert di._plan[1].compiled is not None  # the driver ran on the compiled residual
    for size in BLOCKS:
        assert fi.compiled_advance(scheme, fast, dt, size)
    # against the numpy reference: round-off
    errors = {"S": rel_error(fast.S, ref.S)}
    errors.update({k: rel_error(fast.arrays[k], ref.arrays[k]) for k in ref.arrays})
    for key in ("dissipated_energy", "external_work"):
        errors[key] = rel_error(fast.scalars[key], ref.scalars[key])
    assert max(errors.values()) <= TOL, errors
    assert fast.t == ref.t and fast.scalars["nstep"] == ref.scalars["nstep"] == sum(BLOCKS)
    assert _counters(fi) == _counters(ri)
    assert fi.newton_iterations >= fi.nstep  # Newton did iterate
    # against the Python driver on the same compiled pieces: bit for bit
    assert np.array_equal(fast.S, drv.S)
    assert all(np.array_equal(fast.arrays[k], drv.arrays[k]) for k in drv.arrays)
    for key in ("dissipated_energy", "external_work"):
        assert rel_error(fast.scalars[key], drv.scalars[key]) <= TOL
    assert _counters(fi) == _counters(di)
    assert not np.array_equal(fast.S, _start(scheme).S)  # it moved


def test_restart_mid_run_is_bit_for_bit(tmp_path):
    make, dt = CASES["rod-SE3-d1-dead-load-gravity"]
    problem = make().problem
    kw = {"integrator": "implicit-midpoint", "dt": dt, "save_every": 4, "progress": False, "scheme": "lattice"}
    full = cartan.simulate(problem, t_end=16 * dt, output=tmp_path / "full.nc", **kw)
    cartan.simulate(problem, t_end=8 * dt, output=tmp_path / "part.nc", **kw)
    cont = cartan.simulate(problem, restart=tmp_path / "part.nc", t_end=16 * dt, progress=False)
    for name in ("S", "X", "position", "kinetic_energy", "time"):
        assert np.array_equal(full[name].values, cont[name].values), name


def test_simulate_takes_the_generated_blocks(monkeypatch):
    """No step in Python, no legacy path: every step in ``implicit_loop``."""
    make, dt = CASES["rod-SE3-d1-dead-load-gravity"]
    problem = make().problem
    calls = []
    step = ImplicitMidpoint.step

    def counted(self, *args):
        calls.append(1)
        return step(self, *args)

    monkeypatch.setattr(ImplicitMidpoint, "step", counted)
    run = cartan.simulate(problem, integrator="implicit-midpoint", dt=dt, t_end=8 * dt, save_every=4, progress=False)
    assert calls == [] and int(run["step"].values[-1]) == 8


def test_outside_the_domain_of_exp_the_residual_declines():
    """ξ with a rotation angle ≥ π (the SE(3) injectivity radius) at one node."""
    make, dt = CASES["rod-SE3-d1-dead-load-gravity"]
    scheme = make()
    state = _start(scheme)
    integ = ImplicitMidpoint()
    stage = integ._compiled(scheme, state, integ._layout(scheme))
    xi = np.zeros_like(state.S)
    assert stage(xi, dt) is not None
    xi[3, 5] = 3.2
    assert stage(xi, dt) is None
    assert integ._residual(scheme, state, xi, dt) is None
