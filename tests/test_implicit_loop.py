"""``implicit-midpoint`` in compiled blocks of steps (``ImplicitMidpoint.compiled_advance``).

The Python driver — ``ImplicitMidpoint.step``, one step per call, Newton's iteration in
Python around the compiled residual, norms and substitutions — is the reference here:
``compiled_advance`` runs the same operations on the same compiled pieces in one numba loop
(``cartan.integrators.newton.implicit_loop`` over the scheme's operator set), so the iterates, the counters and
the states must be the same bit for bit.  The only sums done differently are the midpoint
powers of the loads (``Scheme.powers`` in numpy against the operator set's ``op_powers``): the dissipated
energy and the external work agree to round-off, required ≤ 1e-12 relative.  Against the numpy
reference (``compiled_diagnostics`` cleared) the steps agree to the Newton tolerance, as
``tests/test_implicit_compiled.py`` requires of single steps.
"""

from __future__ import annotations

import numpy as np
import pytest
from cartan_verification.stiff import stiff_rod
from test_implicit_compiled import CASES, _toy2_problem, case_params
from toys import rel_error

import cartan
from cartan import _backend
from cartan.integrators import LieVerlet
from cartan.integrators.implicit import ImplicitMidpoint
from cartan.problem import Clamped, Free, Problem, UniformForce
from cartan.schemes.lattice import Lattice
from cartan.simulate import InstabilityError
from cartan.statics import ConvergenceError

#: the energy accumulators: midpoint powers summed in another order than Scheme.powers
#: (round-off of sums over the nodes; measured ≤ 4e-16 relative over the 20 steps of these tests)
ENERGY_TOL = 1e-12
#: the block sizes of a run: the sub-blocks cartan.simulate uses (ending at steps 1, 2, 4, 8, …)
BLOCKS = (1, 1, 2, 4, 8, 4)


def _face_loaded(follower: bool) -> Lattice:
    """The d = 2 toy of ``tests/test_implicit_compiled.py`` with a load on its face u = 1 (whose
    power the lattice weights by ``weights/(h/2)``) and a body-frame force; frames stepped."""
    base = _toy2_problem("SE2")
    problem = Problem(base.medium, base.grid, base.initial,
                      {"u-start": Clamped(), "u-end": Free(load=[0.3, -0.2, 0.1], follower=follower)},
                      [*base.loads, UniformForce([0.1, 0.0, 0.05])])
    return Lattice(problem, track_frames=True)


#: the problems of the single-step comparisons, and face loads on a d = 2 lattice
LOOP_CASES = {
    **CASES,
    "lattice-d2-SE2-face-follower": (lambda: _face_loaded(True), 5e-2),
    "lattice-d2-SE2-face-dead": (lambda: _face_loaded(False), 5e-2),
}


class PythonDriver(ImplicitMidpoint):
    """``implicit-midpoint`` stepped by the Python driver only (``compiled_advance`` declines for a
    subclass that overrides ``step``)."""

    def step(self, scheme, state, dt):
        super().step(scheme, state, dt)


@pytest.fixture(scope="module")
def stiff():
    """The stiff cantilever of ``cartan_verification.stiff`` (n = 21) and its explicit limit."""
    problem = stiff_rod(21, tip_speed=0.01)
    scheme = Lattice(problem)
    return problem, float(LieVerlet().dt_max(scheme, scheme.initial_state()))


def _start(scheme):
    state = scheme.initial_state()
    state.scalars["nstep"] = 0
    return state


def _both(make_scheme, dt, blocks=BLOCKS, **options):
    """The same steps by the Python driver and by ``compiled_advance`` in ``blocks``, each on its own scheme."""
    ref_scheme, fast_scheme = make_scheme(), make_scheme()
    ref, fast = _start(ref_scheme), _start(fast_scheme)
    ref_integ, fast_integ = ImplicitMidpoint(**options), ImplicitMidpoint(**options)
    for _ in range(sum(blocks)):
        ref_integ.step(ref_scheme, ref, dt)
    for size in blocks:
        assert fast_integ.compiled_advance(fast_scheme, fast, dt, size)
    return (ref_scheme, ref, ref_integ), (fast_scheme, fast, fast_integ)


def _counters(integ) -> tuple:
    return integ.nstep, integ.nforce, integ.newton_iterations, integ.jacobians


def _assert_same(ref, fast, ref_integ, fast_integ):
    """The same state bit for bit (energies to round-off) and the same Newton counters."""
    assert np.array_equal(fast.S, ref.S), rel_error(fast.S, ref.S)
    assert set(fast.arrays) == set(ref.arrays)
    for key in ref.arrays:
        assert np.array_equal(fast.arrays[key], ref.arrays[key]), (key, rel_error(fast.arrays[key], ref.arrays[key]))
    assert fast.t == ref.t and fast.scalars["nstep"] == ref.scalars["nstep"]
    for key in ("dissipated_energy", "external_work"):
        assert rel_error(fast.scalars[key], ref.scalars[key]) <= ENERGY_TOL, key
    assert _counters(fast_integ) == _counters(ref_integ)


# ---------------------------------------------------------------------------- blocks against the Python driver
@pytest.mark.parametrize("factor, options", [
    (10, {}),
    (100, {}),
    (100, {"contraction": 0.003}),  # the kept Jacobian is refreshed mid-run (and mid-step)
    (10, {"reuse_jacobian": False, "predictor": False}),
])
def test_stiff_rod_blocks_match_the_python_driver(stiff, factor, options):
    problem, limit = stiff
    (ref_scheme, ref, ri), (scheme, fast, fi) = _both(lambda: Lattice(problem), factor * limit, **options)
    _assert_same(ref, fast, ri, fi)
    assert fi.nstep == sum(BLOCKS) and fi.newton_iterations >= fi.nstep
    if options.get("contraction"):
        # measured: 2 Jacobians over these 20 steps, the second requested after an iteration of
        # a step (the loop resumes that step); at the default contraction, 1
        assert 2 <= fi.jacobians < fi.nstep
    elif options.get("reuse_jacobian") is False:
        assert fi.jacobians == fi.nstep
    # the kept factorisation and ξ carry over to a following step() as between steps
    ri.step(ref_scheme, ref, factor * limit)
    fi.step(scheme, fast, factor * limit)
    _assert_same(ref, fast, ri, fi)


@pytest.mark.parametrize("name", case_params(sorted(LOOP_CASES)))
def test_blocks_match_the_python_driver(name):
    """Lattice d = 1, 2 (open, periodic: a ring and a sphere-rod; SO(2), SE(2), SO(3), SE(3),
    gauge components) and collocation; damping, uniform forces, gravity, dead and follower
    end loads and face loads (whose powers the blocks book)."""
    make, dt = LOOP_CASES[name]
    (_, ref, ri), (_, fast, fi) = _both(make, dt)
    _assert_same(ref, fast, ri, fi)
    has_power = make().has_external_power()
    assert (abs(fast.scalars["dissipated_energy"]) + abs(fast.scalars["external_work"]) > 0) == has_power


def test_blocks_agree_with_the_numpy_reference(stiff):
    """Against the numpy residual (``compiled_diagnostics`` cleared) the Newton iterations are
    the same and the states agree to the Newton tolerance: K steps of a stable method within
    about K·tol relative (as ``test_steps_match_the_reference``); the configuration, far less
    sensitive than the momentum's unresolved stiff oscillation, to 1e-12 (measured 1.4e-15 at
    100×)."""
    problem, limit = stiff
    steps, tol = 30, 1e-10
    for factor in (10, 100):
        ref_scheme = Lattice(problem)
        ref_scheme.compiled_diagnostics = False
        ref, ri = _start(ref_scheme), ImplicitMidpoint(tol=tol)
        assert not ri.compiled_advance(ref_scheme, ref, factor * limit, steps)  # declined: the numpy path
        for _ in range(steps):
            ri.step(ref_scheme, ref, factor * limit)
        scheme = Lattice(problem)
        fast, fi = _start(scheme), ImplicitMidpoint(tol=tol)
        assert fi.compiled_advance(scheme, fast, factor * limit, steps)
        assert rel_error(fast.S, ref.S) <= 2 * steps * tol
        assert rel_error(fast.arrays["G_u"], ref.arrays["G_u"]) <= 1e-12
        assert _counters(fi) == _counters(ri)


# ---------------------------------------------------------------------------- failures
def test_a_failed_step_raises_the_python_drivers_error(stiff):
    """At 100 × the explicit limit with max_iter = 2, step 37 needs a third iteration
    (measured): the blocks stop there with the same error, the state of step 36 and the
    same counters."""
    problem, limit = stiff
    dt = 100 * limit
    ref_scheme, scheme = Lattice(problem), Lattice(problem)
    ref, fast = _start(ref_scheme), _start(scheme)
    ri, fi = ImplicitMidpoint(max_iter=2), ImplicitMidpoint(max_iter=2)
    with pytest.raises(ConvergenceError) as expected:
        for _ in range(40):
            ri.step(ref_scheme, ref, dt)
    with pytest.raises(ConvergenceError) as raised:
        fi.compiled_advance(scheme, fast, dt, 40)
    assert 0 < ref.scalars["nstep"] < 40
    assert "the iteration limit max_iter = 2 was reached" in str(expected.value)
    assert str(raised.value) == str(expected.value)
    assert (raised.value.iterations, raised.value.residual, raised.value.history) == (
        expected.value.iterations, expected.value.residual, expected.value.history)
    _assert_same(ref, fast, ri, fi)
    assert fi._cache is None  # as after a failed step()


def _raising(original):
    def jacobian(self, residual, xi, plan, compiled):
        raise RuntimeError("Factor is exactly singular")  # what SuperLU raises
    return jacobian


def _zero_pivots(original):
    def jacobian(self, residual, xi, plan, compiled):
        lu = original(self, residual, xi, plan, compiled)
        lu._args[3][:] = 0.0  # the diagonal of L: the substitutions divide by zero
        return lu
    return jacobian


def _ascent(original):
    def jacobian(self, residual, xi, plan, compiled):
        def flipped(x):
            res = residual(x)
            return None if res is None else {**res, "R": -res["R"]}
        return original(self, flipped, xi, plan, compiled)  # −∂R/∂ξ: the "Newton step" climbs
    return jacobian


@pytest.mark.parametrize("patch, reason", [
    (None, "the residual is not finite"),
    (_raising, r"the Jacobian is singular \(Factor is exactly singular\)"),
    (_zero_pivots, r"the Jacobian is singular \(non-finite Newton step\)"),
    (_ascent, r"no decrease of the residual along the Newton step after 10 halvings"),
])
def test_every_failure_reason_is_the_python_drivers(stiff, monkeypatch, patch, reason):
    """Each way a step can fail, in the first step of a block: a non-finite momentum (then a
    non-finite residual), a Jacobian that cannot be factorised, a zero pivot, and a Newton
    direction along which the residual only grows (through every halving)."""
    problem, limit = stiff
    dt = 10 * limit
    if patch is not None:
        monkeypatch.setattr(ImplicitMidpoint, "_jacobian", patch(ImplicitMidpoint._jacobian))
    errors, runs = [], []
    for blocks in (False, True):
        scheme = Lattice(problem)
        state = _start(scheme)
        if patch is None:
            state.S[5, 1] = np.nan
        integ = ImplicitMidpoint()
        with pytest.raises(ConvergenceError, match=reason) as info:
            if blocks:
                integ.compiled_advance(scheme, state, dt, 4)
            else:
                for _ in range(4):
                    integ.step(scheme, state, dt)
        errors.append(info.value)
        runs.append((state, integ))
    (ref, ri), (fast, fi) = runs
    assert str(errors[1]) == str(errors[0])
    assert np.array_equal(errors[1].history, errors[0].history, equal_nan=True)
    assert fast.scalars["nstep"] == ref.scalars["nstep"] == 0 and np.array_equal(fast.S, ref.S, equal_nan=True)
    assert _counters(fi) == _counters(ri)


def test_a_failure_in_simulate_names_the_same_step(stiff, tmp_path):
    """The failing step 37 lies inside the sub-block of steps 33–50 of the first save block:
    simulate counts the steps the block did before it."""
    problem, limit = stiff
    dt = 100 * limit
    messages = []
    for integ in (ImplicitMidpoint(max_iter=2), PythonDriver(max_iter=2)):
        with pytest.raises(InstabilityError) as info:
            cartan.simulate(problem, integrator=integ, dt=dt, t_end=60 * dt, save_every=50, progress=False,
                            output=tmp_path / f"{type(integ).__name__}.nc")
        messages.append(str(info.value).replace(type(integ).__name__, ""))  # (as the files' names differ)
        assert info.value.step == 37
    assert messages[0] == messages[1]
    assert "Newton's method did not converge" in messages[0]


# ---------------------------------------------------------------------------- simulate
@pytest.mark.slow  # the SE(2) rod's Newton blocks: ≈ 20 s to compile (make test compiles the SE(3) rod's)
def test_simulate_runs_the_blocks_and_matches_the_python_driver(stiff, monkeypatch):
    problem, limit = stiff
    dt = 100 * limit
    kw = {"dt": dt, "t_end": 40 * dt, "save_every": 10, "progress": False}
    driver = cartan.simulate(problem, integrator=PythonDriver(), **kw)
    calls = []
    step = ImplicitMidpoint.step

    def counted(self, *args):
        calls.append(1)
        return step(self, *args)

    monkeypatch.setattr(ImplicitMidpoint, "step", counted)
    blocks = cartan.simulate(problem, integrator="implicit-midpoint", **kw)
    assert calls == []  # no step in Python
    for name in ("S", "X", "position", "kinetic_energy", "potential_energy", "time", "step"):
        assert np.array_equal(blocks[name].values, driver[name].values), name


def test_the_kinetic_limit_stops_a_block_after_the_first_failing_step(stiff):
    problem, limit = stiff
    scheme = Lattice(problem)
    state = _start(scheme)
    integ = ImplicitMidpoint()
    assert integ.compiled_advance(scheme, state, 10 * limit, 8, kinetic_limit=1e-300)
    assert state.scalars["nstep"] == integ.nstep == 1
    assert integ.compiled_advance(scheme, state, 10 * limit, 8)
    assert state.scalars["nstep"] == 9


# ---------------------------------------------------------------------------- declines
def test_advance_declines_where_the_python_driver_runs(stiff):
    problem, limit = stiff
    dt = 10 * limit

    def untouched(scheme, integ):
        state = _start(scheme)
        before = state.copy()
        assert integ.compiled_advance(scheme, state, dt, 3) is False
        assert state.t == before.t and np.array_equal(state.S, before.S) and integ.nstep == 0
        assert all(np.array_equal(state.arrays[k], before.arrays[k]) for k in before.arrays)

    reference = Lattice(problem)
    reference.compiled_diagnostics = False  # simulate(..., compiled=False)
    untouched(reference, ImplicitMidpoint())
    _backend.set_backend("numpy")
    try:
        untouched(Lattice(problem), ImplicitMidpoint())
    finally:
        _backend.set_backend(None)

    class OwnResidual(ImplicitMidpoint):
        def _residual(self, scheme, state, xi, dt):
            return super()._residual(scheme, state, xi, dt)

    class OwnStep(ImplicitMidpoint):
        def _step(self, scheme, state, dt):
            super()._step(scheme, state, dt)

    for cls in (OwnResidual, OwnStep, PythonDriver):
        untouched(Lattice(problem), cls())
    # zero steps: nothing to do, accepted
    scheme = Lattice(problem)
    state = _start(scheme)
    assert ImplicitMidpoint().compiled_advance(scheme, state, dt, 0) and state.scalars["nstep"] == 0
