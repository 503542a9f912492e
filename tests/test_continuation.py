"""Load continuation (cartan.continuation): Euler buckling, branch switching, the cantilever elastica."""

from __future__ import annotations

import math

import numpy as np
import pytest
from cartan_verification.references import ELASTICA_TABLE as ELASTICA
from cartan_verification.references import pinned_elastica

import cartan
from cartan.continuation import continuation


def _planar_rod(stiff=1e6):
    """Planar rod, B = 1, stretch and shear stiffness ``stiff`` × B/L² (the inextensible limit)."""
    return cartan.medium("planar-cosserat-rod", stretch_shear=[stiff, stiff], bending=1.0, mass=1.0,
                         rotational_inertia=1.0)


def _euler_column(n=101, lam_max=1.5 * math.pi**2, ds0=0.05):
    """Pinned–pinned column of length 1 along x under an axial compressive dead load λ at the end:
    both ends Free in the problem, positions pinned by the continuation (start: x and y, end: y)."""
    rod = _planar_rod()
    grid = cartan.Grid(n, length=1.0)
    prob = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                          {"start": cartan.Free(), "end": cartan.Free(load=[-1.0, 0.0, 0.0])})
    mid = n // 2
    return continuation(prob, lam_max, ds0, pins={"start": (0, 1), "end": (1,)},
                        monitor=lambda d: float(d["position"].isel(time=0, node=mid, row=1)))


@pytest.fixture(scope="module")
def column():
    return _euler_column()


def test_euler_critical_load(column):
    """P_cr found within 1e-3 of π²B/L²: measured +8.23e-5 at n = 101 — the lattice's second-order
    discretisation error π²h²/12 (+3.29e-4 at n = 51, +2.06e-5 at n = 201)."""
    ds = column
    assert list(ds["critical_kind"].values) == ["bifurcation"]
    p_cr = float(ds["critical_load"][0])
    rel = p_cr / math.pi**2 - 1.0
    assert 0.0 < rel < 1e-4, rel
    assert abs(rel - math.pi**2 * 0.01**2 / 12) < 5e-6, rel
    assert abs(float(ds["critical_monitor"][0])) < 1e-8  # on the straight branch


def test_euler_post_buckled_branch(column):
    """Past P_cr the path is the buckled elastica: w_mid/L = k/K(k), P/P_cr = (2K(k)/π)² (pinned–pinned),
    so w ≈ (2√2/π)·√(P/P_cr − 1) near onset.  With P_cr the detected (lattice) critical load the
midspan deflection matches the elastica within 1.1e-5 (measured) along the branch up to P = 1.5 π²B/L²."""
    ds = column
    lam = ds["load_factor"].values / math.pi**2
    w = ds["monitor"].values
    branch = ds["branch"].values
    pre, post = branch == 0, branch == 1
    assert np.all(np.abs(w[pre]) < 1e-8) and np.all(lam[pre] < 1.0)
    assert post.sum() >= 3 and np.all(lam[post] > 1.0)
    assert np.all(np.diff(w[post]) > 0) and w[post][0] > 0  # the deflection grows with the load
    assert lam[-1] == pytest.approx(1.5, abs=1e-12)
    errors = []
    ratio = ds["load_factor"].values[post] / float(ds["critical_load"][0])  # P/P_cr, P_cr of the lattice
    for lam_i, w_i in zip(ratio, w[post], strict=True):
        errors.append(w_i / pinned_elastica(lam_i)[0] - 1.0)  # K(k) = √(P/B)·L/2, w/L = k/K(k)
    assert np.all(np.abs(errors) < 1e-4), errors
    first = np.argmax(post)
    onset = 2.0 * math.sqrt(2.0) / math.pi * math.sqrt(ratio[0] - 1.0)
    assert abs(w[first] / onset - 1.0) < 0.05, (w[first], onset)


def test_cantilever_elastica_path():
    """Tip dead load on a clamped planar rod followed from 0 to PL²/B = 10 by arclength (no load
    steps), with points placed at PL²/B = 1 and 2 (``stops``); tip vertical deflection and shortening
    within 1e-3 of the tabulated elastica (measured ≲ 2e-5)."""
    rod = _planar_rod(1e6)
    grid = cartan.Grid(101, length=1.0)
    prob = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                          {"start": cartan.Clamped(), "end": cartan.Free(load=[0.0, -1.0, 0.0])})
    ds = continuation(prob, 10.0, 0.1, stops=[1.0, 2.0],
                      monitor=lambda d: -float(d["position"].isel(time=0, node=-1, row=1)))
    lam = ds["load_factor"].values
    assert ds.sizes["critical"] == 0
    for alpha, (ref_v, ref_s) in ELASTICA.items():
        i = int(np.argmin(np.abs(lam - alpha)))
        assert lam[i] == pytest.approx(alpha, abs=1e-12)
        vertical = float(ds["monitor"][i])
        shortening = 1.0 - float(ds["position"].isel(path=i, node=-1, row=0))
        assert abs(vertical - ref_v) < 1e-3, (alpha, vertical, ref_v)
        assert abs(shortening - ref_s) < 1e-3, (alpha, shortening, ref_s)
    assert np.all(np.diff(ds["monitor"].values) > 0)


def test_options_are_validated():
    rod = _planar_rod()
    grid = cartan.Grid(11, length=1.0)
    prob = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"),
                          {"start": cartan.Clamped(), "end": cartan.Free(load=[0.0, -1.0, 0.0])})
    with pytest.raises(ValueError, match="positive"):
        continuation(prob, -1.0, 0.1)
    with pytest.raises(ValueError, match="pins"):
        continuation(prob, 1.0, 0.1, pins={"middle": (0,)})
