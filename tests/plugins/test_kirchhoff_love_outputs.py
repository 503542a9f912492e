"""The ``kirchhoff-love`` outputs measured from the problem's reference, in physical components
(docs/media/kirchhoff-love.md, "Outputs").

* A sphere (longitude, colatitude chart) scaled uniformly by λ from its own reference reports
  N^uu = N^vv = Eh e/(1 − ν), e = ½(λ² − 1), N^uv = 0 and M^uu = M^vv = D(1 + ν)(λ − 1)/R at
  every node, poles' neighbours included, to round-off.
* The reference shape itself reports zero resultants and energy densities.
* On a plate (|θ⁰_α| = 1) the outputs are the contravariant chart components of
  :meth:`KirchhoffLove.fields`, to the bit without a reference and to round-off with a flat one.
"""

from __future__ import annotations

import numpy as np

import cartan
from cartan.io import _nodal_reference
from cartan.problem import InitialState, Problem
from cartan.schemes.lattice import Lattice

E, NU, H = 1.0, 0.3, 0.05
FORCES = ("membrane_force_uu", "membrane_force_uv", "membrane_force_vv")
MOMENTS = ("bending_moment_uu", "bending_moment_uv", "bending_moment_vv")
ENERGIES = ("bending_energy_density", "membrane_energy_density")


def _medium():
    return cartan.medium("kirchhoff-love", E=E, poisson=NU, thickness=H, density=1.0)


def _outputs(med, grid, init, Phi):
    """The medium's outputs at the configuration ``Phi`` of a problem with ``init``'s reference,
    through the reference the saved frames pass (:func:`cartan.io._nodal_reference`)."""
    prob = Problem(med, grid, InitialState(Phi=Phi, glue=init.glue, reference=init.reference))
    sch = Lattice(prob)
    X = np.asarray(sch.nodal_strains(sch.initial_state()))
    return med.outputs(Phi, X, np.zeros((*grid.shape, 6)), grid, reference=_nodal_reference(sch)), X


def _sphere():
    med = _medium()
    grid = cartan.Grid((8, 4), (2 * np.pi, np.pi), periodic=(True, False), glued=(None, 0))
    return med, grid, med.initial_state(grid, "sphere")


def test_scaled_sphere_resultants_are_the_closed_form():
    """The unit sphere scaled by λ = 1.01 about its centre, frames kept: every edge's θ scales by
    λ and the lattice's rest metric is diagonal, so ε = ½(λ² − 1)a⁰ and κ = (λ − 1)b⁰, b⁰ = a⁰/R:
    N = Eh e/(1 − ν), M = D(1 + ν)(λ − 1)/R in every direction, exactly up to round-off (1e-10).
    Measured from the medium's flat rest strain in contravariant components (the outputs before
    they read the reference), N^uu/N was between −32 and −4.7 (compression) on this grid."""
    med, grid, init = _sphere()
    assert med.outputs_read_reference
    lam = 1.01
    Phi = init.Phi.copy()
    Phi[..., 1:, 0] *= lam
    out, _ = _outputs(med, grid, init, Phi)
    n_ref = E * H * 0.5 * (lam ** 2 - 1.0) / (1.0 - NU)
    m_ref = E * H ** 3 / (12 * (1 - NU ** 2)) * (1 + NU) * (lam - 1.0)
    for name, ref in (("membrane_force_uu", n_ref), ("membrane_force_vv", n_ref),
                      ("bending_moment_uu", m_ref), ("bending_moment_vv", m_ref)):
        assert out[name].shape == grid.shape
        assert np.abs(out[name] / ref - 1.0).max() <= 1e-10, name
    assert np.abs(out["membrane_force_uv"]).max() <= 1e-10 * n_ref
    assert np.abs(out["bending_moment_uv"]).max() <= 1e-10 * m_ref
    # the small-strain form Eh(λ − 1)/(1 − ν) differs by the Green strain's ½(λ − 1)² only
    assert np.abs(out["membrane_force_uu"] / (E * H * (lam - 1.0) / (1.0 - NU)) - 1.0).max() <= 0.6 * (lam - 1.0)


def test_reference_shape_is_stress_free():
    """The sphere at its own reference: the nodal strains equal the nodal rest strains, so every
    resultant and energy density vanishes (to round-off of the scale of the scaled sphere's)."""
    med, grid, init = _sphere()
    out, _ = _outputs(med, grid, init, init.Phi.copy())
    for name in (*FORCES, *MOMENTS, *ENERGIES):
        assert np.abs(out[name]).max() <= 1e-14 * E * H, name
    assert np.allclose(out["mean_curvature"], 1.0, atol=1e-12)   # the curvatures are not measured from X0


def test_plate_outputs_are_the_contravariant_components():
    """A bent plate (w = 0.1 sin u cos v on a Cartesian chart): without a reference the outputs
    are the contravariant n, m of :meth:`fields` at the medium's rest strain to the bit
    (|θ⁰_α| = 1 exactly); with the flat plate given as the reference, to round-off (1e-12 of the
    largest value: the nodal rest strains are 1 to round-off)."""
    med = _medium()
    grid = cartan.Grid((6, 5), (2.0, 1.5))
    bent = med.initial_state(grid, "surface",
                             position=lambda u, v: np.stack([u, v, 0.1 * np.sin(u) * np.cos(v)], axis=-1))
    prob = Problem(med, grid, bent)
    sch = Lattice(prob)
    X = np.asarray(sch.nodal_strains(sch.initial_state()))
    q = np.asarray(bent.Phi)
    out = med.outputs(q, X, np.zeros((*grid.shape, 6)), grid)
    f = med.fields(X)
    for i, name in enumerate((*FORCES, *MOMENTS, "gauss_curvature", "mean_curvature", *ENERGIES)):
        assert np.array_equal(out[name], f[..., i]), name
    assert np.abs(f[..., 3]).max() > 0.0 and np.abs(f[..., 0]).max() > 0.0
    flat = med.initial_state(grid, "flat")
    out_ref, _ = _outputs(med, grid, InitialState(Phi=flat.Phi, reference=flat), q)
    for name in (*FORCES, *MOMENTS, *ENERGIES):
        assert np.abs(out_ref[name] - out[name]).max() <= 1e-12 * np.abs(out[name]).max(), name
