"""Classical car-following models: hand-computed steps, delays, standstill behaviour."""

import math

import numpy as np
import pytest

from acc_gym.drivers.base import DelayBuffer, Observation, delay_steps
from acc_gym.drivers.baselines import (ACC, GM, IDM, ACCParams, Fuzzy, FuzzyParams, Gipps, GippsParams, GMParams,
                                       IDMParams, Newell, NewellParams, Pipes, PipesParams, Tyler, TylerParams,
                                       acc_accel, cacc_params, free_accel, fuzzy_accel, gipps_speed, gm_accel,
                                       idm_accel, mp_cacc_params, newell_speed, pipes_accel, tyler_accel)
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


def _finite_clipped(a):
    return np.clip(np.nan_to_num(np.asarray(a, float), nan=-20.0, posinf=10.0, neginf=-20.0), -20.0, 10.0)


def _reference_laws(dt):
    """Each model's law as the array functions define it (the numpy form the models ran until
    0.6), on the current scene ``now`` and the perceived one ``seen``."""
    def gipps(p, now, seen):
        return (gipps_speed(seen.v, seen.gap, seen.v_lead, p.a, p.b, p.b_hat, p.tau, p.v_desired, p.s0, p.theta)
                - now.v) / dt

    def gm(p, now, seen):
        a = gm_accel(now.v, seen.gap + p.length_ahead, seen.v_lead - seen.v, p.c, p.m, p.l)
        return np.minimum(np.where(np.isfinite(seen.gap), a, np.inf), free_accel(now.v, p.v_desired, p.k_free, p.a_max))

    def fuzzy(p, now, seen):
        a = fuzzy_accel(seen.v, seen.gap, seen.v_lead - seen.v, seen.a_lead, p.T, p.gamma, p.s0, p.h, p.level_width,
                        p.max_level, p.step)
        return np.minimum(np.where(np.isfinite(seen.gap), a, np.inf), free_accel(now.v, p.v_desired, p.k_free, p.a_max))

    def pipes(p, now, seen):
        a = np.where(np.isfinite(seen.gap), pipes_accel(seen.v_lead - seen.v, seen.gap, p.c), np.inf)
        return np.minimum(a, free_accel(now.v, p.v_desired, p.k_free, p.a_max))

    def newell(p, now, seen):
        return (newell_speed(seen.gap, p.v_desired, p.c, p.r_min) - now.v) / dt

    def tyler(p, now, seen):
        a = np.where(np.isfinite(seen.gap), tyler_accel(seen.v, seen.gap, seen.v_lead - seen.v, p.c_v, p.c_s, p.c_t,
                                                         p.s0), np.inf)
        return np.minimum(a, free_accel(now.v, p.v_desired, p.k_free, p.a_max))

    def idm(p, now, seen):
        return idm_accel(now.v, seen.gap, seen.v_lead - seen.v, p.a, p.b, p.time_gap, p.s0, p.v_desired, p.delta)

    def acc(p, now, seen):
        a = acc_accel(now.v, now.gap, now.v_lead - now.v, p.k1, p.k2, p.time_gap, p.s0, now.a_lead, p.k3)
        if p.predecessors == 2 and now.gap2 is not None:
            a = np.minimum(a, acc_accel(now.v, now.gap2, now.v_lead2 - now.v, p.k1, p.k2, 2.0 * p.time_gap,
                                        2.0 * p.s0 + p.vehicle_length, now.a_lead2, p.k3))
        return np.minimum(a, free_accel(now.v, p.v_set, p.k_cruise, p.a_max))

    return {"gipps": gipps, "gm": gm, "fuzzy": fuzzy, "pipes": pipes, "newell": newell, "tyler": tyler, "idm": idm,
            "acc": acc}


def _random_params(name, rng, n):
    u = lambda lo, hi: rng.uniform(lo, hi, n)  # noqa: E731
    return {
        "gipps": [GippsParams(a=u(0.8, 3.0), b=u(-5.0, -2.0), b_hat=u(-6.0, -2.5), tau=u(0.3, 1.2), v_desired=u(8, 40),
                              s0=u(0.0, 4.0)),
                  GippsParams(theta=u(0.0, 1.0), v_desired=22.0)],
        "gm": [GMParams(c=u(5.0, 30.0), m=rng.choice([0.0, 0.8, 1.0], n), l=rng.choice([1.0, 2.0, 2.5], n),
                        v_desired=u(8, 40), k_free=u(0.2, 1.0), a_max=u(1.0, 3.0), length_ahead=u(0.0, 6.0))],
        "fuzzy": [FuzzyParams(T=u(0.5, 2.0), gamma=u(1.0, 4.0), s0=u(0.0, 4.0), h=u(0.5, 2.5), level_width=u(2.0, 8.0),
                              max_level=rng.choice([1.0, 3.0, 5.0], n), step=u(0.1, 0.6), v_desired=u(8, 40))],
        "pipes": [PipesParams(c=u(0.1, 1.5), v_desired=u(8, 40), k_free=u(0.2, 1.0), a_max=u(1.0, 3.0))],
        "newell": [NewellParams(c=u(0.2, 1.5), r_min=u(0.0, 5.0), v_desired=u(8, 40))],
        "tyler": [TylerParams(c_v=u(0.2, 1.5), c_s=u(0.05, 0.5), c_t=u(0.5, 2.5), s0=u(0.0, 4.0), v_desired=u(8, 40))],
        "idm": [IDMParams(a=u(0.5, 3.0), b=u(1.0, 4.0), time_gap=u(0.0, 2.5), s0=u(0.0, 4.0), v_desired=u(5, 40),
                          delta=rng.choice([2.0, 4.0], n)), IDMParams(v_desired=22.0)],
        "acc": [ACCParams(k1=u(0.0, 0.5), k2=u(0.0, 1.0), k3=u(0.0, 1.0), time_gap=u(0.5, 2.0), s0=u(0.0, 4.0),
                          v_set=u(8, 40)), cacc_params(), mp_cacc_params(v_set=u(8, 40))],
    }[name]


@pytest.mark.parametrize("name", ["gipps", "gm", "fuzzy", "pipes", "newell", "tyler", "idm", "acc"])
def test_compiled_laws_equal_the_array_functions(name):
    """Every driver runs a compiled law (one call for a batch's rows); it equals the array
    functions' law, made finite and clipped to [-20, 10] m/s^2, to 1e-12 -- per-row and shared
    parameters, the current and the perceived scene apart, nothing ahead, zero gaps and speeds."""
    from acc_gym.drivers.baselines import MODELS

    rng = np.random.default_rng(7)
    n, dt = 400, 0.2
    ref_law = _reference_laws(dt)[name]

    def scene():
        v = rng.uniform(0.0, 45.0, n)
        v[:3] = 0.0
        gap = np.where(rng.random(n) < 0.2, np.inf, rng.uniform(0.0, 150.0, n))
        gap[:5] = [0.0, 1e-6, 0.5, np.inf, 2e-3]
        gap2 = np.where(rng.random(n) < 0.3, np.inf, gap + rng.uniform(5.0, 60.0, n))
        return Observation.build(v, rng.uniform(-3, 2, n), gap, rng.uniform(0.0, 45.0, n), rng.uniform(-4, 2, n),
                                 gap2, rng.uniform(0.0, 45.0, n), rng.uniform(-4, 2, n))

    now, seen = scene(), scene()
    for params in _random_params(name, rng, n):
        model = MODELS[name](params, n=n, dt=dt)
        with np.errstate(all="ignore"):
            ref = _finite_clipped(ref_law(params, now, seen))
        out = model._law(now, seen)
        np.testing.assert_allclose(out, ref, rtol=1e-12, atol=1e-12, err_msg=name)
        assert (out == ref).mean() > 0.9  # most entries are the same bits
        rows = np.array([3, 7, 250])
        part = np.full(n, 99.0)
        model.act_into(now, seen, rows, part)
        np.testing.assert_array_equal(part[rows], out[rows])
        assert np.count_nonzero(part == 99.0) == n - rows.size  # only the rows asked for


def test_kernel_clip_bounds_are_the_models():
    from acc_gym.drivers import _baseline_kernels, baselines

    assert (_baseline_kernels.A_FLOOR, _baseline_kernels.A_CEIL) == (baselines.A_FLOOR, baselines.A_CEIL)


def test_idm_driver_shared_parameters_equal_per_row_ones():
    rng = np.random.default_rng(3)
    n = 50
    obs = Observation.build(rng.uniform(0, 40, n), 0.0, rng.uniform(0, 100, n), rng.uniform(0, 40, n), 0.0)
    one = IDM(IDMParams(v_desired=22.0), n=n).act(obs)
    every = IDM(IDMParams(v_desired=np.full(n, 22.0), a=np.full(n, 1.5)), n=n).act(obs)
    np.testing.assert_array_equal(one, every)


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
