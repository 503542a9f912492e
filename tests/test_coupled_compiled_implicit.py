"""``implicit-midpoint`` compiled for a Lagrangian coupling N and X (cartan/integrators/implicit.py,
"Coupled Lagrangians"; docs/media/relativistic-rod.md §3): the elastic relativistic string through
the stage residual and Newton blocks of :mod:`cartan.integrators.newton` over the coupled operator
sets of the lattice and the collocation.

The two pieces that differ from an uncoupled stage are the operator set's: the stage momenta
μ = ∂L/∂N at the midpoint strains (:func:`cartan.integrators.newton.im_coupled_momentum`, Newton's
method per node on the set's ``op_coupled_velocities``) and the force with the Hamiltonian stress at
(μ, X_{k+½}) (``op_state_force``); the gauge components of ξ are Δt times the velocity at the start
of the step (``op_stage_held``).

The per-node Newton Jacobian of the stage momenta is the medium's closed form ∂N/∂S
(``MediumKernels.coupled_jacobian``, the op ``op_coupled_jacobian``) when it declares it, else
forward differences of ``coupled_velocity`` (a ring whose medium drops the kernel).

Fast: the declarations (no compilation) and the closed form against central differences of the
velocity kernel.  Slow: 20 steps of a ring and of a clamped string in
three blocks (1, 2, 17) against the Python driver over the same compiled residual (bit for bit)
and against the numpy reference (``compiled_diagnostics`` cleared): the same Newton iterations,
Jacobians and force evaluations, and the states to 1e-12 relative — the stage momenta are inverted
to 1e-14 of the velocity scale on both paths, from different first iterates (measured: 7e-14 on
the lattice).  The Newton loop of each set compiles on first use (≈ 60–120 s on a fresh cache).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from cartan_relativistic.elastic_rod import ElasticRelativisticRod
from test_driven_compiled_implicit import PythonDriver, _start
from toys import elastic_string

import cartan
from cartan.integrators import ImplicitMidpoint
from cartan.schemes.collocation import Collocation
from cartan.schemes.lattice import Lattice

pytestmark = pytest.mark.filterwarnings("ignore::cartan.StabilityWarning")

NSTEPS = 20
BLOCKS = (1, 2, NSTEPS - 3)
#: Newton's tolerance: the round-off floor of the convergence test decides on both paths
TIGHT = 1e-13
#: compiled against numpy, relative to the largest value: both invert the Legendre map to 1e-14 of
#: the velocity scale (different first iterates) and converge Newton's method to round-off; 20 steps
TOL = 1e-12
SCHEMES = {"lattice": Lattice, "collocation": Collocation}


class _NoJacobian(ElasticRelativisticRod):
    """The elastic string without the ``coupled_jacobian`` kernel: the stage momenta's Newton
    Jacobian by forward differences of ``coupled_velocity`` (the fallback for media without it)."""

    def point_kernels(self):
        return dataclasses.replace(super().point_kernels(), coupled_jacobian=None)


def _problem(kind: str, n: int = 9, jacobian: bool = True) -> cartan.Problem:
    """The elastic string (quadratic law, k = 0.25, no clocks): ``ring`` or ``clamped``
    (:func:`toys.elastic_string`); without ``jacobian``, its medium has no ``coupled_jacobian``."""
    problem = elastic_string(kind, n)
    if not jacobian:
        rod = _NoJacobian(energy="elastic", stiffness=0.25, clocks=False)
        problem = cartan.Problem(rod, problem.grid, problem.initial, boundaries=problem.boundaries)
    return problem


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-300))


@pytest.mark.parametrize("name", list(SCHEMES))
def test_the_coupled_sets_serve_the_newton_loop(name):
    """The coupled operator sets serve implicit-midpoint's loop, without accumulating in it, and
    rebind its stage operators (no compilation here)."""
    ops = SCHEMES[name](_problem("ring")).compiled_operators()
    assert not ops.ok and "coupling N and X" in ops.reason
    assert ops.serves("implicit_loop") and ops.serves("rkmk_loop") and "implicit_loop" not in ops.accumulates
    source = "".join(f.source for f in ops.late)
    assert "op_stage_momentum = im_coupled_momentum" in source and "op_stage_held = im_coupled_held" in source
    assert "def op_coupled_velocities" in source
    # the stage momenta's Newton Jacobian in closed form (the medium declares coupled_jacobian)
    assert "op_coupled_jacobian = op_coupled_jacobian_kernel" in source
    bare = SCHEMES[name](_problem("ring", jacobian=False)).compiled_operators()
    assert "op_coupled_jacobian" not in "".join(f.source for f in bare.late)  # (forward differences)


def test_coupled_jacobian_kernel_is_the_derivative_of_the_velocity_kernel():
    """The elastic string's ``coupled_jacobian`` is ∂N/∂S of its ``coupled_velocity`` (central
    differences, step 1e-6: their truncation error ≈ 1e-10 of the scale, measured 1.3e-10; 1e-8
    allowed) at 20 momenta and strains, up to 0.75c, and zero off the slots of v⃗ and p⃗."""
    rod = cartan.medium("relativistic-rod", energy="elastic", stiffness=0.25, c=1.3)
    kernels = rod.point_kernels()
    p = kernels.params
    rng = np.random.default_rng(1)
    for _ in range(20):
        S, X = np.zeros(10), np.zeros((1, 10))
        S[1:4], X[0, 1:4] = rng.uniform(-0.6, 0.6, 3), rng.uniform(-1.3, 1.3, 3)
        N, J = np.empty(10), np.empty((10, 10))
        assert kernels.coupled_velocity(S, X, p, N) and kernels.coupled_jacobian(S, X, N, p, J)
        fd = np.zeros((10, 10))
        for b in range(1, 4):
            up, down, Nu, Nd = S.copy(), S.copy(), np.empty(10), np.empty(10)
            up[b] += 1e-6
            down[b] -= 1e-6
            assert kernels.coupled_velocity(up, X, p, Nu) and kernels.coupled_velocity(down, X, p, Nd)
            fd[:, b] = (Nu - Nd) / 2e-6
        assert _rel(J, fd) <= 1e-8
        assert not np.any(J[np.ix_([0, *range(4, 10)], range(10))]) and not np.any(J[:, [0, *range(4, 10)]])


@pytest.mark.slow  # (the coupled set's Newton loop compiles on first use: 60–120 s on a fresh cache)
@pytest.mark.parametrize(("name", "kind", "jacobian"), [("lattice", "ring", True), ("lattice", "clamped", True),
                                                      ("collocation", "ring", True), ("lattice", "ring", False)])
def test_blocks_step_the_coupled_string_as_the_python_driver_and_numpy(name, kind, jacobian):
    """(``jacobian``: the medium's closed-form ∂N/∂S in the stage momenta's Newton method, else
    forward differences; both converge to the same tolerance.)"""
    dt = 0.01
    ref_scheme, fast_scheme, py_scheme = (SCHEMES[name](_problem(kind, jacobian=jacobian)) for _ in range(3))
    ref_scheme.compiled_diagnostics = False  # the numpy reference (ImplicitMidpoint._residual)
    ref, fast, py = _start(ref_scheme), _start(fast_scheme), _start(py_scheme)
    ri, fi, pi = ImplicitMidpoint(tol=TIGHT), ImplicitMidpoint(tol=TIGHT), PythonDriver(tol=TIGHT)
    for _ in range(NSTEPS):
        ri.step(ref_scheme, ref, dt)
        pi.step(py_scheme, py, dt)
    for size in BLOCKS:
        assert fi.compiled_advance(fast_scheme, fast, dt, size)
    assert ri._plan[1].compiled is False and pi._plan[1].compiled is not None
    # the blocks and the Python driver over the same compiled residual: bit for bit
    assert np.array_equal(fast.S, py.S) and fast.t == py.t
    for key in py.arrays:
        assert np.array_equal(fast.arrays[key], py.arrays[key]), key
    # against numpy: the same iterations and counters, the states to round-off
    assert fast.scalars["nstep"] == ref.scalars["nstep"] == NSTEPS
    for it in (fi, pi):
        assert (it.newton_iterations, it.jacobians, it.nforce) == (ri.newton_iterations, ri.jacobians, ri.nforce)
    assert _rel(fast.S, ref.S) <= TOL
    for key in ref.arrays:
        assert _rel(fast.arrays[key], ref.arrays[key]) <= TOL, key
    assert _rel(ref.S, _start(ref_scheme).S) > 1e-3  # (the string moved)


@pytest.mark.slow
def test_simulate_runs_the_coupled_string_compiled(monkeypatch):
    """``simulate(..., integrator="implicit-midpoint")`` takes the compiled blocks on the lattice
    and agrees with ``compiled=False`` to 1e-12 of each field's scale."""
    kw = dict(integrator="implicit-midpoint", dt=0.02, t_end=0.4, save_every=5, progress=False)
    calls = []
    original = ImplicitMidpoint.compiled_advance

    def spy(self, *args, **kwargs):
        ran = original(self, *args, **kwargs)
        calls.append(ran)
        return ran

    monkeypatch.setattr(ImplicitMidpoint, "compiled_advance", spy)
    fast = cartan.simulate(_problem("ring"), **kw)
    assert calls and all(calls)
    ref = cartan.simulate(_problem("ring"), compiled=False, **kw)
    for key in ("S", "frame", "energy", "total_momentum"):
        if key in ref:
            assert _rel(fast[key].values, ref[key].values) <= TOL, key
