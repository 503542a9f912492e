"""The ``cartan`` command line."""

from __future__ import annotations

import subprocess
import sys

from click.testing import CliRunner

import cartan
from cartan.cli import main


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
