"""String stability with a selectable human driver model (PlatoonConfig.driver_model): model 5
(the environments' drivers) by default and unchanged; model 6 (a 1.0 s reaction time with
anticipation, a reflex, the following rule) passes a disturbance further down a human column."""

import json

import numpy as np
import pytest

from acc_gym.cli import main
from acc_gym.drivers.mpc import ENV_DRIVER_MODEL
from acc_gym.evaluation.string_stability import PlatoonConfig, lead_trace, string_stability


@pytest.mark.parametrize("value", [7, 4, "6", True, None])
def test_an_unknown_driver_model_is_rejected_naming_it(value):
    with pytest.raises(ValueError, match=r"PlatoonConfig\.driver_model must be one of \[5, 6\], got " + repr(value)):
        PlatoonConfig(driver_model=value)


def test_the_default_is_model_5_and_leaves_the_human_column_as_it_was():
    assert PlatoonConfig().driver_model == ENV_DRIVER_MODEL == 5
    default = string_stability("human", PlatoonConfig(drivers="typical"), frequencies=[0.05])
    # docs/string-stability.md's human (typical) row, measured before the driver model was selectable
    assert default.disturbance.drops[-1] == pytest.approx(1.6264, abs=1e-4)
    explicit = string_stability("human", PlatoonConfig(drivers="typical", driver_model=5), frequencies=[0.05])
    np.testing.assert_array_equal(default.disturbance.v, explicit.disturbance.v)
    np.testing.assert_array_equal(default.pair_gains, explicit.pair_gains)
    assert default.to_dict()["driver_model"] == 5


def test_model_6_passes_the_disturbance_further_down_a_human_column_and_the_stop_and_go_wave_still_fades():
    """Measured (docs/string-stability.md): on every seed 0-4 of typical and naturalistic columns of 6,
    model 6's last vehicle drops 0.30-1.25 m/s more than model 5's after the Gunter-like braking, the
    speed error's L2 norm grows 1.2-1.5 times more over the column, and on the stop-and-go trace the
    largest acceleration reaches further down; the trace's speed still shrinks (column L2 gain < 1)."""
    trace = lead_trace("stopandgo", seed=0)
    r = {m: string_stability("human", PlatoonConfig(vehicles=6, drivers="typical", driver_model=m), frequencies=[0.02],
                             trace=trace) for m in (5, 6)}
    for m in (5, 6):
        assert not r[m].errors and np.all(r[m].disturbance.min_gap > 0) and np.all(r[m].trace.min_gap > 0)
    d5, d6 = r[5].disturbance, r[6].disturbance
    assert d6.drops[-1] > d5.drops[-1] + 0.2  # measured 2.29 against 1.55 m/s (lead 2.68)
    assert np.prod(d6.l2_speed) > 1.1 * np.prod(d5.l2_speed)  # measured 1.31 against 0.96
    assert np.all(np.diff(d5.drops) < 0)  # model 5 damps it from vehicle to vehicle ...
    assert d6.drops[-1] > d6.drops[0]  # ... model 6 does not (2.12 at the first follower, 2.29 at the last)
    t5, t6 = r[5].trace, r[6].trace
    assert np.prod(t6.linf_accel) > np.prod(t5.linf_accel) + 0.3  # measured 0.80 against 0.23 of the lead's
    assert np.prod(t6.l2_speed) < 1.0 and np.prod(t5.l2_speed) < 1.0  # 0.77 and 0.74
    assert r[6].to_dict()["driver_model"] == 6


def test_cli_driver_model_reaches_the_column_and_the_json(capsys):
    argv = ["string-stability", "human", "--vehicles", "3", "--frequencies", "0.02", "--json"]
    assert main(argv) == 0
    m5 = json.loads(capsys.readouterr().out)
    assert main(argv + ["--driver-model", "6"]) == 0
    m6 = json.loads(capsys.readouterr().out)
    assert m5["driver_model"] == 5 and m6["driver_model"] == 6
    assert m6["disturbance"]["drops"] != m5["disturbance"]["drops"]
    with pytest.raises(SystemExit):
        main(argv + ["--driver-model", "7"])
    err = capsys.readouterr().err
    assert "--driver-model" in err and "7" in err
