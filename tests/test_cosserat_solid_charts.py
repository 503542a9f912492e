"""The micropolar solid on a general chart: mass, face loads and outputs (docs/media/cosserat-solid.md, "Charts").

Fast tests run on the numpy path without the medium's batch kernels (the lattice's weights and
nodal strains, the medium's ``outputs``); the equilibrium of the twisted cylinder is slow.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from cartan_cosserat_solid.cases import CylinderTorsion, cylinder_torsion_problem, torsion_stiffness

import cartan
from cartan.schemes.lattice import Lattice

SO3 = cartan.group("SO3")


@pytest.fixture(autouse=True)
def _numpy_backend(request):
    """The fast tests run on the numpy backend (no compilation); the slow ones as users do."""
    if request.node.get_closest_marker("slow") is not None:
        yield
        return
    from cartan._backend import use_backend

    with use_backend("numpy"):
        yield


def _cylinder(n: int, solid, **params):
    """An n × n × 3 slab of the unit cylinder (periodic axis, the ``cylinder`` initial kind)."""
    h = 2.0 / (n - 1)
    grid = cartan.Grid((n, n, 3), length=(2.0, 2.0, 3 * h), periodic=(False, False, True))
    return grid, solid.initial_state(grid, "cylinder", **params)


def _outputs(problem: cartan.Problem) -> dict[str, np.ndarray]:
    """The solid's outputs at the initial state, as the core records them (numpy only)."""
    sch = Lattice(problem)
    state = sch.initial_state()
    ref = problem.reference
    reference = None if ref is None else {"q": ref.Phi, "X0": sch.nodal_rest_strains()}
    return problem.medium.outputs(sch.frames(state), sch.nodal_strains(state), np.zeros((*problem.grid.shape, 6)),
                                  problem.grid, reference=reference)


def test_rigid_translation_kinetic_energy_is_half_m_v2():
    """K = ½ρπa²L|v|² for the charted cylinder translating rigidly: the node masses are ρ det Θ₀ w,
    the quadrature of the chart (trapezoidal weights, the chords' det Θ₀) is O(h²): measured
    relative errors 6.6e-3 (n = 9) and 1.7e-3 (n = 17), ratio 3.98."""
    solid = cartan.medium("cosserat-solid", density=2.0, micro_inertia=0.3)
    v = np.array([0.3, -0.2, 0.5])
    errors = []
    for n in (9, 17):
        grid, init = _cylinder(n, solid, rigid_velocity=[*v, 0.0, 0.0, 0.0])
        problem = cartan.Problem(solid, grid, init)
        assert np.array_equal(problem.reference.Phi, init.reference.Phi)  # the initial kind brings its chart
        sch = Lattice(problem)
        mass = solid.rho * math.pi * grid.length[2]
        errors.append(sch.kinetic_energy(sch.initial_state()) / (0.5 * mass * v @ v) - 1.0)
        # the micro-inertia likewise: a uniform spin Ω, K = ½ρj|Ω|²·volume
        spin = cartan.Problem(solid, grid, solid.initial_state(grid, "cylinder", velocity=[0, 0, 0, 0.4, 0, -0.7]))
        s = Lattice(spin)
        volume = math.pi * grid.length[2]
        K = s.kinetic_energy(s.initial_state())
        assert K / (0.5 * solid.rho * solid.j * 0.65 * volume) - 1.0 == pytest.approx(errors[-1], abs=1e-12)
        # the energy keeps the chart's own quadrature weights
        assert np.array_equal(sch.chart_weights, grid.node_weights())
    assert abs(errors[0]) < 1e-2
    assert abs(errors[1]) < 0.3 * abs(errors[0])  # O(h²): 1/4 at half the spacing, 0.3 allows order ≥ 1.7


def _open_cylinder(n: int, solid, **params):
    """An n × n × 3 piece of the unit cylinder, open along the axis (the collocation scheme takes no
    holonomy), with the ``cylinder`` initial kind's chart."""
    h = 2.0 / (n - 1)
    grid = cartan.Grid((n, n, 3), length=(2.0, 2.0, 2 * h), periodic=(False, False, False))
    return grid, solid.initial_state(grid, "cylinder", **params)


def test_collocation_weighs_the_charted_cylinder_by_its_reference_volume():
    """Collocation on the square-to-disk chart: the node masses are ρJw (J = det Θ₀ of the collocation's
    rest strains), so a rigid translation has K = ½ρπa²L|v|² to the chart's quadrature order, as on the
    lattice (measured relative errors 1.35e-2 (n = 9) and 3.8e-3 (n = 17), ratio 3.6; the chart's
    own weights would give the square's area, 27 % too much), while the energy keeps the chart's
    weights; the internal force is per unit reference volume (divided by J): zero for the rigid motion."""
    from cartan.schemes.collocation import Collocation

    solid = cartan.medium("cosserat-solid", density=2.0, micro_inertia=0.3)
    v = np.array([0.3, -0.2, 0.5])
    errors = []
    for n in (9, 17):
        grid, init = _open_cylinder(n, solid, rigid_velocity=[*v, 0.0, 0.0, 0.0])
        problem = cartan.Problem(solid, grid, init)
        sch = Collocation(problem)
        mass = solid.rho * math.pi * grid.length[2]
        state = sch.initial_state()
        errors.append(sch.kinetic_energy(state) / (0.5 * mass * v @ v) - 1.0)
        assert np.array_equal(sch.chart_weights, grid.node_weights())
        assert np.max(np.abs(sch.weights / sch.chart_weights - 1.0)) > 0.1    # a general chart indeed
        assert np.max(np.abs(sch.internal_force(state))) < 1e-9
    assert abs(errors[0]) < 2e-2
    assert abs(errors[1]) < 0.35 * abs(errors[0])  # O(h²): 1/4 at half the spacing, 0.35 allows order ≥ 1.5


def test_node_force_is_the_given_force_on_a_general_chart():
    """A ``NodeForce`` P at a node of the charted cylinder where J = det Θ₀ ≠ 1: the scheme's weighted
    density sums to P exactly (the scheme hands the load its reference volumes, ``Load.measure``), on
    the lattice and on collocation; its power on a rigid velocity is P·v."""
    from cartan.schemes.collocation import Collocation

    solid = cartan.medium("cosserat-solid")
    v = np.array([0.3, -0.2, 0.5])
    grid, init = _open_cylinder(9, solid, rigid_velocity=[*v, 0.0, 0.0, 0.0])
    P = np.array([0.4, -0.1, 0.25, 0.02, 0.03, -0.05])
    for scheme in (Lattice, Collocation):
        load = cartan.NodeForce(grid, P, node=(1, 2, 1))
        problem = cartan.Problem(solid, grid, init, loads=[load])
        sch = scheme(problem)
        J = sch.weights / sch.chart_weights
        assert abs(J[1, 2, 1] - 1.0) > 0.05                     # the uncorrected force would be J·P
        state = sch.initial_state()
        F = load.force(sch.frames(state), np.zeros((*grid.shape, 6)), 0.0)
        assert np.allclose(np.tensordot(sch.weights, F, axes=3), P, rtol=1e-14, atol=0)
        N = sch.velocity(state)
        assert sch.powers(state, N, 0.0)["external"] == pytest.approx(P[:3] @ v, rel=1e-12)


def test_rigid_motion_of_the_charted_cylinder_has_no_stress():
    """x = c + Q x_ref, R = Q: every stress output vanishes to round-off (the chart's physical
    strains are those of a rigid motion), the displacement is the rigid one and the
    micro-rotation log Q at every node."""
    solid = cartan.medium("cosserat-solid")
    grid, init = _cylinder(9, solid)
    rot = np.array([0.3, -0.5, 0.2])
    G = np.eye(4)
    G[1:, 1:], G[1:, 0] = SO3.exp(rot), [0.4, -1.0, 2.0]
    ref = init.reference
    state = cartan.InitialState(Phi=G @ ref.Phi, holonomy={2: G @ ref.holonomy[2] @ np.linalg.inv(G)})
    out = _outputs(cartan.Problem(solid, grid, state, reference=ref))
    for name in ("force_stress", "couple_stress", "nominal_force_stress", "nominal_couple_stress",
                 "cauchy_force_stress", "cauchy_couple_stress"):
        assert np.max(np.abs(out[name])) < 1e-12, name
    x_ref = ref.Phi[..., 1:, 0]
    disp = np.stack([out[f"displacement_{a}"] for a in "xyz"], axis=-1)
    assert np.allclose(disp, x_ref @ G[1:, 1:].T + G[1:, 0] - x_ref, rtol=0, atol=1e-13)
    phi = np.stack([out[f"microrotation_{a}"] for a in "xyz"], axis=-1)
    assert np.allclose(phi, rot, rtol=0, atol=1e-13)


def test_chart_stress_is_the_physical_one():
    """On an affine chart x_ref = A u (rest strains θ₀_α = A e_α), a homogeneous deformation
    x = F x_ref with frames R records the tensors of the same deformation charted by x_ref itself
    (an orthonormal chart, strains θ_j = RᵀF e_j): body, nominal and Cauchy, and x − x_ref."""
    solid = cartan.medium("cosserat-solid")
    grid = cartan.Grid((3, 3, 3), length=(0.5, 0.5, 0.5))
    A = np.array([[1.3, 0.2, 0.0], [-0.1, 0.8, 0.3], [0.2, 0.0, 1.1]])
    F = np.array([[1.02, 0.01, -0.03], [0.0, 0.97, 0.02], [0.04, -0.01, 1.01]])
    R = SO3.exp(np.array([0.02, -0.01, 0.03]))
    ref = solid.initial_state(grid, "deformation", F=A)
    cur = solid.initial_state(grid, "deformation", F=F @ A, rotation=[0.02, -0.01, 0.03])
    out = _outputs(cartan.Problem(solid, grid, cur, reference=ref.Phi))
    # the same state on a chart of the reference placement itself (x_ref = u: an orthonormal chart)
    X = np.zeros((3, 6))
    X[:, :3] = (R.T @ F).T  # rows θ_j = Rᵀ F e_j
    P, C = solid.nominal_stress_tensors(R, X)
    sigma, _ = solid.cauchy_stress_tensors(R, X)
    assert np.allclose(out["nominal_force_stress"], P, rtol=0, atol=1e-12)
    assert np.allclose(out["cauchy_force_stress"], sigma, rtol=0, atol=1e-12)
    assert np.allclose(out["nominal_couple_stress"], C, rtol=0, atol=1e-12)
    assert np.allclose(out["force_stress"], solid.stress_tensors(X)[0], rtol=0, atol=1e-12)
    disp = np.stack([out[f"displacement_{a}"] for a in "xyz"], axis=-1)
    assert np.allclose(disp, (ref.Phi[..., 1:, 0]) @ (F - np.eye(3)).T, rtol=0, atol=1e-13)


def test_identity_chart_outputs_and_weights_to_the_bit():
    """A reference that is the grid itself (θ₀_α = e_α exactly, R_ref = I; spacing 0.25 so that
    the chords are exact) gives the outputs, node weights and face loads of no reference, bit for bit."""
    solid = cartan.medium("cosserat-solid")
    grid = cartan.Grid((5, 3, 3), length=(1.0, 0.5, 0.5))
    rng = np.random.default_rng(1)
    base = solid.initial_state(grid, "undeformed")
    Phi = base.Phi.copy()
    Phi[..., 1:, 0] += 0.01 * rng.standard_normal((*grid.shape, 3))
    Phi[..., 1:, 1:] = SO3.exp(0.02 * rng.standard_normal((*grid.shape, 3)))
    end = {"u-end": cartan.Free(load=[0.1, 0.2, 0.0, 0.0, 0.0, 0.1])}
    plain = cartan.Problem(solid, grid, cartan.InitialState(Phi=Phi), boundaries=end)
    charted = cartan.Problem(solid, grid, cartan.InitialState(Phi=Phi), boundaries=end, reference=base.Phi)
    a, b = _outputs(plain), _outputs(charted)
    assert a.keys() == b.keys()
    for name in a:
        assert np.array_equal(a[name], b[name]), name
    sa, sb = Lattice(plain), Lattice(charted)
    assert np.array_equal(sa.weights, sb.weights)
    assert sb._end_factors == [None]
    P = rng.standard_normal((3, 3, 6))
    assert np.array_equal(sa.end_load_density(0, P), sb.end_load_density(0, P))


def test_face_traction_uses_the_reference_area():
    """A traction per unit reference area on the face u = L of an affine chart x_ref = A u adds
    up to P·|A e_v × A e_w|·L_v L_w (the face's reference area), exactly (the chart is affine)."""
    solid = cartan.medium("cosserat-solid")
    grid = cartan.Grid((3, 4, 3), length=(0.5, 0.75, 0.5))
    A = np.array([[1.3, 0.2, 0.0], [-0.1, 0.8, 0.3], [0.2, 0.0, 1.1]])
    ref = solid.initial_state(grid, "deformation", F=A)
    P = np.array([0.3, -0.1, 0.2, 0.05, 0.0, -0.02])
    problem = cartan.Problem(solid, grid, ref, boundaries={"u-end": cartan.Free(load=P, follower=True)},
                             reference=ref.Phi)
    sch = Lattice(problem)
    idx, _ = sch._end_loads[0]
    total = np.sum(sch.weights[idx][..., None] * sch.end_load_density(0, np.broadcast_to(P, (4, 3, 6))), axis=(0, 1))
    area = np.linalg.norm(np.cross(A[:, 1], A[:, 2])) * grid.length[1] * grid.length[2]
    assert np.allclose(total, P * area, rtol=1e-13, atol=0)
    # and the node masses are ρ det A times the chart's weights
    assert np.allclose(sch.weights, np.linalg.det(A) * grid.node_weights(), rtol=1e-13, atol=0)
    # the medium's area element is |θ₀_β × θ₀_γ| for random charts
    T = np.random.default_rng(2).standard_normal((5, 3, 3)) + 2 * np.eye(3)
    X0 = np.concatenate([T, np.zeros((5, 3, 3))], axis=-1)
    for axis, (b, c) in enumerate(((1, 2), (2, 0), (0, 1))):
        expected = np.linalg.norm(np.cross(T[:, b], T[:, c]), axis=-1)
        assert np.allclose(solid.reference_area(X0, axis), expected * np.sign(np.linalg.det(T)), rtol=1e-12)
    with pytest.raises(ValueError, match="axis must be 0, 1 or 2"):
        solid.reference_area(X0, 3)


def test_cylinder_kind_and_centre_support_load():
    """The ``cylinder`` initial kind is the slab of ``cylinder_torsion_problem`` (positions,
    frames, holonomies, reference), ``centre-support`` holds the problem's centre node, and
    both refuse bad input naming the parameter."""
    case = CylinderTorsion()
    solid = cartan.medium("cosserat-solid", **case.constants, output_stresses=False)
    tau = 2e-3
    grid, init = _cylinder(9, solid, twist=tau)
    support = solid.make_load("centre-support", stiffness=2.0, rotation_stiffness=1.0)
    problem = cartan.Problem(solid, grid, init, loads=[support])
    ref = cylinder_torsion_problem(1.0, 9, twist=tau, **case.constants)
    assert np.allclose(problem.initial.Phi, ref.initial.Phi, rtol=0, atol=1e-14)
    assert np.allclose(problem.reference.Phi, ref.reference.Phi, rtol=0, atol=1e-14)
    assert np.allclose(problem.initial.holonomy[2], ref.initial.holonomy[2], rtol=0, atol=1e-15)
    assert np.allclose(problem.reference.holonomy[2], ref.reference.holonomy[2], rtol=0, atol=1e-15)
    assert support.node == (4, 4, 1)
    assert np.array_equal(support.held, init.Phi[4, 4, 1])
    with pytest.raises(ValueError, match="centre-support"):
        solid.make_load("centre-support", stiffness=1.0)
    with pytest.raises(ValueError, match="rotation_stiffness must be > 0"):
        solid.make_load("centre-support", stiffness=1.0, rotation_stiffness=-1.0)
    with pytest.raises(ValueError, match="radius must be"):
        solid.initial_state(grid, "cylinder", radius=0.0)
    with pytest.raises(ValueError, match="must not be periodic"):
        solid.initial_state(cartan.Grid((4, 3, 3), periodic=(True, False, False)), "cylinder")


def test_cylinder_scene_loads():
    """The shipped scene builds the charted problem (reference from the initial kind)."""
    scene = cartan.scene("solid-cylinder-torsion")
    problem = scene.problem
    assert scene.mode == "static"
    assert problem.reference is not None and problem.grid.shape == (17, 17, 9)
    H = problem.initial.holonomy[2]
    assert SO3.log(H[1:, 1:])[2] == pytest.approx(0.05 * problem.grid.length[2], rel=1e-12)


@pytest.mark.slow
def test_torsion_mantle_is_traction_free():
    """The equilibrium of the twisted slab (n = 5, 9; τa = 10⁻³): the recorded nominal tensors
    give P N ≈ 0 and C N ≈ 0 on the mantle (N the reference's radial normal, the chart's four
    corner lines left out), relative to the largest stress there.  The boundary nodes' strains
    are one-sided edge averages (the strain half a cell inside), so the traction is O(h):
    measured 7.2e-2, 2.7e-2 (force) and 1.5e-1, 7.4e-2 (couple) at n = 5, 9, and the torque
    M/(GJτ) 1.432124 at n = 9 (the case's)."""
    case = CylinderTorsion()
    solid = cartan.medium("cosserat-solid", **case.constants)
    G = solid.shear_modulus
    errors = []
    for n in (5, 9):
        h = 2.0 / (n - 1)
        grid, init = _cylinder(n, solid, twist=1e-3)
        support = solid.make_load("centre-support", stiffness=G / h**2, rotation_stiffness=G)
        problem = cartan.Problem(solid, grid, init, loads=[support])
        eq = cartan.solve_static(problem, tol=1e-10)
        P, C = eq["nominal_force_stress"].values[-1], eq["nominal_couple_stress"].values[-1]
        mantle = np.zeros(grid.shape, dtype=bool)
        mantle[[0, -1]] = mantle[:, [0, -1]] = True
        mantle[[0, 0, -1, -1], [0, -1, 0, -1]] = False
        N = init.reference.Phi[..., 1:, 0] * np.array([1.0, 1.0, 0.0])
        N /= np.maximum(np.linalg.norm(N, axis=-1, keepdims=True), 1e-300)
        errors.append([np.max(np.abs(np.einsum("...ij,...j->...i", T, N)[mantle])) / np.max(np.abs(T[mantle]))
                       for T in (P, C)])
        if n == 9:
            ratio = torsion_stiffness(eq, problem) / (G * math.pi / 2)
            assert abs(ratio / case.exact()[1] - 1) < 4e-3  # the case's level 0 (2.5e-3 measured)
    force, couple = np.array(errors).T
    assert force[1] < 0.05 and couple[1] < 0.12
    assert force[1] < 0.6 * force[0] and couple[1] < 0.6 * couple[0]  # O(h): 1/2 at half the spacing


@pytest.mark.slow
def test_charted_dynamics_compiled_and_numpy_agree():
    """lie-verlet on the twisted charted slab moving rigidly: the compiled operators (which read
    the lattice's reference-volume weights) and the numpy path agree to round-off, the spatial
    momentum starts at ρΣ w_i det Θ₀ v and keeps its axial component (the screw holonomy's
    symmetry), and K + V drifts by O(Δt²) only (measured 7.6e-7 over 50 steps)."""
    solid = cartan.medium("cosserat-solid", output_stresses=False)
    v = np.array([0.3, -0.2, 0.5])
    grid, init = _cylinder(9, solid, twist=0.05, rigid_velocity=[*v, 0.0, 0.0, 0.0])
    problem = cartan.Problem(solid, grid, init)
    sch = Lattice(problem)
    assert sch.compiled_operators().ok
    settings = {"integrator": "lie-verlet", "scheme": "lattice", "dt": 0.01, "t_end": 0.5, "save_every": 10,
                "progress": False}
    fast = cartan.simulate(problem, **settings)
    slow = cartan.simulate(problem, compiled=False, **settings)
    assert np.max(np.abs(fast.position.values - slow.position.values)) < 1e-12
    p = fast.total_momentum.values
    mass = solid.rho * float(np.sum(sch.weights))
    assert np.allclose(p[0, :3], mass * v, rtol=1e-13, atol=0)
    assert np.allclose(p[:, 2], mass * v[2], rtol=1e-12, atol=0)
    E = fast.kinetic_energy.values + fast.potential_energy.values
    assert np.ptp(E) / E[0] < 1e-5


@pytest.mark.slow
def test_charted_collocation_compiled_and_numpy_agree():
    """lie-verlet on collocation over the twisted, open charted cylinder: the compiled operators
    (reference volumes w·J for the mass, chart weights for the energy, the internal force divided
    by J) and the numpy path agree to round-off (measured 1.3e-15), and K + V drifts by O(Δt²) only
    (measured 2.6e-6 of E over 50 steps; 1e-4 allows a 40× larger step error)."""
    from cartan.schemes.collocation import Collocation

    solid = cartan.medium("cosserat-solid", output_stresses=False)
    v = np.array([0.3, -0.2, 0.5])
    grid, init = _open_cylinder(9, solid, twist=0.05, rigid_velocity=[*v, 0.0, 0.0, 0.0])
    problem = cartan.Problem(solid, grid, init)
    assert Collocation(problem).compiled_operators().ok
    settings = {"integrator": "lie-verlet", "scheme": "collocation", "dt": 0.005, "t_end": 0.25, "save_every": 10,
                "progress": False}
    fast = cartan.simulate(problem, **settings)
    slow = cartan.simulate(problem, compiled=False, **settings)
    assert np.max(np.abs(fast.position.values - slow.position.values)) < 1e-12
    for name in ("kinetic_energy", "potential_energy"):
        assert np.allclose(fast[name].values, slow[name].values, rtol=1e-11, atol=1e-15), name
    E = fast.kinetic_energy.values + fast.potential_energy.values
    assert np.ptp(E) / E[0] < 1e-4
