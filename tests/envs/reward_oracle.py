"""The environments' built-in rewards written with numpy: the test oracles the compiled terms
(:func:`acc_gym.envs._kernel.criteria_reward_rows`, :func:`acc_gym.envs._kernel.margin_reward_rows`,
which ``CriteriaReward.__call__`` and ``MarginReward.__call__`` run) are checked against. Kept in
the tests: the package has one implementation of each reward."""

from __future__ import annotations

import numpy as np

from acc_gym.envs._kernel import REACH_BAND
from acc_gym.envs.reward import CriteriaReward, MarginReward, StepIndicators


def criteria_oracle(reward: CriteriaReward, s: StepIndicators) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The same reward written with numpy (the definition the compiled one is tested against)."""
    speed_err = np.minimum(np.abs(s.v - s.set_speed) / (0.2 * s.set_speed), 1.0)
    terms = {
        "band": reward.band * (s.following & s.in_band),
        "efficiency": reward.efficiency * np.where(s.following, 1.0 - np.nan_to_num(s.u, nan=1.0), 0.0),
        "speed": reward.speed * np.where(s.free, 1.0 - speed_err, 0.0),
        "comfort": -reward.comfort * (s.a / s.a_comfort) ** 2,
        "jerk": -reward.jerk * (s.jerk / reward.jerk_scale) ** 2,
        "safety": -reward.safety * s.violation,
        "collision": -reward.collision * s.collision,
    }
    if s.followable is not None:
        far = 1.2 * s.tau1 * s.v_lead + 5.0  # [m] the band's upper edge at the lead's speed, plus 5 m
        terms["lag"] = -reward.lag * np.where(s.followable, np.clip((s.gap - far) / far, 0.0, 1.0), 0.0)
    terms = {k: np.asarray(v, dtype=float) for k, v in terms.items()}
    return sum(terms.values()), terms


def margin_oracle(reward: MarginReward, s: StepIndicators) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    if s.followable is None or s.v_lead is None or s.tau1 is None:
        raise ValueError("MarginReward needs the indicators followable, v_lead and tau1 (acc_gym's environments "
                         "give them)")
    if s.a_lead is None and reward.stop_demand:
        raise ValueError("MarginReward.stop_demand needs the indicator a_lead (acc_gym's environments give it)")
    a_lead = np.zeros_like(np.asarray(s.v, dtype=float)) if s.a_lead is None else np.asarray(s.a_lead, dtype=float)
    v = np.asarray(s.v, dtype=float)
    following = np.asarray(s.following, dtype=bool)
    followable = np.asarray(s.followable, dtype=bool)
    gap = np.asarray(s.gap, dtype=float)
    v_lead = np.asarray(s.v_lead, dtype=float)
    q = np.asarray(s.q, dtype=float)  # [m]
    far = 1.2 * np.asarray(s.tau1, dtype=float) * v_lead + 5.0  # [m]
    with np.errstate(invalid="ignore"):
        behind = followable & (gap > far)
        if reward.behind_outside_margin:
            behind &= ~(q < 0)  # not inside Gapsafe
        x = np.where(behind, (gap - far) / far, 0.0)
        lag = np.where(behind, np.where(np.isfinite(x), x / (1.0 + x), 1.0), 0.0)
    set_speed = np.asarray(s.set_speed, dtype=float)
    e = np.abs(v - set_speed) / (0.2 * set_speed)
    speed = np.where(e <= 1.0, 1.0 - e, -reward.slope * (np.minimum(e, reward.E_COUNTED) - 1.0))
    width = max(reward.peak, 1.0 - reward.peak)
    u = np.nan_to_num(np.asarray(s.u, dtype=float), nan=1.0)
    tent = np.maximum(0.0, 1.0 - np.abs(u - reward.peak) / width)
    a = np.asarray(s.a, dtype=float)  # [m/s^2]
    short = a + reward.response_decel
    gs = np.asarray(s.gap_safe, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        reach = np.where(following & (gs > 0), np.minimum(np.maximum(q / gs - REACH_BAND, 0.0) / REACH_BAND, 1.0),
                         0.0)
        stopped = np.isfinite(gap) & (v_lead < reward.STOPPED)  # a stopped vehicle ahead
        stop_gap = gap - v * v / (2.0 * reward.response_decel)  # [m] left if the ego braked at the proper response
        stand = np.where(stopped, np.clip((reward.standstill_gap - stop_gap) / reward.standstill_gap, 0.0, 1.0), 0.0)
        # [m/s^2] paper 001's required deceleration where closing, counted up to A_COUNTED
        closing = (q < 0) & (gap > 0) & np.isfinite(gap) & (v > v_lead)
        a_req = np.where(closing, np.minimum((v - v_lead) * (v - v_lead) / (2.0 * gap), reward.A_COUNTED), 0.0)
        demanding = closing & (a_req > reward.response_decel)
        demand = np.where(demanding, np.clip((a + a_req)
                                             / (a_req - reward.response_decel), 0.0, 1.0), 0.0)
        # [m/s^2] the deceleration that stops the ego behind a braking vehicle ahead, its own stop counted
        braking = (q < 0) & (gap > 0) & np.isfinite(gap) & (a_lead < 0)
        a_stop = np.where(braking, np.minimum(v * v / (2.0 * (gap + v_lead * v_lead / (2.0 * -a_lead))),
                                              reward.A_COUNTED), 0.0)
        stopping = braking & (a_stop > reward.response_decel)
        stop = np.where(stopping, np.clip((a + a_stop) / (a_stop - reward.response_decel), 0.0, 1.0), 0.0)
    # [-] the acceleration's rise this step, counted up to JERK_COUNTED, squared in jerk_scale units (release, let_go)
    rise = (np.minimum(np.maximum(np.asarray(s.jerk, dtype=float), 0.0), reward.JERK_COUNTED) / reward.jerk_scale) ** 2
    steps_left = 0.0 if s.steps_left is None else np.maximum(np.asarray(s.steps_left, dtype=float), 0.0)
    terms = {
        "band": reward.band * (following & np.asarray(s.in_band, dtype=bool)),
        "efficiency": reward.efficiency * np.where(following, tent, 0.0),
        "speed": reward.speed * np.where(np.asarray(s.free, dtype=bool) | behind, speed, 0.0),
        "response": -reward.response * np.where(q < 0, np.clip(short / reward.response_decel, 0.0, 1.0), 0.0),
        "comfort": -reward.comfort * (np.minimum(np.abs(a), reward.A_COUNTED)
                                    / s.a_comfort) ** 2,
        "jerk": -reward.jerk * (np.minimum(np.abs(np.asarray(s.jerk, dtype=float)), reward.JERK_COUNTED)
                              / reward.jerk_scale) ** 2,
        "safety": -reward.safety * np.asarray(s.violation, dtype=float),
        "collision": -np.asarray(s.collision, dtype=float) * (reward.collision + reward.max_step_cost * steps_left),
        "lag": -reward.lag * lag,
        "overspeed": -reward.overspeed * np.minimum(np.maximum(v - set_speed, 0.0) / (reward.overspeed_scale * set_speed),
                                                  reward.E_COUNTED),
        "reach": -reward.reach * reach,
        "behind": -reward.behind * behind.astype(float),
        "standstill": -reward.standstill * stand,
        "demand": -reward.demand * demand,
        # the acceleration rising inside Gapsafe (kernel: the same operations)
        "release": -reward.release * np.where(q < 0, rise, 0.0),
        # ... where it ends weaker than the proper response
        "let_go": -reward.let_go * np.where((q < 0) & (a > -reward.response_decel), rise, 0.0),
        "stop_demand": -reward.stop_demand * stop,
    }
    terms = {k: np.asarray(val, dtype=float) for k, val in terms.items()}
    return sum(terms.values()), terms
