"""UN Regulation No. 157's "careful and competent (C&C) human driver" as a controller.

R157 (ALKS) judges an automated lane keeping system against a reference driver who
perceives a critical event, reacts after a fixed delay and then brakes with a fixed jerk
up to a fixed deceleration (Annex 4 Appendix 3 of the original text, Annex 3 after the
amendments). :class:`CCDriver` is that driver on the environment's observation,
:func:`r157_cut_in_must_avoid` the regulation's simpler cut-in rule and :func:`cc_driver`
the factory (``acc_gym_agents.controllers.cc_driver:cc_driver``).

Every number is in the table below, with its source: [Q] quoted from the regulation,
[S] as the JRC's open implementation of the model reads the regulation, [R] our own
decision for this package. Change them here, or per controller: the factory's keyword
arguments are the lower-case names (``cc_driver(reaction_time=1.0)``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import ClassVar

import numpy as np

from acc_gym_agents.controllers.linear import LinearACC, _Policy

# ---- the model's numbers: value, unit, source, meaning ------------------------------------------------------
DT = 0.2                       # [s]      env  the env's step (acc_gym.envs.core.DT)
G = 9.80665                    # [m/s^2]  [Q]  standard gravity (for 0.774 g)
WANDERING_ZONE = 0.375         # [m]      [Q]  lateral wandering zone: a cut-in is perceived from crossing it.
                               #               The observation has no lateral position: documentation only
RISK_PERCEPTION_TIME = 0.4     # [s]      [Q]  cut-in: perception to reaction. [R] counted from the first step
                               #               that shows the vehicle in the lane (the env reports it only then)
CUT_OUT_PERCEPTION_TIME = 0.4  # [s]      [R]  cut-out: as the cut-in (the env shows the revealed vehicle once
                               #               the leaving one has left the lane)
DECEL_PERCEPTION_TIME = 0.0    # [s]      [R]  lead deceleration: the threshold crossing is the perception point
LEAD_DECEL_THRESHOLD = 5.0     # [m/s^2]  [Q]  the vehicle ahead braking harder than this is an event
TTC_CRITICAL = 2.0             # [s]      [S]  a cut-in is critical below this time to collision
HEADWAY_CRITICAL = 2.0         # [s]      [S]  a cut-out or lead deceleration is critical below this headway
REACTION_TIME = 0.75           # [s]      [S]  from the end of perception to the start of braking
REACTION_DECEL = 0.4           # [m/s^2]  [S]  during the reaction: the foot leaves the accelerator (interpretation)
BRAKE_DECEL = 0.774 * G        # [m/s^2]  [S]  full braking, 7.59
BRAKE_RAMP_TIME = 0.6          # [s]      [S]  braking rises linearly from 0 to BRAKE_DECEL (jerk 12.65 m/s^3)
AVOID_DECEL = 6.0              # [m/s^2]  [Q]  r157_cut_in_must_avoid: the deceleration of the cut-in rule
AVOID_MARGIN = 0.35            # [s]      [Q/S] r157_cut_in_must_avoid: the rule's time margin
GAP_JUMP = 3.0                 # [m]      [R]  a gap this far from the one the relative speeds predict over one
                               #               step is another vehicle: closer = cut-in, farther = cut-out
RELEASE_GAP = 2.5              # [m]      [R]  the event ends once the threat no longer closes in (v_rel >= 0)
RELEASE_HEADWAY = 1.0          # [s]      [R]  and gap >= RELEASE_GAP + RELEASE_HEADWAY * v, or the ego stopped
STOP_SPEED = 0.1               # [m/s]    [R]  "stopped"

PHASES = ("normal", "perceiving", "reacting", "braking")
EVENTS = ("none", "cut-in", "lead deceleration", "cut-out")
WIDTHS = (7, 11, 13, 23)  # observation widths: plain, V2V, -v1, -v1 with V2V
_V2V = (11, 23)
_FIELDS = ("speed", "acceleration", "gap", "relative speed", "in-range flag", "set speed", "time gap",
           "lead acceleration (V2V)", "gap2", "relative speed 2", "in-range flag 2")


def check_params(obj, who: str, positive=()) -> None:
    """Every dataclass field of ``obj`` a finite number >= 0, those named in ``positive`` > 0; else a
    ValueError naming ``who``, the field and the value."""
    for f in fields(obj):
        x = getattr(obj, f.name)
        number = isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool)
        if not number or not math.isfinite(x) or x < 0:
            raise ValueError(f"{who}: {f.name} must be a finite number >= 0, got {x!r}")
    for name in positive:
        if getattr(obj, name) <= 0:
            raise ValueError(f"{who}: {name} must be > 0, got {getattr(obj, name)!r}")


def check_rows(o: np.ndarray, who: str) -> None:
    """Observation rows ``(n, 7 | 11 | 13 | 23)`` of finite numbers, else a ValueError naming ``who``,
    the field and the row."""
    if o.ndim != 2 or o.shape[1] not in WIDTHS:
        got = f"{o.shape[1]} fields" if o.ndim == 2 else f"an array of shape {o.shape}"
        raise ValueError(f"{who}: an observation has {', '.join(map(str, WIDTHS))} fields, got {got}")
    bad = ~np.isfinite(o)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        what = _FIELDS[j] if j < (11 if o.shape[1] in _V2V else 7) else "safety-margin feature"
        kind = "NaN" if np.isnan(o[i, j]) else f"not finite ({o[i, j]})"
        raise ValueError(f"{who}: observation field {j} ({what}) is {kind} in row {i}")


def r157_cut_in_must_avoid(ttc_at_intrusion, v_rel):
    """R157's cut-in rule: a collision must be avoided when the time to collision at the
    lane intrusion [s] exceeds ``v_rel / (2 * 6 m/s^2) + 0.35 s``, ``v_rel`` the closing speed
    [m/s] (> 0 closing). Scalars give a bool, arrays a bool array; NaN is a ValueError."""
    ttc, w = np.asarray(ttc_at_intrusion, dtype=float), np.asarray(v_rel, dtype=float)
    for name, x in (("ttc_at_intrusion", ttc), ("v_rel", w)):
        if np.isnan(x).any():
            raise ValueError(f"r157_cut_in_must_avoid: {name} is NaN ({x!r})")
    out = ttc > w / (2.0 * AVOID_DECEL) + AVOID_MARGIN
    return bool(out) if out.ndim == 0 else out


@dataclass
class CCDriver(_Policy):
    """R157's careful and competent human driver, one row of state per observation row.

    ## Description

    Outside an event it drives carefully: the linear ACC law (:class:`LinearACC`, by
    composition) at the observation's time gap, the set speed with nothing ahead -- our
    decision [R]: R157 specifies only the event response. An event starts when one of three
    triggers is critical:

    * **cut-in** -- the vehicle ahead becomes a closer one: the gap is more than ``gap_jump``
      below the one predicted from the last step's gap and the relative speeds, or a vehicle
      appears in range where none was. Critical if its time to collision gap / closing speed
      is below ``ttc_critical``. The 0.4 s risk perception time starts at that step.
    * **lead deceleration** -- the vehicle ahead starts braking harder than
      ``lead_decel_threshold`` (its V2V acceleration, field 7, with 11 or 23 fields; else the
      change of its speed ``v + v_rel`` over one step, only while it is the same vehicle).
      Only the onset triggers (it must not have been braking that hard the step before).
      Critical if the time headway gap / v is below ``headway_critical``.
    * **cut-out** -- the vehicle ahead leaves and reveals a farther one: the gap is more than
      ``gap_jump`` above the prediction. Critical if the revealed vehicle is closing in and the
      headway is below ``headway_critical``; none revealed is no event.

    An event runs on a clock ``tau`` from its detection: the perception time (acceleration held
    at the last normal command: it has not seen the risk yet), the reaction time at
    ``-d_r = min(held, -reaction_decel)``, then braking ``max(d_r, min(brake_decel, J s))`` with
    ``J = brake_decel / brake_ramp_time``, ``s`` the time since braking began. Each step's
    command is the mean of that profile over the step, so the speed follows the continuous
    model exactly. From the braking phase on, the event ends (back to normal driving) once the
    ego has stopped, nothing is in range, or the vehicle ahead no longer closes in and the gap
    is at least ``release_gap + release_headway * v`` [R]. No trigger is looked for during an
    event; the onset of a lead deceleration lasting beyond it does not trigger again.

    ## Observation

    7, 11 (V2V), 13 or 23 (``-v1``) fields; only fields 0-6 and, with V2V, 7 are read. NaN or
    another width is a ValueError naming it.

    ## State (per row; ``reset()`` clears all)

    ``phase`` (index into :data:`PHASES`), ``phase_time`` [s], ``event`` (index into
    :data:`EVENTS`), the event's step count and perception time, the held command [m/s^2],
    and the previous step's gap [m], relative speed [m/s], lead speed [m/s], in-range flag and
    hard-braking flag (for the triggers). A batch of another size restarts them all.
    """

    risk_perception_time: float = RISK_PERCEPTION_TIME  # [s]
    cut_out_perception_time: float = CUT_OUT_PERCEPTION_TIME  # [s]
    decel_perception_time: float = DECEL_PERCEPTION_TIME  # [s]
    lead_decel_threshold: float = LEAD_DECEL_THRESHOLD  # [m/s^2]
    ttc_critical: float = TTC_CRITICAL  # [s]
    headway_critical: float = HEADWAY_CRITICAL  # [s]
    reaction_time: float = REACTION_TIME  # [s]
    reaction_decel: float = REACTION_DECEL  # [m/s^2]
    brake_decel: float = BRAKE_DECEL  # [m/s^2]
    brake_ramp_time: float = BRAKE_RAMP_TIME  # [s]
    gap_jump: float = GAP_JUMP  # [m]
    release_gap: float = RELEASE_GAP  # [m]
    release_headway: float = RELEASE_HEADWAY  # [s]
    dt: float = DT  # [s]
    vectorised: ClassVar[bool] = True

    def __post_init__(self) -> None:
        check_params(self, "cc-driver", ("brake_decel", "brake_ramp_time", "dt", "accel_max", "decel_max"))
        self.follow = LinearACC(accel_max=self.accel_max, decel_max=self.decel_max)
        self.reset()

    def reset(self) -> None:
        self._n = None
        self._init(0)

    def _init(self, n: int, rows=slice(None)) -> None:
        if self._n != n:
            self._n = n
            z, f = np.zeros(n), np.zeros(n, dtype=bool)
            self.phase, self.event, self.steps = (np.zeros(n, dtype=int) for _ in range(3))
            self.phase_time, self.t_perc, self.a_hold, self.a_last = z.copy(), z.copy(), z.copy(), z.copy()
            self.prev_gap, self.prev_vrel, self.prev_v_lead = z.copy(), z.copy(), z.copy()
            self.prev_seen, self.prev_hard, self.have_prev = f.copy(), f.copy(), f.copy()
            return
        for arr in (self.phase, self.event, self.steps, self.phase_time, self.t_perc, self.a_hold, self.a_last,
                    self.prev_gap, self.prev_vrel, self.prev_v_lead, self.prev_seen, self.prev_hard, self.have_prev):
            arr[rows] = 0

    def predict(self, obs, state=None, episode_start=None, deterministic: bool = True):
        if episode_start is not None and self._n:  # stable-baselines3's convention: restart those rows
            starts = np.asarray(episode_start, dtype=bool).reshape(-1)
            if starts.shape == (self._n,):
                self._init(self._n, starts)
        return super().predict(obs, state, episode_start, deterministic)

    def _accel(self, o: np.ndarray) -> np.ndarray:
        check_rows(o, "cc-driver")
        n, dt = o.shape[0], self.dt
        if self._n != n:
            self._init(n)
        v, gap, vrel, seen = o[:, 0], o[:, 2], o[:, 3], o[:, 4] > 0.5
        v_lead = v + vrel

        # perception: what changed since the previous step
        was = self.have_prev & self.prev_seen
        dev = gap - (self.prev_gap + 0.5 * (vrel + self.prev_vrel) * dt)
        same = was & seen & (np.abs(dev) <= self.gap_jump)
        cut_in = self.have_prev & seen & (~self.prev_seen | (dev < -self.gap_jump))
        cut_out = was & seen & (dev > self.gap_jump)
        if o.shape[1] in _V2V:
            a_lead = np.where(seen, o[:, 7], 0.0)
        else:
            a_lead = np.where(same, (v_lead - self.prev_v_lead) / dt, 0.0)
        hard = seen & (a_lead < -self.lead_decel_threshold)
        closing = -vrel  # [m/s] > 0 closing in
        ttc = np.where(closing > 0, gap / np.maximum(closing, 1e-9), np.inf)  # [s]
        headway = gap / np.maximum(v, 1e-3)  # [s]
        trigger = np.select([cut_in & (ttc < self.ttc_critical),
                             cut_out & (closing > 0) & (headway < self.headway_critical),
                             hard & ~self.prev_hard & (headway < self.headway_critical)], [1, 3, 2], 0)

        # the events: advance, end, start
        active = self.phase > 0
        self.steps = np.where(active, self.steps + 1, 0)
        tau = self.steps * dt
        t_brake = self.t_perc + self.reaction_time
        safe = (vrel >= 0) & (gap >= self.release_gap + self.release_headway * v)
        over = active & (tau >= t_brake - 1e-9) & ((v <= STOP_SPEED) | ~seen | safe)
        start = ~active & (trigger > 0)
        self.event = np.where(start, trigger, np.where(over, 0, self.event))
        perc = np.array([0.0, self.risk_perception_time, self.decel_perception_time, self.cut_out_perception_time])
        self.t_perc = np.where(start, perc[trigger], self.t_perc)
        self.a_hold = np.where(start, self.a_last, self.a_hold)
        in_event = (active & ~over) | start
        tau = np.where(start, 0.0, tau)

        a = np.where(in_event, self._profile(tau), self.follow._accel(o))
        a = np.clip(a, -self.decel_max, self.accel_max)

        # bookkeeping for the next step
        t_brake = self.t_perc + self.reaction_time
        phase = np.where(~in_event, 0, np.where(tau < self.t_perc - 1e-9, 1, np.where(tau < t_brake - 1e-9, 2, 3)))
        since = np.select([phase == 1, phase == 2, phase == 3], [tau, tau - self.t_perc, tau - t_brake],
                          np.where(self.have_prev, self.phase_time + dt, 0.0))
        self.phase_time = np.where((phase == self.phase) | in_event, since, 0.0)
        self.phase = phase
        self.a_last = a
        self.prev_gap, self.prev_vrel, self.prev_v_lead = gap.copy(), vrel.copy(), v_lead.copy()
        self.prev_seen, self.prev_hard, self.have_prev = seen.copy(), hard, np.ones(n, dtype=bool)
        return a

    def _profile(self, tau: np.ndarray) -> np.ndarray:
        """The mean acceleration [m/s^2] of each row's event profile over ``[tau, tau + dt]`` (exact)."""
        t_p, hold = self.t_perc, self.a_hold
        a_r = np.minimum(hold, -self.reaction_decel)  # [m/s^2] the reaction phase
        d_r, b = -a_r, self.brake_decel
        jerk = b / self.brake_ramp_time  # [m/s^3]
        s1, s2 = np.minimum(d_r, b) / jerk, b / jerk  # ramp passes d_r, reaches b

        def integral(t):  # of the profile from 0 to t [m/s]
            s = np.maximum(t - t_p - self.reaction_time, 0.0)
            brake = (d_r * np.minimum(s, s1) + 0.5 * jerk * (np.clip(s, s1, s2) ** 2 - s1 ** 2)
                     + np.maximum(d_r, b) * np.maximum(s - s2, 0.0))
            return hold * np.minimum(t, t_p) + a_r * np.clip(t - t_p, 0.0, self.reaction_time) - brake

        return (integral(tau + self.dt) - integral(tau)) / self.dt


def cc_driver(**params) -> CCDriver:
    """The ``cc-driver`` controller: :class:`CCDriver` with ``params`` (its fields, e.g.
    ``reaction_time``, ``brake_decel``, ``accel_max``); an unknown name is a ValueError naming it."""
    return build_with(CCDriver, "cc-driver", params)


def build_with(cls, name: str, params: dict):
    """``cls(**params)``, an unknown parameter a ValueError naming it and listing ``cls``'s fields."""
    allowed = sorted(f.name for f in fields(cls))
    bad = sorted(set(params) - set(allowed))
    if bad:
        raise ValueError(f"controller {name!r} has no parameter {', '.join(map(repr, bad))}: its parameters are "
                         f"{allowed}")
    return cls(**params)
