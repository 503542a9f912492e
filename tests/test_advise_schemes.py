"""``cartan advise --tol`` on a dynamic scene: the scheme as a candidate (lattice or collocation).

The scene is the registered ``rod-cantilever-gravity`` (cosserat-rod, lie-verlet) on n = 11 nodes
over its first :data:`STEPS` steps; each scheme runs on n = 11, 21, 41 with Δt, Δt/2, Δt/4 and
Richardson's estimates use the observed order.  The estimates are checked against a run one level
beyond the study's finest (n = 81, Δt/8), made here.  Times are reported, never asserted.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import cartan
from cartan import advise as advise_module
from cartan.advise import SchemeCandidate, advise_method, advise_schemes, choose_scheme, scheme_table
from cartan.scene import load_scene, scene

NAME, N, STEPS = "rod-cantilever-gravity", 11, 200
#: requested accuracy (length units; the rod is 1 long) at t = 0.4: between the study's coarsest
#: and finest estimates of both schemes (lattice ≈ 7e-3 … 5e-4, collocation ≈ 5e-2 … 2.5e-3), so
#: that the level reaching it is measured, not extrapolated
TOL = 3e-3


def _scene(n: int = N):
    src = dict(scene(NAME).source)
    src["grid"] = dict(src["grid"]) | {"n": n}
    return load_scene(src)


def _without(monkeypatch, name: str) -> None:
    """Make the scheme ``name`` unavailable, as for a medium or integrator that does not run on it."""
    real = advise_module._try_resolve

    def fake(problem, integrator, settings, dt):
        return None if settings.get("scheme") == name else real(problem, integrator, settings, dt)

    monkeypatch.setattr(advise_module, "_try_resolve", fake)


def _candidate(scheme: str, cost: float, status: str = "ok") -> SchemeCandidate:
    return SchemeCandidate(scheme, status, "lie-verlet", (11, 21, 41), (2e-3, 1e-3, 5e-4), (0.1, 0.2, 0.4),
                           (1e-3, 2.5e-4, 6e-5), 2.0, (7.5e-4, 1.9e-4), 21 if math.isfinite(cost) else 0, False,
                           2.5e-4, cost)


def test_choice_rule_on_given_studies():
    """The rule (data, not measurements): the smaller cost to reach tol; a scheme that does not
    apply or does not reach tol is passed over, and the reason says so."""
    lat, col = _candidate("lattice", 0.2), _candidate("collocation", 0.1)
    chosen, why = choose_scheme([lat, col], 1e-3)
    assert chosen is col and "collocation reaches it at n = 21" in why and "2× the cost" in why
    off = _candidate("collocation", math.inf, "not applicable: no")
    chosen, why = choose_scheme([lat, off], 1e-3)
    assert chosen is lat and "collocation: not applicable" in why and "the only scheme" in why
    far = _candidate("collocation", math.inf)
    chosen, why = choose_scheme([far], 1e-3)
    assert chosen is None and "no scheme reaches" in why
    assert "<- recommended" in scheme_table([lat, col], col) and "not applicable" in scheme_table([lat, off])


def test_chart_and_json_carry_the_scheme_study(tmp_path):
    """The report's chart and JSON, from given data (no runs)."""
    import json

    from cartan.advise import MethodAdvice, MethodCandidate

    lat, col = _candidate("lattice", 0.2), _candidate("collocation", 0.1)
    run = MethodCandidate("lie-verlet", "lattice", 2e-3, "ok", error=1e-4, wall_time=0.05, dt_max=8e-3)
    adv = MethodAdvice("s", "cosserat-rod", "lattice", 11, 1e-3, 0.4, 2e-3, "rkmk4 at dt = 0.00025", 1e-11, [run],
                       run, run, schemes=[lat, col], scheme_recommended=col, scheme_note="why")
    data = json.loads(json.dumps(adv.to_dict()))
    assert data["scheme_recommended"] == "collocation" and data["schemes"][0]["n"] == [11, 21, 41]
    assert "scheme recommended: collocation — why" in str(adv)
    assert adv.plot(tmp_path / "wp.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_an_unavailable_scheme_is_listed_and_the_other_recommended(monkeypatch):
    """Collocation made unavailable: the lattice alone (its compiled lie-verlet loop, which the
    fast suite already builds) is studied and recommended when it reaches tol."""
    _without(monkeypatch, "collocation")
    study, chosen, why = advise_schemes(_scene(), 1e-2, pilot_steps=4)
    lat, col = study
    assert col.scheme == "collocation" and col.status.startswith("not applicable") and not col.ok
    assert lat.status == "ok" and lat.n == (11, 21, 41) and lat.dt[0] == pytest.approx(2 * lat.dt[1])
    assert chosen is lat and "the only scheme" in why
    with pytest.raises(ValueError, match="schemes"):
        advise_schemes(_scene(), 1e-2, schemes=("lattice", "finite-volume"))
    with pytest.raises(ValueError, match="schemes"):
        advise_schemes(_scene(), 1e-2, schemes="lattice")


# ---------------------------------------------------------------------------- measured (slow)
#: compiles collocation's lie-verlet loop and stiffness probe for the rod (≈ 2 min on a fresh cache)
@pytest.fixture(scope="module")
def study():
    return advise_schemes(_scene(), TOL, pilot_steps=STEPS)


def _final(n: int, scheme: str, dt: float, t_end: float) -> np.ndarray:
    ds = cartan.simulate(_scene(n), scheme=scheme, dt=dt, t_end=t_end, progress=False, reduce=False)
    return np.asarray(ds["position"].isel(time=-1).values, dtype=float)


@pytest.mark.slow
def test_estimates_meet_a_finer_run(study):
    """For each scheme, the level chosen for tol re-run against n = 8N − 7 with Δt/8 (one level
    beyond the study's finest): the difference is its error minus the finer run's, e·(1 − 2^(−p·k))
    at the observed order for k levels apart if the order holds.  It must be within a factor 2 of
    that prediction: the lattice converges cleanly (orders 1.96, 2.01, 1.94 from n = 11 to 161 at
    t = 0.4), collocation (fd2, SBP closures of order 1 at the clamped and free ends) erratically
    (2.13, 1.27, 2.16), so that its three-level estimate at n = 41 is low by ×1.8.  The
    recommended scheme's level must meet tol against the finer run."""
    runs, chosen, why = study
    t_end = STEPS * _scene().dt
    assert chosen is not None and chosen.cost == min(c.cost for c in runs), why
    for c in runs:
        assert c.status == "ok", c.status
        assert c.chosen_n and not c.extrapolated, scheme_table(runs)
        i = c.n.index(c.chosen_n)
        k = 3 - i
        fine = _final(8 * N - 7, c.scheme, c.dt[0] / 8, t_end)[::8]
        coarse = _final(c.chosen_n, c.scheme, c.dt[i], t_end)[:: 2 ** i]
        measured = float(np.max(np.linalg.norm(coarse - fine, axis=-1)))
        predicted = c.predicted_error * (1 - 2.0 ** (-c.order * k))
        assert 0.5 <= measured / predicted <= 2.0, (c.scheme, measured, predicted)
        if c is chosen:
            assert measured <= TOL, (c.scheme, measured)


@pytest.mark.slow
def test_the_recommendation_changes_when_the_chosen_scheme_is_unavailable(study, monkeypatch):
    runs, chosen, why = study
    other = next(c for c in runs if c is not chosen)
    assert f"{chosen.scheme} reaches it" in why and f"{other.scheme} reaches it" in why
    _without(monkeypatch, chosen.scheme)
    again, rechosen, rewhy = advise_schemes(_scene(), TOL, pilot_steps=STEPS)
    assert rechosen is not None and rechosen.scheme == other.scheme
    assert rechosen.errors == pytest.approx(other.errors, rel=1e-9)  # the same runs, re-timed
    assert f"{chosen.scheme}: not applicable" in rewhy


@pytest.mark.slow
def test_the_method_advice_prints_the_scheme_study():
    adv = advise_method(_scene(), TOL, pilot_steps=STEPS, integrators=("lie-verlet",), dt_powers=(0,))
    assert [c.scheme for c in adv.schemes] == ["lattice", "collocation"]
    text = str(adv)
    assert "scheme recommended: " in text and "to reach tol" in text
    assert adv.to_dict()["scheme_recommended"] == (adv.scheme_recommended.scheme if adv.scheme_recommended else None)


@pytest.mark.parametrize("args, text", [
    (["--quantity", "measure"], "--quantity and --schemes need --tol"),
    (["--schemes", "lattice"], "--quantity and --schemes need --tol"),
    (["--tol", "1e-3", "--schemes", ","], "--schemes"),
    (["--tol", "1e-3", "--schemes", "lattice,finite-volume"], "finite-volume"),
])
def test_cli_bad_scheme_options_are_one_line(args, text):
    from click.testing import CliRunner

    from cartan.cli import main

    res = CliRunner().invoke(main, ["advise", "--scene", NAME, *args])
    assert res.exit_code == 2, (res.stdout, res.stderr)
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("cartan: error: ")]
    assert len(lines) == 1 and res.stdout == "", res.stderr
    assert text in lines[0], lines[0]
