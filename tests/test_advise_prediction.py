"""``cartan advise --check``: the predicted difference against the measured one.

The check of a dynamic scene measures ``x_full,Δt − x_twin,Δt'`` at the full pilot's last step:
the model difference plus the two runs' time-step errors.  The prediction estimates each part
(the displacement the held strains carry; Richardson from a run at Δt/2 for each time-step
error) and adds their sizes, the upper estimate (cartan.advise._advise_held_dynamic).  No time
is asserted.
"""

from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest

from cartan import advise as adv
from cartan.advise import HELD_STRAINS, Advice, ReductionAdvice, advise

#: the stiff rod of ``examples/stiff-rod-swing.toml`` (EA = GA = 1e6 B/L², n = 11, to t = 0.5)
STIFF_SWING = pathlib.Path(__file__).resolve().parents[1] / "examples" / "stiff-rod-swing.toml"


def test_time_error_is_richardson_at_the_integrators_order():
    """The time-step error of a lie-verlet pilot (order 2) from a second run at Δt/2, against
    its difference from a run at Δt/16 (whose own error is 16⁻² = 0.4 % of it): the estimate
    neglects O(Δt) of itself and the reference carries 0.4 %, so 5 % is allowed."""
    sub = adv._subject("rod-cantilever-gravity")
    dt, t_end, run = adv._dynamic_settings(sub, 20)
    ds = adv._simulate(sub.problem, sub.run_settings, t_end)
    order = int(run.integrator.order)
    assert order == 2
    estimate = adv._time_error(sub.problem, sub.run_settings, t_end, ds, 3, order)
    fine = dict(sub.run_settings, dt=dt / 16)
    reference = adv._simulate(sub.problem, fine, t_end)
    error = adv._last_positions(ds, 3) - adv._last_positions(reference, 3)
    assert adv._largest(error) > 0.0
    assert adv._largest(estimate - error) <= 0.05 * adv._largest(error)
    # at order 1 the same two runs give twice the difference, at order 2 four thirds of it
    e1 = adv._time_error(sub.problem, sub.run_settings, t_end, ds, 3, 1)
    assert adv._largest(e1) == pytest.approx(1.5 * adv._largest(estimate), rel=1e-12)


def test_report_lists_both_parts_of_the_prediction():
    """The text, the dict and the Dataset carry the model difference and the time-step errors
    beside the predicted and measured differences."""
    r = ReductionAdvice(HELD_STRAINS, "approximate", admitted=True, indicator_name="max |X − X_held|",
                        indicator=1e-5, error_estimate=9e-6, error_scale=1.0, speedup_estimate=100.0,
                        measured_difference=1.3e-4, time_ratio=4.0, predicted_difference=1.2e-4,
                        model_difference=9e-6, time_error=1.25e-4, full_time_error=4e-8)
    report = Advice("s", "dynamic", "cosserat-rod", "a pilot", 1e-3, True, [r])
    text = str(report)
    assert "predicted 0.00012 (predicted / measured 0.923)" in text
    assert "model difference 9e-06 at the pilot's end" in text
    assert "reduced run 0.000125, full run 4e-08" in text
    assert "the sum of the parts' sizes is its upper estimate" in text
    row = report.to_dict()["reductions"][0]
    assert row["prediction_ratio"] == pytest.approx(1.2 / 1.3)
    assert row["time_error"] == 1.25e-4 and row["model_difference"] == 9e-6
    ds = report.to_dataset()
    for name in ("predicted_difference", "model_difference", "time_error", "full_time_error", "prediction_ratio"):
        assert name in ds
    # unchecked: no parts, no ratio
    blank = ReductionAdvice(HELD_STRAINS, "approximate")
    assert math.isnan(blank.prediction_ratio)


@pytest.mark.slow  # compiles the filament's rattle loop (≈ 1–2 min on a fresh cache); ≈ 3·10⁴ rod steps
def test_stiff_rod_prediction_is_within_2x_of_the_check():
    """The whole run as the pilot: the twin's time-step error at its step (≈ 100 × the rod's)
    dominates the measured difference, and the prediction — the model difference plus the two
    runs' time-step errors — is within a factor 2 of it; the model difference alone is not."""
    report = advise(STIFF_SWING, check=True, pilot_steps=20000)
    fil = report[HELD_STRAINS]
    assert fil.admitted and math.isfinite(fil.measured_difference)
    assert 0.5 <= fil.prediction_ratio <= 2.0
    assert fil.model_difference / fil.measured_difference < 0.5  # the model alone misses it
    assert fil.time_error > fil.model_difference > 0.0
    assert 0.0 < fil.full_time_error < fil.time_error
    parts = fil.model_difference + fil.time_error + fil.full_time_error
    assert fil.predicted_difference == pytest.approx(parts, rel=1e-12)
    text = str(report)
    assert "time-step errors: reduced run" in text and "predicted / measured" in text
    assert "the twin's step shortened to end there" in fil.check_note
    # the two runs end at the same time: the full pilot's last step
    assert "t = 0.500016" in fil.check_note
    assert np.isfinite(fil.time_ratio)
