"""acc-gym robustness: one axis at a time from the ideal car, against direct runs."""

import json

import numpy as np
import pytest

from acc_gym.cli import main
from acc_gym.evaluation import robustness as rb
from acc_gym.evaluation.string_stability import PlatoonConfig, string_stability
from acc_gym.onboard import SENSOR_PRESETS, ActuatorConfig


def test_each_level_is_the_suite_driven_with_that_car_and_the_column_with_those_actuators():
    r = rb.robustness("acc", "ncap-v2", lags=(0.0, 0.5), delays=(1.0,), noise=(0.0, 2.0), episodes=6)
    rows = {(x["axis"], x["value"]): x for x in r["levels"]}
    assert list(rows) == [("lag", 0.0), ("lag", 0.5), ("delay", 1.0), ("noise", 0.0), ("noise", 2.0)]
    assert r["episodes"] == 6 and all(x["episodes"] == 6 for x in rows.values())
    # the ideal car is one run, reported on each axis's 0
    ideal, noise0 = rows[("lag", 0.0)], rows[("noise", 0.0)]
    assert all(ideal[k] == noise0[k] for k in ("mean_score", "share_qualified", "collisions"))
    # a level is what a direct run of the same episodes with that car gives
    import gymnasium as gym

    from acc_gym.evaluation.runner import run_episode
    from acc_gym.suites import get_suite

    suite = get_suite("ncap-v2")
    env = gym.make(suite.env_id, actuators=ActuatorConfig(dead_time=1.0))
    scores = [run_episode(env, "acc", scenario=sc, record=False)[0]["score"] for sc in suite.episodes("test")[:6]]
    assert rows[("delay", 1.0)]["mean_score"] == pytest.approx(np.mean(scores), abs=1e-9)
    # the column: the same verdict as string_stability with those actuators; none on the noise axis
    col = string_stability("acc", PlatoonConfig(vehicles=rb.COLUMN, actuators={"dead_time": 1.0}),
                           frequencies=rb.FREQUENCIES, disturbance=False)
    assert rows[("delay", 1.0)]["max_gain"] == pytest.approx(col.max_gain) and col.string_stable is False
    assert rows[("lag", 0.0)]["string_stable"] is True
    assert rows[("noise", 2.0)]["max_gain"] is None and rows[("noise", 2.0)]["string_stable"] is None


def test_noise_levels_scale_the_typical_radar():
    t = SENSOR_PRESETS["typical"]
    two = rb.noisy_radar(2.0)
    assert two.gap_sd == 2 * t.gap_sd and two.rate_sd == 2 * t.rate_sd
    assert two.dropout_share == 2 * t.dropout_share
    assert (two.far_fov, two.latency, two.coast) == (t.far_fov, t.latency, t.coast)
    assert rb.noisy_radar(0.0).ideal and rb.noisy_radar(100.0).dropout_share == rb.MAX_DROPOUT
    with pytest.raises(ValueError, match="noise level must be a number >= 0.*got -1"):
        rb.noisy_radar(-1)


def test_the_command_prints_one_json_object_and_plots(tmp_path, capsys):
    png = tmp_path / "rob.png"
    assert main(["robustness", "acc", "--episodes", "3", "--lags", "0", "0.5", "--delays", "0.5", "--noise", "1",
                 "--no-string-stability", "--json", "--plot", str(png)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["controller"] == "acc" and out["suite"] == "ncap-v2" and len(out["levels"]) == 4
    assert set(out["levels"][0]) >= {"axis", "value", "mean_score", "share_qualified", "collisions",
                                     "preventable_collisions", "non_preventable_collisions", "max_gain"}
    assert png.stat().st_size > 5000
    with pytest.raises(SystemExit):
        main(["robustness", "acc", "--lags", "-1"])
    assert "ActuatorConfig.lag" in capsys.readouterr().err
