"""The ``cartan`` command line: version, listing, and the hardening of ``cartan run`` against bad input
(one error line, status 2, nothing written) and of its outputs."""

from __future__ import annotations

import importlib
import json
import math
import os
import pathlib
import signal
import stat
import subprocess
import sys

import cartan_cosserat
import netCDF4
import pytest
import xarray as xr
from click.testing import CliRunner
from test_fuzz import BASE, ENV, dumps, reference_path
from test_io import damage_data

import cartan
from cartan.cli import main
from cartan.cli_run import safe_name

simulate_module = importlib.import_module("cartan.simulate")


def test_version():
    res = CliRunner().invoke(main, ["--version"])
    assert res.exit_code == 0, res.output
    assert res.output.startswith(f"cartan {cartan.__version__}")


def test_list_groups_shows_origin():
    res = CliRunner().invoke(main, ["list", "groups"])
    assert res.exit_code == 0, res.output
    for name in ("SO2", "SE2", "SO3", "SE3", "SO", "SO13", "Poincare"):
        assert f"  {name} " in res.output
    assert "[cartan " in res.output
    assert "cartan.groups.se3:SE3" in res.output


def test_list_everything():
    res = CliRunner().invoke(main, ["list"])
    assert res.exit_code == 0, res.output
    for kind in ("groups", "spaces", "media", "integrators", "schemes", "cases", "scenes"):
        assert kind in res.output


def test_list_rejects_unknown_kind():
    res = CliRunner().invoke(main, ["list", "widgets"])
    assert res.exit_code != 0
    assert "widgets" in res.output


def test_console_script_runs():
    out = subprocess.run([sys.executable, "-m", "cartan.cli", "list", "spaces"], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "sphere" in out.stdout


# ---------------------------------------------------------------------------- hardening: bad input
# Each case is one line ``cartan: error: ...`` on stderr, status 2 and nothing written; the
# cases run the steps in the numpy reference path (test_fuzz.reference_path).
def _cli(args: list[str], env: dict | None = None):
    with reference_path(False):
        return CliRunner().invoke(main, args, env={**ENV, **(env or {})})


def _scene(folder: pathlib.Path, edit=None, name: str = "scene.toml") -> pathlib.Path:
    doc = json.loads(json.dumps(BASE))
    if edit is not None:
        edit(doc)
    path = folder / name
    path.write_text(dumps(doc))
    return path


def _refused(res, *expected: str) -> str:
    assert res.exception is None or isinstance(res.exception, SystemExit), repr(res.exception)
    assert res.exit_code == 2, (res.stdout, res.stderr)
    lines = res.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("cartan: error: "), res.stderr
    assert res.stdout == ""
    for text in expected:
        assert text in lines[0], lines[0]
    return lines[0]


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--dt", "5e-324"], "above the limit of 100 steps"),
        (["--t-end", "1e308"], "above the limit of 100 steps"),
        (["--t-end", "1e-12"], "the run would take no step"),
        (["--t-end", "0.05", "--max-steps", "3"], "above the limit of 3 steps"),
        (["--max-steps", "0"], "max_steps must be an integer ≥ 1"),
        (["--dt", "nan"], "dt must be finite and > 0"),
        (["--dt", "-1"], "dt must be finite and > 0"),
        (["--save-every", "0"], "save_every must be an integer ≥ 1"),
    ],
)
def test_cli_step_counts_are_bounded(tmp_path, args, expected):
    scene = _scene(tmp_path)
    _refused(_cli(["run", str(scene), "-o", str(tmp_path / "out.nc"), *args]), expected)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.toml"]


def test_cli_step_limit_from_the_environment(tmp_path):
    scene = _scene(tmp_path)
    _refused(_cli(["run", str(scene), "-o", str(tmp_path / "out.nc")], {"CARTAN_MAX_STEPS": "5"}),
             "above the limit of 5 steps", "CARTAN_MAX_STEPS")
    _refused(_cli(["run", str(scene), "-o", str(tmp_path / "out.nc")], {"CARTAN_MAX_STEPS": "many"}),
             "CARTAN_MAX_STEPS must be an integer")
    res = _cli(["run", str(scene), "-o", str(tmp_path / "out.nc"), "--max-steps", "10"], {"CARTAN_MAX_STEPS": "5"})
    assert res.exit_code == 0, res.stderr  # the option overrides the variable


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (lambda d: d["run"].update(dt=1e-320), "above the limit"),
        (lambda d: d["parameters"].update(radius=1e308), "parameters: radius = 1e+308 is out of range"),
        (lambda d: d["parameters"].update(radius=1e100), "parameters: radius = 1e+100 is out of range"),
        (lambda d: (d["parameters"].update(radius=1e-200), d.pop("loads")), "has no inertia"),
        (lambda d: d.update(mode=math.inf), "mode: must be a finite number"),
        (lambda d: d["grid"].update(n=1000000000), "a grid of 1000000000 nodes needs ≈"),
        (lambda d: d["grid"].update(periodic="false"), "grid.periodic: must be true or false, not the string"),
        (lambda d: d["parameters"].update(E="1e5"), "parameters.E: must be a number, not the string '1e5'"),
        (lambda d: d["parameters"].update(E=True), "parameters.E: must be a number, got True"),
        (lambda d: d["run"].update(dt="1e-3"), "run.dt: must be a number, not the string"),
        (lambda d: d["loads"][1].update(g=[0, True, -9.81]), "loads[1].g[1]: must be a number"),
        (lambda d: d["boundaries"]["end"].update(follower="yes"), "must be true or false"),
        (lambda d: d["initial"].update(curvature=math.nan), "initial.curvature: must be a finite number"),
    ],
)
def test_cli_bad_scene_values(tmp_path, edit, expected):
    scene = _scene(tmp_path, edit)
    _refused(_cli(["run", str(scene), "-o", str(tmp_path / "out.nc")]), expected)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.toml"]


def test_cli_ring_mode_inf(tmp_path):
    def ring(d):
        d["grid"]["periodic"] = True
        d.pop("boundaries")
        d["initial"] = {"kind": "ring", "mode": math.inf}

    _refused(_cli(["run", str(_scene(tmp_path, ring)), "-o", str(tmp_path / "out.nc")]), "initial.mode")


def test_cli_scene_files_are_read_safely(tmp_path):
    out = str(tmp_path / "out.nc")
    _refused(_cli(["run", "/dev/zero", "-o", out]), "/dev/zero: not a regular file")
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    _refused(_cli(["run", str(fifo), "-o", out]), "not a regular file")  # does not wait for a writer
    fifo.unlink()
    deep = tmp_path / "deep.toml"
    for depth in (900, 5000):
        deep.write_text(dumps(BASE) + "x = " + "[" * depth + "]" * depth + "\n")
        _refused(_cli(["run", str(deep), "-o", out]), "nested deeper than 32 levels")
    big = tmp_path / "big.toml"
    big.write_text(dumps(BASE) + "#" * (1 << 20))
    _refused(_cli(["run", str(big), "-o", out]), "larger than 1048576 bytes")
    bom = tmp_path / "bom.toml"
    bom.write_bytes(b"\xef\xbb\xbf" + dumps(BASE).encode())
    res = _cli(["run", str(bom), "-o", out])
    assert res.exit_code == 0, res.stderr  # a byte-order mark is accepted
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.toml", "bom.toml", "deep.toml", "out.nc"]


def test_cli_static_load_steps_are_bounded(tmp_path):
    text = (pathlib.Path(cartan_cosserat.__file__).parent / "scenes" / "rod-timoshenko-static.toml").read_text()
    scene = tmp_path / "static.toml"
    scene.write_text(text.replace("load_steps = 1", "load_steps = 1000000000"))
    _refused(_cli(["run", str(scene), "-o", str(tmp_path / "out.nc")]),
             "static.load_steps: must be an integer in 1..10000")


def test_cli_damaged_restart(tmp_path):
    scene = _scene(tmp_path)
    run = tmp_path / "run.nc"
    assert _cli(["run", str(scene), "-o", str(run)]).exit_code == 0
    before = run.read_bytes()
    with netCDF4.Dataset(run, "a") as nc:
        meta = json.loads(nc.groups["checkpoint"].getncattr("cartan_checkpoint"))
        del meta["run"]["dt"]
        meta["t"] = math.nan
        nc.groups["checkpoint"].setncattr("cartan_checkpoint", json.dumps(meta))
    damaged = run.read_bytes()
    assert damaged != before
    _refused(_cli(["run", "--restart", str(run), "--t-end", "0.02"]), "damaged checkpoint: t must be a finite number")
    assert run.read_bytes() == damaged


# ---------------------------------------------------------------------------- hardening: outputs
@pytest.mark.parametrize(
    ("name", "expected"),
    [("../ESCAPED", "_ESCAPED.nc"), ("/tmp/absolute/x", "_tmp_absolute_x.nc"), ("..", "run.nc"),
     ("a b\\c", "a_b_c.nc"), ("fine-name_1.2", "fine-name_1.2.nc")],
)
def test_cli_default_output_stays_beside_the_scene(tmp_path, name, expected):
    folder = tmp_path / "scenes"
    folder.mkdir()
    scene = _scene(folder, lambda d: d.update(name=name))
    res = _cli(["run", str(scene)])
    assert res.exit_code == 0, res.stderr
    assert sorted(p.name for p in folder.iterdir()) == sorted(["scene.toml", expected])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scenes"]
    assert res.stdout.startswith(f"wrote {folder / expected} ")


def test_safe_name():
    assert safe_name("../../etc/passwd") == "_.._etc_passwd"
    assert "/" not in safe_name("/a/b/") and safe_name("") == "run" and safe_name("...") == "run"
    assert len(safe_name("é" * 500).encode()) <= 200


def test_cli_output_is_checked_before_the_run(tmp_path, monkeypatch):
    scene = _scene(tmp_path)

    def never(*args, **kwargs):  # pragma: no cover - the run must not start
        raise AssertionError("the run started")

    monkeypatch.setattr(simulate_module, "_advance", never)
    _refused(_cli(["run", str(scene), "-o", str(tmp_path / "missing" / "out.nc")]),
             "the output folder", "does not exist")
    _refused(_cli(["run", str(scene), "-o", "/dev/null"]), "/dev/null: is a device")
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
    _refused(_cli(["run", str(scene), "-o", str(scene)]), "that is the scene file")
    _refused(_cli(["run", str(scene), "-o", str(tmp_path)]), "is a directory")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.toml"]


def test_cli_blow_up_keeps_the_existing_output(tmp_path):
    scene = _scene(tmp_path)
    out = tmp_path / "out.nc"
    assert _cli(["run", str(scene), "-o", str(out)]).exit_code == 0
    good = out.read_bytes()
    res = _cli(["run", str(scene), "-o", str(out), "--dt", "1", "--t-end", "50"])
    assert res.exit_code == 1, res.stderr
    lines = res.stderr.splitlines()
    assert lines[0].startswith("cartan: warning: Δt = 1 exceeds the CFL estimate")
    assert lines[-1].startswith("cartan: error: unstable at step") and len(lines) == 2
    lastgood = tmp_path / "out.lastgood.nc"
    assert f"saved to {lastgood} ({out} is left as it was)" in lines[-1]
    assert out.read_bytes() == good
    assert cartan.open(lastgood).sizes["time"] >= 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.lastgood.nc", "out.nc", "scene.toml"]


def test_cli_sigterm_during_a_write_leaves_no_temporary_file(tmp_path, monkeypatch):
    scene = _scene(tmp_path)
    real = xr.Dataset.to_netcdf

    def terminated(self, target, *args, **kwargs):
        real(self, target, *args, **kwargs)  # half-way through the write ...
        os.kill(os.getpid(), signal.SIGTERM)  # ... the process is told to stop

    monkeypatch.setattr(xr.Dataset, "to_netcdf", terminated)
    res = _cli(["run", str(scene), "-o", str(tmp_path / "out.nc")])
    assert res.exit_code == 128 + signal.SIGTERM
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.toml"]
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL  # the handler is removed afterwards


def test_cli_leaves_ignored_signals_ignored(tmp_path):
    """Under ``nohup`` SIGHUP is ignored, and stays so: the run is not stopped by a hangup."""
    previous = signal.signal(signal.SIGHUP, signal.SIG_IGN)
    try:
        res = _cli(["run", str(_scene(tmp_path)), "-o", str(tmp_path / "out.nc")])
        assert res.exit_code == 0, res.stderr
        assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGHUP, previous)


def test_cli_plot_of_a_damaged_file(tmp_path):
    scene = _scene(tmp_path)
    out = tmp_path / "out.nc"
    assert _cli(["run", str(scene), "-o", str(out)]).exit_code == 0
    damage_data(out, 0.005)  # a saved time
    res = CliRunner().invoke(main, ["plot", str(out)])
    assert res.exit_code == 2
    assert res.stderr.count("\n") == 1 and res.stderr.startswith(f"cartan: error: {out}: ")
