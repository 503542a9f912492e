"""The work around the steps of ``simulate``: whole save blocks in one compiled call, the CFL
estimate computed once per content.

Once a run's energy scale is set, a compiled loop takes a whole save block in one call and the
energy test runs at the save; a block that fails is run again in the sub-blocks of the step-by-step
schedule (steps 1, 2, 4, 8, … of the block).  Each step depends only on the state, so the frames
are the same numbers as with the sub-blocks, and a blow-up names the same step, time and reason.
The runs here use the toy registry's rod (the lattice's hand-written lie-verlet loop, which the
fast suite compiles anyway).
"""

from __future__ import annotations

import importlib
import json

import numpy as np
import pytest
from test_scene import toy_registry

from cartan.api import InstabilityError, StabilityWarning, scene, simulate
from cartan.integrators import LieVerlet
from cartan.plugins import reset_registry

sim = importlib.import_module("cartan.simulate")  # the module, not the function


@pytest.fixture
def toy(tmp_path):
    toy_registry(tmp_path)
    yield tmp_path
    reset_registry()


@pytest.fixture
def sub_blocks(monkeypatch):
    """Switch the whole blocks off (the schedule before them), counting the calls that asked for them."""
    real, asked = sim._advance, []

    def patched(*args, whole=False, **kwargs):
        asked.append(whole)
        return real(*args, **kwargs)

    def on():
        monkeypatch.setattr(sim, "_advance", patched)

    def off():
        monkeypatch.setattr(sim, "_advance", real)

    return on, off, asked


def _same(a, b) -> None:
    for name in a.variables:
        x, y = a[name].values, b[name].values
        assert np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), name
    ca, cb = json.loads(a.attrs["cartan_config"]), json.loads(b.attrs["cartan_config"])
    assert ca["run"] == cb["run"] and ca["counters"]["nstep"] == cb["counters"]["nstep"]


def test_whole_blocks_give_the_frames_of_the_sub_blocks(toy, sub_blocks):
    on, off, asked = sub_blocks
    kw = {"dt": 0.01, "t_end": 0.6, "save_every": 7, "progress": False}
    whole = simulate(scene("toy-butterfly"), **kw)
    on()
    split = simulate(scene("toy-butterfly"), **kw)
    off()
    assert any(asked)  # the run did ask for whole blocks (after its first one)
    _same(whole, split)


@pytest.mark.parametrize("dt, save_every, reason", [(0.033, 10, "kinetic energy"), (0.05, 2, "energy balance")])
def test_a_blow_up_in_a_later_block_names_the_same_step(toy, sub_blocks, dt, save_every, reason):
    """Δt above the CFL estimate (0.0318): the energy scale is set in the first block and the run
    blows up in a later one — the compiled loop's kinetic test stops the block early (Δt = 0.033,
    step 17), or the energy test at the save fails (Δt = 0.05, step 4); the block is run again in
    sub-blocks and the error is the sub-blocks' own."""
    on, off, _ = sub_blocks
    errors = []
    for mode in ("whole", "sub-blocks"):
        if mode == "sub-blocks":
            on()
        with pytest.warns(StabilityWarning), pytest.raises(InstabilityError) as info:
            simulate(scene("toy-butterfly"), dt=dt, t_end=100.0, save_every=save_every, output=toy / f"{mode}.nc")
        errors.append(info.value)
    off()
    a, b = errors
    assert a.step > save_every and reason in str(a)  # after the first block
    assert (a.step, a.time, a.dt, a.dt_max) == (b.step, b.time, b.dt, b.dt_max)
    assert str(a).split("; last good state")[0] == str(b).split("; last good state")[0]
    from cartan.api import open as open_run

    _same(open_run(a.path), open_run(b.path))


def test_the_cfl_estimate_is_computed_once_per_content(toy, monkeypatch):
    """Two runs of the same problem estimate once; a changed problem (a load changed in place)
    is estimated afresh, and its estimate is the one a fresh estimate gives."""
    calls = []
    real = LieVerlet.dt_max

    def counted(self, scheme, state):
        calls.append(1)
        return real(self, scheme, state)

    monkeypatch.setattr(LieVerlet, "dt_max", counted)
    sim._CFL_MEMO.clear()
    problem = scene("toy-butterfly").problem
    first = simulate(problem, t_end=0.05, progress=False)
    second = simulate(problem, t_end=0.05, progress=False)
    assert len(calls) == 1
    assert json.loads(first.attrs["cartan_config"])["run"] == json.loads(second.attrs["cartan_config"])["run"]
    problem.initial.N[...] = 0.5  # the estimate is taken at the initial state
    changed = simulate(problem, dt=0.01, t_end=0.05, progress=False)
    assert len(calls) == 2
    sim._CFL_MEMO.clear()
    fresh = simulate(problem, dt=0.01, t_end=0.05, progress=False)
    assert len(calls) == 3
    dt_max = [json.loads(ds.attrs["cartan_config"])["run"]["dt_max"] for ds in (first, changed, fresh)]
    assert dt_max[1] == dt_max[2]


@pytest.mark.parametrize("compiled", [True, False])
def test_diagnostics_left_to_the_assembly_are_those_of_each_frame(toy, monkeypatch, compiled):
    """A saved frame's group defect, total momentum and integrability residual, computed for all
    frames at once (``cartan.io.complete_records``: every ``_COMPLETE_EVERY`` frames, here 2, at
    each checkpoint and when the Dataset is assembled), are the numbers each frame's own methods
    give, bit for bit."""
    io = importlib.import_module("cartan.io")
    real_record, real_complete = io.frame_record, io.complete_records
    left = []

    def counted(scheme, records, start=0):
        left.append(sum(isinstance(v, io._Pending) for name in io.DEFERRED for v in records.get(name, ())[start:]))
        return real_complete(scheme, records, start=start)

    monkeypatch.setattr(io, "complete_records", counted)
    monkeypatch.setattr(sim, "_COMPLETE_EVERY", 2)
    kw = {"dt": 0.01, "t_end": 0.3, "save_every": 4, "checkpoint_every": 3, "progress": False, "compiled": compiled,
          "scheme_options": {"track_frames": True}}  # (stepped frames: the lattice's integrability residual)
    batched = simulate(scene("toy-butterfly"), output=toy / "batched.nc", **kw)
    assert sum(n > 0 for n in left) >= 4  # every 2 frames, at checkpoints and at the end: frames to complete
    monkeypatch.setattr(io, "frame_record", lambda scheme, integ, state, defer=False: real_record(scheme, integ, state))
    each = simulate(scene("toy-butterfly"), output=toy / "each.nc", **kw)
    _same(batched, each)
    assert float(batched["integrability_residual"].max()) > 0.0 and float(batched["group_defect"].max()) > 0.0
