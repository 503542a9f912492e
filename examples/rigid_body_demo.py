"""Free rigid body on SO(3): geometric integrators against the exact Jacobi solution.

Integrates the reference case 𝕀 = diag(1, 2, 3), ω₀ = (1, 0, 0.5) over five periods of the
body angular velocity with ``lie-verlet`` and ``rkmk4`` at two time steps each and with
``forward-euler``, compares every run with the exact solution of
:func:`cartan.rigid_body.rigid_body_exact`, prints a table and writes

* ``rigid_body.nc`` — CF-1.11 netCDF: attitudes, momenta and errors on dims
  (method, time, component).  ``method`` is also the name of an argument of
  ``Dataset.sel``: select a run with ``ds.sel({"method": "rkmk4 dt=0.05"})``;
* ``rigid_body.png`` — energy error and attitude error against time, log scale.

Usage::

    python examples/rigid_body_demo.py [--outdir out]
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as dt_
import importlib.metadata
import os
import sys
import tempfile
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402

from cartan.groups.so3 import SO3  # noqa: E402
from cartan.rigid_body import kinetic_energy, period, rigid_body_exact, step_rigid_body  # noqa: E402

INERTIA = np.array([1.0, 2.0, 3.0])
OMEGA0 = np.array([1.0, 0.0, 0.5])
N_PERIODS = 5
SAVE_DT = 0.1  # every run saves on this common time grid
#: (method, dt) pairs; every dt divides SAVE_DT.
RUNS = [
    ("lie-verlet", 0.05),
    ("lie-verlet", 0.025),
    ("rkmk4", 0.1),
    ("rkmk4", 0.05),
    ("forward-euler", 0.01),
]


def cartan_version() -> str:
    try:
        return importlib.metadata.version("cartan")
    except importlib.metadata.PackageNotFoundError:
        return "unknown"


@contextlib.contextmanager
def atomic_path(final: Path):
    """Yield a temporary path next to ``final``; move it into place if the body succeeds."""
    fd, tmp = tempfile.mkstemp(prefix=f".{final.name}.", suffix=final.suffix, dir=final.parent)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp creates 0600; give the usual permissions
        os.replace(tmp, final)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def simulate() -> xr.Dataset:
    """Run every (method, dt) and the exact solution on a common save grid.

    Returns
    -------
    xarray.Dataset
        Dims ``method`` (len(RUNS)), ``time`` (nt), ``component`` (3).
    """
    group = SO3()
    T = period(INERTIA, OMEGA0)
    nsave = int(np.ceil(N_PERIODS * T / SAVE_DT))
    t = SAVE_DT * np.arange(nsave + 1)
    W_ex, R_ex = rigid_body_exact(INERTIA, OMEGA0, t)
    M_ex = INERTIA * W_ex
    E0 = kinetic_energy(INERTIA, M_ex[0])

    labels, rotvec, momentum, energy_err, att_err, defect, dts, schemes, walls = ([] for _ in range(9))
    for method, dt in RUNS:
        every = int(round(SAVE_DT / dt))
        tic = time.perf_counter()
        ts, R, M = step_rigid_body(group, np.eye(3), INERTIA * OMEGA0, INERTIA, dt, nsave * every, method,
                                   save_every=every)
        walls.append(time.perf_counter() - tic)
        assert np.allclose(ts, t, rtol=0, atol=1e-9)
        labels.append(f"{method} dt={dt:g}")
        schemes.append(method)
        dts.append(dt)
        # The projection is needed only for forward-euler, whose R is not a rotation: log of
        # its closest rotation (polar factor) is the attitude it represents.
        U, _, Vt = np.linalg.svd(R)
        R_rot = U @ Vt
        rotvec.append(group.log(R_rot))
        momentum.append(M)
        energy_err.append(kinetic_energy(INERTIA, M) / E0 - 1.0)
        att_err.append(np.linalg.norm(group.log(np.swapaxes(R_ex, -1, -2) @ R_rot), axis=-1))
        defect.append(group.defect(R))

    ds = xr.Dataset(
        data_vars={
            "attitude": (("method", "time", "component"), np.array(rotvec),
                         {"long_name": "attitude as rotation vector log(R) (body to space)", "units": "rad"}),
            "angular_momentum": (("method", "time", "component"), np.array(momentum),
                                 {"long_name": "body angular momentum M", "units": "kg m2 s-1"}),
            "attitude_exact": (("time", "component"), group.log(R_ex),
                               {"long_name": "exact attitude as rotation vector log(R)", "units": "rad"}),
            "angular_momentum_exact": (("time", "component"), M_ex,
                                       {"long_name": "exact body angular momentum M", "units": "kg m2 s-1"}),
            "energy_error": (("method", "time"), np.array(energy_err),
                             {"long_name": "relative kinetic energy error E/E(0) - 1", "units": "1"}),
            "attitude_error": (("method", "time"), np.array(att_err),
                               {"long_name": "attitude error |log(R_exact^T R)|", "units": "rad"}),
            "so3_defect": (("method", "time"), np.array(defect),
                           {"long_name": "distance from SO(3), |R^T R - I|_F", "units": "1"}),
            "time_step": (("method",), np.array(dts), {"long_name": "integrator time step", "units": "s"}),
            "integrator": (("method",), np.array(schemes, dtype=object),
                           {"long_name": "integrator name", "units": "1"}),
            "wall_time": (("method",), np.array(walls),
                          {"long_name": "wall-clock time of the integration", "units": "s"}),
            "inertia": (("component",), INERTIA, {"long_name": "principal moments of inertia",
                                                  "units": "kg m2"}),
            "omega0": (("component",), OMEGA0, {"long_name": "initial body angular velocity",
                                                "units": "rad s-1"}),
        },
        coords={
            "method": ("method", np.array(labels, dtype=object),
                       {"long_name": "integrator and time step", "units": "1"}),
            "time": ("time", t, {"long_name": "time", "units": "s"}),
            "component": ("component", np.array([1, 2, 3], dtype=np.int32),
                          {"long_name": "body principal axis index", "units": "1"}),
        },
    )
    now = dt_.datetime.now(dt_.UTC).replace(microsecond=0).isoformat()
    ds.attrs = {
        "Conventions": "CF-1.11",
        "title": "Free rigid body on SO(3): integrators against the exact Jacobi elliptic solution",
        "institution": "cartan",
        "source": f"cartan {cartan_version()} (cartan.rigid_body, examples/rigid_body_demo.py)",
        "history": f"{now} created by: python {' '.join(sys.argv)}",
        "references": "Landau & Lifshitz, Mechanics, §37; Celledoni, Fassò, Säfström & Zanna, "
                      "SIAM J. Sci. Comput. 30 (2008) 2084",
        "comment": f"inertia diag(1, 2, 3), omega0 (1, 0, 0.5), Omega period {T:.9f} s; "
                   "SI units when the inertia is read in kg m2",
    }
    return ds


def summary(ds: xr.Dataset) -> str:
    """Table (method, dt, max attitude error, max energy error, max SO(3) defect)."""
    lines = [f"{'method':<15}{'dt':>8}{'max |log(Rex^T R)|':>21}{'max |E/E0-1|':>14}{'SO(3) defect':>14}"
             f"{'wall [s]':>10}"]
    for i in range(ds.sizes["method"]):
        run = ds.isel(method=i)
        lines.append(
            f"{str(run.integrator.values):<15}{float(run.time_step):>8g}"
            f"{float(run.attitude_error.max()):>21.3e}{float(abs(run.energy_error).max()):>14.3e}"
            f"{float(run.so3_defect.max()):>14.3e}{float(run.wall_time):>10.3f}"
        )
    return "\n".join(lines)


def plot(ds: xr.Dataset, path: Path) -> None:
    """Energy error and attitude error against time for every run, log scale."""
    fig, (ax_e, ax_r) = plt.subplots(2, 1, figsize=(8, 7), sharex=True, constrained_layout=True)
    tiny = 1e-17  # keeps exact zeros (t = 0) off a log axis
    for i, label in enumerate(ds.method.values):
        run = ds.isel(method=i)
        ax_e.semilogy(ds.time[1:], np.abs(run.energy_error[1:]) + tiny, label=label, lw=1)
        ax_r.semilogy(ds.time[1:], run.attitude_error[1:] + tiny, label=label, lw=1)
    ax_e.set_ylabel("|E/E(0) − 1|")
    ax_r.set_ylabel("‖log(R_exactᵀ R)‖ [rad]")
    ax_r.set_xlabel("t")
    ax_e.set_title("Free rigid body, 𝕀 = diag(1, 2, 3), ω₀ = (1, 0, 0.5)")
    ax_e.legend(fontsize=8, ncol=2)
    for ax in (ax_e, ax_r):
        ax.grid(True, which="major", alpha=0.3)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120, format="png")
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--outdir", type=Path, default=Path("out"), help="output directory (default: out/)")
    args = parser.parse_args(argv)
    args.outdir.mkdir(parents=True, exist_ok=True)

    ds = simulate()
    print(f"Free rigid body, inertia diag(1, 2, 3), omega0 (1, 0, 0.5): Omega period "
          f"{period(INERTIA, OMEGA0):.6f}, integrated to t = {float(ds.time[-1]):g}")
    print(summary(ds))

    nc_path = args.outdir / "rigid_body.nc"
    png_path = args.outdir / "rigid_body.png"
    with atomic_path(nc_path) as tmp:
        ds.to_netcdf(tmp, engine="netcdf4")
    plot(ds, png_path)
    print(f"wrote {nc_path}")
    print(f"wrote {png_path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
