"""The R157 careful and competent driver (acc_gym_agents.controllers.cc_driver): its phases on
scripted events, its criticality rule, its avoid/collide boundary against a hand-computed
stopping distance, the R157 cut-in rule, batches, reset and bad input.

The scenes are simulated here with point kinematics at the env's 0.2 s step: each vehicle's
speed ``v += a dt`` (never below 0) and position ``x += v dt + a dt^2 / 2``, the ego applying
exactly the controller's desired acceleration (action * 3 above 0, action * 8 below).
The regulation's numbers are written out (0.4 s, 0.75 s, 0.6 s, 0.774 g) so that a changed
table shows up here."""

import importlib
import math

import numpy as np
import pytest

from acc_gym_agents.controllers import LinearACC
from acc_gym_agents.controllers.cc_driver import CCDriver, cc_driver, r157_cut_in_must_avoid

# the module (the package's own name cc_driver is the factory function)
ccm = importlib.import_module("acc_gym_agents.controllers.cc_driver")

DT = 0.2  # [s]
G_774 = 0.774 * 9.80665  # [m/s^2] full braking, 7.59
JERK = G_774 / 0.6  # [m/s^3] 12.65


def accel(action) -> np.ndarray:
    a = np.asarray(action, dtype=float).reshape(-1)
    return np.where(a >= 0, a * 3.0, a * 8.0)


def advance(v, x, a):
    """One step of point kinematics that never reverses (stops within the step if it must)."""
    v, x, a = np.asarray(v, float), np.asarray(x, float), np.asarray(a, float)
    stop = v + a * DT < 0
    t = np.where(stop, v / np.maximum(-a, 1e-12), DT)
    return np.where(stop, 0.0, v + a * DT), x + v * t + 0.5 * a * t * t


def simulate(ctrl, v_ego, v_other, gap0, a_other=lambda k: 0.0, appear=0, steps=60, v_set=25.0, h=1.5,
             v2v=False, width=None):
    """Rows of scenes: the ego at ``v_ego``, the other vehicle ``gap0`` ahead at ``v_other`` with
    acceleration ``a_other(k)`` over step k, in the ego's lane (visible) from step ``appear``.
    Returns the per-step desired accelerations, gaps, ego speeds and phases, each (steps, rows)."""
    v_e, v_o, g0 = np.broadcast_arrays(*(np.atleast_1d(np.asarray(x, float)) for x in (v_ego, v_other, gap0)))
    n = v_e.size
    x_e, x_o, v_e, v_o = np.zeros(n), g0.copy(), v_e.copy(), v_o.copy()
    a_e, a_o_last = np.zeros(n), np.zeros(n)
    out = {k: np.empty((steps, n)) for k in ("a", "gap", "v", "phase")}
    for k in range(steps):
        gap = x_o - x_e
        seen = np.full(n, k >= appear) & (gap < 200.0)
        cols = [v_e, a_e, np.where(seen, np.maximum(gap, 0.0), 200.0), np.where(seen, v_o - v_e, 0.0),
                seen.astype(float), np.full(n, v_set), np.full(n, h)]
        if v2v:
            cols += [np.where(seen, a_o_last, 0.0), np.full(n, 200.0), np.zeros(n), np.zeros(n)]
        obs = np.stack(cols, axis=1)
        if width is not None:
            obs = np.hstack([obs, np.zeros((n, width - obs.shape[1]))])
        act, state = ctrl.predict(obs if n > 1 else obs[0])
        assert state is None
        a_e = accel(act)
        out["a"][k], out["gap"][k], out["v"][k], out["phase"][k] = a_e, gap, v_e, getattr(ctrl, "phase", 0)
        a_o = np.full(n, float(a_other(k)))
        v_o_new, x_o = advance(v_o, x_o, a_o)
        a_o_last, v_o = (v_o_new - v_o) / DT, v_o_new
        v_e, x_e = advance(v_e, x_e, a_e)
    return out


def first(mask) -> int:
    return int(np.flatnonzero(mask)[0])


# ---- 1. the phases of a cut-in ------------------------------------------------------------------------------------

def test_cut_in_phases_perception_reaction_ramp_and_full_braking():
    k0 = 5  # the vehicle appears 15 m ahead, 10 m/s slower, while the ego cruises at its set speed
    r = simulate(CCDriver(), 25.0, 15.0, 15.0 + 10.0 * DT * k0, appear=k0, steps=25)
    a, phase = r["a"][:, 0], r["phase"][:, 0]
    assert np.all(a[:k0] == 0.0) and np.all(phase[:k0] == 0)  # cruising at the set speed
    assert r["gap"][k0, 0] == pytest.approx(15.0)

    # perception (0.4 s = 2 steps): no braking, it has not perceived the risk yet
    assert np.all(a[k0:k0 + 2] == 0.0) and np.all(phase[k0:k0 + 2] == 1)
    # reaction: begins 0.4 s after detection, about -0.4 m/s^2 for 0.75 s
    reaction = first(a < -0.1)
    assert abs(reaction - (k0 + 0.4 / DT)) <= 1 and first(phase == 2) == k0 + 2
    assert a[k0 + 2:k0 + 5] == pytest.approx(-0.4, abs=1e-6)  # actions are float32
    # braking: begins 0.4 + 0.75 s after detection, rises at 12.65 m/s^3 ...
    ramp = first(a < -0.5)
    assert abs(ramp - (k0 + 1.15 / DT)) <= 1 and abs(first(phase == 3) - (k0 + 1.15 / DT)) <= 1
    slopes = -np.diff(a[ramp - 1:ramp + 4]) / DT
    assert slopes[1] == pytest.approx(JERK, rel=0.02) and np.all(slopes <= JERK + 1e-3)
    # ... to 0.774 g, reached 0.6 s later, and held
    full = first(a <= -G_774 + 1e-5)
    assert abs(full - (k0 + 1.75 / DT)) <= 1
    assert a[full:] == pytest.approx(-G_774, abs=1e-5)
    assert np.all(a >= -G_774 - 1e-5)  # never more than 0.774 g
    # the speed follows the continuous profile: 0.75 s at 0.4, a 0.6 s ramp, then 0.774 g
    t_full = (full - k0) * DT  # time since detection at the start of full braking
    expected = 25.0 - 0.4 * 0.75 - 0.4 * (0.4 / JERK) - 0.5 * JERK * (0.6 ** 2 - (0.4 / JERK) ** 2) \
        - G_774 * (t_full - 1.75)
    assert r["v"][full, 0] == pytest.approx(expected, abs=1e-3)
    # 15 m at 10 m/s closing is inside the model's envelope (about 20 m, test 4): it collides
    assert r["gap"][:, 0].min() < 0.0


# ---- 2. the phases of a lead deceleration -------------------------------------------------------------------------

@pytest.mark.parametrize("v2v", [False, True])
def test_lead_braking_at_6_triggers_reaction_ramp_and_full_braking(v2v):
    k0 = 4  # the lead (20 m/s, 20 m = 1.0 s ahead) brakes at 6 m/s^2 over step k0 onwards
    r = simulate(CCDriver(), 20.0, 20.0, 20.0, a_other=lambda k: -6.0 if k >= k0 else 0.0, steps=40,
                 h=17.5 / 20.0, v2v=v2v)  # time gap of the steady state: the linear law is at rest before
    a, phase = r["a"][:, 0], r["phase"][:, 0]
    assert a[:k0 + 1] == pytest.approx(0.0, abs=1e-9)
    seen = k0 + 1  # the first observation that shows the lead's -6 m/s^2
    assert first(phase > 0) == seen and phase[seen] == 2  # no perception time: the 5 m/s^2 crossing is it
    assert a[seen:seen + 3] == pytest.approx(-0.4, abs=1e-6)  # the 0.75 s reaction (actions are float32)
    ramp = first(a < -0.5)
    assert abs(ramp - (seen + 0.75 / DT)) <= 1
    assert (a[ramp] - a[ramp + 1]) / DT == pytest.approx(JERK, rel=0.02)
    full = first(a <= -G_774 + 1e-5)
    assert abs(full - (seen + 1.35 / DT)) <= 1
    # held until the threat is over: here until the ego has stopped (the lead stops first, 3.3 s)
    stop = first(r["v"][:, 0] <= 0.1)
    assert a[full:stop] == pytest.approx(-G_774, abs=1e-5) and stop - full >= 8
    assert phase[stop] == 0 and r["gap"][:, 0].min() > 0.0  # back to normal driving, no collision


def test_lead_braking_at_3_is_left_to_normal_following():
    a_lead = lambda k: -3.0 if k >= 4 else 0.0  # noqa: E731
    r = simulate(CCDriver(), 20.0, 20.0, 20.0, a_other=a_lead, steps=30, h=0.875)
    ref = simulate(LinearACC(), 20.0, 20.0, 20.0, a_other=a_lead, steps=30, h=0.875)
    assert np.all(r["phase"] == 0)
    assert r["a"] == pytest.approx(ref["a"], abs=1e-6)
    assert r["a"].min() < -2.0  # it does brake, with the linear law


def test_a_long_lead_braking_triggers_once_and_a_new_onset_again():
    # scripted V2V observations: the lead brakes at 6 m/s^2 (field 7) while the gap (30 m, 1.5 s) opens
    c = CCDriver()
    phases = []
    for k in range(14):
        a_lead = -6.0 if k < 8 or k >= 10 else 0.0  # braking, a pause of two steps, braking again
        c.predict(np.array([20.0, 0.0, 30.0 + 0.2 * k, 1.0, 1.0, 25.0, 1.5, a_lead, 200.0, 0.0, 0.0]))
        phases.append(int(c.phase[0]))
    # reaction from the first step, braking from 0.75 s, over at once (no longer closing, gap safe);
    # the braking goes on but only its onset is an event: nothing until the new onset at step 10
    assert phases == [2, 2, 2, 2, 0, 0, 0, 0, 0, 0, 2, 2, 2, 2]


# ---- 3. not critical, no event ------------------------------------------------------------------------------------

def test_cut_in_with_ttc_above_2s_is_no_event():
    # 60 m ahead, 2 m/s slower: TTC 30 s. The linear law handles it from the first step.
    r = simulate(CCDriver(), 25.0, 23.0, 60.0 + 2.0 * DT * 5, appear=5, steps=40)
    ref = simulate(LinearACC(), 25.0, 23.0, 60.0 + 2.0 * DT * 5, appear=5, steps=40)
    assert np.all(r["phase"] == 0) and r["a"].min() > -1.0
    assert r["a"] == pytest.approx(ref["a"], abs=1e-6)
    # just below 2 s is critical, just above is not
    below = simulate(CCDriver(), 25.0, 15.0, 19.5 + 10.0 * DT * 2, appear=2, steps=4)
    above = simulate(CCDriver(), 25.0, 15.0, 20.5 + 10.0 * DT * 2, appear=2, steps=4)
    assert below["phase"][2, 0] == 1 and np.all(above["phase"] == 0)


def test_cut_out_revealing_a_slow_vehicle_is_an_event():
    # following a vehicle 25 m ahead at 25 m/s; at step 3 it leaves and reveals one 30 m further
    # ahead at 10 m/s (55 m, headway 2.2 s: not critical) or 15 m further (40 m, 1.6 s: critical)
    for extra, critical in ((30.0, False), (15.0, True)):
        c = CCDriver()
        phases = []
        for k in range(6):
            gap, v_rel = (25.0, 0.0) if k < 3 else (25.0 + extra - 15.0 * DT * (k - 3), -15.0)
            c.predict(np.array([25.0, 0.0, gap, v_rel, 1.0, 25.0, 1.0]))
            phases.append(int(c.phase[0]))
        assert phases[:3] == [0, 0, 0]
        assert phases[3:] == ([1, 1, 2] if critical else [0, 0, 0])
        assert c.event[0] == (3 if critical else 0)


# ---- 4. the avoid/collide boundary on a cut-in grid ---------------------------------------------------------------

def closing_distance(w: float) -> float:
    """How far [m] the ego closes in on a vehicle at constant speed, w m/s slower, from the
    cut-in's detection until it no longer closes: perception (held speed), reaction (0.4 m/s^2),
    a ramp from 0 to full braking, full braking. By hand, from the module's constants."""
    t_p, t_r, d_r = ccm.RISK_PERCEPTION_TIME, ccm.REACTION_TIME, ccm.REACTION_DECEL
    b, t_j = ccm.BRAKE_DECEL, ccm.BRAKE_RAMP_TIME
    s = w * t_p
    if w <= d_r * t_r:  # stops closing in during the reaction
        return s + w * w / (2 * d_r)
    s += w * t_r - d_r * t_r ** 2 / 2
    w -= d_r * t_r
    # the ramp: deceleration b t / t_j (its first 0.03 s at 0.4 m/s^2 instead changes < 1 mm)
    if w <= b * t_j / 2:  # stops closing in during the ramp, at t* with w = b t*^2 / (2 t_j)
        t = math.sqrt(2 * t_j * w / b)
        return s + w * t - b * t ** 3 / (6 * t_j)
    s += w * t_j - b * t_j ** 2 / 6
    w -= b * t_j / 2
    return s + w * w / (2 * b)


def test_closing_distance_by_hand():
    # w = 10: 4 m + (7.5 - 0.1125) m + (9.7 * 0.6 - 7.59 * 0.06) m + 7.423^2 / (2 * 7.59) m
    w2, w3 = 10 - 0.3, 10 - 0.3 - G_774 * 0.3
    assert closing_distance(10.0) == pytest.approx(4 + 7.3875 + w2 * 0.6 - G_774 * 0.06 + w3 ** 2 / (2 * G_774),
                                                   abs=1e-3)
    assert closing_distance(0.2) == pytest.approx(0.08 + 0.05)  # 0.4 s at 0.2 m/s, then 0.2^2 / 0.8


def test_cut_in_grid_boundary_is_monotone_and_matches_the_stopping_distance():
    cell = 0.25  # [m]
    d = np.arange(cell / 2, 60.0, cell)  # cut-in distances (half-cell offsets: no exact 2 s TTC ties)
    for v_ego in (20.0, 25.0, 30.0):
        for w in (2.0, 4.0, 6.0, 8.0, 10.0, 14.0, 20.0):  # closing speed; the other keeps v_ego - w >= 0
            r = simulate(CCDriver(), v_ego, v_ego - w, d + w * DT * 2, appear=2, steps=70, v_set=v_ego)
            assert r["gap"][2] == pytest.approx(d)
            avoided = r["gap"].min(axis=0) > 0.0
            assert avoided.any() and not avoided.all(), (v_ego, w)
            boundary = d[first(avoided)]
            assert np.all(avoided[d >= boundary]), (v_ego, w, avoided)  # monotone in the distance
            # critical (TTC < 2 s): the C&C response avoids iff d > its closing distance; not critical:
            # the linear law brakes at once (8 m/s^2: w^2 / 16 < 2 w) and avoids
            expected = min(closing_distance(w), 2.0 * w)
            assert abs(boundary - expected) <= cell, (v_ego, w, boundary, expected)
            assert r["v"][-1].max() <= v_ego + 1e-9  # it never sped up into the threat
    # the closed form is what sets the boundary at low closing speeds, the 2 s rule above about 10 m/s
    assert all(closing_distance(w) < 2 * w - 2 * cell for w in (2.0, 4.0, 6.0, 8.0))
    assert all(closing_distance(w) > 2 * w + 2 * cell for w in (14.0, 20.0))


# ---- 5. the R157 cut-in rule --------------------------------------------------------------------------------------

def test_r157_cut_in_must_avoid_on_hand_computed_values():
    # threshold v_rel / 12 + 0.35 s: 10 m/s -> 1.1833 s, 6 m/s -> 0.85 s, 0 -> 0.35 s
    assert r157_cut_in_must_avoid(1.19, 10.0) is True
    assert r157_cut_in_must_avoid(1.18, 10.0) is False
    assert r157_cut_in_must_avoid(0.86, 6.0) and not r157_cut_in_must_avoid(0.84, 6.0)
    assert r157_cut_in_must_avoid(0.36, 0.0) and not r157_cut_in_must_avoid(0.35, 0.0)
    out = r157_cut_in_must_avoid(np.array([2.0, 2.0, 1.0]), np.array([10.0, 20.0, 30.0]))  # 1.18, 2.02, 2.85 s
    assert out.tolist() == [True, False, False]
    with pytest.raises(ValueError, match="NaN"):
        r157_cut_in_must_avoid(float("nan"), 10.0)


# ---- 6. batches, reset, input, parameters -------------------------------------------------------------------------

def test_batch_rows_are_independent():
    k0 = 3
    a_lead = lambda k: -6.0 if k >= k0 else 0.0  # noqa: E731
    # row 0: a critical cut-in while speeding up to the set speed (it holds that during perception);
    # row 1: a lead braking hard; row 2: free road, speeding up
    v_e, v_o, g = np.array([22.0, 20.0, 20.0]), np.array([15.0, 20.0, 20.0]), np.array([17.0, 20.0, 300.0])
    single = [simulate(CCDriver(), v_e[i], v_o[i], g[i], a_other=(a_lead if i == 1 else (lambda k: 0.0)),
                       appear=(k0 if i == 0 else 0), steps=30, h=0.875)["a"][:, 0] for i in range(3)]
    c, phases = CCDriver(), []
    # the batch: each row's scene stepped with the batched controller's own answers
    v, x_e, x_o, vo, a = v_e.copy(), np.zeros(3), g.copy(), v_o.copy(), np.zeros(3)
    for k in range(30):
        gap = x_o - x_e
        seen = np.array([k >= k0, True, False])
        obs = np.stack([v, a, np.where(seen, gap, 200.0), np.where(seen, vo - v, 0.0), seen.astype(float),
                        np.full(3, 25.0), np.full(3, 0.875)], axis=1)
        act, _ = c.predict(obs)
        assert act.shape == (3, 1)
        a = accel(act)
        assert a == pytest.approx([s[k] for s in single], abs=1e-9)
        phases.append(c.phase.copy())
        vo, x_o = advance(vo, x_o, np.array([0.0, a_lead(k), 0.0]))
        v, x_e = advance(v, x_e, a)
    phases = np.array(phases)
    held = single[0][k0 - 1]  # row 0's last normal command: held through its 0.4 s perception
    assert held > 0.5 and single[0][k0:k0 + 2] == pytest.approx(held, abs=1e-6)
    assert phases[:, 0].max() == 3 and phases[:, 1].max() == 3 and np.all(phases[:, 2] == 0)
    assert first(phases[:, 0] > 0) == k0 and first(phases[:, 1] > 0) == k0 + 1  # each at its own event


def test_reset_restores_the_initial_state_and_v2v_widths_are_read():
    c = CCDriver()
    first_run = simulate(c, 25.0, 15.0, 17.0, appear=1, steps=12)
    assert c.phase[0] == 3
    c.reset()
    again = simulate(c, 25.0, 15.0, 17.0, appear=1, steps=12)
    assert again["a"] == pytest.approx(first_run["a"]) and again["phase"] == pytest.approx(first_run["phase"])
    # the -v1 widths (extra columns) change nothing; 13 fields carry no V2V field
    for width in (13, 23):
        r = simulate(CCDriver(), 25.0, 15.0, 17.0, appear=1, steps=12, v2v=(width == 23), width=width)
        assert r["a"] == pytest.approx(first_run["a"])
    # episode_start (stable-baselines3's convention) restarts a row as reset() does
    c.predict(np.array([25.0, 0.0, 200.0, 0.0, 0.0, 25.0, 1.5]), episode_start=np.array([True]))
    assert c.phase[0] == 0


def test_bad_input_is_a_value_error_naming_it():
    c = CCDriver()
    row = np.array([25.0, 0.0, 30.0, -2.0, 1.0, 25.0, 1.5])
    bad = row.copy()
    bad[2] = np.nan
    with pytest.raises(ValueError, match=r"field 2 \(gap\) is NaN"):
        c.predict(bad)
    with pytest.raises(ValueError, match="NaN in row 1"):
        c.predict(np.stack([row, bad]))
    with pytest.raises(ValueError, match="fields"):
        c.predict(row[:6])
    with pytest.raises(ValueError, match="fields"):
        c.predict(np.zeros((2, 9)))
    with pytest.raises(ValueError, match="reaction_tme"):
        cc_driver(reaction_tme=1.0)
    with pytest.raises(ValueError, match="brake_decel"):
        cc_driver(brake_decel=float("nan"))
    slow = cc_driver(reaction_time=1.0)  # a parameter changes the model
    assert isinstance(slow, CCDriver) and slow.reaction_time == 1.0


def test_in_the_environment_a_braking_lead_gets_the_r157_response():
    import gymnasium as gym

    from acc_gym.evaluation.runner import load_controller

    ctrl = load_controller("acc_gym_agents.controllers.cc_driver:cc_driver")
    env = gym.make("acc_gym/NCAP-v1", drivers="idm")  # -v1: 13 fields
    try:
        obs, _ = env.reset(seed=4, options={"scenario": "ncap/ccrb/6-12"})  # the lead brakes at 6 m/s^2
        assert obs.shape == (13,)
        phases, applied, term = [], [], False
        while True:
            act, _ = ctrl.predict(obs)
            obs, _, term, trunc, info = env.step(act)
            phases.append(int(ctrl.phase[0]))
            applied.append(info["a_applied"])
            if term or trunc:
                break
    finally:
        env.close()
    assert not term  # no collision
    start = phases.index(2)
    assert phases[start:start + 4] == [2, 2, 2, 2] and phases[start + 4] == 3
    assert min(applied) == pytest.approx(-G_774, abs=0.05)  # the vehicle model applies the 0.774 g


def test_constants_table_is_the_regulations():
    import acc_gym.envs.core

    assert ccm.DT == acc_gym.envs.core.DT
    assert (ccm.RISK_PERCEPTION_TIME, ccm.REACTION_TIME, ccm.BRAKE_RAMP_TIME) == (0.4, 0.75, 0.6)
    assert ccm.BRAKE_DECEL == pytest.approx(7.59, abs=0.01) and ccm.LEAD_DECEL_THRESHOLD == 5.0
    assert ccm.BRAKE_DECEL / ccm.BRAKE_RAMP_TIME == pytest.approx(12.65, abs=0.01)
    assert (ccm.TTC_CRITICAL, ccm.HEADWAY_CRITICAL, ccm.WANDERING_ZONE) == (2.0, 2.0, 0.375)
