"""The generated compiled loops: one loop per integrator over a scheme's operator set, for any
group with point kernels and any medium that declares point kernels.

Tolerances: the compiled loops evaluate the reference path's formulas in another order, so
the two agree to round-off; over the few hundred operations per step and ≤ 20 steps here the
observed relative differences are ≤ 6e-15, and 1e-12 (the project's compiled-vs-reference
bound) leaves two and a half digits of margin.
"""

from __future__ import annotations

import contextlib
import importlib
import sys

import numpy as np
import pytest
from toys import CoupledQuartic, IndefiniteMetric, arc_problem, rel_error

import cartan
from cartan.compiled import codegen
from cartan.grid import Grid
from cartan.problem import Clamped, Damping, Free, InitialState, Problem
from cartan.schemes.lattice import Lattice
from cartan.simulate import StabilityWarning, simulate
from cartan.testing import check_medium

TOL = 1e-12
INTEGRATORS = ["lie-verlet", "rkmk4", "lie-euler", "forward-euler"]


def _sets(fast, slow: bool = False):
    """``fast`` in ``make test``; every explicit integrator under ``slow`` (each further loop of
    a generated module compiles for about 10 s).  ``slow=True`` moves both to ``make test-slow``
    (a group whose first generated module compiles for a minute or more on a fresh cache)."""
    marks = [pytest.mark.slow] if slow else []
    return [pytest.param(fast, id="fast", marks=marks), pytest.param(INTEGRATORS, id="all", marks=pytest.mark.slow)]


def _compare(problem, integrators, names=("S", "X", "kinetic_energy", "potential_energy", "dissipated_energy",
                                          "external_work"), **kw):
    for integ in integrators:
        opts = dict(dt=2e-3, t_end=0.02, save_every=5, scheme="lattice", progress=False, integrator=integ)
        opts.update(kw)
        with pytest.warns(StabilityWarning) if integ in ("lie-euler", "forward-euler") else contextlib.nullcontext():
            fast = simulate(problem, **opts)
            ref = simulate(problem, **opts, compiled=False)
        assert np.array_equal(fast.step.values, ref.step.values)
        for name in names:
            if name in ref:
                err = rel_error(fast[name].values, ref[name].values)
                assert err <= TOL, (integ, name, err)


def _sheet(reference: bool, boundaries=None, loads=(), velocity=True):
    """The coupled quartic medium on SE(3), d = 2, on a curved sheet (open × periodic)."""
    med = CoupledQuartic("SE3", d=2)
    G = med.group
    grid = Grid((7, 6), (1.0, 0.8), periodic=(False, True))
    U, V = np.meshgrid(grid.coordinates(0), grid.coordinates(1), indexing="ij")
    xu = np.array([1.0, 0, 0, 0, 0.3, 0])
    xv = np.array([0, 1.0, 0, 0.5, 0, 0])
    Phi_ref = G.compose(G.exp(U[..., None] * xu), G.exp(V[..., None] * xv))
    rng = np.random.default_rng(1)
    Phi0 = G.compose(Phi_ref, G.exp(0.02 * np.sin(3 * U)[..., None] * rng.standard_normal(6)))
    N0 = 0.1 * np.cos(2 * np.pi * V)[..., None] * np.linspace(1, 0.5, 6) if velocity else None
    return Problem(med, grid, InitialState(Phi=Phi0, N=N0), reference=Phi_ref if reference else None,
                   boundaries=boundaries or {}, loads=list(loads))


@pytest.mark.parametrize("integrators", _sets(["lie-verlet"], slow=True))
def test_sigma_model_on_s3_d2_runs_compiled_and_agrees(integrators):
    """SO(4) (the sigma model on S³) in d = 2: no hand-written loop covers it."""
    medium = cartan.medium("sigma-model", n=3, d=2)
    grid = Grid((10, 8), 1.0, periodic=True)
    problem = Problem(medium, grid, medium.initial_state(grid, "random-smooth"))
    scheme = Lattice(problem)
    assert scheme.compiled_plan("_lattice_compiled") is None  # the hand-written loops decline
    assert scheme.compiled_operators().ok
    _compare(problem, integrators)


@pytest.mark.parametrize("integrators", _sets(["lie-verlet"], slow=True))
def test_lorentz_group_toy_runs_compiled_and_agrees(integrators):
    """A quadratic rod on SO(1,3) (a non-compact group)."""
    problem = arc_problem(n=15, group="SO13", curvature=0.5, velocity=np.linspace(0.1, 0.3, 6))
    assert Lattice(problem).compiled_operators().ok
    _compare(problem, integrators, dt=1e-3, t_end=0.01)


@pytest.mark.parametrize("integrators", _sets(["rkmk4"], slow=True))
def test_poincare_toy_runs_compiled(integrators):
    """A quadratic rod on the Poincaré group: its dexp⁻¹ and 𝓔 kernels sum the series in ad_ξ
    for a small Lorentz part and take the Van Loan block exponential beyond (this arc's edges
    and velocities, 0.03–0.3), and the loops agree with the reference."""
    problem = arc_problem(n=9, group="Poincare", curvature=0.3, velocity=np.linspace(0.1, 0.3, 10))
    imports = cartan.group("Poincare").point_kernels().imports
    assert imports["g_dexp_inv"][1] == "poincare_dexp_inv_point" and imports["g_E"][1] == "poincare_E_point"
    _compare(problem, integrators, dt=1e-3, t_end=0.01)


def test_a_group_without_dexp_inv_kernels_gets_van_loan():
    """A group module with neither ``E`` nor ``dexp_inv`` point kernels (a plugin group) gets
    both from ad by the Van Loan block exponential in the generated module."""
    import sys
    import types

    from cartan.compiled.kernels import GROUP_OPS, group_fragment
    from cartan.groups import poincare

    fake = types.ModuleType("cartan_test_group_without_dexp")
    for op in GROUP_OPS:
        if op not in ("E", "dexp_inv"):
            setattr(fake, f"poincare_{op}_point", getattr(poincare, f"poincare_{op}_point"))
    sys.modules[fake.__name__] = fake
    try:
        frag = group_fragment(fake.__name__, "poincare")
    finally:
        del sys.modules[fake.__name__]
    assert "_vanloan_E" in frag.imports and "def g_dexp_inv(" in frag.source and "def g_E(" in frag.source


@pytest.mark.slow  # compiles the Van Loan and Padé kernels on their own (≈ 15 s on a fresh cache)
def test_van_loan_kernels_match_the_reference():
    from cartan.groups._generic_kernels import expm_point, vanloan_E_point

    G = cartan.group("Poincare")
    rng = np.random.default_rng(0)
    for scale in (1e-8, 0.3, 1.5):  # below, at and above the Padé scaling threshold's reach
        xi = scale * rng.standard_normal(10)
        out = np.empty((10, 10))
        vanloan_E_point(0.7, G.ad(xi), out)
        assert np.max(np.abs(out - G.E(0.7, xi))) <= 1e-13 * max(1.0, np.max(np.abs(out)))
    A = 10.0 * rng.standard_normal((8, 8))  # ‖A‖ > θ₁₃: scaled and squared
    out = np.empty((8, 8))
    expm_point(A, out)
    import scipy.linalg

    ref = scipy.linalg.expm(A)
    # squaring amplifies the approximant's relative error by about 2^s ‖A‖: 1e-12 of ‖exp A‖
    assert np.max(np.abs(out - ref)) <= 1e-12 * np.max(np.abs(ref))


@pytest.mark.parametrize("integrators", _sets(["lie-verlet", "lie-euler"], slow=True))
def test_coupled_nonquadratic_sheet_with_reference_runs_compiled_and_agrees(integrators):
    """Non-quadratic, axis-coupled energy on SE(3), d = 2, with a rest strain that varies over
    the body, clamped and follower-loaded faces and damping: every explicit integrator."""
    problem = _sheet(True, boundaries={"u-start": Clamped(),
                                       "u-end": Free(load=[0, 0, 0.1, 0, 0, 0.05], follower=True)},
                     loads=[Damping(0.1)])
    scheme = Lattice(problem)
    assert scheme.coupled and scheme.compiled_operators().ok
    _compare(problem, integrators)
    relax = _sheet(True, boundaries={"u-start": Clamped()}, loads=[Damping(1.0)], velocity=False)
    for order in (1, 2):
        _compare(relax, [cartan.registry("integrators")["overdamped"](order=order)],
                 names=("X", "potential_energy", "dissipated_energy"), dt=1e-3, t_end=0.01)


@pytest.mark.slow
def test_dead_face_load_runs_compiled_and_agrees():
    problem = _sheet(False, boundaries={"u-start": Clamped(), "u-end": Free(load=[0.1, 0, 0.2, 0, 0.05, 0])})
    assert Lattice(problem).track
    _compare(problem, ["lie-verlet"], dt=1e-3)


@pytest.mark.parametrize("reference", [True, False])
def test_corner_force_is_the_gradient_of_the_corner_energy(reference):
    """−dV/dε along the drift Φ ← Φ exp(εv) is Σ F·v: the central difference's error falls
    like ε² (100× per decade of ε; a force that is not the gradient leaves an O(1) error)."""
    scheme = Lattice(_sheet(reference))
    state = scheme.initial_state()
    v = np.random.default_rng(3).standard_normal(state.S.shape)
    g = -float(np.sum(scheme.internal_force(state) * v))
    errs = []
    for eps in (1e-3, 1e-4, 1e-5):
        plus, minus = state.copy(), state.copy()
        scheme.drift(plus, eps, v)
        scheme.drift(minus, -eps, v)
        errs.append(abs((scheme.potential_energy(plus) - scheme.potential_energy(minus)) / (2 * eps) - g))
    assert errs[1] <= 0.02 * errs[0] and errs[2] <= 0.02 * errs[1] and errs[2] <= 1e-4 * abs(g), errs


def test_reference_configuration_is_stress_free():
    """The edges' rest strains are those of the reference: no force there, any curvature."""
    problem = _sheet(True, velocity=False)
    ref = Problem(problem.medium, problem.grid, InitialState(Phi=problem.reference.Phi), reference=problem.reference)
    scheme = Lattice(ref)
    state = scheme.initial_state()
    assert np.max(np.abs(scheme.internal_force(state))) <= 1e-12
    assert abs(scheme.potential_energy(state)) <= 1e-24
    rod = arc_problem(n=9, curvature=3.0)
    rod_ref = Problem(rod.medium, rod.grid, rod.initial, reference=rod.initial.Phi)
    assert np.max(np.abs(Lattice(rod_ref).internal_force(Lattice(rod_ref).initial_state()))) <= 1e-12


@pytest.mark.slow  # the coupled quartic toy's own module (20-30 s on a fresh cache); corner energies of
# coupled SE(3) media stay in the fast suite through the shell and the solid
def test_lie_verlet_conserves_the_corner_energy_to_second_order():
    """Free sheet (no loads): the energy error of lie-verlet falls 4× when Δt halves."""
    problem = _sheet(True)
    errs = []
    for dt in (4e-3, 2e-3):
        ds = simulate(problem, integrator="lie-verlet", dt=dt, t_end=0.2, save_every=10, progress=False)
        E = ds.kinetic_energy.values + ds.potential_energy.values
        errs.append(float(np.max(np.abs(E - E[0]))))
    assert 3.0 <= errs[0] / errs[1] <= 5.0, errs


def test_kernel_medium_reference_path_uses_its_kernels():
    """KernelMedium's potential and stress are its kernels, point by point."""
    med = CoupledQuartic("SE3", d=2)
    k = med.point_kernels()
    X = med.rest_strain() + 0.1 * np.random.default_rng(0).standard_normal((5, 2, 6))
    U = med.potential(X)
    Q = med.stress(X)
    for i in range(5):
        assert U[i] == k.energy(X[i], med.rest_strain(), k.params)
        out = np.empty((2, 6))
        k.stress(X[i], med.rest_strain(), k.params, out)
        assert np.array_equal(Q[i], out)


@pytest.mark.slow  # compiles the coupled quartic toy's loop (≈ 25 s on a fresh cache); kernel media run
# compiled in the fast suite through the shell and the solid (tests/test_cosserat_surface.py, _solid.py)
def test_kernel_medium_conforms_compiled():
    check_medium(CoupledQuartic("SE3", d=2), schemes=["lattice"], integrators=["lie-verlet"])


def test_group_point_kernels_declared():
    for name, kw in (("SO2", {}), ("SE2", {}), ("SO3", {}), ("SE3", {}), ("SO13", {}), ("SO", {"n": 4}),
                     ("SO", {"n": 3}), ("Poincare", {})):
        frag = cartan.group(name, **kw).point_kernels()
        assert frag is not None, name
        bound = set(frag.imports) | {ln.split("(")[0][4:] for ln in frag.source.splitlines() if ln.startswith("def ")}
        assert {f"g_{op}" for op in ("exp", "log", "compose", "inverse", "hat", "Ad", "ad", "dexp_inv", "E")} <= bound
    assert cartan.group("SO", n=5).point_kernels() is None


def test_declined_problem_says_why():
    problem = arc_problem(n=5, group="SE3")
    from cartan.problem import UniformForce

    spatial = Problem(problem.medium, problem.grid, problem.initial, loads=[UniformForce(np.ones(6), "spatial")])
    ops = Lattice(spatial).compiled_operators()
    assert not ops.ok and "UniformForce" in ops.reason


def test_generated_module_name_follows_its_kernels(tmp_path, monkeypatch):
    """Editing a kernel's source gives a new generated module (stale machine code is never
    loaded); the same source gives the same module."""
    monkeypatch.setenv("CARTAN_CACHE_DIR", str(tmp_path / "cache"))
    pkg = tmp_path / "kernels_pkg"
    pkg.mkdir()
    monkeypatch.syspath_prepend(str(tmp_path))

    def write(body):
        (pkg / "__init__.py").write_text("")
        (pkg / "k.py").write_text(f"from numba import njit\n\n\n@njit\ndef twice(x):\n    return {body}\n")
        for key in [k for k in sys.modules if k.startswith("kernels_pkg")]:
            del sys.modules[key]
        importlib.invalidate_caches()

    use = codegen.Fragment(imports={"twice": ("kernels_pkg.k", "twice")},
                           source="def run(x):\n    return twice(x) + 1.0\n")
    write("2.0 * x")
    first = codegen.generate("probe", [use])
    assert first.run(1.5) == 4.0
    assert codegen.generate("probe", [use]) is first
    write("3.0 * x")
    second = codegen.generate("probe", [use])
    assert second is not first and second.run(1.5) == 5.5
    assert len(list((tmp_path / "cache" / "generated").glob("probe_*.py"))) == 2


def test_first_compile_is_announced_once(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("CARTAN_CACHE_DIR", str(tmp_path))
    module = codegen.generate("announce", [codegen.Fragment(source="def f(x):\n    return x\n")])
    with codegen.first_call(module, "f", "a probe"):
        module.f(1.0)
    err = capsys.readouterr().err
    assert "compiling a probe" in err and "compiled a probe" in err
    with codegen.first_call(module, "f", "a probe"):
        module.f(2.0)
    assert capsys.readouterr().err == ""


def test_a_failed_first_call_is_not_recorded_and_releases_its_lock(tmp_path, monkeypatch, capsys):
    """An error inside the first call leaves no marker (the next call announces again) and
    frees the lock (another ``first_call`` of the same function does not wait forever)."""
    monkeypatch.setenv("CARTAN_CACHE_DIR", str(tmp_path))
    module = codegen.generate("failing", [codegen.Fragment(source="def f(x):\n    return x\n")])
    with pytest.raises(RuntimeError), codegen.first_call(module, "f", "a probe"):
        raise RuntimeError("inside the first call")
    assert not list(tmp_path.glob("generated/*.f.compiled"))
    with codegen.first_call(module, "f", "a probe"):
        module.f(1.0)
    assert "compiled a probe" in capsys.readouterr().err
    assert list(tmp_path.glob("generated/*.f.compiled"))


def test_a_second_process_waits_for_the_first_compile(tmp_path):
    """Two processes reaching the same first call: one compiles (and announces), the other
    waits for it and announces nothing."""
    import os
    import subprocess

    code = ("import sys, time\n"
            "from cartan.compiled import codegen\n"
            "m = codegen.generate('race', [codegen.Fragment(source='def f(x):\\n    return x + 1.0\\n')])\n"
            "with codegen.first_call(m, 'f', 'the race'):\n"
            "    time.sleep(float(sys.argv[1]))\n"
            "    m.f(1.0)\n")
    env = {**os.environ, "CARTAN_CACHE_DIR": str(tmp_path)}
    procs = [subprocess.Popen([sys.executable, "-c", code, delay], env=env, stderr=subprocess.PIPE, text=True)
             for delay in ("2.0", "0.0")]
    errs = [p.communicate(timeout=300)[1] for p in procs]
    assert all(p.returncode == 0 for p in procs), errs
    assert sum("compiling the race" in e for e in errs) == 1, errs


def _indefinite_problem(n=13):
    medium = IndefiniteMetric("SO13")
    G = medium.group
    grid = Grid(n, 1.0, periodic=True)
    u = grid.coordinates(0)
    wave = np.sin(2 * np.pi * u)[:, None] * np.linspace(0.05, 0.02, G.dim)
    return Problem(medium, grid, InitialState(Phi=G.exp(wave), N=np.cos(2 * np.pi * u)[:, None] * 0.1 * np.ones(6)))


def test_indefinite_nondiagonal_metric_legendre_map():
    med = IndefiniteMetric("SO13")
    S = np.random.default_rng(0).standard_normal((4, 6))
    assert np.allclose(med.momentum(med.velocity(S)), S, rtol=0, atol=1e-13)
    N = med.velocity(S)
    assert np.allclose(med.kinetic(N), 0.5 * np.einsum("...k,...k->...", N, S), rtol=0, atol=1e-13)
    assert np.any(np.linalg.eigvalsh(med.kinetic_metric()) < 0)  # really indefinite


@pytest.mark.parametrize("integrators", _sets(["lie-verlet"], slow=True))
def test_indefinite_metric_runs_compiled_and_agrees(integrators):
    """SO(1,3) with a non-diagonal indefinite kinetic metric: lie-verlet splits the free flow
    along the metric's eigenvectors; compiled and reference agree."""
    problem = _indefinite_problem()
    scheme = Lattice(problem)
    assert not scheme.diagonal_metric and scheme.compiled_plan("_lattice_compiled") is None
    _compare(problem, integrators, dt=1e-3, t_end=0.01)


@pytest.mark.slow  # the Poincaré toy's own module (20-30 s on a fresh cache); the indefinite metric stays
# in the fast suite through the relativistic string (tests/test_relativistic_rod.py)
def test_indefinite_metric_lie_verlet_energy_second_order():
    """The energy K + V (both indefinite) of lie-verlet errs by O(Δt²): 4× less per halving."""
    problem = _indefinite_problem()
    errs = []
    for dt in (4e-3, 2e-3):
        ds = simulate(problem, integrator="lie-verlet", dt=dt, t_end=0.4, save_every=10, progress=False)
        E = ds.kinetic_energy.values + ds.potential_energy.values
        errs.append(float(np.max(np.abs(E - E[0]))))
    assert 3.0 <= errs[0] / errs[1] <= 5.0, errs


def test_kernels_that_disagree_with_stress_are_refused_by_name():
    """A declaration that does not describe the medium is a clear error, not other physics."""

    class Wrong(CoupledQuartic):
        name = "toy-wrong-kernels"

        def stress(self, X):
            return 2.0 * super().stress(X)

        def stress_at(self, X, X0):
            return 2.0 * super().stress_at(X, X0)

    problem = _sheet(False)
    wrong = Problem(Wrong("SE3", d=2), problem.grid, problem.initial)
    with pytest.raises(ValueError, match="toy-wrong-kernels.*point_kernels\\(\\) disagree with stress\\(\\)"):
        Lattice(wrong).compiled_operators()


def test_quadratic_medium_that_replaces_its_energy_declares_no_kernels():
    from toys import QuadraticMedium

    class Replaced(QuadraticMedium):
        def stress(self, X):
            return super().stress(X)

    assert QuadraticMedium("SE3").point_kernels() is not None
    assert Replaced("SE3").point_kernels() is None


def test_kernels_defined_in_exec_code_run_compiled(tmp_path, monkeypatch):
    """Kernels without an importable module (a notebook, a script, exec) are registered by
    the code they carry; the same code finds the same generated module."""
    monkeypatch.setenv("CARTAN_CACHE_DIR", str(tmp_path))
    space = {}
    exec(compile("from numba import njit\n"
                 "@njit\n"
                 "def e(X, X0, p):\n"
                 "    return 0.5 * p[0] * ((X[0, 0] - X0[0, 0]) ** 2 + (X[0, 1] - X0[0, 1]) ** 2)\n"
                 "@njit\n"
                 "def s(X, X0, p, Q):\n"
                 "    Q[0, 0] = p[0] * (X[0, 0] - X0[0, 0])\n"
                 "    Q[0, 1] = p[0] * (X[0, 1] - X0[0, 1])\n", "<cell>", "exec"), space)
    from cartan.compiled.kernels import medium_batch
    from cartan.medium import MediumKernels

    kernels = MediumKernels(space["e"], space["s"], np.array([3.0]))
    module = medium_batch(kernels)
    assert module is medium_batch(MediumKernels(space["e"], space["s"], np.array([3.0])))
    X = np.ones((4, 1, 2))
    out = np.empty(4)
    module.energy_batch(X, np.zeros((4, 1, 2)), kernels.params, out)
    assert np.all(out == 3.0)


@pytest.mark.slow
def test_s3_sigma_scene_runs_in_the_generated_loop():
    """The registered scene of the O(4) sigma model runs compiled and conserves its energy
    (lie-verlet at Courant 0.12 on 48²: the energy error is O(Δt²), far below 1e-3)."""
    sc = cartan.scene("sigma-s3-waves")
    scheme = Lattice(sc.problem)
    assert scheme.compiled_plan("_lattice_compiled") is None and scheme.compiled_operators().ok
    ds = simulate(sc, t_end=0.1, save_every=10, progress=False)
    E = ds.kinetic_energy.values + ds.potential_energy.values
    assert np.max(np.abs(E - E[0])) <= 1e-3 * E[0]
