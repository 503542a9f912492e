"""``cartan warm``: compiling every numba kernel into the on-disk cache.

A process started after ``cartan warm`` must load every kernel it uses from numba's cache:
the tests count numba's cache misses (signatures compiled in the process) over every cached
kernel of the loaded cartan modules (:func:`cartan.cli_cache.kernel_inventory`).
"""

from __future__ import annotations

import pathlib
import subprocess
import sys
import textwrap

import pytest
from click.testing import CliRunner

from cartan.cli import main
from cartan.cli_cache import kernel_inventory, warm

ROOT = pathlib.Path(__file__).resolve().parents[1]
CARTAN = [sys.executable, "-c", "from cartan.cli import main; main()"]

#: a first run in a new process: a free SE(3) rod, 100 lie-verlet steps (the T6 scene), then
#: the numba cache misses over every cached cartan kernel
FIRST_RUN = textwrap.dedent(
    """
    import numpy as np
    import cartan
    from cartan.cli_cache import kernel_inventory

    rod = cartan.medium("cosserat-rod", E=1e6, G=1e4, radius=0.25, density=5000.0)
    grid = cartan.Grid(101, length=3.0)
    init = rod.initial_state(grid, "straight", velocity=[0.01, 0.0, 0.0, 0.0, 0.0, 0.0])
    ds = cartan.simulate(cartan.Problem(rod, grid, init), dt=1e-4, t_end=1e-2, progress=False)
    assert int(ds.step[-1]) == 100
    kernels = kernel_inventory()
    print(len(kernels), sum(k.hits for k in kernels), sum(k.misses for k in kernels))
    """
)


def _run(args, **kw):
    return subprocess.run(args, capture_output=True, text=True, cwd=ROOT, timeout=1200, **kw)


def _compiled(stdout: str) -> int:
    """The number of signatures compiled, from the summary line of ``cartan warm``."""
    line = next(ln for ln in stdout.splitlines() if ln.startswith("cartan warm:"))
    return int(line.split(" signature(s) compiled")[0].rsplit(" ", 1)[1])


def test_warm_rejects_unknown_names():
    with pytest.raises(ValueError, match="parts must be among"):
        warm(["kernels"])
    with pytest.raises(ValueError, match="groups: unknown group 'SE4'"):
        warm(["groups"], groups=["SE4"])
    with pytest.raises(ValueError, match="cases: unknown case 'no-such-case'"):
        warm(["cases"], cases=["no-such-case"])
    with pytest.raises(ValueError, match="integrators: unknown integrator 'leapfrog'"):
        warm(["cases"], integrators=["leapfrog"])
    with pytest.raises(ValueError, match="schemes: unknown scheme 'fem'"):
        warm(["cases"], schemes=["fem"])
    result = CliRunner().invoke(main, ["warm", "--group", "SE4"])
    assert result.exit_code == 2 and "unknown group 'SE4'" in result.output


@pytest.mark.slow
def test_warm_reports_every_workload():
    lines: list[str] = []
    steps = warm(groups=["SO2", "SE3"], cases=["rod-axial-wave-free"], integrators=["lie-verlet", "overdamped"],
                 schemes=["lattice"], log=lines.append)
    assert [s.name for s in steps if s.part == "groups"] == ["SO2", "SE3"]
    runs = {s.name: s for s in steps if s.part == "cases"}
    assert sorted(runs) == ["rod-axial-wave-free / lie-verlet / lattice", "rod-axial-wave-free / overdamped / lattice"]
    assert runs["rod-axial-wave-free / lie-verlet / lattice"].status == "ok"
    # a combination the case does not support is skipped with the reason, not failed
    assert runs["rod-axial-wave-free / overdamped / lattice"].status == "skipped"
    assert "Damping" in runs["rod-axial-wave-free / overdamped / lattice"].message
    assert not [s for s in steps if s.status == "failed"]
    assert len(lines) == len(steps)
    names = {(k.module, k.name) for k in kernel_inventory()}
    assert any(mod.startswith("cartan.schemes._lattice_compiled") and name == "lie_verlet_se3_loop"
               for mod, name in names)
    assert ("cartan.groups.se3", "_exp_batch") in names
    assert ("cartan.schemes.base", "_prefix_products_kernel") in names


@pytest.mark.slow
def test_a_process_after_warm_compiles_nothing():
    """``cartan warm`` on an SE(3) rod case with ``lie-verlet`` on the lattice, then a first rod
    simulation in a new process: every kernel it uses comes from the cache."""
    args = [*CARTAN, "warm", "--group", "SE3", "--case", "rod-axial-wave-free", "--integrator", "lie-verlet",
            "--scheme", "lattice", "--strict"]
    first = _run(args)
    assert first.returncode == 0, first.stderr
    again = _run(args)
    assert again.returncode == 0, again.stderr
    assert _compiled(again.stdout) == 0, again.stdout
    run = _run([sys.executable, "-c", FIRST_RUN])
    assert run.returncode == 0, run.stderr
    kernels, hits, misses = map(int, run.stdout.split()[-3:])
    assert kernels > 100 and hits >= 1 and misses == 0, run.stdout


@pytest.mark.slow
def test_full_warm_leaves_nothing_to_compile():
    """After a full ``cartan warm``, a second one (every group, case, integrator and scheme)
    loads everything from the cache."""
    first = _run([*CARTAN, "warm"])
    assert first.returncode == 0, first.stderr
    again = _run([*CARTAN, "warm", "--strict", "--verbose"])
    assert again.returncode == 0, again.stderr
    assert _compiled(again.stdout) == 0, [ln for ln in again.stdout.splitlines() if not ln.endswith(" 0 compiled")]
