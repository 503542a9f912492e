"""A medium refuses a support its equations do not admit (``Medium.check_support``, called by
``Problem`` for every end): the core's hook, the Nambu–Goto string's refusal of an end that holds
its time component (docs/media/relativistic-rod.md §3 "Fixed ends"), the scene loader and the
command line on such a scene (one ``cartan: error:`` line, status 2, nothing written)."""

from __future__ import annotations

import pathlib

import cartan_relativistic
import pytest
from cartan_relativistic.fixed import FIXED_END, fixed_end
from click.testing import CliRunner

import cartan
from cartan.cli import main


def _string(**bounds):
    rod = cartan.medium("relativistic-rod")
    grid = cartan.Grid(9, length=1.0)
    return cartan.Problem(rod, grid, rod.initial_state(grid, "standing"), boundaries=bounds)


def test_default_hook_accepts_and_is_called_for_every_end(monkeypatch):
    rod = cartan.medium("cosserat-rod", E=1e6, G=1e4, radius=0.25, density=5000.0)
    grid = cartan.Grid(5, length=1.0)
    init = rod.initial_state(grid, "straight")
    bounds = {"start": cartan.Clamped(), "end": cartan.Held(components=(0, 1, 2))}
    assert rod.check_support(bounds["start"], "start") is None  # the base class accepts every support
    seen = []
    monkeypatch.setattr(rod, "check_support", lambda b, end: seen.append((end, b.kind)))
    cartan.Problem(rod, grid, init, boundaries=bounds)
    assert sorted(seen) == [("end", "held"), ("start", "clamped")]

    def refuse(b, end):
        if isinstance(b, cartan.Held):
            raise ValueError(f"boundaries[{end!r}]: not here")

    monkeypatch.setattr(rod, "check_support", refuse)
    with pytest.raises(ValueError, match=r"^boundaries\['end'\]: not here$"):
        cartan.Problem(rod, grid, init, boundaries=bounds)


@pytest.mark.parametrize("support", [cartan.Clamped(), cartan.Held(components=(0,)),
                                     cartan.Held(components=tuple(range(10)))])
@pytest.mark.parametrize("end", ["start", "end"])
def test_nambu_goto_refuses_an_end_holding_its_time(support, end):
    with pytest.raises(ValueError) as info:
        _string(**{end: support})
    text = str(info.value)
    assert text.startswith(f"boundaries[{end!r}]: a {support.kind} end of the Nambu–Goto string")
    assert "fixed_end()" in text and f"Held(components={FIXED_END})" in text


def test_nambu_goto_accepts_ends_free_in_time():
    p = _string(start=fixed_end(), end=cartan.Held(components=(1, 2, 3)))
    assert p.boundaries["start"].components == FIXED_END
    assert isinstance(_string(start=cartan.Free(), end=fixed_end()).boundaries["start"], cartan.Free)


def test_elastic_string_accepts_a_clamp():
    """The elastic string runs in the temporal gauge with the run's time the lab time: a clamp
    holds the end at rest in the lab (tests/test_relativistic_clocks.py), accepted."""
    rod = cartan.medium("relativistic-rod", energy="elastic", stiffness=0.25)
    grid = cartan.Grid(5, length=1.0)
    p = cartan.Problem(rod, grid, rod.initial_state(grid, "straight"), boundaries={"start": cartan.Clamped()})
    assert isinstance(p.boundaries["start"], cartan.Clamped)


def _clamped_scene(tmp_path: pathlib.Path) -> pathlib.Path:
    scenes = pathlib.Path(cartan_relativistic.__file__).parent / "scenes"
    text = (scenes / "relativistic-string-plucked.toml").read_text()
    held = "start = { kind = \"held\", components = [1, 2, 3, 4, 5, 6, 7, 8, 9] }"
    assert held in text
    path = tmp_path / "clamped.toml"
    path.write_text(text.replace(held, "start = { kind = \"clamped\" }"))
    return path


def test_scene_with_a_refused_support(tmp_path):
    with pytest.raises(cartan.SceneError, match=r"boundaries\['start'\]: a clamped end of the Nambu–Goto string"):
        cartan.load_scene(_clamped_scene(tmp_path))


def test_cli_refuses_the_scene_in_one_line(tmp_path):
    scene = _clamped_scene(tmp_path)
    out = tmp_path / "out.nc"
    res = CliRunner().invoke(main, ["run", str(scene), "-o", str(out), "--no-progress"])
    assert res.exit_code == 2, (res.stdout, res.stderr)
    lines = res.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("cartan: error: "), res.stderr
    assert "boundaries['start']: a clamped end of the Nambu–Goto string" in lines[0] and "fixed_end()" in lines[0]
    assert res.stdout == "" and not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["clamped.toml"]
