"""Small media used by the core's tests (the core itself knows no medium)."""

from __future__ import annotations

import numpy as np
from numba import njit

import cartan
from cartan.grid import Grid
from cartan.medium import KernelMedium as _KernelMedium
from cartan.medium import Medium as _Medium
from cartan.medium import MediumKernels
from cartan.medium import QuadraticMedium as _Quadratic
from cartan.problem import Clamped, Damping, Free, InitialState, Problem, UniformForce


class QuadraticMedium(_Quadratic):
    """U = ½ Σ_k C_k (X_k − X0_k)², K = ½ Σ_k m_k N_k² on any group, d = 1."""

    name = "toy-quadratic"
    material_dim = 1

    def __init__(self, group="SE3", mass=None, stiffness=None, rest=None):
        self.group = cartan.group(group) if isinstance(group, str) else group
        r = self.group.dim
        self.space = None
        self.m = np.asarray(mass if mass is not None else np.linspace(1.0, 0.2, r), dtype=float)
        self.C = np.asarray(stiffness if stiffness is not None else np.linspace(10.0, 2.0, r), dtype=float)
        self.X0 = np.asarray(rest if rest is not None else np.eye(r)[0], dtype=float)
        self._set_energy(self.X0, self.C)

    def parameters(self):
        return {"group": self.group.name, "mass": self.m.tolist(), "stiffness": self.C.tolist(),
                "rest": self.X0.tolist()}

    def inertia(self):
        return self.m


def arc_problem(n=21, length=1.0, curvature=2.0, group="SE3", periodic=False, twist=0.0, velocity=None,
                **kw) -> Problem:
    """A rod bent into an arc (constant strain), optionally spinning."""
    medium = QuadraticMedium(group, **kw)
    G = medium.group
    grid = Grid(n, length, periodic=periodic)
    u = grid.coordinates(0)
    xi = np.zeros(G.dim)
    xi[0] = 1.0
    xi[-1] = curvature
    if G.dim >= 6:
        xi[3] = twist
    Phi = G.exp(u[:, None] * xi)
    N = None if velocity is None else np.broadcast_to(velocity, (n, G.dim)).copy()
    return Problem(medium, grid, InitialState(Phi=Phi, N=N))


class TorsionChain(_Medium):
    """A stiffening torsion chain on SO(2), d = 1: ``U = ½C D² + ¼β D⁴`` with ``D = X − X0``,
    ``K = ½ m N²``; provides the analytic static Jacobian.

    SO(2) is abelian (``dexp⁻¹ = 1``, ``Ad = 1``), so the lattice force on node i is
    ``F_i = Q(X_{i,i+1}) − Q(X_{i−1,i})`` with ``X_e = (θ_j − θ_i)/h`` and its Jacobian along
    ``θ_i ← θ_i + δ_i`` is the weighted graph Laplacian ``−Σ_e k_e (e_i − e_j)(e_i − e_j)ᵀ``,
    ``k_e = U''(X_e)/h = (C + 3βD_e²)/h``.  Loads of SO(2) that do not depend on the
    configuration (damping at N = 0, uniform forces in either frame, end moments, dead or
    follower, since Ad = 1) add nothing; any other load makes :meth:`static_jacobian` None.
    """

    name = "toy-torsion-chain"
    material_dim = 1

    def __init__(self, stiffness=2.0, cubic=0.0, rest=0.0, mass=1.0):
        self.group = cartan.group("SO2")
        self.space = None
        self.C, self.beta, self.X0, self.m = float(stiffness), float(cubic), float(rest), float(mass)

    def parameters(self):
        return {"stiffness": self.C, "cubic": self.beta, "rest": self.X0, "mass": self.m}

    def inertia(self):
        return np.array([self.m])

    def rest_strain(self):
        return np.array([[self.X0]])

    def potential(self, X):
        D = np.asarray(X, dtype=float)[..., 0, 0] - self.X0
        return 0.5 * self.C * D**2 + 0.25 * self.beta * D**4

    def stress(self, X):
        D = np.asarray(X, dtype=float) - self.X0
        return self.C * D + self.beta * D**3

    def static_jacobian(self, scheme, state, lam):
        import scipy.sparse as sp

        if scheme.name != "lattice" or any(not isinstance(ld, (Damping, UniformForce)) for ld in scheme.problem.loads):
            return None
        n, h = scheme.grid.shape[0], scheme.h[0]
        X = scheme.edge_strains(state)[0][:, 0]  # [edges]
        k = (self.C + 3.0 * self.beta * (X - self.X0) ** 2) / h
        tail = np.arange(len(k))
        head = (tail + 1) % n
        rows = np.concatenate([tail, head, tail, head])
        cols = np.concatenate([tail, head, head, tail])
        vals = np.concatenate([-k, -k, k, k])
        return sp.coo_matrix((vals, (rows, cols)), shape=(n, n)).tocsr()


def chain_problem(n=41, length=2.0, periodic=False, boundaries=None, loads=(), **kw) -> Problem:
    """A straight :class:`TorsionChain` (all angles zero)."""
    medium = TorsionChain(**kw)
    grid = Grid(n, length, periodic=periodic)
    Phi = medium.group.exp(np.zeros((n, 1)))
    return Problem(medium, grid, InitialState(Phi=Phi), dict(boundaries or {}), list(loads))


def moving_rod(planar: bool):
    """A Cosserat rod (SE(3)) or its planar restriction (SE(2)) with unequal stiffnesses and inertias."""
    rod = cartan.medium(
        "cosserat-rod", stretch_shear=[100.0, 50.0, 50.0], bend_twist=[1.0, 2.0, 2.0], mass=1.0,
        rotational_inertia=[0.02, 0.01, 0.01],
    )
    return rod.planar() if planar else rod


def rod_problem(kind: str, planar: bool = False, n: int = 11) -> Problem:
    """Rods bent into an arc and moving: clamped with a dead end load, clamped with a follower
    end load and a body-frame force, or a ring; damping and gravity on all of them."""
    rod = moving_rod(planar)
    r = rod.group.dim
    grid = Grid(n, length=1.0, periodic=kind == "ring")
    init = rod.initial_state(grid, "arc", curvature=2.0, velocity=np.linspace(0.1, 0.3, r))
    loads = [Damping(np.linspace(0.1, 0.2, r)), rod.make_load("gravity", g=[0.0, -9.81, 0.0][: 2 if planar else 3])]
    boundaries = {}
    if kind == "dead":
        boundaries = {"start": Clamped(), "end": Free(load=np.linspace(0.5, 1.0, r), follower=False)}
    elif kind == "follower":
        boundaries = {"start": Clamped(), "end": Free(load=np.linspace(0.5, 1.0, r), follower=True)}
        loads.append(UniformForce(np.linspace(-0.2, 0.3, r)))
    return Problem(rod, grid, init, boundaries, loads)


# ---------------------------------------------------------------------------- compiled vs reference
def rel_error(a, b) -> float:
    """max |a − b| over max |b| (the absolute difference when b is zero or empty)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    scale = float(np.max(np.abs(b))) if b.size else 0.0
    diff = float(np.max(np.abs(a - b))) if b.size else 0.0
    return diff / scale if scale > 0 else diff


def assert_close_states(a, b, tol: float) -> None:
    """Same time and step count; every state array and energy accumulator within ``tol``
    (relative to its magnitude)."""
    assert a.t == b.t
    assert set(a.arrays) == set(b.arrays)
    errors = {"S": rel_error(a.S, b.S)}
    errors.update({k: rel_error(a.arrays[k], b.arrays[k]) for k in b.arrays})
    for key in ("dissipated_energy", "external_work"):
        errors[key] = rel_error(a.scalars[key], b.scalars[key])
    assert max(errors.values()) <= tol, errors
    assert a.scalars["nstep"] == b.scalars["nstep"]


def advance_compiled(scheme, integrator, state, dt, nsteps) -> bool:
    """Steps on a compiled path, in :func:`cartan.simulate`'s order of preference: the
    scheme's hand-written loops (``compiled_advance``), then the integrator's generated loop
    over the scheme's operator set (``run_compiled_loop``); False when neither runs them."""
    fast = getattr(scheme, "compiled_advance", None)
    if fast is not None and fast(integrator, state, dt, nsteps):
        return True
    return integrator.run_compiled_loop(scheme, state, dt, nsteps)


def run_both(scheme_type, problem, make, dt, nsteps, blocks=(None,), **scheme_options):
    """The same steps on the Python path (``Integrator.step``) and, in ``blocks`` calls, on
    the compiled path (:func:`advance_compiled`) of a ``scheme_type`` scheme."""
    scheme = scheme_type(problem, **scheme_options)
    start = scheme.initial_state()
    start.scalars.setdefault("nstep", 0)
    ref, fast = start.copy(), start.copy()
    ref_integ, fast_integ = make(), make()
    for _ in range(nsteps):
        ref_integ.step(scheme, ref, dt)
    sizes = [nsteps] if blocks == (None,) else list(blocks)
    assert sum(sizes) == nsteps
    for size in sizes:
        assert advance_compiled(scheme, fast_integ, fast, dt, size)
    return scheme, (ref, ref_integ), (fast, fast_integ)


# ---------------------------------------------------------------------------- a coupled, non-quadratic medium
@njit(cache=True)
def coupled_quartic_energy(X, X0, p):  # pragma: no cover - compiled
    """``U = ½ DᵀCD + ¼β(DᵀD)²``, D = X − X₀ flattened, ``p = [β, C.ravel()]``."""
    d, r = X.shape
    quad = 0.0
    sq = 0.0
    col = 1
    for a in range(d):
        for k in range(r):
            da = X[a, k] - X0[a, k]
            sq += da * da
            s = 0.0
            for b in range(d):
                for j in range(r):
                    s += p[col] * (X[b, j] - X0[b, j])
                    col += 1
            quad += da * s
    return 0.5 * quad + 0.25 * p[0] * sq * sq


@njit(cache=True)
def coupled_quartic_stress(X, X0, p, Q):  # pragma: no cover - compiled
    """``Q = CD + β(DᵀD)D``."""
    d, r = X.shape
    sq = 0.0
    for a in range(d):
        for k in range(r):
            da = X[a, k] - X0[a, k]
            sq += da * da
    col = 1
    for a in range(d):
        for k in range(r):
            s = p[0] * sq * (X[a, k] - X0[a, k])
            for b in range(d):
                for j in range(r):
                    s += p[col] * (X[b, j] - X0[b, j])
                    col += 1
            Q[a, k] = s


class CoupledQuartic(_KernelMedium):
    """A non-quadratic medium whose energy couples the axes: ``U = ½DᵀCD + ¼β(DᵀD)²`` with
    ``D = X − X₀`` over all d·r strain components and a full symmetric positive definite C."""

    name = "toy-coupled-quartic"

    def __init__(self, group="SE3", d=2, beta=50.0, coupling=0.3, seed=0):
        self.group = cartan.group(group) if isinstance(group, str) else group
        self.space = None
        self.material_dim = d
        r = self.group.dim
        rng = np.random.default_rng(seed)
        B = rng.standard_normal((d * r, d * r))
        self.C = np.diag(np.linspace(4.0, 1.0, d * r)) + coupling * (B @ B.T) / (d * r)
        self.beta, self.coupling, self.seed = float(beta), float(coupling), int(seed)
        self.X0 = np.zeros((d, r))
        for a in range(min(d, r)):
            self.X0[a, a] = 1.0
        self.m = np.linspace(1.0, 0.5, r)

    def parameters(self):
        return {"group": self.group.name, "d": self.material_dim, "beta": self.beta, "coupling": self.coupling,
                "seed": self.seed}

    def inertia(self):
        return self.m

    def rest_strain(self):
        return self.X0.copy()

    def point_kernels(self):
        return MediumKernels(coupled_quartic_energy, coupled_quartic_stress,
                             np.concatenate([[self.beta], self.C.ravel()]))


class IndefiniteMetric(QuadraticMedium):
    """A quadratic rod whose kinetic metric is neither diagonal nor definite: on SO(1,3) the
    boost block has the opposite sign, ``M = diag(m ⊙ s) + ε(offset)``, and the stiffness has
    the same signs, so M⁻¹C is positive (oscillatory waves, an indefinite energy)."""

    name = "toy-indefinite-metric"

    def __init__(self, group="SO13", coupling=0.1):
        super().__init__(group)
        r = self.group.dim
        sign = np.where(np.arange(r) < r // 2, 1.0, -1.0)
        self.coupling = float(coupling)
        offset = np.zeros((r, r))
        for k in range(r - 1):
            offset[k, k + 1] = offset[k + 1, k] = coupling * sign[k] * (sign[k] == sign[k + 1])
        self.M = np.diag(self.m * sign) + offset
        self._set_energy(self.X0, self.C * sign)

    def parameters(self):
        return {"group": self.group.name, "coupling": self.coupling}

    def inertia(self):
        return np.diag(self.M).copy()

    def kinetic_metric(self):
        return self.M.copy()


@njit
def wave(t, u, X):  # pragma: no cover - compiled
    """A prescribed body velocity for ``kinematic``, on a grid of any dimension: a travelling
    wave plus a strain feedback, ``N_k = 0.3 sin(2u₀ + t + k) + 0.2 X₀ₖ`` (``u [*shape, d]``,
    ``X [*shape, d, r]`` → ``N [*shape, r]``).  The tests share this one function: each
    velocity function compiles its own generated loop."""
    r = X.shape[-1]
    uf = u.reshape(-1, u.shape[-1])
    Xf = X.reshape(uf.shape[0], -1, r)
    N = np.empty((uf.shape[0], r))
    for i in range(uf.shape[0]):
        for k in range(r):
            N[i, k] = 0.3 * np.sin(2.0 * uf[i, 0] + t + k) + 0.2 * Xf[i, 0, k]
    return N.reshape(u.shape[:-1] + (r,))


def params_of(item) -> dict:
    """The parameters of a collected test (empty when it has none), for the test modules'
    ``slow_when`` rules (tests/conftest.py)."""
    spec = getattr(item, "callspec", None)
    return dict(spec.params) if spec is not None else {}


def assert_volume_gradient(load, g, Phi, nodes, tol: float, eps: float = 1e-6) -> None:
    """``load.volume_and_gradient(Phi)``'s gradient against central differences of
    ``load.volume`` along ``Φ_i exp(±ε e_k)`` at ``nodes`` (every component k): truncation ε² and
    round-off ≈ 1e-16 V/ε, so ``tol`` (relative to the gradient's largest component) of 1e-8 is
    far above both and far below a wrong term."""
    _, G = load.volume_and_gradient(Phi)
    r = G.shape[-1]
    for i in nodes:
        for k in range(r):
            step = np.zeros(r)
            step[k] = eps
            plus, minus = Phi.copy(), Phi.copy()
            plus[i] = Phi[i] @ g.exp(step)
            minus[i] = Phi[i] @ g.exp(-step)
            fd = (load.volume(plus) - load.volume(minus)) / (2 * eps)
            assert abs(fd - G[i][k]) <= tol * np.abs(G).max(), (i, k)


def check_move_and_frames_passes(frames_pass, move_pass, inverse, compose, Dn, G, Phi, seed: int) -> None:
    """Assert that a group's frame and edge-update passes equal the products of its point
    kernels bit for bit: ``frames_pass(Dn, Di, Phi, 0, n)`` gives ``Di = Dn⁻¹`` and
    ``Phi ← Phi·Dn``, ``move_pass(Di, Dn, G, tail, head, 0, E)`` gives
    ``G_e ← Dn_tail⁻¹ G_e Dn_head`` (random ends drawn with ``seed``)."""
    n, E, m = Dn.shape[0], G.shape[0], Dn.shape[-1]
    rng = np.random.default_rng(seed)
    tail, head = rng.integers(0, n, E), rng.integers(0, n, E)
    Di = np.empty_like(Dn)
    Phi2, G2 = Phi.copy(), G.copy()
    frames_pass(Dn, Di, Phi2, 0, n)
    move_pass(Di, Dn, G2, tail, head, 0, E)
    inv, tmp, ref = np.empty((m, m)), np.empty((m, m)), np.empty((m, m))
    for i in range(n):
        inverse(Dn[i], inv)
        assert np.array_equal(Di[i], inv)
        compose(Phi[i], Dn[i], ref)
        assert np.array_equal(Phi2[i], ref)
    for e in range(E):
        inverse(Dn[tail[e]], inv)
        compose(inv, G[e], tmp)
        compose(tmp, Dn[head[e]], ref)
        assert np.array_equal(G2[e], ref)


# ---------------------------------------------------------------------------- held components, compiled
def held_rod():
    """The stiff SE(3) rod of the held-components tests (tests/test_held_compiled.py,
    tests/test_collocation_held_compiled.py)."""
    return cartan.medium("cosserat-rod", E=1e6, G=1e4, radius=0.25, density=5000.0)


def pinned_rod(end_load=(0.0, 0.0, 0.0, 0.0, 0.0, 10.0)) -> Problem:
    """A 9-node arc pinned at its start (translations held) under a follower end load, damped."""
    from cartan.problem import Held

    rod = held_rod()
    grid = Grid(9, length=1.0)
    init = rod.initial_state(grid, "arc", curvature=1.0)
    ends = {"start": Held(components=(0, 1, 2)), "end": Free(load=list(end_load), follower=True)}
    return Problem(rod, grid, init, ends, [Damping([0.1] * 6)])


def mirrored_rod() -> Problem:
    """A 9-node arc clamped at its start with a symmetry end (the plane through the end ⊥ its tangent)."""
    from cartan.problem import Symmetry

    rod = held_rod()
    grid = Grid(9, length=1.0)
    return Problem(rod, grid, rod.initial_state(grid, "arc", curvature=1.0), {"start": Clamped(), "end": Symmetry()},
                   [UniformForce([0.0, 200.0, -500.0, 0.0, 0.0, 0.0])])


def run_both_held(scheme_type, problem, make, dt: float, nsteps: int):
    """The scheme, the start, the Python run and the compiled run (blocks 1, 2, nsteps − 3, stepped
    frames) of ``make()``'s integrator on a problem with held components, and that compiled run's
    integrator; asserts the operator set holds some components and not all of a node."""
    scheme, (ref, _), (fast, fi) = run_both(scheme_type, problem, make, dt, nsteps, (1, 2, nsteps - 3),
                                            track_frames=True)
    ops = scheme.compiled_operators()
    assert ops.ok, ops.reason
    assert ops.data.any_held  # some node holds some components and not all
    start = scheme.initial_state()
    start.scalars.setdefault("nstep", 0)
    assert fast.scalars["nstep"] == ref.scalars["nstep"] == nsteps
    return scheme, start, ref, fast, fi


def assert_agree_and_held(scheme, start, ref, fast, bound: float, tol: float, moved: float,
                          momentum: bool = True) -> None:
    """Compiled against Python: the momenta within ``bound``, the other arrays within ``tol``
    relative; the run moved the frames by more than ``moved`` (not two copies of the start); the
    held components zero in both (``momentum``: the free ones not)."""
    assert fast.t == ref.t
    assert rel_error(ref.arrays["Phi"], start.arrays["Phi"]) > moved
    assert float(np.max(np.abs(fast.S - ref.S))) <= bound
    errors = {k: rel_error(fast.arrays[k], ref.arrays[k]) for k in ref.arrays}
    assert max(errors.values()) <= tol, errors
    held = np.broadcast_to(scheme._clamped, fast.S.shape)
    for state in (ref, fast):
        assert np.all(state.S[held] == 0.0)
        assert np.all(scheme.velocity(state)[held] == 0.0)
        assert np.any(state.S[~held] != 0.0) or not momentum


def assert_kinetic_of_held(scheme, state) -> None:
    """The kinetic energy of partly held nodes (``op_kinetic``) as ``Scheme.kinetic_energy`` takes
    it: a sum of a few tens of positive terms, to 1e-14 relative."""
    ops = scheme.compiled_operators()
    S = np.ascontiguousarray(state.S.reshape(ops.nodes, -1))
    K = scheme.kinetic_energy(state)
    assert K > 0 and abs(ops.generated().op_kinetic(ops.data, S) - K) <= 1e-14 * K


def assert_rows_follow_the_drift(scheme, state, seed: int, rate_tol: float, second_tol: float) -> None:
    """``rattle``'s rows on ``scheme`` at ``state``: ``B_c δ`` and ``Ḃ_c``-rate ``rows_rate`` against
    central differences of the rows along the exact drift of a random δ (ε = 1e-4: truncation
    O(ε²) relative), within ``rate_tol`` and ``second_tol`` of the largest entry."""
    from cartan.integrators import Rattle

    integ = Rattle()
    integ.reset()
    con, unknown, _, _ = integ._constraints(scheme, state)
    rng = np.random.default_rng(seed)
    delta = np.where(unknown, rng.standard_normal(unknown.shape), 0.0)
    eps = 1e-4
    vals = []
    for s in (1.0, -1.0, 0.0):
        moved = state.copy()
        scheme.drift(moved, s * eps, delta, exact=True)
        vals.append(con.values(moved))
    rate = (vals[0] - vals[1]) / (2 * eps)
    second = (vals[0] - 2 * vals[2] + vals[1]) / eps**2
    assert np.max(np.abs(con.matrix(state) @ delta[unknown] - rate)) < rate_tol * np.max(np.abs(rate))
    assert np.max(np.abs(con.rows_rate(state, delta) - second)) < second_tol * np.max(np.abs(second))


def assert_pin_holds(scheme, start, states) -> None:
    """The pinned start of :func:`pinned_rod` keeps its position exactly (its translation components
    never move) while its frame turns."""
    for state in states:
        Phi = scheme.frames(state)
        assert np.array_equal(Phi[0, :, 0], start.arrays["Phi"][0, :, 0])
        assert not np.array_equal(Phi[0, 1:, 1:], start.arrays["Phi"][0, 1:, 1:])


def assert_symmetry_end_slides(scheme, start, states, slide: float) -> None:
    """The symmetry end of :func:`mirrored_rod` slides in its plane (normal n, the end's initial
    tangent) by more than ``slide`` and its frame turns about n only, both to round-off of the O(1)
    frames (the updates R ← R exp(τω^) with ω ∥ e₀ keep R e₀ and n·x in exact arithmetic)."""
    end = start.arrays["Phi"][-1]
    n = end[1:, 1]
    for state in states:
        Phi = scheme.frames(state)[-1]
        assert abs(n @ (Phi[1:, 0] - end[1:, 0])) <= 1e-14
        assert np.max(np.abs(Phi[1:, 1] - n)) <= 1e-14
        assert np.max(np.abs(Phi[1:, 0] - end[1:, 0])) > slide


#: a planar pin: the position and the out-of-plane rotations held, Ω₃ (about e₃ = z) free
PLANAR_PIN = (0, 1, 2, 3, 4)


def pinned_arc(pin=PLANAR_PIN, n: int = 11, end=None) -> Problem:
    """A filament arc of curvature 1.5 in the x–y plane (L = 1, symmetric about x = 0) pinned at
    both ends (``pin`` held; ``end`` replaces the pin at s = L), released from rest under gravity
    −2e_y: not an equilibrium (the straight rest shape pushes the pins apart), it oscillates in its
    plane (tests/test_rattle_held.py, tests/test_collocation_rattle_reactions.py)."""
    from cartan.problem import Held

    fil = cartan.medium("filament", bending=1.0, twist=1.0, mass=1.0, rotational_inertia=0.05)
    grid = Grid(n, length=1.0)
    return Problem(fil, grid, fil.initial_state(grid, "arc", curvature=1.5, centered=True),
                   {"start": Held(pin), "end": end or Held(pin)}, loads=[fil.make_load("gravity", g=[0.0, -2.0, 0.0])])


def frames_of(ds, k: int = -1) -> np.ndarray:
    """The SE(3) frames Φ ``[*shape, 4, 4]`` of frame ``k`` of a rod's Dataset (``position``, ``frame``)."""
    pos, E = ds.position.values[k], ds.frame.values[k]
    Phi = np.zeros((*pos.shape[:-1], 4, 4))
    Phi[..., 0, 0] = 1.0
    Phi[..., 1:, 0], Phi[..., 1:, 1:] = pos, E
    return Phi


def elastic_string(kind: str, n: int = 9, clocks: bool = False, law: dict | None = None) -> Problem:
    """The elastic relativistic string (``law``: the medium's law keywords, default the quadratic
    law with k = 0.25): ``free`` (stretched, bent, moving in 3-D), ``clamped`` (the same, held at
    its start) or ``ring`` (a closed string, spinning and breathing)."""
    import math

    rod = cartan.medium("relativistic-rod", energy="elastic", clocks=clocks, **(law or {"stiffness": 0.25}))
    if kind == "ring":
        grid = Grid(n, length=2 * math.pi, periodic=True)
        return Problem(rod, grid, rod.initial_state(grid, "ring", radius=1.1, spin=0.3, radial_speed=0.1))
    grid = Grid(n, length=1.0)
    u = grid.coordinates(0)
    x = np.stack([1.1 * u, 0.05 * np.sin(np.pi * u), 0.02 * u * u], -1)
    v = np.stack([0.2 * np.cos(np.pi * u), 0.3 * np.sin(2 * np.pi * u), 0.1 * u], -1)
    if kind == "free":
        return Problem(rod, grid, rod.state_from(x, v))
    v[0] = 0.0
    return Problem(rod, grid, rod.state_from(x, v), boundaries={"start": Clamped()})
