"""Acceptance checks of `relativistic-rod` and `filament` against closed forms that no registered
case covers (docs/media/relativistic-rod.md §8 and docs/media/filament.md, "Further checks").

Relativistic string (c = μ = 1; the Nambu–Goto runs take ``clocks=True``, which keeps them on
the numpy path, so that the fast suite compiles no Poincaré loop): a finite-amplitude
travelling wave on a Nambu–Goto string, the rigidly rotating rod and the Regge relation, a
Kibble–Turok loop boosted in its plane (the run against the Lorentz transform of the exact
worldsheet, the 4-momentum and the Lorentz charges as tensors), long-run Poincaré charges and
group membership (slow), and the transverse and longitudinal wave speeds of the elastic string
against docs §2 ("General ε(λ)").

Filament: a helix as an exact Kirchhoff equilibrium (its axial force in closed form), the
cantilever elastica at large loads α = 20, 50 (quadratures of the first integral), and the
Greenhill twist-buckling moment of the clamped–clamped rod (slow).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

import cartan

pytestmark = pytest.mark.filterwarnings("ignore::cartan.StabilityWarning")


def _order(e1: float, e2: float) -> float:
    return math.log2(e1 / e2)


def _lab(ds, frame: int = -1) -> np.ndarray:
    return np.stack([ds.lab_x.values[frame], ds.lab_y.values[frame], ds.lab_z.values[frame]], axis=-1)


# ============================================================================ Nambu–Goto string
def _travelling_wave(n: int, cfl: float, theta0: float = 1.0, length: float = 1.0) -> float:
    """Left mover only, x = ½[a(σ − t) + (σ + t)e₁] with a′ = (cos θ, sin θ, 0), θ = θ₀ cos(2πs/L):
    the lab curve translates rigidly at c along e₁ whatever θ₀ (largest point speed sin(θ₀/2))."""
    from cartan_relativistic.limit import tilt_curve
    from scipy.special import jv

    med = cartan.medium("relativistic-rod", clocks=True)  # numpy path: no loop to compile
    grid = cartan.Grid(n, length=length, periodic=True)
    s = grid.coordinates(0)
    e1 = np.array([1.0, 0.0, 0.0])

    def exact(t: float) -> tuple[np.ndarray, np.ndarray]:
        a, da = tilt_curve(s - t, theta0, length)
        return 0.5 * a + 0.5 * (s + t)[:, None] * e1, 0.5 * (e1 - da)

    x, v = exact(0.0)
    init = med.state_from(x, v)
    hol = np.eye(5)
    hol[2, 0] = 0.5 * length * (jv(0, theta0) + 1.0)  # one period in σ: ½L(J₀(θ₀) + 1) along e₁
    t_end = 0.5 * length
    steps = round(t_end / (cfl * grid.spacing[0]))
    ds = cartan.simulate(
        cartan.Problem(med, grid, cartan.InitialState(Phi=init.Phi, N=init.N, holonomy=hol)),
        integrator="lie-verlet",
        dt=t_end / steps,
        t_end=t_end,
        save_every=steps,
        progress=False,
    )
    assert float(np.ptp(ds.energy.values)) < 1e-13
    return float(np.abs(_lab(ds) - exact(float(ds.time[-1]))[0]).max())


def test_travelling_wave_runs_at_c_at_any_amplitude():
    """At Courant number 1 the chain reproduces the travelling wave at the nodes (round-off:
    measured ≤ 9e-16); at Δt = h/2 the O(h²) dispersion: 3.06e-4, 7.56e-5, 1.88e-5 (orders 2.02,
    2.01)."""
    for n in (32, 64):
        assert _travelling_wave(n, 1.0) < 1e-13
    errs = [_travelling_wave(n, 0.5) for n in (32, 64, 128)]
    for e1, e2 in zip(errs, errs[1:], strict=False):
        assert abs(_order(e1, e2) - 2.0) < 0.1  # second-order lattice × leapfrog


def _rotating_rod(n: int, radius: float = 1.0, t_end: float = 1.0) -> dict[str, float]:
    """x = R cos(σ/R)(cos(t/R), sin(t/R), 0), σ ∈ [0, πR], free ends moving at c."""
    med = cartan.medium("relativistic-rod", clocks=True)  # numpy path: no loop to compile
    grid = cartan.Grid(n + 1, length=math.pi * radius)
    s = grid.coordinates(0)

    def exact(t: float) -> tuple[np.ndarray, np.ndarray]:
        c = np.cos(s / radius)[:, None]
        return (
            radius * c * [math.cos(t / radius), math.sin(t / radius), 0.0],
            c * [-math.sin(t / radius), math.cos(t / radius), 0.0],
        )

    steps = round(t_end / (0.5 * grid.spacing[0]))
    ds = cartan.simulate(
        cartan.Problem(med, grid, med.state_from(*exact(0.0))),
        integrator="lie-verlet",
        dt=t_end / steps,
        t_end=t_end,
        save_every=steps,
        progress=False,
    )
    E, J = ds.energy.values, ds.angular_momentum_z.values
    return {
        "position": float(np.abs(_lab(ds) - exact(float(ds.time[-1]))[0]).max()) / radius,
        "energy": float(np.abs(E - math.pi * radius).max()),
        "angular_momentum": float(np.abs(J - 0.5 * math.pi * radius**2).max()),
        "regge": float(np.abs(J * 2 * math.pi / E**2 - 1.0).max()),
    }


def test_rotating_rod_regge_relation():
    """E = πRμc², J = πR²μ/2, J = E²/(2πμc³) (Regge): the nodal quadratures of the rod are exact
    (cos² over a period) and conserved by the symplectic run, so all three hold to round-off;
    the positions converge at O(h²): 1.76e-3, 4.40e-4, 1.06e-4 (orders 2.00, 2.05)."""
    rows = [_rotating_rod(n) for n in (16, 32, 64)]
    for r in rows:
        assert r["energy"] < 1e-13 and r["angular_momentum"] < 1e-13 and r["regge"] < 1e-13
    for a, b in zip(rows, rows[1:], strict=False):
        assert abs(_order(a["position"], b["position"]) - 2.0) < 0.15


def test_boosted_kibble_turok_data():
    """:func:`cartan_relativistic.lorentz.boosted_kibble_turok`: at β = 0 the rest-frame loop of
    :func:`loop_exact` (round-off); at β = 0.9 unit-speed movers (the Virasoro constraints
    x′·v = 0 and |x′|² + |v|² = 1, x′ by central differences of step 1e-5: O(1e-10)), the centre of
    energy moving at β; β outside (−1, 1) is a ValueError naming beta."""
    from cartan_relativistic.lorentz import boosted_kibble_turok
    from cartan_relativistic.string import loop_exact

    sig = np.linspace(0.0, 2 * math.pi, 40, endpoint=False)
    for t in (0.0, 0.7):
        x, v = boosted_kibble_turok(sig, t, 0.0, 0.4)
        xr_, vr_ = loop_exact(sig, t, 1.0, 1.0, 0.4)
        assert np.abs(x - xr_).max() < 1e-14 and np.abs(v - vr_).max() < 1e-14
    beta, g, d = 0.9, 1.0 / math.sqrt(1 - 0.81), 1e-5
    sig = np.linspace(0.0, 2 * math.pi * g, 64, endpoint=False)
    x, v = boosted_kibble_turok(sig, 0.3, beta)
    xp = (boosted_kibble_turok(sig + d, 0.3, beta)[0] - boosted_kibble_turok(sig - d, 0.3, beta)[0]) / (2 * d)
    assert np.abs(np.sum(xp * v, -1)).max() < 1e-8
    assert np.abs(np.sum(xp * xp + v * v, -1) - 1.0).max() < 1e-8
    # the energy density is uniform in σ̃: the centre of energy, the mean over σ̃, moves at β (the
    # trapezoidal mean converges spectrally, slowly at β = 0.9: 1.2e-4 with 64 points, 6e-16 with 1024)
    fine = np.linspace(0.0, 2 * math.pi * g, 1024, endpoint=False)
    shift = boosted_kibble_turok(fine, 0.3, beta)[0].mean(0) - boosted_kibble_turok(fine, 0.0, beta)[0].mean(0)
    assert np.abs(shift - [beta * 0.3, 0.0, 0.0]).max() < 1e-11
    with pytest.raises(ValueError, match="beta must be in"):
        boosted_kibble_turok(sig, 0.0, 1.0)


def _boosted_loop(n: int, beta: float, psi: float = math.pi / 3, t_end: float = 1.5) -> dict[str, float]:
    from cartan_relativistic.lorentz import boosted_kibble_turok

    g = 1.0 / math.sqrt(1.0 - beta * beta)
    med = cartan.medium("relativistic-rod", clocks=True)  # numpy path: no loop to compile
    grid = cartan.Grid(n, length=2 * math.pi * g, periodic=True)
    sig = grid.coordinates(0)
    steps = round(t_end / (0.5 * grid.spacing[0]))
    ds = cartan.simulate(
        cartan.Problem(med, grid, med.state_from(*boosted_kibble_turok(sig, 0.0, beta, psi))),
        integrator="lie-verlet",
        dt=t_end / steps,
        t_end=t_end,
        save_every=steps,
        progress=False,
    )
    E0 = 2 * math.pi  # rest energy μc²L of the loop, L = 2π
    J0 = 0.5 * math.pi * np.array([0.0, -math.sin(psi), math.cos(psi) - 1.0])  # rest frame, about its centre
    P = np.array([ds.energy.values, ds.momentum_x.values, ds.momentum_y.values, ds.momentum_z.values])
    J = np.array([ds.angular_momentum_x.values, ds.angular_momentum_y.values, ds.angular_momentum_z.values])
    # P′ = Λ(β e₁)P; M′^{23} = M^{23}, M′^{31} = γM^{31}, M′^{12} = γM^{12} (the boost charges M^{0i} = 0)
    return {
        "position": float(np.abs(_lab(ds) - boosted_kibble_turok(sig, float(ds.time[-1]), beta, psi)[0]).max()),
        "momentum": float(np.abs(P - np.array([g * E0, g * beta * E0, 0.0, 0.0])[:, None]).max()),
        "angular_momentum": float(np.abs(J - np.array([J0[0], g * J0[1], g * J0[2]])[:, None]).max()),
        "mass": float(np.abs(np.sqrt(P[0] ** 2 - (P[1:] ** 2).sum(0)) - E0).max()),
    }


def test_boosted_kibble_turok_loop_is_the_boost_of_the_solution():
    """β = 0.6 in the loop's plane (not the registered boost along the axis): the run against the
    Lorentz transform of the exact worldsheet at equal lab time, 1.99e-2, 5.06e-3, 1.32e-3
    (orders 1.97, 1.94: O(h²)); P and J of the run are the transformed rest charges and
    E² − |P|² = (2πμc²)² to 3e-15 at n = 128 (the trapezoidal sums of the periodic data converge
    spectrally: 9e-5, 5e-9, 2e-15 at n = 32, 64, 128), conserved over the run."""
    rows = [_boosted_loop(n, 0.6) for n in (32, 64, 128)]
    for a, b in zip(rows, rows[1:], strict=False):
        assert 1.85 < _order(a["position"], b["position"]) < 2.15
    last = rows[-1]
    assert last["momentum"] < 1e-12 and last["angular_momentum"] < 1e-12 and last["mass"] < 1e-12


@pytest.mark.parametrize("beta", [0.0, 0.6, 0.9])
def test_boosted_loop_four_momentum(beta):
    """The registered boosted loop (along its axis): E = γ·2πR₀μ, P_z = γβ·2πR₀μ and the
    invariant mass 2πR₀μ, whatever β, to round-off (measured ≤ 1.2e-14)."""
    g = 1.0 / math.sqrt(1.0 - beta * beta)
    med = cartan.medium("relativistic-rod", clocks=True)  # numpy path: no loop to compile
    grid = cartan.Grid(64, length=2 * math.pi * g, periodic=True)
    h = grid.spacing[0]
    ds = cartan.simulate(
        cartan.Problem(med, grid, med.initial_state(grid, "loop", boost=beta)),
        integrator="lie-verlet",
        dt=h / 2,
        t_end=20 * h,
        save_every=40,
        progress=False,
    )
    E, Pz = ds.energy.values, ds.momentum_z.values
    mass = np.sqrt(E**2 - Pz**2 - ds.momentum_x.values**2 - ds.momentum_y.values**2)
    assert np.abs(E - g * 2 * math.pi).max() < 1e-12
    assert np.abs(Pz - g * beta * 2 * math.pi).max() < 1e-12
    assert np.abs(mass - 2 * math.pi).max() < 1e-12


@pytest.mark.slow  # the compiled Poincaré lie-verlet loop (≈ 45 s on a fresh cache; tests/test_relativistic_rod.py)
def test_long_run_poincare_charges_and_group_membership():
    """10⁴ lie-verlet steps of the Kibble–Turok loop (n = 64): E, P⃗, J⃗ conserved to round-off
    (measured ptp ≤ 4.4e-15) — the lattice Hamiltonian is Poincaré invariant and the splitting
    preserves it — with J⃗ = (μπρ²/2)(0, −sin ψ, cos ψ − 1) and Φ in the Poincaré group."""
    med = cartan.medium("relativistic-rod")
    grid = cartan.Grid(64, length=2 * math.pi, periodic=True)
    h = grid.spacing[0]
    psi = math.pi / 3
    ds = cartan.simulate(
        cartan.Problem(med, grid, med.initial_state(grid, "loop", tilt=psi)),
        integrator="lie-verlet",
        dt=h / 2,
        t_end=10_000 * h / 2,
        save_every=1000,
        progress=False,
    )
    for name in (
        "energy",
        "momentum_x",
        "momentum_y",
        "momentum_z",
        "angular_momentum_x",
        "angular_momentum_y",
        "angular_momentum_z",
    ):
        assert float(np.ptp(ds[name].values)) < 1e-12, name
    assert abs(float(ds.angular_momentum_y.values[-1]) + 0.5 * math.pi * math.sin(psi)) < 1e-12
    assert abs(float(ds.angular_momentum_z.values[-1]) - 0.5 * math.pi * (math.cos(psi) - 1)) < 1e-12
    assert float(np.max(ds.group_defect.values)) < 1e-12


# ============================================================================ elastic string
def _mode_frequency(
    n: int, direction: int, lam: float, law: tuple, record: dict, amplitude: float = 1e-5
) -> tuple[float, float, float]:
    """Frequency of the fundamental mode sin(πu/L) (transverse: direction 1, longitudinal: 0) of
    an elastic string clamped at both ends, pre-stretched to λ, c = μ = 1, L = 1.

    ``law`` = (W, W′, W″) written out here (independent of the plugin), ``record`` the same law by
    its registered name.  Returns (measured ω, continuum ω = π c_wave/(λL), lattice ω_h = ω·sin(πh/2L)/(πh/2L))."""
    W, dW, ddW = law  # the closed form of the registered law ``record``
    rod = cartan.medium("relativistic-rod", energy="elastic", law=record)
    grid = cartan.Grid(n, length=1.0)
    u = grid.coordinates(0)
    eps, T, K = 1.0 + W(lam), dW(lam), ddW(lam)
    c2 = lam * T / eps if direction == 1 else lam * lam * K / (eps - lam * T)  # docs §2, "General ε(λ)"
    omega = math.pi * math.sqrt(c2) / lam
    z = math.pi * grid.spacing[0] / 2
    omega_h = omega * math.sin(z) / z  # the chain's dispersion: sin(πu/L) is an exact lattice mode
    x = np.stack([lam * u, 0 * u, 0 * u], -1)
    shape = np.sin(math.pi * u)
    x[:, direction] += amplitude * shape
    t_end = 0.9 * math.pi / (2 * omega)
    # at least 24 steps (rkmk4 phase error ≈ 1e-7) and Δt ≤ 1.5h (the estimate bounds it by 2.5h)
    steps = max(24, math.ceil(t_end / (1.5 * grid.spacing[0])))
    ds = cartan.simulate(
        cartan.Problem(
            rod, grid, rod.state_from(x, np.zeros_like(x)), {"start": cartan.Clamped(), "end": cartan.Clamped()}
        ),
        integrator="rkmk4",
        dt=t_end / steps,
        t_end=t_end,
        save_every=steps,
        progress=False,
    )
    comp = (ds.lab_x if direction == 0 else ds.lab_y).values[-1] - (lam * u if direction == 0 else 0.0)
    ratio = float(comp @ shape / (shape @ shape)) / amplitude
    return math.acos(ratio) / float(ds.time[-1]), omega, omega_h


_QUADRATIC = (lambda l: 0.125 * (l - 1) ** 2, lambda l: 0.25 * (l - 1), lambda l: 0.25 + 0 * l)  # k = 0.25
_QUARTIC = (
    lambda l: 0.1 * (l - 1) ** 2 + 0.25 * (l - 1) ** 4,  # k = 0.2, q = 1
    lambda l: 0.2 * (l - 1) + (l - 1) ** 3,
    lambda l: 0.2 + 3 * (l - 1) ** 2,
)


@pytest.mark.parametrize(
    ("law", "record", "lam"),
    [(_QUADRATIC, {"name": "quadratic", "k": 0.25}, 1.3), (_QUARTIC, {"name": "quartic", "k": 0.2, "q": 1.0}, 1.2)],
    ids=["quadratic", "quartic"],
)
@pytest.mark.parametrize("direction", [1, 0], ids=["transverse", "longitudinal"])
def test_elastic_string_wave_speeds(law, record, lam, direction):
    """c_T² = c²λε′/ε and c_L² = c²λ²ε″/(ε − λε′) (docs §2): the measured frequency equals the
    chain's ω_h to 1e-7 (rkmk4's O((ωΔt)⁴) phase error, ≥ 24 steps to 0.9 of a quarter
    period, and the O(A²) amplitude shift; asked within 1e-6) and the continuum one at O(h²)
    (quadratic law, λ = 1.3: 6.41e-3, 1.61e-3, 4.02e-4 for n = 9, 17, 33, orders 2.00); the
    Newtonian speeds (ε → μc² in the denominators) differ by 0.2–0.6 % (transverse) and
    2.7–4.6 % (longitudinal), far outside."""
    errs = []
    for n in (9, 17, 33):
        w, w0, wh = _mode_frequency(n, direction, lam, law, record)
        assert abs(w / wh - 1.0) < 1e-6
        errs.append(abs(w / w0 - 1.0))
    for e1, e2 in zip(errs, errs[1:], strict=False):
        assert abs(_order(e1, e2) - 2.0) < 0.05
    W, dW, ddW = law
    newton = lam * dW(lam) if direction == 1 else lam * lam * ddW(lam)  # c² with ε → μc² = 1
    assert abs(math.sqrt(newton) / (w0 * lam / math.pi) - 1.0) > 20 * abs(w / wh - 1.0) + 1e-3


# ============================================================================ filament
def _helix_equilibrium(
    n: int,
    force_factor: float = 1.0,
    perturb: float = 0.05,
    radius: float = 1.0,
    p: float = 0.5,
    bending: float = 1.0,
    twist: float = 0.7,
) -> dict[str, float]:
    """A helix (radius R, rise p per radian, one turn) with its Frenet frame as the material frame,
    clamped at s = 0 and loaded at s = L by the dead wrench of the exact equilibrium: with
    m = Cτ d₁ + Bκ d₃ (π = (τ, 0, κ)) and m′ + d₁ × n = 0, the internal force is axial,
    n = F e_z, F = (C − B)τ/ℓ = (C − B)p/ℓ³, ℓ = √(R² + p²), and the end moment is m(L)."""
    from scipy.spatial.transform import Rotation

    ell = math.hypot(radius, p)
    kappa, tau = radius / ell**2, p / ell**2
    F = force_factor * (twist - bending) * p / ell**3
    L = 2 * math.pi * ell
    rod = cartan.medium("filament", bending=bending, twist=twist)
    grid = cartan.Grid(n, length=L)
    init = rod.initial_state(grid, "helix", radius=radius, pitch=2 * math.pi * p)
    rng = np.random.default_rng(1)
    Phi = init.Phi.copy()  # translation in column 0, rotation in [1:, 1:]
    dR = Rotation.from_rotvec(perturb * rng.standard_normal((n, 3))).as_matrix()
    dR[0] = np.eye(3)  # the clamp holds the exact frame of node 0
    Phi[:, 1:, 1:] = dR @ Phi[:, 1:, 1:]
    Phi[1:, 1:, 0] += perturb * rng.standard_normal((n - 1, 3))
    start = rod.initial_state(grid, "arrays", positions=Phi[:, 1:, 0], frames=Phi[:, 1:, 1:])
    phi = L / ell
    d1 = np.array([-radius * math.sin(phi), radius * math.cos(phi), p]) / ell
    d3 = np.cross(d1, [-math.cos(phi), -math.sin(phi), 0.0])
    moment = twist * tau * d1 + bending * kappa * d3
    ds = cartan.solve_static(
        cartan.Problem(rod, grid, start, {"start": cartan.Clamped(), "end": cartan.Free(load=[0.0, 0.0, F, *moment])}),
        max_iter=40,
    )
    t = grid.coordinates(0) / ell
    exact = np.stack([radius * np.cos(t), radius * np.sin(t), p * t], -1)
    X = ds["X"].isel(time=0).values.reshape(-1, 6)
    nf = ds["constraint_force"].isel(time=0).values
    return {
        "position": float(np.abs(ds["position"].isel(time=0).values - exact).max()) / radius,
        "force": float(np.abs(np.linalg.norm(nf, axis=-1) - abs(F)).max()),
        "strain": float(max(np.abs(X[:, 3] - tau).max(), np.abs(X[:, 4]).max(), np.abs(X[:, 5] - kappa).max())),
        "constraint": float(ds.attrs["constraint_residual_max"]),
    }


def test_helix_is_an_exact_kirchhoff_equilibrium():
    """The sampled helix is a one-parameter subgroup of SE(3): its lattice strains log(Φᵢ⁻¹Φⱼ)/h
    are the continuum (1, 0, 0; τ, 0, κ) exactly, so from a start perturbed by 0.05 (rad, L) the
    statics return the helix to round-off at every n (measured ≤ 9e-15) and the multipliers are
    the closed-form |n| = |F|; with F off by 10 % the solution leaves the helix by O(1)."""
    for n in (21, 41):
        r = _helix_equilibrium(n)
        assert r["position"] < 1e-12 and r["force"] < 1e-12 and r["strain"] < 1e-12 and r["constraint"] < 1e-12
    assert _helix_equilibrium(21, force_factor=1.1)["position"] > 1e-3


def cantilever_elastica(alpha: float) -> tuple[float, float, float]:
    """Tip angle φ_L, tip deflection and tip abscissa (L = 1) of the inextensible cantilever
    under the dead tip load α = PL²/B (φ the downward tangent angle, φ″ = −α cos φ, φ(0) = 0,
    φ′(L) = 0) by the first integral ½φ′² = α(sin φ_L −
    sin φ) and the substitution sin φ = sin φ_L − w² (smooth integrands):
    1 = ∫ 2 dw/√(2α q), y = ∫ 2(s − w²) dw/√(2α q), q = (1 − s + w²)(1 + s − w²), s = sin φ_L,
    w ∈ [0, √s]; x = √(2s/α)."""

    def integral(f, s):
        return quad(
            lambda w: 2 * f(s - w * w) / math.sqrt(2 * alpha * (1 - s + w * w) * (1 + s - w * w)),
            0.0,
            math.sqrt(s),
            limit=400,
            epsabs=1e-14,
            epsrel=1e-13,
        )[0]

    s = brentq(lambda s: integral(lambda u: 1.0, s) - 1.0, 1e-12, 1.0 - 1e-15, xtol=1e-16)
    return math.asin(s), integral(lambda u: u, s), math.sqrt(2 * s / alpha)


def test_elastica_reference_reproduces_bisshopp_drucker():
    """The quadrature reproduces the registered table (α = 1, 2, 10: tip vertical 0.30172,
    0.49346, 0.81061; shortening 0.05643, 0.16064, 0.55500) to its 5 digits."""
    for alpha, y, short in ((1, 0.30172, 0.05643), (2, 0.49346, 0.16064), (10, 0.81061, 0.55500)):
        _, yv, xv = cantilever_elastica(alpha)
        assert abs(yv - y) < 6e-6 and abs(1 - xv - short) < 6e-6


def test_filament_elastica_at_large_loads():
    """α = 20 and 50 (tip angle 87.8° and 89.8°) on one continuation path, n = 21, 41, 81: tip
    deflection, tip abscissa and the last edge's angle converge at O(h²) (α = 50, deflection:
    9.57e-4, 2.38e-4, 5.95e-5, orders 2.005, 2.001)."""
    from cartan_filament.cases import FilamentCantileverElastica

    case = FilamentCantileverElastica()
    loads = (20.0, 50.0)
    rows = []
    for level in (1, 2, 3):
        prob, settings = case.problem(level)
        settings.update(lam_max=max(loads), stops=list(loads[:-1]))
        ds = cartan.continuation(prob, **settings)
        lf = ds["load_factor"].values
        row = []
        for alpha in loads:
            k = int(np.argmin(np.abs(lf - alpha)))
            assert abs(lf[k] - alpha) < 1e-9
            pos = ds["position"].isel(path=k).values
            phi_l, y, x = cantilever_elastica(alpha)
            edge = pos[-1] - pos[-2]  # the angle at s = L − h/2: φ′(L) = 0, so O(h²) from φ_L
            row += [abs(-pos[-1, 1] - y), abs(pos[-1, 0] - x), abs(math.atan2(-edge[1], edge[0]) - phi_l)]
        rows.append(row)
    for a, b in zip(rows, rows[1:], strict=False):
        for e1, e2 in zip(a, b, strict=True):
            assert abs(_order(e1, e2) - 2.0) < 0.1


@pytest.mark.slow
def test_greenhill_clamped_twist_buckling():
    """Greenhill (clamped–clamped, dead axial moment, the end sliding and turning about its axis):
    M_c L/B = 2x₁, tan x₁ = x₁ (8.98682), through the registered ``filament-greenhill`` (the double
    eigenvalue split by B₂, B₃ = 1 ∓ 0.01, the mean of the pair): relative errors 8.25e-4,
    1.95e-4 at n = 21, 41 (O(h²), order 2.08), and the quadrature of tan x = x against 8.98682."""
    from cartan_filament.cases import FilamentGreenhill, greenhill_clamped

    assert abs(greenhill_clamped() - 8.98682) < 1e-5
    case = FilamentGreenhill()
    errs = []
    for level in case.levels:
        problem, settings = case.problem(level)
        ds = case.solve(problem, settings)
        parts = case.parts(ds)
        assert 0.0 < parts["splitting"] < 0.05  # two simple bifurcations, O(δ) apart
        errs.append(parts["critical_moment"])
    assert errs[-1] < case.tolerance
    assert abs(_order(*errs) - 2.0) < 0.2  # O(h²)


@pytest.mark.slow  # the compiled rattle loop of the filament (≈ 2 min on a fresh cache; warm < 1 s)
def test_free_filament_dynamics_energy_order_and_constraints():
    """A free filament released at rest from a helix (no rest curvature; B = (1, 1.5), C = 0.8,
    ρI = 0.01, n = 21), ``rattle`` to t = 2: the energy's fluctuation max − min falls as Δt²
    (3.23e-4, 7.88e-5, 1.96e-5 of E at Δt = 4e-3, 2e-3, 1e-3: orders 2.04, 2.01; a symplectic
    method, no drift), θ = (1, 0, 0) holds to < 1e-13 and the momentum map (P⃗, J⃗: no load) is
    constant to 3e-13, round-off."""
    fluct = []
    for dt in (4e-3, 2e-3, 1e-3):
        rod = cartan.medium("filament", bending=(1.0, 1.5), twist=0.8, rotational_inertia=0.01)
        grid = cartan.Grid(21, length=2 * math.pi * math.hypot(1.0, 0.5))
        init = rod.initial_state(grid, "helix", radius=1.0, pitch=math.pi)
        steps = round(2.0 / dt)
        ds = cartan.simulate(
            cartan.Problem(rod, grid, init), dt=dt, t_end=steps * dt, save_every=steps // 50, progress=False
        )
        E = ds.kinetic_energy.values + ds.potential_energy.values
        fluct.append(float(np.ptp(E)) / float(E[0]))
        assert float(ds.constraint_residual.max()) < 1e-12
        assert float(np.ptp(ds.total_momentum.values, axis=0).max()) < 1e-11
    for e1, e2 in zip(fluct, fluct[1:], strict=False):
        assert abs(_order(e1, e2) - 2.0) < 0.15
