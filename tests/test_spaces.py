"""Homogeneous spaces: lifts, gauges, the action, validation and registration."""

from __future__ import annotations

import importlib.metadata as md

import numpy as np
import pytest

from cartan import plugins, spaces
from cartan.spaces import (
    Euclidean3,
    FrameBundleE2,
    FrameBundleE3,
    HomogeneousSpace,
    MinkowskiFrameBundle,
    PointDirector,
    Sphere,
    SphereFrameBundle,
)

TOL = 1e-13

SPACES = {
    "S1": lambda: Sphere(n=1),
    "S2": lambda: Sphere(),
    "S2-r3.5": lambda: Sphere(n=2, radius=3.5),
    "S3": lambda: Sphere(n=3),
    "S5-r0.5": lambda: Sphere(n=5, radius=0.5),
    "E3": Euclidean3,
    "E3xS2": PointDirector,
    "frame-E3": FrameBundleE3,
    "frame-E2": FrameBundleE2,
    "frame-S2": lambda: SphereFrameBundle(radius=2.0),
    "frame-M13": MinkowskiFrameBundle,
}


@pytest.fixture(params=list(SPACES), scope="module")
def space(request) -> HomogeneousSpace:
    return SPACES[request.param]()


def _points(space, shape, seed):
    """Random points: uniform directions on spheres, group orbits of q_r otherwise."""
    rng = np.random.default_rng(seed)
    if isinstance(space, Sphere):
        v = rng.standard_normal((*shape, space.n + 1))
        return space.radius * v / np.linalg.norm(v, axis=-1, keepdims=True)
    if isinstance(space, PointDirector):
        x = 3.0 * rng.standard_normal((*shape, 3))
        p = rng.standard_normal((*shape, 3))
        return np.concatenate([x, p / np.linalg.norm(p, axis=-1, keepdims=True)], axis=-1)
    scale = 0.4 if isinstance(space, MinkowskiFrameBundle) else 1.0
    return space.sample(shape, rng=rng, scale=scale)


def _elements(space, shape, seed, scale=0.5):
    rng = np.random.default_rng(seed)
    return space.group.exp(scale * rng.standard_normal((*shape, space.group.dim)))


def _gauges(space, shape, seed, scale=0.5):
    rng = np.random.default_rng(seed)
    return scale * rng.standard_normal((*shape, space.gauge_dim))


def _close(a, b, tol=TOL):
    a, b = np.broadcast_arrays(np.asarray(a, float), np.asarray(b, float))
    err = float(np.max(np.abs(a - b))) if a.size else 0.0
    assert err <= tol, f"max deviation {err:.3g} > {tol:g}"


# ---------------------------------------------------------------------- the contract
def test_attributes(space):
    r, m = space.group.dim, space.group.matrix_size
    assert 1 <= space.dim <= r
    assert space.gauge_dim == r - space.dim
    q_r = space.q_r
    assert q_r.shape == space.point_shape and q_r.dtype == np.float64
    q_r[...] = 7.0  # a copy: the reference point cannot be corrupted
    assert space.contains(space.q_r)
    assert space.defect(space.q_r) <= TOL
    assert space.stabiliser_basis().shape == (space.gauge_dim, r)
    _close(space.lift(space.q_r), np.eye(m))
    assert isinstance(type(space).name, str) and type(space).name


def test_lift_reproduces_points(space):
    q = _points(space, (7, 3), seed=1)
    phi = space.lift(q)
    assert phi.shape == (7, 3, space.group.matrix_size, space.group.matrix_size)
    _close(space.act(phi, space.q_r), q)
    assert np.max(space.group.defect(phi)) <= TOL


def test_lift_with_gauge(space):
    q = _points(space, (6,), seed=2)
    gauge = _gauges(space, (6,), seed=3)
    phi0 = space.lift(q)
    phi = space.lift(q, gauge)
    _close(space.act(phi, space.q_r), q)
    assert np.max(space.group.defect(phi)) <= TOL
    h = space.group.exp(gauge @ space.stabiliser_basis())
    _close(phi, space.group.compose(phi0, h), 1e-12)
    if space.gauge_dim:
        assert np.min(np.linalg.norm(phi - phi0, axis=(-2, -1))) > 1e-3  # the gauge changes Φ ...
    _close(space.lift(q, np.zeros(space.gauge_dim)), phi0)  # ... and zero gauge is the section


def test_gauge_broadcasts_to_points(space):
    q = _points(space, (4, 2), seed=4)
    g = _gauges(space, (), seed=5)
    _close(space.lift(q, g), space.lift(q, np.broadcast_to(g, (4, 2, space.gauge_dim))))
    with pytest.raises(ValueError, match="gauge"):
        space.lift(q[0, 0], np.zeros((3, space.gauge_dim)))  # would add a batch axis
    with pytest.raises(ValueError, match="gauge"):
        space.lift(q, np.zeros(space.gauge_dim + 1))


def test_stabiliser_fixes_reference(space):
    H = space.stabiliser_basis()
    q_r = space.q_r
    for t in (0.3, -1.7, 3.0):
        _close(space.act(space.group.exp(t * H), q_r), np.broadcast_to(q_r, (len(H), *q_r.shape)))
    _close(space.infinitesimal_action(H, q_r), 0.0)
    if len(H):
        assert np.linalg.matrix_rank(H) == space.gauge_dim
    # infinitesimal transitivity: the orbit map at q_r has rank n
    J = space.infinitesimal_action(np.eye(space.group.dim), q_r).reshape(space.group.dim, -1)
    assert np.linalg.matrix_rank(J, tol=1e-10) == space.dim


def test_action_is_a_group_action(space):
    q = _points(space, (5,), seed=6)
    g = _elements(space, (5,), seed=7)
    h = _elements(space, (5,), seed=8)
    _close(space.act(g, space.act(h, q)), space.act(space.group.compose(g, h), q), 1e-12)
    _close(space.act(space.group.identity(), q), q)
    _close(space.act(space.group.inverse(g), space.act(g, q)), q, 1e-12)
    moved = space.act(g, q)
    assert np.max(space.defect(moved)) <= 1e-12


def test_transitivity(space):
    q1 = _points(space, (8,), seed=9)
    q2 = _points(space, (8,), seed=10)
    g = space.group.compose(space.lift(q2), space.group.inverse(space.lift(q1)))
    _close(space.act(g, q1), q2, 1e-12)


def test_act_broadcasts(space):
    q = _points(space, (3, 4), seed=11)
    g = _elements(space, (), seed=12)
    out = space.act(g, q)
    assert out.shape == q.shape
    _close(out[1, 2], space.act(g, q[1, 2]))
    gs = _elements(space, (3, 1), seed=13)
    assert space.act(gs, q).shape == q.shape


def test_infinitesimal_action_is_derivative(space):
    q = _points(space, (4,), seed=14)
    xi = np.random.default_rng(15).standard_normal((4, space.group.dim))
    eps = 1e-6
    fd = (space.act(space.group.exp(eps * xi), q) - space.act(space.group.exp(-eps * xi), q)) / (2 * eps)
    _close(space.infinitesimal_action(xi, q), fd, 1e-7)


def test_jacobian_and_pullback(space):
    q = _points(space, (3,), seed=16)
    phi = space.lift(q, _gauges(space, (3,), seed=17))
    J = space.jacobian(phi)
    r = space.group.dim
    assert J.shape == (3, r, *space.point_shape)
    eps = 1e-6
    for i in range(r):
        e = eps * np.eye(r)[i]
        plus = space.act(space.group.compose(phi, space.group.exp(e)), space.q_r)
        minus = space.act(space.group.compose(phi, space.group.exp(-e)), space.q_r)
        _close(J[:, i], (plus - minus) / (2 * eps), 1e-7)
    f = np.random.default_rng(18).standard_normal((3, *space.point_shape))
    k = len(space.point_shape)
    expected = np.sum(J * f[:, None], axis=tuple(range(-k, 0)))
    _close(space.pullback(phi, f), expected)


def test_project(space):
    q = _points(space, (5,), seed=19)
    _close(space.project(q), q, 1e-12)
    noisy = q + 1e-5 * np.random.default_rng(20).standard_normal(q.shape)
    p = space.project(noisy)
    assert np.max(space.defect(p)) <= 1e-12
    _close(p, q, 1e-3)


def test_sample_shapes(space):
    assert space.sample(rng=0).shape == space.point_shape
    assert space.sample(4, rng=0).shape == (4, *space.point_shape)
    assert space.sample((2, 3), rng=0).shape == (2, 3, *space.point_shape)
    _close(space.sample((2, 3), rng=5), space.sample((2, 3), rng=5), 0.0)


def test_shape_errors_name_the_argument(space):
    m = space.group.matrix_size
    q = space.q_r
    bad_q = np.zeros((*space.point_shape[:-1], space.point_shape[-1] + 1))
    with pytest.raises(ValueError, match=r"^q must have shape"):
        space.act(np.eye(m), bad_q)
    with pytest.raises(ValueError, match=r"^g must have shape"):
        space.act(np.eye(m + 1), q)
    with pytest.raises(ValueError, match=r"^q must have shape"):
        space.lift(bad_q)
    with pytest.raises(ValueError, match=r"^points must have shape"):
        space.validate(bad_q, "points")
    with pytest.raises(ValueError, match="non-finite"):
        space.lift(np.full(space.point_shape, np.nan))
    with pytest.raises(ValueError, match=r"^Phi must have shape"):
        space.jacobian(np.eye(m + 1))


def test_equality_and_repr(space):
    twin = type(space)(**space._params())
    assert twin == space and hash(twin) == hash(space)
    assert repr(space).startswith(type(space).__name__ + "(")
    assert space != object()


# ---------------------------------------------------------------------- spheres
@pytest.mark.parametrize("n", [1, 2, 3, 4])
@pytest.mark.parametrize("radius", [1.0, 0.25])
def test_sphere_near_and_at_the_antipode(n, radius):
    S = Sphere(n=n, radius=radius)
    rng = np.random.default_rng(n)
    pts = [-S.q_r, S.q_r]
    for eps in (1e-2, 1e-8, 1e-12, 1e-17, 1e-200, 1e-320):
        for sign in (-1.0, 1.0):
            v = np.zeros(n + 1)
            v[:-1] = eps * rng.standard_normal(n)
            v[-1] = sign
            pts.append(radius * v / np.linalg.norm(v))
    q = np.array(pts)
    phi = S.lift(q)
    assert np.all(np.isfinite(phi))
    _close(S.act(phi, S.q_r), q)
    assert np.max(S.group.defect(phi)) <= TOL
    antipode = np.eye(n + 1)
    antipode[0, 0] = antipode[-1, -1] = -1.0  # the fixed rotation by π in the (e1, e_{n+1}) plane
    _close(phi[0], antipode, 0.0)
    _close(phi[1], np.eye(n + 1), 0.0)
    if S.gauge_dim:
        g = _gauges(S, (len(q),), seed=3)
        phig = S.lift(q, g)
        _close(S.act(phig, S.q_r), q)
        assert np.max(S.group.defect(phig)) <= TOL


def test_sphere_section_is_the_geodesic_rotation():
    S = Sphere(n=2)
    q = _points(S, (20,), seed=21)
    q = q[q[:, 2] > -0.99]  # stay inside the injectivity radius of log
    xi = S.group.log(S.lift(q))
    _close(xi @ S.stabiliser_basis().T, 0.0, 1e-12)  # no stabiliser (spin) component
    _close(np.linalg.norm(xi, axis=-1), np.arccos(q[:, 2]), 1e-12)  # angle = geodesic distance


def test_sphere_reference_point_and_stabiliser():
    S = Sphere(n=3, radius=2.0)
    _close(S.q_r, [0, 0, 0, 2.0], 0.0)
    assert S.gauge_dim == 3 and S.group.dim == 6
    h = S.group.hat(S.stabiliser_basis())
    _close(h[:, -1, :], 0.0, 0.0)
    _close(h[:, :, -1], 0.0, 0.0)
    assert Sphere(n=1).gauge_dim == 0


@pytest.mark.parametrize("n", [2, 3, 4, 5])
def test_sphere_stabiliser_is_the_tail_of_the_algebra(n):
    S = Sphere(n=n)
    r = S.group.dim
    _close(S.stabiliser_basis(), np.eye(r)[n:], 0.0)


def test_sphere_pullback_matches_paper_example():
    """Paper §IV.B: U = a pˢ·p on S² gives T = a Rᵀ(p × pˢ) (with f = −∂U/∂q)."""
    S = Sphere()
    a = 1.7
    p = S.q_r
    q = _points(S, (5,), seed=22)
    R = S.lift(q, _gauges(S, (5,), seed=23))
    T = S.pullback(R, -a * np.broadcast_to(p, q.shape))
    expected = a * np.einsum("...ji,...j->...i", R, np.cross(p, q))
    _close(T, expected, 1e-12)


def test_sphere_validation():
    S = Sphere(n=2, radius=2.0)
    with pytest.raises(ValueError, match=r"^q is not on Sphere"):
        S.lift([0.0, 0.0, 1.0])  # unit vector, radius 2
    assert S.lift([0.0, 0.0, 2.0 * (1 + 1e-10)]).shape == (3, 3)  # within tol
    with pytest.raises(ValueError, match="zero"):
        S.project(np.zeros(3))
    assert not S.contains([0.0, 0.0, 1.0]) and S.contains([0.0, 2.0, 0.0])
    for bad in (0, -1, 1.5, True, "2", None):
        with pytest.raises(ValueError, match=r"^n .* integer ≥ 1"):
            Sphere(n=bad)
    for bad in (0, -1.0, np.nan, np.inf, "1", True):
        with pytest.raises(ValueError, match=r"^radius must be .* > 0"):
            Sphere(radius=bad)
    assert Sphere(n=np.int64(3)).n == 3


# ---------------------------------------------------------------------- E3 and E3 × S2
def test_euclidean_lift_and_rotation_keyword():
    E = Euclidean3()
    x = _points(E, (4,), seed=24)
    w = _gauges(E, (4,), seed=25)
    phi = E.lift(x, w)
    _close(phi[:, 1:, 0], x, 0.0)
    _close(phi[:, 0], np.broadcast_to([1.0, 0, 0, 0], (4, 4)), 0.0)
    R = phi[:, 1:, 1:]
    _close(E.lift(x, rotation=R), phi, 0.0)
    _close(E.lift(x), np.broadcast_to(np.eye(4), (4, 4, 4)) + np.pad(x[:, :, None], ((0, 0), (1, 0), (0, 3))))
    with pytest.raises(ValueError, match="not both"):
        E.lift(x, w, rotation=R)
    with pytest.raises(ValueError, match="^rotation must hold proper rotation"):
        E.lift(x, rotation=np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ValueError, match="^rotation must have shape"):
        E.lift(x, rotation=np.eye(4))
    with pytest.raises(ValueError, match="rotation batch shape"):
        E.lift(x[0], rotation=R)


def test_point_director_drill_gauge():
    P = PointDirector()
    q = _points(P, (6,), seed=26)
    phi0 = P.lift(q)
    _close(phi0[:, 1:, 3], q[:, 3:])  # third frame vector is the director
    _close(phi0[:, 1:, 0], q[:, :3], 0.0)
    theta = np.linspace(-3.0, 3.0, 6)
    phi = P.lift(q, theta[:, None])
    c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
    e1, e2 = phi0[:, 1:, 1], phi0[:, 1:, 2]
    _close(phi[:, 1:, 1], c * e1 + s * e2, 1e-12)  # e1 turned by θ about p (right-handed)
    _close(phi[:, 1:, 3], q[:, 3:], 1e-12)
    _close(P.position(q), q[:, :3], 0.0)
    _close(P.director(q), q[:, 3:], 0.0)
    with pytest.raises(ValueError, match=r"^q is not on PointDirector.*director length"):
        P.lift([0.0, 0.0, 0.0, 0.0, 0.0, 1.1])
    down = P.lift([1.0, 2.0, 3.0, 0.0, 0.0, -1.0])
    _close(down[1:, 1:], np.diag([-1.0, 1.0, -1.0]), 0.0)


# ---------------------------------------------------------------------- frame bundles
def test_frame_bundles_lift_is_identity_map():
    for space in (FrameBundleE3(), FrameBundleE2(), SphereFrameBundle(radius=3.0), MinkowskiFrameBundle()):
        q = _points(space, (4,), seed=27)
        _close(space.lift(q), q, 0.0)
        assert space.gauge_dim == 0
        _close(space.q_r, np.eye(space.group.matrix_size), 0.0)
        with pytest.raises(ValueError, match=r"^gauge must have shape \[\.\.\., 0\]"):
            space.lift(q, np.zeros(1))


def test_frame_bundle_helpers():
    F = FrameBundleE3()
    q = _points(F, (3,), seed=28)
    _close(F.position(q), q[:, 1:, 0], 0.0)
    _close(F.frame(q), q[:, 1:, 1:], 0.0)
    S = SphereFrameBundle(radius=2.5)
    R = _points(S, (5,), seed=29)
    _close(S.centreline(R), 2.5 * R[:, :, 2], 0.0)
    _close(S.centreline(S.q_r), [0.0, 0.0, 2.5], 0.0)
    _close(np.linalg.norm(S.centreline(R), axis=-1), 2.5, 1e-13)


def test_frame_bundle_validation():
    F = FrameBundleE3()
    reflect = np.diag([1.0, 1.0, 1.0, -1.0])
    with pytest.raises(ValueError, match=r"^q is not on FrameBundleE3"):
        F.lift(reflect)
    shifted = np.eye(4)
    shifted[0, 1] = 0.5
    with pytest.raises(ValueError, match=r"^q is not on FrameBundleE3"):
        F.lift(shifted)
    S = SphereFrameBundle()
    with pytest.raises(ValueError, match=r"^q is not on SphereFrameBundle"):
        S.lift(2.0 * np.eye(3))
    with pytest.raises(ValueError, match=r"^R must have shape"):
        S.centreline(np.eye(4))
    for bad in (0.0, -2.0, np.nan, "x"):
        with pytest.raises(ValueError, match=r"^radius must be .* > 0"):
            SphereFrameBundle(radius=bad)
    M = MinkowskiFrameBundle()
    flip = np.diag([1.0, -1.0, -1.0, 1.0, 1.0])  # time reversal × parity: det 1, not orthochronous
    assert not M.contains(flip)
    with pytest.raises(ValueError, match=r"^q is not on MinkowskiFrameBundle"):
        M.lift(flip)
    euclid = np.eye(5)
    euclid[1, 2] = euclid[2, 1] = 0.5  # symmetric, not η-orthogonal
    with pytest.raises(ValueError, match=r"^q is not on MinkowskiFrameBundle"):
        M.lift(euclid)


def test_minkowski_frames_preserve_the_metric():
    M = MinkowskiFrameBundle()
    q = _points(M, (6,), seed=30)
    E = q[:, 1:, 1:]
    eta = np.diag([-1.0, 1.0, 1.0, 1.0])
    _close(np.swapaxes(E, -1, -2) @ eta @ E, np.broadcast_to(eta, E.shape), 1e-12)
    assert np.all(E[:, 0, 0] >= 1.0 - 1e-12)


# ---------------------------------------------------------------------- registration
def test_registered_through_the_hook(monkeypatch):
    monkeypatch.setattr(plugins, "_registry", None)
    reg = plugins.reset_registry([("builtin-spaces", spaces)], entry_points=False)
    table = {name: entry.obj for name, entry in reg.table("spaces").items()}
    assert table == {
        "sphere": Sphere,
        "E3": Euclidean3,
        "E3xS2": PointDirector,
        "frame-E3": FrameBundleE3,
        "frame-E2": FrameBundleE2,
        "frame-S2": SphereFrameBundle,
        "frame-M13": MinkowskiFrameBundle,
    }
    for name, cls in table.items():
        assert cls.name == name


def test_spaces_by_registry_name():
    import cartan

    assert cartan.space("sphere", n=4, radius=2.0) == Sphere(n=4, radius=2.0)
    assert cartan.space("frame-S2") == SphereFrameBundle()
    assert isinstance(cartan.space("frame-M13"), MinkowskiFrameBundle)
    assert set(cartan.registry("spaces")) >= {"sphere", "E3", "E3xS2", "frame-E3", "frame-S2", "frame-M13"}


def test_entry_point_declared():
    eps = {ep.name: ep.value for ep in md.entry_points(group="cartan")}
    assert eps.get("spaces") == "cartan.spaces"
