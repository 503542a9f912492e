"""The ``helfrich-membrane`` outputs measured from the problem's reference
(docs/media/kirchhoff-love.md, "Helfrich membrane").

* A sphere (longitude, colatitude chart) at its own reference reports the area stretch j = 1 and
  the tension σ (here the area multiplier of :meth:`HelfrichMembrane.with_tension`) at every node;
  scaled uniformly by λ, j = λ² and σ + K_a(λ² − 1), to round-off.
* The Helfrich energy density of a sphere of radius R is ½κ_b(2/R − c₀)² + κ_G/R² per unit
  deformed area (8πκ_b in all for c₀ = 0, κ_G = 0), with or without the reference.
* Without a reference the outputs are :meth:`HelfrichMembrane.fields` at the medium's rest strain,
  to the bit; with a flat plate as the reference, to round-off.
"""

from __future__ import annotations

import numpy as np

import cartan
from cartan.io import _nodal_reference
from cartan.problem import InitialState, Problem
from cartan.schemes.lattice import Lattice

KB, KG, C0, KA = 1.0, -0.4, 0.3, 10.0
NAMES = ("mean_curvature", "gauss_curvature", "helfrich_energy_density", "area_stretch", "surface_tension")


def _medium(sigma: float = -0.7):
    base = cartan.medium("helfrich-membrane", bending_modulus=KB, gaussian_modulus=KG, spontaneous_curvature=C0,
                         area_modulus=KA)
    return base.with_tension(sigma)     # a held area's multiplier, of either sign


def _sphere(med, R: float):
    grid = cartan.Grid((8, 4), (2 * np.pi, np.pi), periodic=(True, False), glued=(None, 0))
    return grid, med.initial_state(grid, "sphere", radius=R)


def _outputs(med, grid, init, Phi, with_reference: bool = True):
    """The outputs at ``Phi`` of a problem with ``init``'s reference, through the reference the
    saved frames pass (:func:`cartan.io._nodal_reference`), or without one."""
    prob = Problem(med, grid, InitialState(Phi=Phi, glue=init.glue, reference=init.reference))
    sch = Lattice(prob)
    X = np.asarray(sch.nodal_strains(sch.initial_state()))
    ref = _nodal_reference(sch) if with_reference else None
    return med.outputs(Phi, X, np.zeros((*grid.shape, 6)), grid, reference=ref)


def test_sphere_at_its_reference_has_unit_stretch():
    """A sphere of radius R = 1.5 at its own reference: j = 1 and the tension is the multiplier σ
    at every node (1e-13: the nodal strains are the nodal rest strains up to round-off).  From
    the medium's flat rest strain j was the chart's area element R² sin θ, varying with the
    latitude (0.86 to 2.08 on this grid)."""
    med = _medium()
    assert type(med).outputs_read_reference
    R = 1.5
    grid, init = _sphere(med, R)
    out = _outputs(med, grid, init, init.Phi.copy())
    assert out["area_stretch"].shape == grid.shape
    assert np.abs(out["area_stretch"] - 1.0).max() <= 1e-13
    assert np.abs(out["surface_tension"] - med.sigma).max() <= 1e-13 * KA
    flat = _outputs(med, grid, init, init.Phi.copy(), with_reference=False)["area_stretch"]
    assert np.ptp(flat) > 0.5 * R ** 2 and flat.max() < R ** 2


def test_scaled_sphere_stretch_and_tension():
    """The unit sphere scaled by λ = 1.02 about its centre, frames kept: every edge's θ scales by
    λ, so j = λ² and the tension σ + K_a(λ² − 1) at every node, to round-off (1e-12)."""
    med = _medium()
    grid, init = _sphere(med, 1.0)
    lam = 1.02
    Phi = init.Phi.copy()
    Phi[..., 1:, 0] *= lam
    out = _outputs(med, grid, init, Phi)
    assert np.abs(out["area_stretch"] / lam ** 2 - 1.0).max() <= 1e-12
    tension = med.sigma + KA * (lam ** 2 - 1.0)
    assert np.abs(out["surface_tension"] / tension - 1.0).max() <= 1e-12


def test_sphere_energy_density_is_the_closed_form():
    """Spheres of radii 0.5 and 2: H = 1/R, K = 1/R², the Helfrich density ½κ_b(2/R − c₀)² + κ_G/R²
    at every node (1e-12; the nodal curvatures of the lattice's sphere are exact to round-off),
    the same with or without the reference (it is per unit deformed area); with c₀ = κ_G = 0
    the density times the sphere's area 4πR² is 8πκ_b for either radius."""
    med = _medium()
    pure = cartan.medium("helfrich-membrane", bending_modulus=KB)
    for R in (0.5, 2.0):
        grid, init = _sphere(med, R)
        out = _outputs(med, grid, init, init.Phi.copy())
        noref = _outputs(med, grid, init, init.Phi.copy(), with_reference=False)
        assert np.abs(out["mean_curvature"] * R - 1.0).max() <= 1e-12
        assert np.abs(out["gauss_curvature"] * R ** 2 - 1.0).max() <= 1e-12
        dens = 0.5 * KB * (2.0 / R - C0) ** 2 + KG / R ** 2
        assert np.abs(out["helfrich_energy_density"] / dens - 1.0).max() <= 1e-12
        for name in ("mean_curvature", "gauss_curvature", "helfrich_energy_density"):
            assert np.array_equal(out[name], noref[name]), name
        w = _outputs(pure, grid, init, init.Phi.copy())["helfrich_energy_density"] * 4 * np.pi * R ** 2
        assert np.abs(w / (8 * np.pi * KB) - 1.0).max() <= 1e-12


def test_plate_outputs_are_the_fields():
    """A bent plate (w = 0.1 sin u cos v on a Cartesian chart): without a reference the outputs are
    :meth:`fields` at the medium's rest strain to the bit; with the flat plate as the reference,
    to round-off (1e-12 of the largest value: the nodal rest strains are the unit metric to
    round-off)."""
    med = _medium(0.2)
    grid = cartan.Grid((6, 5), (2.0, 1.5))
    bent = med.initial_state(grid, "surface",
                             position=lambda u, v: np.stack([u, v, 0.1 * np.sin(u) * np.cos(v)], axis=-1))
    sch = Lattice(Problem(med, grid, bent))
    X = np.asarray(sch.nodal_strains(sch.initial_state()))
    q = np.asarray(bent.Phi)
    out = med.outputs(q, X, np.zeros((*grid.shape, 6)), grid)
    f = med.fields(X)
    for i, name in enumerate(NAMES):
        assert np.array_equal(out[name], f[..., i]), name
    assert np.abs(f[..., 3] - 1.0).max() > 1e-3          # the bent plate stretches its chart
    flat = med.initial_state(grid, "flat")
    out_ref = _outputs(med, grid, InitialState(Phi=flat.Phi, reference=flat), q)
    for name in NAMES:
        assert np.abs(out_ref[name] - out[name]).max() <= 1e-12 * np.abs(out[name]).max(), name
