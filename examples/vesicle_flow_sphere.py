"""The Helfrich flow of a vesicle of reduced volume v = 0.9 on the sphere's chart.

A ``helfrich-membrane`` (κ_b = 1, c₀ = κ_G = 0, R₀ = 1) on the sphere's chart with 2n × n nodes
(longitude periodic, colatitude glued across the poles), the adaptation θ_α,3 = 0 held by the
core's strain constraints on every edge, those across the poles included, starts from the prolate
spheroid of v = 0.9 (colatitude nodes at equal meridian arc length) and relaxes under
:func:`cartan_kirchhoff_love.vesicle.helfrich_flow` (normal motion, area and volume held by their
multipliers σ and p, the mesh redistributed through the poles before every step).  Left: the
lattice energy E_H/8πκ_b and ∫K dA/4π against the flow time, with the stationary prolate shape
of the axisymmetric shape equations (E/8πκ_b = 1.189644033) and that shape's lattice energy on the
same chart; right: the last shape's meridian against the reference meridian
(docs/media/kirchhoff-love.md, "The 2D flow on the sphere's chart").

Run: ``python examples/vesicle_flow_sphere.py [n] [steps] [out.png] [flow.nc]``
(defaults 8, 16, ``docs/media/kirchhoff-love/vesicle-flow-v09.png`` and no file).  Given a
``flow.nc`` that exists, the flow is read from it instead of run; given one that does not, the
flow is run and saved there.  About 3 minutes at n = 8; at n = 16 a step takes about 20 s (2 shared cores).
"""

from __future__ import annotations

import math
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402
from cartan_kirchhoff_love.cases_vesicle import reference_prolate  # noqa: E402
from cartan_kirchhoff_love.vesicle import flow_configuration, helfrich_flow  # noqa: E402
from cartan_kirchhoff_love.vesicle_sphere import ellipsoid_problem, revolved_problem, vesicle_shape  # noqa: E402

#: the flow's settings (normal motion; the in-plane regularisation K_a, μ is then dropped)
FLOW = {"tau": 0.0125, "growth": 1.5, "tau_max": 5.0, "motion": "normal", "hold": ("area", "volume")}


def main(n: int = 8, steps: int = 16, out: str = "docs/media/kirchhoff-love/vesicle-flow-v09.png",
         data: str | None = None) -> None:
    ref = reference_prolate()
    problem = ellipsoid_problem(n, 0.9, spacing="arc")
    if data is not None and pathlib.Path(data).exists():
        ds = xr.open_dataset(data)
    else:
        ds = helfrich_flow(problem, steps=steps, progress=True, **FLOW)
        if data is not None:
            ds.to_netcdf(data)
    lattice_ref = revolved_problem(ref, n, normal_stiffness=None)
    e_ref_h = vesicle_shape(lattice_ref, np.asarray(lattice_ref.initial.Phi))["energy"]
    E = ds["bending_energy"].values / (8.0 * math.pi * problem.medium.kb)
    K = ds["gauss_bonnet_curvature"].values / (4.0 * math.pi)
    t = ds["flow_time"].values
    A, V = ds["area"].values, ds["volume"].values
    last = vesicle_shape(problem, flow_configuration(ds))
    print(f"E/8πκ_b {E[0]:.6f} → {E[1]:.6f} (step 1) → {E[-1]:.6f}; reference {ref.energy:.6f}, on this lattice "
          f"{e_ref_h:.6f}; ∫K dA/4π {K[1]:.4f} → {K[-1]:.4f}; max |A/A₀ − 1| {np.max(np.abs(A / A[0] - 1)):.1e}, "
          f"|V/V₀ − 1| {np.max(np.abs(V / V[0] - 1)):.1e}; axis ratio {last['axis_ratio']:.4f} (reference "
          f"{ref.axis_ratio:.4f})")
    fig = plt.figure(figsize=(12, 5))
    left = fig.add_subplot(1, 2, 1)
    left.plot(t[1:], E[1:], "o-", ms=3, label="E_H/8πκ_b (lattice)")
    left.plot(t[1:], K[1:], "s-", ms=3, label="∫K dA/4π (corner quadrature)")
    left.axhline(ref.energy, color="crimson", lw=1.0, ls="--", label="stationary prolate (continuum)")
    left.axhline(e_ref_h, color="crimson", lw=1.0, ls=":", label="stationary prolate on this lattice")
    left.set_xscale("log")
    left.set_xlabel("flow time")
    left.set_title(f"Helfrich flow at v = 0.9 from the spheroid, sphere's chart {2 * n} × {n} nodes\n"
                   "(A and V held by multipliers; the first step projects onto θ_α,3 = 0)", fontsize=10)
    left.legend(fontsize=8)
    right = fig.add_subplot(1, 2, 2)
    for k, style, label in ((1, "--", "step 1"), (len(t) - 1, "-", f"step {len(t) - 1}")):
        x = flow_configuration(ds, k)[..., 1:, 0]
        x = x - x.reshape(-1, 3).mean(axis=0)
        rho, z = np.hypot(x[..., 0], x[..., 1]).mean(axis=0), x[..., 2].mean(axis=0)
        right.plot(np.concatenate([rho, -rho[::-1], rho[:1]]), np.concatenate([z, z[::-1], z[:1]]), style, marker="o",
                   ms=3,
                   label=f"lattice, {label} (ring means)")
    rm, zm = ref.meridian(400)
    right.plot(rm, zm, color="crimson", lw=1.5, label="stationary prolate meridian")
    right.plot(-rm, zm, color="crimson", lw=1.5)
    right.set_aspect("equal")
    right.set_xlabel("distance from the axis")
    right.set_ylabel("z")
    right.legend(fontsize=8, loc="lower right")
    right.set_title("meridians", fontsize=10)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


if __name__ == "__main__":
    args = sys.argv[1:]
    main(*(int(a) for a in args[:2]), *args[2:4])
