"""The rigidly rotating elastic ring: a relative equilibrium of the discrete string (docs §4, §6).

An elastic ``relativistic-rod`` closed into a ring of radius R (reference radius L/2π) and set
turning about e₃ at angular velocity ω, each node at speed v = ωR along the ring — a flow
along the string, not a rotation of a rigid body: the rest-frame stretch is λ = |x⃗′|γ.  When
ω balances the tension, the ring turns rigidly forever.  On the ``lattice`` the balance is that
of the semi-discrete system (§3): with translations only (Λ = I), Ṡ = W, and a state that
rotates rigidly has ṗ⃗ = ω e₃ × p⃗ = −ω|p⃗| r̂ at every node, so ω solves

    g(ω) = W·r̂ + ω|p⃗| = 0,

the same equation at every node by symmetry (:func:`equilibrium_spin`, a scalar root by
Brent's method).  The semi-discrete solution is then exactly x⃗_i(t) = R_{e₃}(ωt) x⃗_i(0)
(:func:`rigid_rotation`) with constant γ = 1/√(1 − ω²R²/c²): the reference of the case
``relativistic-elastic-rotating-ring`` (the time discretisation's error alone) and of the
proper time of every node, τ = t√(1 − v²/c²) (:func:`cartan_relativistic.clocks.proper_time`).

:func:`energy_drift` runs the ring off its equilibrium (the scene's breathing ring) for a long
time with ``implicit-midpoint`` and ``rkmk4``; ``python -m cartan_relativistic.rotating OUT.png``
draws the chart of the docs.
"""

from __future__ import annotations

import math
import sys
from typing import Any

import numpy as np

import cartan

__all__ = ["energy_drift", "equilibrium_spin", "main", "ring_problem", "rigid_rotation"]

#: the ring of the case: k = 0.1 (μ = c = 1), 12 nodes, reference radius 1, radius 1.3
STIFFNESS, NODES, RADIUS = 0.1, 12, 1.3


def ring_problem(spin: float, radius: float = RADIUS, nodes: int = NODES, law: Any = None,
                 name: str = "") -> cartan.Problem:
    """The elastic ring (μ = c = 1, ``STIFFNESS`` or ``law``) of radius ``radius`` turning at ``spin``."""
    kw = {"law": law} if law is not None else {"stiffness": STIFFNESS}
    med = cartan.medium("relativistic-rod", energy="elastic", **kw)
    grid = cartan.Grid(nodes, length=2 * math.pi, periodic=True)
    return cartan.Problem(med, grid, med.initial_state(grid, "ring", radius=radius, spin=spin), name=name)


def _balance(problem: cartan.Problem) -> float:
    """g(ω) = mean over nodes of W·r̂ + ω|p⃗| for the ring ``problem`` (module docstring)."""
    from cartan.schemes.lattice import Lattice

    scheme = Lattice(problem)
    state = scheme.initial_state()
    W = scheme.force(state, scheme.velocity(state), 0.0)
    x = scheme.frames(state)[:, 2:5, 0]  # the lab position (r¹, r², r³) of each node
    rhat = x / np.linalg.norm(x, axis=1, keepdims=True)
    p = state.S[:, 1:4]
    omega = float(np.linalg.norm(problem.initial.N[0, 1:4])) / float(np.linalg.norm(x[0]))
    return float(np.mean(np.sum(W[:, 1:4] * rhat, axis=1) + omega * np.linalg.norm(p, axis=1)))


def equilibrium_spin(radius: float = RADIUS, nodes: int = NODES, bracket: tuple[float, float] = (0.02, 0.5),
                     law: Any = None) -> float:
    """The angular velocity ω at which the discrete ring of ``radius`` turns rigidly (c = 1).

    Parameters
    ----------
    radius : float
        Lab radius R of the ring (> the reference radius 1: the tension pulls inwards).
    nodes : int
        Lattice nodes.
    bracket : (float, float)
        Speeds ωR/c between which g changes sign (g < 0: the tension wins).
    law : ElasticLaw, optional
        The elastic law (default: the quadratic one with k = ``STIFFNESS``).

    Returns
    -------
    float
        ω, with |g(ω)| at round-off (Brent's method to 1e-15 in ω).

    Raises
    ------
    ValueError
        When g does not change sign over ``bracket`` (no equilibrium there).
    """
    from scipy.optimize import brentq

    def g(v: float) -> float:
        return _balance(ring_problem(v / radius, radius, nodes, law))

    lo, hi = bracket
    if g(lo) * g(hi) > 0:
        raise ValueError(f"bracket must hold speeds ωR/c on both sides of the equilibrium; g has one sign on "
                         f"{bracket!r}")
    return brentq(g, lo, hi, xtol=1e-15, rtol=4 * np.finfo(float).eps) / radius


def rigid_rotation(x0: np.ndarray, omega: float, t: np.ndarray) -> np.ndarray:
    """``R_{e₃}(ωt) x⃗₀``: positions ``[node, 3]`` turned at ω, ``[time, node, 3]`` for the times ``[time]``."""
    a = omega * np.asarray(t, dtype=float)[:, None]
    x, y, z = (np.asarray(x0, dtype=float)[None, :, k] for k in range(3))
    return np.stack([np.cos(a) * x - np.sin(a) * y, np.sin(a) * x + np.cos(a) * y, z + 0 * a], axis=-1)


def energy_drift(t_end: float = 300.0, dt: float = 0.2, nodes: int = NODES,
                 integrators: tuple[str, ...] = ("implicit-midpoint", "rkmk4")) -> dict[str, dict[str, np.ndarray]]:
    """Long runs of the breathing ring (radius 1.3 at 0.4c, off its equilibrium: the scene's ring
    on ``nodes`` nodes) by each integrator: per integrator the saved ``t``, the change ``dH`` of
    the discrete Hamiltonian H_d, of the angular momentum ``dJ`` (J₃) and the largest change of
    the linear momentum ``dP`` (components 1–3)."""
    problem = ring_problem(0.4 / 1.3, 1.3, nodes)
    out = {}
    for name in integrators:
        ds = cartan.simulate(problem, integrator=name, dt=dt, t_end=t_end, save_every=10, progress=False)
        H = ds.kinetic_energy.values + ds.potential_energy.values
        M = ds.total_momentum.values
        out[name] = {"t": ds.time.values, "dH": H - H[0], "H0": np.full(1, H[0]), "dJ": M[:, 9] - M[0, 9],
                     "dP": np.max(np.abs(M[:, 1:4] - M[0, 1:4]), axis=1)}
    return out


def draw(runs: dict[str, dict[str, np.ndarray]], fig: Any, dt: float) -> None:
    """The chart: |ΔH_d|/H_d and |ΔJ₃|/J₃ against time for each integrator (log scale)."""
    a1, a2 = fig.subplots(1, 2)
    for name, r in runs.items():
        a1.semilogy(r["t"][1:], np.abs(r["dH"][1:]) / abs(float(r["H0"][0])), lw=0.8, label=name)
        a2.semilogy(r["t"][1:], np.maximum(np.abs(r["dJ"][1:]), 1e-17), lw=0.8, label=name)
    a1.set_xlabel("lab time t")
    a1.set_ylabel("|H_d(t) − H_d(0)| / H_d(0)")
    a1.set_title(f"breathing elastic ring, Δt = {dt:g}: energy error")
    a2.set_xlabel("lab time t")
    a2.set_ylabel("|J₃(t) − J₃(0)|")
    a2.set_title("angular momentum")
    for a in (a1, a2):
        a.grid(True, which="both", alpha=0.3)
        a.legend(fontsize=8)


def main(argv: list[str] | None = None) -> int:
    """``python -m cartan_relativistic.rotating OUT.png [T_END]``: the energy chart of the docs."""
    args = sys.argv[1:] if argv is None else argv
    if not args:
        print(__doc__.split("\n\n")[0])
        print("usage: python -m cartan_relativistic.rotating OUT.png [T_END]")
        return 2
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    t_end = float(args[1]) if len(args) > 1 else 300.0
    runs = energy_drift(t_end)
    fig = Figure(figsize=(11, 4), layout="constrained")
    draw(runs, fig, 0.2)
    fig.savefig(args[0], dpi=110)
    for name, r in runs.items():
        n = len(r["t"])
        print(f"{name}: max |dH|/H first quarter {np.max(np.abs(r['dH'][:n // 4])) / r['H0'][0]:.3e}, "
              f"last quarter {np.max(np.abs(r['dH'][3 * n // 4:])) / r['H0'][0]:.3e}; "
              f"max |dJ3| {np.max(np.abs(r['dJ'])):.2e}; max |dP| {np.max(r['dP']):.2e}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
