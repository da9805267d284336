"""How a controller degrades with its car's actuators and radar: one axis at a time.

``robustness(controller)`` drives a suite's episodes (default ``ncap-v2``'s test split: cut-ins,
cut-outs, stopped and braking targets) at each level of three axes, each from the ideal car:

* ``lag``: the actuators' first-order lag [s] (:class:`~acc_gym.onboard.ActuatorConfig`);
* ``delay``: the actuators' dead time [s];
* ``noise``: the radar, as a multiple of the ``typical`` preset's errors and dropouts (its
  gap and relative-speed standard deviations and biases and its dropout share scaled by the
  factor; its beams, track coasting and latency as ``typical``); 0 is the ideal radar.

At each level: the mean score, the share qualified, collisions and how many of them UN R157's
careful driver prevents on the same scenario (:func:`acc_gym.evaluation.runner.preventability`),
and on the ``lag`` and ``delay`` axes the string-stability verdict of a column of copies with
those actuators (:func:`acc_gym.evaluation.string_stability.string_stability`: :data:`COLUMN`
copies, the :data:`FREQUENCIES` grid, no disturbance; the sweep does not model the radar, so
the ``noise`` axis has none). The ideal car (every axis at 0) is run once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from acc_gym.onboard import SENSOR_PRESETS, ActuatorConfig, SensorConfig

LAGS = (0.0, 0.25, 0.5, 1.0)  # [s]
DELAYS = (0.0, 0.25, 0.5, 1.0)  # [s]
NOISE = (0.0, 1.0, 2.0, 4.0)  # multiples of the typical radar's errors and dropouts
AXES = ("lag", "delay", "noise")
COLUMN = 4  # copies in the string-stability column at each level
FREQUENCIES = tuple(np.geomspace(0.005, 1.0, 12).round(6))  # [Hz]
MAX_DROPOUT = 0.9


def noisy_radar(factor: float) -> SensorConfig:
    """The ``typical`` radar with its errors and dropout share scaled by ``factor`` (0: the ideal radar)."""
    if not (isinstance(factor, (int, float)) and math.isfinite(factor) and factor >= 0):
        raise ValueError(f"a noise level must be a number >= 0 (a multiple of the typical radar's errors), "
                         f"got {factor!r}")
    if factor == 0:
        return SensorConfig()
    t = SENSOR_PRESETS["typical"]
    return replace(t, gap_sd=t.gap_sd * factor, gap_bias=t.gap_bias * factor, rate_sd=t.rate_sd * factor,
                   rate_bias=t.rate_bias * factor, dropout_share=min(MAX_DROPOUT, t.dropout_share * factor))


@dataclass(frozen=True)
class Level:
    """One point of a sweep: the axis, its value, and the car it means."""

    axis: str
    value: float
    sensors: SensorConfig
    actuators: ActuatorConfig

    @property
    def ideal(self) -> bool:
        return self.sensors.ideal and self.actuators.ideal


def levels(lags=LAGS, delays=DELAYS, noise=NOISE) -> list[Level]:
    """The levels of the three axes in order (a bad value is a ``ValueError`` naming it)."""
    out = [Level("lag", float(v), SensorConfig(), ActuatorConfig(lag=v)) for v in lags]
    out += [Level("delay", float(v), SensorConfig(), ActuatorConfig(dead_time=v)) for v in delays]
    out += [Level("noise", float(v), noisy_radar(v), ActuatorConfig()) for v in noise]
    return out


def _drive(policy, env_id: str, scenarios: list, level: Level) -> dict:
    import gymnasium as gym

    from acc_gym.evaluation.runner import preventability, run_episode, summarise

    env = gym.make(env_id, sensors=level.sensors, actuators=level.actuators)
    reports, ids, collided = [], [], []
    try:
        for sc in scenarios:
            info, _ = run_episode(env, policy, scenario=sc, record=False)
            reports.append(info["report"])
            ids.append(info["scenario"])
            if info["report"]["metrics"]["collision"]:
                collided.append(sc)
    finally:
        env.close()
    s = summarise(reports, ids)
    out = {k: s[k] for k in ("episodes", "mean_score", "share_qualified", "collisions")}
    out.update(preventability(collided, env_id))
    return out


def _column(policy, level: Level) -> dict:
    from acc_gym.evaluation.string_stability import PlatoonConfig, StringStabilityError, string_stability

    try:
        r = string_stability(policy, PlatoonConfig(vehicles=COLUMN, actuators=level.actuators),
                             frequencies=FREQUENCIES, disturbance=False)
    except StringStabilityError as exc:
        return {"max_gain": None, "string_stable": None, "string_stability_error": str(exc)}
    gain = r.max_gain
    return {"max_gain": None if gain is None or not math.isfinite(gain) else float(gain),
            "string_stable": r.string_stable}


def robustness(controller, suite: str = "ncap-v2", split: str = "test", *, lags=LAGS, delays=DELAYS, noise=NOISE,
               episodes: int | None = None, string_stability: bool = True, progress=None) -> dict:
    """The sweep of the module docstring: ``{"controller", "suite", "split", "episodes", "levels": [...]}``,
    each level ``{"axis", "value", "mean_score", "share_qualified", "collisions",
    "preventable_collisions", "non_preventable_collisions", "max_gain", "string_stable"}``
    (``max_gain`` and ``string_stable`` None on the noise axis or without ``string_stability``, and
    where the column has no steady state to disturb: then ``string_stability_error`` says why).
    ``episodes``: the first N of the split; ``progress(done, total)`` after each level."""
    from acc_gym.evaluation.runner import load_controller
    from acc_gym.suites import get_suite

    if episodes is not None and (isinstance(episodes, bool) or int(episodes) != episodes or episodes < 1):
        raise ValueError(f"episodes must be a positive integer or None, got {episodes!r}")
    s = get_suite(suite)
    scenarios = s.episodes(split)[:episodes]
    sweep = levels(lags, delays, noise)
    policy = load_controller(controller)
    ideal_drive = ideal_column = None
    rows = []
    for i, level in enumerate(sweep):
        if level.ideal and ideal_drive is not None:
            drive = ideal_drive
        else:
            drive = _drive(policy, s.env_id, scenarios, level)
            ideal_drive = drive if level.ideal else ideal_drive
        column = {"max_gain": None, "string_stable": None}
        if string_stability and level.axis != "noise":
            if level.ideal and ideal_column is not None:
                column = ideal_column
            else:
                column = _column(policy, level)
                ideal_column = column if level.ideal else ideal_column
        rows.append({"axis": level.axis, "value": level.value, **drive, **column})
        if progress is not None:
            progress(i + 1, len(sweep))
    name = controller if isinstance(controller, str) else type(controller).__name__
    return {"controller": name, "suite": suite, "split": split, "episodes": len(scenarios), "levels": rows}


def format_table(result: dict) -> str:
    """The sweep as a text table."""
    lines = [f"{result['controller']} on {result['suite']} ({result['split']}, {result['episodes']} episodes): "
             f"one axis at a time from the ideal car",
             f"  {'axis':<6} {'value':>6}  {'score':>6}  {'qualified':>9}  {'collisions':>10}  {'preventable':>11}  "
             f"{'largest gain':>12}"]
    units = {"lag": "s", "delay": "s", "noise": "x"}
    for r in result["levels"]:
        gain = "no steady state" if r.get("string_stability_error") else "-" if r["max_gain"] is None else \
            f"{r['max_gain']:.3f}" + ("" if r["string_stable"] else " !")
        lines.append(f"  {r['axis']:<6} {r['value']:>5g}{units[r['axis']]}  {r['mean_score']:>6.1f}  "
                     f"{r['share_qualified']:>9.0%}  {r['collisions']:>10}  {r['preventable_collisions']:>11}  "
                     f"{gain:>12}")
    lines.append("  (! string unstable; noise: multiples of the typical radar's errors and dropouts)")
    return "\n".join(lines)
