"""The JRC's Fuzzy Safety Model (FSM) as a controller: UN R157's second reference driver.

The Joint Research Centre proposed the FSM (Mattas et al. 2020, "Fuzzy Surrogate Safety
Metrics for real-time assessment of rear-end collision risk", Accident Analysis & Prevention
148: 105794) as a reference for what an automated system must avoid, beside R157's careful
and competent driver (:mod:`acc_gym_agents.controllers.cc_driver`). It rates the situation
ahead with two fuzzy metrics in [0, 1]:

* **PFS** (proactive fuzzy safety), from the distance the ego would need if the vehicle
  ahead braked at ``lead_decel`` and the ego, after ``reaction_time``, braked at
  ``comfort_decel`` (safe) or ``max_fuzzy_decel`` (unsafe): with ``d = gap - margin``,
  ``d_safe = v rt + v^2 / (2 b_comf) - v_l^2 / (2 b_lead) + safe_margin`` and ``d_unsafe`` the
  same with ``b_max`` and no ``safe_margin``: 0 above ``d_safe``, 1 below ``d_unsafe``, linear
  between;
* **CFS** (critical fuzzy safety), from the closing speed now: 0 when not closing in; if the
  ego's own deceleration ``a`` (limited to ``comfort_decel``) would shed the closing speed
  within the reaction time, 1 when ``gap < (v - v_l)^2 / (2 |a|)`` else 0; otherwise with
  ``d_safe = (v + a rt / 2 - v_l) rt + (v + a rt - v_l)^2 / (2 b_comf)`` and ``d_unsafe`` with
  ``b_max``: 0 above, 1 below, linear between.

The driver: the linear ACC law (:class:`LinearACC`) while both metrics are 0 -- our decision
[R], as for ``cc-driver``: the model specifies only the response -- with its gap target
raised to at least PFS's safe distance at equal speeds plus ``FOLLOW_BUFFER`` (1 m), so that
steady following is not inside the model's own unsafe zone (with the plain ACC law, 32.5 m at
20 m/s against PFS's 40.4 m, it cycled around the PFS boundary and had no steady state). When either turns positive an
event starts: for ``reaction_time`` it commands 0 m/s^2 (it keeps its speed, as the JRC's
implementation does), then it brakes towards ``cfs (b_max - b_comf) + b_comf`` when CFS > 0,
else ``pfs b_comf``, its deceleration rising at most ``jerk`` per second, never above
``brake_decel`` (0.774 g) and dropping at once to a lower target. The event ends when both
metrics are 0 again; a later one starts with a new reaction time [R] (the JRC's simulations
run one event each).

Every number below is the JRC's (github.com/ec-jrc/JRC-FSM, ``utility/vehicle.py``,
``utility/fuzzy_functs.py``, ``utility/models.py`` [S]; ``../shared/STANDARDS.md``), our own
implementation on the environment's observation: the gap and the speeds come from fields 0-3,
the ego's acceleration from field 1. Change them per controller with the factory's keyword
arguments (``fsm_driver(reaction_time=1.0)``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from acc_gym_agents.controllers.cc_driver import build_with, check_params, check_rows
from acc_gym_agents.controllers.linear import LinearACC, _Policy

# ---- the model's numbers: value, unit, source ------------------------------------------------------------
DT = 0.2                   # [s]      env  the env's step
G = 9.81                   # [m/s^2]  [S]  the JRC's g (for 0.774 g)
REACTION_TIME = 0.75       # [s]      [S]  FSM_rt
COMFORT_DECEL = 4.0        # [m/s^2]  [S]  FSM_br_min: the ego's comfortable braking
MAX_FUZZY_DECEL = 6.0      # [m/s^2]  [S]  FSM_br_max: the ego's braking at which a metric reaches 1
LEAD_DECEL = 7.0           # [m/s^2]  [S]  FSM_bl: the braking assumed of the vehicle ahead
MARGIN = 2.0               # [m]      [S]  FSM_margin_dist: taken off the gap (PFS)
SAFE_MARGIN = 2.0          # [m]      [S]  FSM_margin_safe_dist: added to PFS's safe distance
BRAKE_DECEL = 0.774 * G    # [m/s^2]  [S]  FSM_max_deceleration, 7.59
JERK = 12.65               # [m/s^3]  [S]  CC_min_jerk: the braking's rise
FOLLOW_BUFFER = 1.0        # [m]      [R]  normal following keeps this beyond PFS's safe distance


def pfs(gap, v, v_lead, reaction_time=REACTION_TIME, comfort_decel=COMFORT_DECEL,
        max_fuzzy_decel=MAX_FUZZY_DECEL, lead_decel=LEAD_DECEL, margin=MARGIN, safe_margin=SAFE_MARGIN):
    """Proactive fuzzy safety in [0, 1] (arrays broadcast; see the module docstring)."""
    gap, v, v_lead = (np.asarray(x, dtype=float) for x in (gap, v, v_lead))
    d = gap - margin
    base = v * reaction_time - v_lead ** 2 / (2.0 * lead_decel)
    d_safe = base + v ** 2 / (2.0 * comfort_decel) + safe_margin
    d_unsafe = base + v ** 2 / (2.0 * max_fuzzy_decel)
    between = (d - d_safe) / np.minimum(d_unsafe - d_safe, -1e-12)
    return np.where(d > d_safe, 0.0, np.where(d < d_unsafe, 1.0, between))


def cfs(gap, v, v_lead, a, reaction_time=REACTION_TIME, comfort_decel=COMFORT_DECEL,
        max_fuzzy_decel=MAX_FUZZY_DECEL):
    """Critical fuzzy safety in [0, 1] (arrays broadcast; ``a`` the ego's acceleration [m/s^2])."""
    gap, v, v_lead, a = (np.asarray(x, dtype=float) for x in (gap, v, v_lead, a))
    a_f = np.maximum(a, -comfort_decel)  # very hard braking is not counted on
    closing = v - v_lead
    v_new = v + reaction_time * a_f  # the ego's speed after the reaction time
    # shed within the reaction time: only a gap shorter than the stopping-the-closing distance counts
    shed = (gap < closing ** 2 / np.maximum(np.abs(2.0 * a), 1e-12)).astype(float)
    lead_in = (closing + 0.5 * a_f * reaction_time) * reaction_time
    rest = v_new - v_lead
    d_safe = lead_in + rest ** 2 / (2.0 * comfort_decel)
    d_unsafe = lead_in + rest ** 2 / (2.0 * max_fuzzy_decel)
    fuzzy = np.where(gap > d_safe, 0.0, np.where(gap < d_unsafe, 1.0,
                                                  (gap - d_safe) / np.minimum(d_unsafe - d_safe, -1e-12)))
    return np.where(closing <= 0.0, 0.0, np.where(v_new < v_lead, shed, fuzzy))


@dataclass
class FSMDriver(_Policy):
    """The Fuzzy Safety Model driver, one row of state per observation row (see the module
    docstring). State: the time left to react [s] (NaN outside an event) and the current
    deceleration [m/s^2]; ``reset()`` clears them, a batch of another size restarts them.
    Observation: 7, 11, 13 or 23 fields, fields 0-4 read; NaN or another width is a ValueError."""

    reaction_time: float = REACTION_TIME  # [s]
    comfort_decel: float = COMFORT_DECEL  # [m/s^2]
    max_fuzzy_decel: float = MAX_FUZZY_DECEL  # [m/s^2]
    lead_decel: float = LEAD_DECEL  # [m/s^2]
    margin: float = MARGIN  # [m]
    safe_margin: float = SAFE_MARGIN  # [m]
    brake_decel: float = BRAKE_DECEL  # [m/s^2]
    jerk: float = JERK  # [m/s^3]
    dt: float = DT  # [s]
    vectorised: ClassVar[bool] = True

    def __post_init__(self) -> None:
        check_params(self, "fsm-driver", ("comfort_decel", "lead_decel", "brake_decel", "jerk", "dt", "accel_max",
                                          "decel_max"))
        if self.max_fuzzy_decel <= self.comfort_decel:
            raise ValueError(f"fsm-driver: max_fuzzy_decel ({self.max_fuzzy_decel!r}) must exceed comfort_decel "
                             f"({self.comfort_decel!r})")
        self.follow = LinearACC(accel_max=self.accel_max, decel_max=self.decel_max)
        self.reset()

    def reset(self) -> None:
        self._n = None
        self.follow.reset()

    def predict(self, obs, state=None, episode_start=None, deterministic: bool = True):
        if episode_start is not None and self._n:  # stable-baselines3's convention: restart those rows
            starts = np.asarray(episode_start, dtype=bool).reshape(-1)
            if starts.shape == (self._n,):
                self.react[starts], self.decel[starts] = np.nan, 0.0
        return super().predict(obs, state, episode_start, deterministic)

    def metrics(self, o: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(pfs, cfs)`` of each observation row (0 where nothing is in range)."""
        v, a, gap, seen = o[:, 0], o[:, 1], o[:, 2], o[:, 4] > 0.5
        v_lead = np.maximum(v + o[:, 3], 0.0)
        p = pfs(gap, v, v_lead, self.reaction_time, self.comfort_decel, self.max_fuzzy_decel, self.lead_decel,
                self.margin, self.safe_margin)
        c = cfs(gap, v, v_lead, a, self.reaction_time, self.comfort_decel, self.max_fuzzy_decel)
        return np.where(seen, p, 0.0), np.where(seen, c, 0.0)

    def following(self, o: np.ndarray) -> np.ndarray:
        """Normal driving [m/s^2]: the linear ACC law with its gap target ``s0 + h v`` raised to PFS's
        safe distance at equal speeds (``v rt + v^2 / (2 b_comf) - v^2 / (2 b_lead) + safe_margin +
        margin``) plus ``FOLLOW_BUFFER`` where that is longer (the gap it sees is shortened by the
        difference)."""
        v, h = o[:, 0], o[:, 6]
        pfs_safe = (v * self.reaction_time + v ** 2 / (2.0 * self.comfort_decel) - v ** 2 / (2.0 * self.lead_decel)
                    + self.safe_margin + self.margin)
        extra = np.maximum(pfs_safe + FOLLOW_BUFFER - (self.follow.s0 + h * v), 0.0)
        shifted = o.copy()
        shifted[:, 2] = o[:, 2] - extra
        return self.follow._accel(shifted)

    def _accel(self, o: np.ndarray) -> np.ndarray:
        check_rows(o, "fsm-driver")
        n = o.shape[0]
        if self._n != n:
            self._n, self.react, self.decel = n, np.full(n, np.nan), np.zeros(n)
        p, c = self.metrics(o)
        risky = (p + c) > 0.0
        self.react = np.where(~risky, np.nan, np.where(np.isnan(self.react), self.reaction_time, self.react))
        reacting = risky & (self.react > 1e-9)
        braking = risky & ~reacting
        target = np.where(c > 0.0, c * (self.max_fuzzy_decel - self.comfort_decel) + self.comfort_decel,
                          p * self.comfort_decel)
        rise = np.minimum(self.decel + self.jerk * self.dt, self.brake_decel)
        self.decel = np.where(braking, np.minimum(rise, target), 0.0)
        self.react = np.where(reacting, self.react - self.dt, self.react)
        a = np.where(braking, -self.decel, np.where(reacting, 0.0, self.following(o)))
        return np.clip(a, -self.decel_max, self.accel_max)


def fsm_driver(**params) -> FSMDriver:
    """The ``fsm-driver`` controller: :class:`FSMDriver` with ``params`` (its fields); an unknown
    name is a ValueError naming it."""
    return build_with(FSMDriver, "fsm-driver", params)
