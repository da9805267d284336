"""Per-step reward from the same criteria as the 100-point score (paper 003).

:class:`StepIndicators` holds, for ``n`` scenes, what the score looks at in one step --
the car-following band, efficiency ``u_t``, speed keeping, comfort, jerk, the
proper-response safety check and a collision -- computed with the same definitions as
:mod:`acc_gym.evaluation.scoring` (car-following samples, free samples, transients).
:class:`CriteriaReward` (the default) weighs them:

==============  ===========================================================  ==========
term            per step                                                     default w
==============  ===========================================================  ==========
band            ``+w`` on a car-following sample inside ``0 < G < 0.2 Gapsafe``   1.0
efficiency      ``+w (1 - u_t)`` on a car-following sample                     0.5
speed           ``+w (1 - min(|v - v_set| / (0.2 v_set), 1))`` with nothing       1.0
                to follow in view
comfort         ``-w (a / 3 m/s^2)^2``                                         0.1
jerk            ``-w (jerk / 10 m/s^3)^2``                                      0.02
safety          ``-w`` on a proper-response violation                           2.0
collision       ``-w`` once, when the ego hits the vehicle ahead (terminates)   100
lag             ``-w min((gap - D) / D, 1)`` while a followable vehicle is       0.5
                ahead beyond ``D = 1.2 tau1 v_lead + 5 m`` (any distance)
==============  ===========================================================  ==========

Why an agent cannot do better by parking or oscillating than by following well: the
positive terms are paid only for *following* (inside the band, steady, both moving) or,
when there is nothing to follow, for holding the set speed. A parked or crawling ego
earns neither (a followable vehicle ahead at any distance makes the step a following
step, so hanging back out of sensor range earns nothing either) and pays the lag term, so
standing still behind a moving vehicle costs up to 0.5 a step rather than nothing (a PPO
agent trained without it learned to stay parked); following well earns the most a step
can give (1.5, against 1.0 for free driving). Oscillating costs comfort
and jerk and leaves the band. Tailgating pays the safety penalty once Q < 0 outlasts the
reaction time without braking. Any object with ``__call__(StepIndicators) -> (reward,
terms)`` can replace it (``reward_fn=``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np


@dataclass
class StepIndicators:
    """One step's criteria for ``n`` scenes (arrays ``(n,)``)."""

    v: np.ndarray  # [m/s] ego speed
    a: np.ndarray  # [m/s^2] ego acceleration applied over the step
    jerk: np.ndarray  # [m/s^3]
    set_speed: np.ndarray  # [m/s]
    has_lead: np.ndarray  # a vehicle ahead (any distance)
    gap: np.ndarray  # [m] D1 (inf: none)
    gap_safe: np.ndarray  # [m]
    q: np.ndarray  # [m] D1 - Gapsafe (inf: none)
    in_band: np.ndarray
    following: np.ndarray  # a car-following sample (scoring's definition)
    free: np.ndarray  # nothing to follow in view
    u: np.ndarray  # efficiency u_t clipped to [0, 1] (NaN where Gapsafe <= 0)
    violation: np.ndarray  # proper-response violation this step
    collision: np.ndarray  # the ego's gap reached 0 this step
    a_comfort: float = 3.0  # [m/s^2]
    followable: np.ndarray | None = None  # a vehicle ahead the ego could follow (moving, not faster than v_set)
    v_lead: np.ndarray | None = None  # [m/s]
    tau1: np.ndarray | None = None  # [s]


@dataclass(frozen=True)
class CriteriaReward:
    """The default reward (weights as in the module table)."""

    band: float = 1.0
    efficiency: float = 0.5
    speed: float = 1.0
    comfort: float = 0.1
    jerk: float = 0.02
    safety: float = 2.0
    collision: float = 100.0
    lag: float = 0.5
    jerk_scale: float = 10.0  # [m/s^3]

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
                raise ValueError(f"CriteriaReward.{f.name} must be a number >= 0, got {value!r}")
        if self.jerk_scale <= 0:
            raise ValueError(f"CriteriaReward.jerk_scale must be > 0, got {self.jerk_scale!r}")
        object.__setattr__(self, "_w", np.array([self.band, self.efficiency, self.speed, self.comfort, self.jerk,
                                                 self.safety, self.collision, self.lag, self.jerk_scale], dtype=float))

    def __call__(self, s: StepIndicators) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """``(reward, terms)`` for one step of ``n`` scenes, in one compiled pass
        (:func:`acc_gym.envs._kernel.criteria_reward`; the numpy formulation is :meth:`reference`)."""
        if s.followable is None or s.v_lead is None or s.tau1 is None:
            return self.reference(s)
        from acc_gym.envs import _kernel as K

        n = np.shape(s.v)[0]

        def f(x):
            x = np.asarray(x, dtype=float)
            return x if x.shape == (n,) else np.broadcast_to(x, (n,))

        def b(x):
            x = np.asarray(x, dtype=bool)
            return x if x.shape == (n,) else np.broadcast_to(x, (n,))

        terms = np.empty((len(K.TERMS), n))
        reward = np.empty(n)
        K.criteria_reward(f(s.v), f(s.a), f(s.jerk), f(s.gap), f(s.u), f(s.v_lead), f(s.set_speed), f(s.tau1),
                          b(s.following), b(s.in_band), b(s.free), b(s.violation), b(s.collision), b(s.followable),
                          float(s.a_comfort), self._w, terms, reward)
        return reward, dict(zip(K.TERMS, terms))

    def from_criteria(self, fl: np.ndarray, bo: np.ndarray, set_speed: np.ndarray, tau1: np.ndarray,
                      a_comfort: float) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """What :meth:`__call__` returns for the :class:`StepIndicators` the environment core
        would build from the rows of :func:`acc_gym.envs._kernel.criteria`'s outputs ``fl``
        and ``bo`` (float arrays ``(n,)`` ``set_speed`` and ``tau1``), without building
        them: the core's fast path for the default reward (one step of the single env is
        a few tens of microseconds, and the indicators and their checks cost ten)."""
        from acc_gym.envs import _kernel as K

        n = fl.shape[1]
        terms = np.empty((len(K.TERMS), n))
        reward = np.empty(n)
        K.criteria_reward_rows(fl, bo, set_speed, tau1, float(a_comfort), self._w, terms, reward)
        return reward, dict(zip(K.TERMS, terms))

    def reference(self, s: StepIndicators) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """The same reward written with numpy (the definition the compiled one is tested against)."""
        speed_err = np.minimum(np.abs(s.v - s.set_speed) / (0.2 * s.set_speed), 1.0)
        terms = {
            "band": self.band * (s.following & s.in_band),
            "efficiency": self.efficiency * np.where(s.following, 1.0 - np.nan_to_num(s.u, nan=1.0), 0.0),
            "speed": self.speed * np.where(s.free, 1.0 - speed_err, 0.0),
            "comfort": -self.comfort * (s.a / s.a_comfort) ** 2,
            "jerk": -self.jerk * (s.jerk / self.jerk_scale) ** 2,
            "safety": -self.safety * s.violation,
            "collision": -self.collision * s.collision,
        }
        if s.followable is not None:
            far = 1.2 * s.tau1 * s.v_lead + 5.0  # [m] the band's upper edge at the lead's speed, plus 5 m
            terms["lag"] = -self.lag * np.where(s.followable, np.clip((s.gap - far) / far, 0.0, 1.0), 0.0)
        terms = {k: np.asarray(v, dtype=float) for k, v in terms.items()}
        return sum(terms.values()), terms
