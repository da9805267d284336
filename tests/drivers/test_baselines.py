"""Classical car-following models: hand-computed steps, delays, standstill behaviour."""

import math

import numpy as np
import pytest

from acc_gym.drivers.base import DelayBuffer, Observation, delay_steps
from acc_gym.drivers.baselines import (ACC, GM, IDM, Fuzzy, FuzzyParams, Gipps, GippsParams, GMParams, IDMParams,
                                       Newell, NewellParams, Pipes, PipesParams, Tyler, TylerParams, acc_accel,
                                       cacc_params, fuzzy_accel, gipps_speed, gm_accel, idm_accel, mp_cacc_params,
                                       newell_speed, pipes_accel, tyler_accel)
from acc_gym.simulation.profiles import SpeedProfile
from acc_gym.simulation.rollout import simulate_column

LENGTH = 4.7


def test_gipps_hand_step_both_forms():
    v, gap, vl = 20.0, 30.0, 18.0
    a, b, bh, tau, V, s0 = 1.7, -3.0, -3.5, 0.6, 25.0, 2.0
    free = v + 2.5 * a * tau * (1 - v / V) * math.sqrt(0.025 + v / V)
    safe = b * tau + math.sqrt(b * b * tau * tau - b * (2 * (gap - s0) - v * tau - vl * vl / bh))
    assert gipps_speed(v, gap, vl, a, b, bh, tau, V, s0) == pytest.approx(min(free, safe))
    # paper 003's form with an extra reaction time theta
    th = 0.5
    h = tau / 2 + th
    safe3 = b * h + math.sqrt(b * b * h * h - b * (2 * (gap - s0) - v * tau - vl * vl / bh))
    assert gipps_speed(v, gap, vl, a, b, bh, tau, V, s0, theta=th) == pytest.approx(min(free, safe3))
    assert gipps_speed(v, np.inf, vl, a, b, bh, tau, V, s0) == pytest.approx(free)


def test_idm_hand_step():
    v, gap, vl = 20.0, 25.0, 15.0
    a, b, T, s0, v0 = 1.5, 2.0, 1.5, 2.0, 30.0
    s_star = s0 + max(0.0, v * T - v * (vl - v) / (2 * math.sqrt(a * b)))
    expect = a * (1 - (v / v0) ** 4 - (s_star / gap) ** 2)
    assert idm_accel(v, gap, vl - v, a, b, T, s0, v0) == pytest.approx(expect)
    assert idm_accel(v, np.inf, 0.0, a, b, T, s0, v0) == pytest.approx(a * (1 - (v / v0) ** 4))


def test_idm_driver_compiled_law_equals_the_array_function():
    """IDM drivers run a compiled law (one call per batch of rows); it is idm_accel made
    finite and clipped to [-20, 10] m/s^2, per row, with per-row or shared parameters."""
    rng = np.random.default_rng(7)
    n = 400
    v = rng.uniform(0.0, 45.0, n)
    v[:3] = 0.0
    gap = np.where(rng.random(n) < 0.2, np.inf, rng.uniform(0.0, 150.0, n))
    gap[:5] = [0.0, 1e-6, 0.5, np.inf, 2e-3]
    v_lead = rng.uniform(0.0, 45.0, n)
    params = IDMParams(a=rng.uniform(0.5, 3.0, n), b=rng.uniform(1.0, 4.0, n), time_gap=rng.uniform(0.0, 2.5, n),
                       s0=rng.uniform(0.0, 4.0, n), v_desired=rng.uniform(5.0, 40.0, n), delta=rng.choice([2.0, 4.0], n))
    obs = Observation.build(v, 0.0, gap, v_lead, 0.0)
    with np.errstate(all="ignore"):
        ref = idm_accel(v, gap, v_lead - v, params.a, params.b, params.time_gap, params.s0, params.v_desired,
                        params.delta)
    ref = np.clip(np.nan_to_num(ref, nan=-20.0, posinf=10.0, neginf=-20.0), -20.0, 10.0)
    out = IDM(params, n=n).act(obs)
    np.testing.assert_allclose(out, ref, rtol=1e-12, atol=1e-12)
    assert (out == -20.0).sum() >= 3 and (ref == -20.0).sum() == (out == -20.0).sum()  # the floor is reached
    # shared parameters (one value for every row) give the same as the same values per row
    one = IDM(IDMParams(v_desired=22.0), n=n).act(obs)
    every = IDM(IDMParams(v_desired=np.full(n, 22.0), a=np.full(n, 1.5)), n=n).act(obs)
    np.testing.assert_array_equal(one, every)
    # act_into writes only the rows asked for
    out2 = np.full(n, 99.0)
    IDM(params, n=n).act_into(obs, obs, np.array([3, 7]), out2)
    assert out2[3] == out[3] and out2[7] == out[7] and np.count_nonzero(out2 == 99.0) == n - 2


def test_other_laws_hand_steps():
    assert gm_accel(20.0, 40.0, -2.0, 12.0, 0.0, 1.0) == pytest.approx(12.0 * -2.0 / 40.0)
    assert gm_accel(20.0, 40.0, -2.0, 30.0, 1.0, 2.0) == pytest.approx(30.0 * 20.0 * -2.0 / 1600.0)
    assert pipes_accel(-3.0, 20.0, 0.5) == pytest.approx(-1.5)
    assert newell_speed(22.0, 25.0, 0.6, 2.0) == pytest.approx(25.0 * (1 - math.exp(-0.6 * 20.0 / 25.0)))
    assert tyler_accel(20.0, 40.0, -1.0, 0.8, 0.2, 1.5, 2.0) == pytest.approx(0.8 * -1.0 + 0.2 * (40 - 2 - 30))
    # fuzzy: gap 45 vs appropriate 2 + 1.5 * 20 = 32 -> (45-32)/5 = 2.6 -> 3 levels (capped at 3)
    assert fuzzy_accel(20.0, 45.0, -1.0, -0.5, 1.0, 2.5, 2.0, 1.5, 5.0, 3, 0.3) == pytest.approx(
        (-1.0 - 0.5) / 2.5 + 0.9)
    assert fuzzy_accel(20.0, 32.0, -1.0, -0.5, 1.0, 2.5, 2.0, 1.5, 5.0, 3, 0.3) == pytest.approx(-0.6)
    assert acc_accel(20.0, 40.0, -1.0, 0.2, 0.6, 1.5, 2.0) == pytest.approx(0.6 * -1.0 + 0.2 * (40 - 32))
    assert acc_accel(20.0, 40.0, -1.0, 0.2, 0.6, 1.5, 2.0, a_lead=-2.0, k3=1.0) == pytest.approx(-2.0 - 0.6 + 1.6)


def test_multi_predecessor_cacc_takes_the_minimum():
    m = ACC(mp_cacc_params(k1=0.2, k2=0.6, k3=1.0, time_gap=0.6, s0=2.0, vehicle_length=5.0))
    obs = Observation.build(v=20.0, a=0.0, gap=14.0, v_lead=20.0, a_lead=0.0, gap2=25.0, v_lead2=18.0, a_lead2=-1.0)
    a1 = 0.2 * (14.0 - (2.0 + 12.0))
    a2 = -1.0 + 0.6 * -2.0 + 0.2 * (25.0 - (2 * 14.0 + 5.0))  # spacing 2 x_d + l_v
    assert m.act(obs)[0] == pytest.approx(min(a1, a2, 0.4 * 5.0))


def test_delay_buffer_delays_by_whole_steps():
    buf = DelayBuffer(2)
    assert [buf.push(k) for k in range(5)] == [0, 0, 0, 1, 2]
    assert delay_steps(0.6, 0.2) == 3
    with pytest.raises(ValueError):
        delay_steps(-1.0, 0.2)


def test_gm_reacts_after_its_reaction_time():
    m = GM(GMParams(tau=1.0))  # 5 steps at 0.2 s
    calm = Observation.build(v=20.0, gap=40.0, v_lead=20.0)
    brake = Observation.build(v=20.0, gap=40.0, v_lead=15.0)
    outs = [m.act(calm)[0] for _ in range(3)] + [m.act(brake)[0] for _ in range(7)]
    assert np.allclose(outs[:8], outs[0])  # still reacting to the calm scene
    assert outs[8] == pytest.approx(12.0 * -5.0 / (40.0 + 4.7))  # head to head: the gap plus the car ahead


def test_gm_divides_by_the_distance_between_the_heads():
    """Paper 003: 'inversely proportional to the distance between the heads of the two
    vehicles' -- the bumper gap plus the vehicle ahead's length."""
    for length in (0.0, 4.7, 12.0):
        m = GM(GMParams(tau=0.0, length_ahead=length, c=10.0, m=1.0, l=2.0))
        a = m.act(Observation.build(v=20.0, gap=10.0, v_lead=17.0))[0]
        assert a == pytest.approx(10.0 * 20.0 * -3.0 / (10.0 + length) ** 2)
    with pytest.raises(ValueError, match="length_ahead"):
        GMParams(length_ahead=-1.0)


@pytest.mark.parametrize("model,s0", [(Gipps(GippsParams(s0=2.0)), 2.0), (IDM(IDMParams(s0=2.0)), 2.0)])
def test_gipps_and_idm_stop_behind_a_stopped_lead_at_their_standstill_gap(model, s0):
    lead = SpeedProfile.from_segments(20.0, [(0.0, 10.0), (-3.0, 10.0), (0.0, 60.0)])
    tr = simulate_column(lead, [model], [60.0 + LENGTH, 0.0], [20.0, 20.0])
    assert tr.v[-1, 1] == pytest.approx(0.0, abs=1e-3)
    assert tr.gap[-1, 1] == pytest.approx(s0, abs=0.05)
    assert tr.gap[:, 1].min() >= s0 - 0.05


@pytest.mark.parametrize("model", [Gipps(), IDM(), GM(), Fuzzy(), Pipes(), Newell(), Tyler(), ACC(), ACC(cacc_params())])
def test_every_model_cruises_alone_and_follows_without_nan(model):
    lead = SpeedProfile.from_segments(15.0, [(1.0, 5.0), (0.0, 10.0), (-2.0, 5.0), (0.0, 10.0)])
    tr = simulate_column(lead, [model], [40.0 + LENGTH, 0.0], [15.0, 15.0])
    assert np.all(np.isfinite(tr.a)) and np.all(tr.v >= 0)
    alone = simulate_column(lead, [model], [4000.0, 0.0], [15.0, 10.0], sensor_range=200.0)
    assert np.all(np.isinf(alone.gap[1:, 1]) | (alone.gap[1:, 1] > 200.0))
    assert alone.v[-1, 1] > 15.0  # nobody seen: speeds up towards its desired speed (25 m/s)


@pytest.mark.parametrize("cls,kw,match", [(GippsParams, dict(b=1.0), "b must be < 0"),
                                          (IDMParams, dict(time_gap=-1.0), "time_gap"),
                                          (FuzzyParams, dict(gamma=0.0), "gamma"),
                                          (PipesParams, dict(c=np.nan), "c must be finite"),
                                          (NewellParams, dict(tau=-0.1), "tau"),
                                          (TylerParams, dict(c_t=-1.0), "c_t")])
def test_bad_parameters_are_named(cls, kw, match):
    with pytest.raises(ValueError, match=match):
        cls(**kw)


def test_model_rejects_bad_observations():
    with pytest.raises(ValueError, match="observation.v"):
        IDM().act(Observation.build(v=np.nan, gap=10.0, v_lead=10.0))
    with pytest.raises(ValueError, match="shape"):
        IDM(n=2).act(Observation.build(v=[1.0, 2.0, 3.0], gap=10.0, v_lead=10.0))


def test_idm_tau_is_a_delay_and_mistaking_it_for_the_headway_warns():
    with pytest.warns(UserWarning, match=r"reaction delay, not IDM's time headway.*time_gap=1.5"):
        IDMParams(tau=1.5)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        IDMParams(tau=0.2)  # a small delay: no warning
        IDMParams(tau=1.0, time_gap=1.2)  # both given: meant
