"""The actuator model: its lag and dead time as declared, its transfer function, and the
linear ACC's string stability with it against the analysis."""

import math

import numpy as np
import pytest

from acc_gym.evaluation.string_stability import (PlatoonConfig, linear_transfer, string_stability,
                                                 time_gap_threshold)
from acc_gym.onboard import ACTUATOR_PRESETS, ActuatorConfig, Actuators
from acc_gym.onboard.actuators import transfer

DT = 0.2


def _run(config: ActuatorConfig, u: np.ndarray) -> np.ndarray:
    """The realised accelerations for commands ``u`` (one vehicle, no envelope)."""
    act = Actuators(config, 1, DT)
    act.reset([0], 0.0)
    a, out = np.zeros(1), []
    for uk in u:
        a = act.command(np.array([uk]), a)
        out.append(a[0])
    return np.array(out)


def test_the_lag_follows_the_continuous_first_order_step_response_at_every_step():
    for lag in (0.1, 0.3, 1.0):
        a = _run(ActuatorConfig(lag=lag), np.ones(40))
        t = (np.arange(40) + 1) * DT  # a[k] is the lag's value at the end of step k
        assert np.abs(a - (1.0 - np.exp(-t / lag))).max() < 1e-12


def test_a_whole_dead_time_delays_by_exactly_its_steps_and_a_fraction_interpolates():
    u = np.sin(np.arange(50) * 0.37) + 0.1 * np.arange(50)
    a = _run(ActuatorConfig(dead_time=0.6), u)
    assert np.array_equal(a[3:], u[:-3]) and np.all(a[:3] == 0.0)
    frac = _run(ActuatorConfig(dead_time=0.3), u)  # 1.5 steps: half of one step ago, half of two
    assert np.allclose(frac[2:], 0.5 * u[1:-1] + 0.5 * u[:-2], atol=1e-12)
    assert np.array_equal(_run(ActuatorConfig(), u), u)  # ideal: the command itself


def test_the_transfer_function_is_the_simulated_filter_s_frequency_response():
    cfg = ActuatorConfig(lag=0.4, dead_time=0.5)
    for f in (0.01, 0.1, 0.5, 1.3):
        k = np.arange(4000)
        u = np.sin(2 * np.pi * f * k * DT)
        a = _run(cfg, u)[2000:]  # past the transient
        t = k[2000:] * DT
        X = np.column_stack([np.sin(2 * np.pi * f * t), np.cos(2 * np.pi * f * t)])
        (s, c), *_ = np.linalg.lstsq(X, a, rcond=None)
        g = transfer(cfg, f, DT)
        assert math.hypot(s, c) == pytest.approx(abs(g), abs=1e-6)
        assert math.atan2(c, s) == pytest.approx(np.angle(g), abs=1e-6)


@pytest.mark.parametrize("lag,dead", [(0.3, 0.0), (0.6, 0.0), (0.2, 0.3), (0.0, 0.4)])
def test_linear_acc_with_an_actuator_matches_the_analytic_gain_within_2_percent_at_every_frequency(lag, dead):
    cfg = ActuatorConfig(lag=lag, dead_time=dead)
    h = 2.0
    r = string_stability("acc", PlatoonConfig(vehicles=3, time_gap=h, actuators=cfg), disturbance=False)
    ref = np.abs(linear_transfer(r.frequencies, 0.3, 1.2, h, actuators=cfg))
    measured = np.isfinite(r.pair_gains)
    assert measured[:, 0].all()
    assert np.abs(r.pair_gains / ref[:, None] - 1.0)[measured].max() < 0.02
    # the lag is in what was measured: without it the analysis is off
    plain = np.abs(linear_transfer(r.frequencies, 0.3, 1.2, h))
    assert np.abs(r.pair_gains[:, 0] / plain - 1.0).max() > 0.05


def _threshold_from_the_polynomial(k1: float, k2: float, lag: float) -> float:
    """The continuous ACC with a first-order lag, ``Gamma = (k2 s + k1) / (T s^3 + s^2 + (k2 + k1 h) s + k1)``:
    ``|den|^2 - |num|^2 = w^2 (c1 + c2 w^2 + c3 w^4)`` with ``c1 = (k2 + k1 h)^2 - k2^2 - 2 k1``,
    ``c2 = 1 - 2 T (k2 + k1 h)``, ``c3 = T^2``; string stable iff that is >= 0 for every w >= 0:
    ``c1 >= 0`` and (``c2 >= 0`` or ``c2^2 <= 4 c1 c3``). The smallest such h, by bisection."""
    def ok(h):
        c1 = (k2 + k1 * h) ** 2 - k2 ** 2 - 2 * k1
        c2 = 1 - 2 * lag * (k2 + k1 * h)
        return c1 >= 0 and (c2 >= 0 or c2 * c2 <= 4 * c1 * lag * lag)

    grid = [h for h in np.arange(0.0, 5.0, 0.001) if ok(h)]
    return float(grid[0])


def test_the_time_gap_threshold_grows_with_the_lag_as_the_analysis_says():
    k1, k2 = 0.3, 1.2
    found = []
    for lag in (0.0, 0.2, 0.35, 0.5, 0.8):
        cfg = ActuatorConfig(lag=lag)
        analytic = _threshold_from_the_polynomial(k1, k2, lag)
        assert time_gap_threshold(k1, k2, dt=0, actuators=cfg) == pytest.approx(analytic, abs=2e-3)
        found.append(time_gap_threshold(k1, k2, actuators=cfg))  # sampled at 0.2 s: a little more, from the hold
        assert analytic - 1e-3 <= found[-1] <= analytic * 1.04 + 1e-3
    assert found[0] == pytest.approx(0.761, abs=2e-3)
    assert all(b >= a - 1e-9 for a, b in zip(found, found[1:])) and found[-1] > found[0] + 0.5
    # small lags leave it where it is (c2 > 0): Rajamani's h > 2T is not binding for this law
    assert found[1] == pytest.approx(found[0], abs=1e-3)


def test_a_controller_under_a_1_s_dead_time_and_a_short_time_gap_is_string_unstable():
    cfg = PlatoonConfig(vehicles=4, time_gap=1.0)
    assert string_stability("acc", cfg, disturbance=False).string_stable is True
    late = string_stability("acc", PlatoonConfig(vehicles=4, time_gap=1.0, actuators={"dead_time": 1.0}),
                            frequencies=np.geomspace(0.005, 0.5, 10))
    assert late.string_stable is False and late.max_gain > 1.1
    assert late.disturbance.drops[-1] > late.disturbance.lead_drop  # the disturbance grows down the column


def test_configs_are_validated_and_presets_resolve():
    with pytest.raises(ValueError, match="ActuatorConfig.lag .* got -0.1"):
        ActuatorConfig(lag=-0.1)
    with pytest.raises(ValueError, match="ActuatorConfig.dead_time .* got nan"):
        ActuatorConfig(dead_time=float("nan"))
    with pytest.raises(ValueError, match="unknown actuators preset 'fast'"):
        PlatoonConfig(actuators="fast")
    assert PlatoonConfig(actuators="typical").actuators == ACTUATOR_PRESETS["typical"]
    assert ActuatorConfig().ideal and not ACTUATOR_PRESETS["typical"].ideal
