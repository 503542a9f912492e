"""A fuzzer of ``cartan run``: scene files, command lines and restart files, good and bad.

Hypothesis builds scene files from a small valid one (a Cosserat rod on a tiny grid, a
few steps) by replacing, deleting and adding keys with awkward values (strings that spell
numbers, booleans, huge, tiny and non-finite numbers, nested tables), by damaging the bytes
(a byte-order mark, garbage, truncation, deep nesting, a file over 1 MiB), and combines them
with command-line options (``--dt``, ``--t-end``, ``--save-every``, ..., ``-o`` naming a new
file, an existing one, a missing folder, a device, a directory or the scene itself) and with
damaged checkpoints for ``--restart``.  ``cartan`` runs in-process through its ``main``
function, and every case must end in one of the documented outcomes:

* success: status 0, ``wrote ...`` on stdout, the output is a readable run file, stderr holds
  warning lines only, and nothing else is written;
* bad input: status 2, exactly one stderr line starting ``cartan: error:``, nothing on stdout
  and nothing written in the output folder (no output, no temporary file, existing files
  unchanged);
* a blow-up (or a solve that fails): status 1, the last stderr line ``cartan: error: ...``
  (after warning lines), existing files unchanged and at most the last good state
  ``NAME.lastgood.nc`` written beside the output.

The cases run the steps in the numpy reference path (``compiled=False``, backend ``numpy``):
what is fuzzed is the handling of the input, and this way no case waits for numba to compile
a loop for a new combination.  ``CARTAN_MAX_STEPS`` and ``CARTAN_MAX_MEMORY`` are set low, so
that whatever the fuzzer draws, a case runs within a second.  The default run has 150
cases (3 × 50); the ``slow`` tests draw thirty times as many and also let the compiled loops and
the other integrators and schemes run.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib
import json
import math
import pathlib
import re
import shutil
import tempfile

import netCDF4
import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import cartan
from cartan.cli import main

simulate_module = importlib.import_module("cartan.simulate")

#: the environment of every case: small limits, no progress bar, no compile messages
ENV = {"CARTAN_MAX_STEPS": "100", "CARTAN_MAX_MEMORY": "1M", "CI": "1", "CARTAN_SHOW_COMPILE": "0"}
FAST = settings(max_examples=50, deadline=None, suppress_health_check=list(HealthCheck))
SLOW = settings(max_examples=1500, deadline=None, suppress_health_check=list(HealthCheck))

BASE = {
    "name": "fuzz",
    "description": "a small rod",
    "medium": "cosserat-rod",
    "parameters": {"E": 1e4, "poisson": 0.5, "radius": 0.25, "density": 5000.0},
    "grid": {"n": 5, "length": 1.0, "periodic": False},
    "boundaries": {
        "start": {"kind": "clamped"},
        "end": {"kind": "free", "load": [0.0, 0.0, -0.05, 0.0, 0.0, 0.0], "follower": False},
    },
    "loads": [
        {"kind": "damping", "coefficients": [1.0, 1.0, 1.0, 1e-3, 1e-3, 1e-3]},
        {"kind": "gravity", "g": [0.0, 0.0, -9.81]},
    ],
    "initial": {"kind": "arc", "curvature": 0.6},
    "run": {"dt": 1e-3, "t_end": 0.01, "save_every": 5},
}

#: every key of BASE, as paths
PATHS = [
    ("name",), ("description",), ("medium",), ("mode",),
    ("parameters",), ("parameters", "E"), ("parameters", "poisson"), ("parameters", "radius"),
    ("parameters", "density"), ("parameters", "G"),
    ("grid",), ("grid", "n"), ("grid", "shape"), ("grid", "length"), ("grid", "periodic"),
    ("boundaries",), ("boundaries", "start"), ("boundaries", "end"), ("boundaries", "u-start"),
    ("boundaries", "end", "load"), ("boundaries", "end", "follower"), ("boundaries", "end", "kind"),
    ("loads",), ("loads", 0, "coefficients"), ("loads", 1, "g"), ("loads", 0, "kind"),
    ("initial",), ("initial", "kind"), ("initial", "curvature"), ("initial", "centered"),
    ("initial", "angle"), ("initial", "mode"),
    ("run",), ("run", "dt"), ("run", "t_end"), ("run", "save_every"), ("run", "checkpoint_every"),
    ("run", "integrator"), ("run", "scheme"), ("run", "integrator_options"),
    ("static",), ("static", "load_steps"), ("continuation",),
]

# ---------------------------------------------------------------------------- values
SPELLED = ["1e5", "false", "true", "inf", "nan", "-inf", " 2 ", "0x10", "1_000", "yes", "", "..", "/", "lattice",
           "lie-verlet", "static", "continuation", "dynamic", "arc", "straight", "clamped", "free", "gravity",
           "damping", "../ESCAPED", "/tmp/ABSOLUTE", "a/b", "\u00e9t\u00e9", "\x00", "\x7f"]
EDGE_FLOATS = [0.0, -0.0, 5e-324, 1e-320, 1e-200, 1e-160, 1e-12, 1e-3, 0.5, 1.0, 2.0, 1e5, 1e77, 1e100, 1e300,
               1e308, -1.0, -1e308, math.inf, -math.inf, math.nan]
EDGE_INTS = [-1, 0, 1, 2, 3, 5, 7, 10**9, 10**12, 2**63 - 1, 2**63, 10**30]

scalars = st.one_of(
    st.booleans(),
    st.sampled_from(EDGE_INTS),
    st.integers(-20, 20),
    st.sampled_from(EDGE_FLOATS),
    st.floats(),
    st.sampled_from(SPELLED),
    st.text(max_size=8),
)
values = st.recursive(
    scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=7), st.dictionaries(st.sampled_from(["kind", "x", "n", "g"]),
                                                                         inner, max_size=3)),
    max_leaves=12,
)


# ---------------------------------------------------------------------------- TOML
def _text(s: str) -> str:
    out = json.dumps(s, ensure_ascii=False)
    return out.replace("\x7f", "\\u007f")


def _key(k: object) -> str:
    k = str(k)
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else _text(k)


def _value(v: object) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return _text(v)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def dumps(doc: dict) -> str:
    """TOML text of ``doc``: top-level tables as ``[table]``, arrays of tables as ``[[name]]``."""
    lines = [f"{_key(k)} = {_value(v)}" for k, v in doc.items()
             if not isinstance(v, dict) and not (isinstance(v, list) and v and all(isinstance(x, dict) for x in v))]
    for k, v in doc.items():
        if isinstance(v, dict):
            lines += ["", f"[{_key(k)}]", *(f"{_key(a)} = {_value(b)}" for a, b in v.items())]
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            for table in v:
                lines += ["", f"[[{_key(k)}]]", *(f"{_key(a)} = {_value(b)}" for a, b in table.items())]
    return "\n".join(lines) + "\n"


def test_dumps_round_trips():
    import tomllib

    assert tomllib.loads(dumps(BASE)) == BASE


# ---------------------------------------------------------------------------- scene edits
def _edit(doc: dict, path: tuple, action: str, value: object) -> None:
    """Set (``"set"``) or delete (``"del"``) the key at ``path``, creating tables on the way."""
    node: object = doc
    for part in path[:-1]:
        if isinstance(node, dict):
            node = node.setdefault(part, {})
        elif isinstance(node, list) and isinstance(part, int) and part < len(node):
            node = node[part]
        else:
            return
    last = path[-1]
    if isinstance(node, dict):
        if action == "del":
            node.pop(last, None)
        else:
            node[last] = value
    elif isinstance(node, list) and isinstance(last, int) and last < len(node):
        if action == "del":
            del node[last]
        else:
            node[last] = value


@st.composite
def scene_bytes(draw, max_edits: int = 3, damaged: int = 7) -> bytes:
    """A scene file: BASE with up to ``max_edits`` keys set or deleted, damaged (one of the
    ways below) about ``damaged`` times in 13."""
    doc = json.loads(json.dumps(BASE))
    edits = st.lists(st.tuples(st.sampled_from(PATHS), st.sampled_from(["set", "set", "del"]), values),
                     max_size=max_edits)
    for path, action, value in draw(edits):
        _edit(doc, path, action, value)
    text = dumps(doc).encode("utf-8")
    damage = draw(st.sampled_from(["none"] * (13 - damaged)
                                  + ["bom", "garbage", "truncate", "deep", "huge", "latin1", "empty"][:damaged]))
    if damage == "bom":
        text = b"\xef\xbb\xbf" + text
    elif damage == "garbage":
        at = draw(st.integers(0, len(text)))
        text = text[:at] + draw(st.binary(min_size=1, max_size=8)) + text[at:]
    elif damage == "truncate":
        text = text[: draw(st.integers(0, len(text)))]
    elif damage == "deep":
        depth = draw(st.sampled_from([20, 40, 200, 900, 3000]))
        text += b"x = " + b"[" * depth + b"]" * depth + b"\n"
    elif damage == "huge":
        text += b"#" * ((1 << 20) + 1) + b"\n"
    elif damage == "latin1":
        text = text.replace(b"fuzz", "f\u00fczz".encode("latin-1"))
    elif damage == "empty":
        text = b""
    return text


# ---------------------------------------------------------------------------- command lines
numbers_text = st.one_of(
    st.sampled_from(["5e-324", "1e308", "1e-12", "nan", "inf", "-1", "0", "abc", "1e-3", "0.002", "0.02", "0.5", "1",
                     ""]),
    st.floats().map(repr),
)
counts_text = st.one_of(st.sampled_from(["0", "-1", "1", "2", "3", "100000", "1.5", "x", "99999999999999999999"]),
                        st.integers(-5, 200).map(str))
OPTIONS = {
    "--dt": numbers_text,
    "--t-end": numbers_text,
    "--save-every": counts_text,
    "--checkpoint-every": counts_text,
    "--max-steps": counts_text,
    "--integrator": st.sampled_from(["lie-verlet", "magic", ""]),
    "--scheme": st.sampled_from(["lattice", "fem", ""]),
}
SLOW_OPTIONS = {**OPTIONS, "--integrator": st.sampled_from(["lie-verlet", "rkmk4", "lie-euler", "forward-euler",
                                                             "implicit-midpoint", "overdamped", "magic"]),
                "--scheme": st.sampled_from(["lattice", "collocation", "fem"])}
OUTPUTS = ["run.nc", "run.nc", "existing.nc", None, "missing/run.nc", "/dev/null", ".", "scene.toml",
           "existing.lastgood.nc", "run"]


def options(table: dict) -> st.SearchStrategy[list[str]]:
    """Up to three of the options of ``table``, each with a value drawn from its strategy."""

    def with_values(names: list[str]) -> st.SearchStrategy[list[str]]:
        return st.tuples(*(table[n] for n in names)).map(lambda vals: [x for pair in zip(names, vals) for x in pair])

    return st.lists(st.sampled_from(sorted(table)), max_size=3, unique=True).flatmap(with_values)


# ---------------------------------------------------------------------------- running and judging
def _digest(folder: pathlib.Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir()) if p.is_file()}


@contextlib.contextmanager
def reference_path(compiled: bool):
    """The steps in the numpy reference path (unless ``compiled``)."""
    if compiled:
        yield
        return
    real = simulate_module.simulate
    simulate_module.simulate = functools.partial(real, compiled=False)
    try:
        with cartan.use_backend("numpy"):
            yield
    finally:
        simulate_module.simulate = real


def run_case(folder: pathlib.Path, args: list[str], compiled: bool = False) -> None:
    """Run ``cartan args`` in ``folder`` and check that it ended in a documented outcome."""
    before = _digest(folder)
    with reference_path(compiled):
        res = CliRunner().invoke(main, args, env=ENV)
    if res.exception is not None and not isinstance(res.exception, SystemExit):
        raise AssertionError(f"cartan {args} raised {type(res.exception).__name__}: {res.exception}") from res.exception
    after = _digest(folder)
    err = res.stderr.splitlines()
    event(f"status {res.exit_code}")  # pytest --hypothesis-show-statistics shows the mix
    context = f"cartan {' '.join(args)}\nstatus {res.exit_code}\nstdout {res.stdout!r}\nstderr {res.stderr!r}"
    assert "Traceback" not in res.stderr, context
    new = set(after) - set(before)
    changed = {name for name in before if after.get(name) != before[name]}
    if res.exit_code == 0:
        assert res.stdout.startswith("wrote "), context
        assert all(line.startswith("cartan: warning: ") for line in err), context
        written = pathlib.Path(res.stdout.split()[1])
        assert written.is_file(), context
        ds = cartan.open(written)
        assert ds.sizes["time"] >= 2 and np.all(np.isfinite(ds["time"].values)), context
        if written.parent.resolve() == folder.resolve():
            assert new | changed <= {written.name}, context
        else:
            assert not new and not changed, context
    elif res.exit_code == 2:
        assert len(err) == 1 and err[0].startswith("cartan: error: "), context
        assert res.stdout == "", context
        assert not new and not changed, context
    elif res.exit_code == 1:
        assert err and err[-1].startswith("cartan: error: "), context
        assert all(line.startswith("cartan: warning: ") for line in err[:-1]), context
        assert not changed, context
        assert all(name.endswith(".lastgood.nc") for name in new), context
        for name in new:
            assert cartan.open(folder / name).sizes["time"] >= 1, context
    else:
        raise AssertionError(f"undocumented exit status\n{context}")


@pytest.fixture(scope="module")
def good_run(tmp_path_factory) -> pathlib.Path:
    """A finished run of the base scene, for ``existing.nc`` and ``--restart``."""
    folder = tmp_path_factory.mktemp("good")
    (folder / "scene.toml").write_text(dumps(BASE))
    with reference_path(False):
        res = CliRunner().invoke(main, ["run", str(folder / "scene.toml"), "-o", str(folder / "good.nc")], env=ENV)
    assert res.exit_code == 0, res.output
    return folder / "good.nc"


def _prepare(folder: pathlib.Path, scene: bytes, output: str | None, good: pathlib.Path) -> list[str]:
    (folder / "scene.toml").write_bytes(scene)
    shutil.copy(good, folder / "existing.nc")
    if output is None:
        return []
    target = output if output.startswith("/") else str(folder / output)
    return ["-o", target]


# ---------------------------------------------------------------------------- the fuzz tests
def _scene_case(good_run, scene, opts, output, where, compiled=False):
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(tmp)
        out = _prepare(folder, scene, output, good_run)
        source = {"file": str(folder / "scene.toml"), "device": "/dev/zero", "folder": str(folder),
                  "missing": str(folder / "nothing.toml")}[where]
        run_case(folder, ["run", source, *out, *opts], compiled=compiled)


@FAST
@given(scene=scene_bytes(), output=st.sampled_from(OUTPUTS))
def test_fuzz_scene_files(good_run, scene, output):
    _scene_case(good_run, scene, [], output, "file")


@FAST
@given(scene=scene_bytes(max_edits=1, damaged=1), opts=options(OPTIONS), output=st.sampled_from(OUTPUTS),
       where=st.sampled_from(["file"] * 8 + ["device", "folder", "missing"]))
def test_fuzz_command_lines(good_run, scene, opts, output, where):
    _scene_case(good_run, scene, opts, output, where)


CHECKPOINT_FIELDS = [("t",), ("step",), ("nsaves",), ("nframes",), ("e0",), ("scale",), ("scale_set",),
                     ("arrays",), ("scalars",), ("scalars", "nstep"), ("run",), ("run", "dt"), ("run", "t_end"),
                     ("run", "dt_max"), ("run", "save_every"), ("run", "checkpoint_every"), ("run", "integrator"),
                     ("run", "scheme"), ("run", "integrator_options"), ("counters",), ("counters", "nstep"),
                     ("counters", "wall_time"), ("problem",), ("problem", "grid"), ("scene",), ("scene", "grid")]


@st.composite
def damaged_checkpoints(draw) -> tuple[list, str | None]:
    fields = draw(st.lists(st.tuples(st.sampled_from(CHECKPOINT_FIELDS), st.sampled_from(["set", "set", "del"]),
                                     values), max_size=2))
    data = draw(st.sampled_from([None, None, "S", "time", "step"]))
    return fields, data


def _damage(path: pathlib.Path, fields: list, data: str | None, fill: float) -> None:
    with netCDF4.Dataset(path, "a") as nc:
        group = nc.groups["checkpoint"]
        meta = json.loads(group.getncattr("cartan_checkpoint"))
        for where, action, value in fields:
            _edit(meta, where, action, value)
        group.setncattr("cartan_checkpoint", json.dumps(meta))
        if data == "S":
            group.variables["S"][0, 0] = fill
        elif data == "time":
            nc.variables["time"][-1] = fill
        elif data == "step":
            nc.variables["step"][-1] = int(fill) if math.isfinite(fill) and abs(fill) < 2**62 else 2**40


def _restart_case(good_run, damage, fill, opts, output):
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(tmp)
        out = _prepare(folder, b"", output, good_run)
        (folder / "scene.toml").unlink()
        restart = folder / "restart.nc"
        shutil.copy(good_run, restart)
        _damage(restart, *damage, fill)
        run_case(folder, ["run", "--restart", str(restart), *out, *opts])


@FAST
@given(damage=damaged_checkpoints(), fill=st.sampled_from([math.nan, math.inf, -1.0, 1e308]),
       opts=options({k: OPTIONS[k] for k in ("--t-end", "--dt", "--save-every")}),
       output=st.sampled_from([None, "run.nc", "existing.nc", "missing/run.nc"]))
def test_fuzz_restart_files(good_run, damage, fill, opts, output):
    _restart_case(good_run, damage, fill, opts, output)


@pytest.mark.slow
@SLOW
@given(scene=scene_bytes(max_edits=1, damaged=1), opts=options(SLOW_OPTIONS), output=st.sampled_from(OUTPUTS),
       where=st.sampled_from(["file"] * 8 + ["device", "folder", "missing"]))
def test_fuzz_command_lines_slow(good_run, scene, opts, output, where):
    _scene_case(good_run, scene, opts, output, where)


@pytest.mark.slow
@SLOW
@given(scene=scene_bytes(max_edits=1, damaged=0), opts=options(OPTIONS), output=st.sampled_from(OUTPUTS))
def test_fuzz_compiled_runs_slow(good_run, scene, opts, output):
    """The same inputs with the compiled loops and the numba backend, as users run them."""
    _scene_case(good_run, scene, opts, output, "file", compiled=True)


@pytest.mark.slow
@SLOW
@given(damage=damaged_checkpoints(), fill=st.sampled_from([math.nan, math.inf, -1.0, 1e308]),
       opts=options({k: OPTIONS[k] for k in ("--t-end", "--dt", "--save-every", "--checkpoint-every")}),
       output=st.sampled_from([None, "run.nc", "existing.nc", "missing/run.nc", "/dev/null"]))
def test_fuzz_restart_files_slow(good_run, damage, fill, opts, output):
    _restart_case(good_run, damage, fill, opts, output)
