"""Residual RL: a learnt correction on top of a hand-written controller.

The executed action is ``clip(a_base(obs) + scale * clip(a_rl, -1, 1), -1, 1)``, with
``a_base`` a stateless hand-written law (:data:`BASES`, e.g. the linear ACC) evaluated on
the *raw* observation and ``a_rl`` the policy's action. A policy that outputs 0 is the
base controller, so training starts from a qualified controller and only has to improve
it (with a small initial action noise, e.g. PPO's ``log_std_init=-2``). With
``shield=True`` the result is then capped at a 2.5 m/s^2 brake whenever the observed
``Q = gap - Gapsafe`` is negative (:func:`proper_response_shield`): the proper response
that the score's safety item asks for, which a reward-driven policy otherwise trades
for efficiency (it learns to follow closer and fails the item when the lead brakes).
``max_overspeed`` caps the desired acceleration at ``v_set + max_overspeed - v`` per
second (:func:`speed_cap`): without it a policy learns to drive above the set speed to
close gaps to slightly faster leads (the score does not charge it).

:class:`ResidualVecEnv` applies it during training; it sits directly on
:class:`agents.rl.vec_env.SB3VecEnv`, *below* ``VecNormalize``, so it sees raw
observations. :class:`agents.rl.policy.SB3Policy` applies the same function at inference
(the run's manifest records ``residual``, ``residual_kwargs``, ``residual_scale``,
``shield`` and ``max_overspeed``), so a saved residual run is an ordinary controller for
``acc-gym evaluate``.

:class:`ScoreBonusVecEnv` (optional) adds ``bonus * score / 100`` to the reward of an
episode's last step: the 100-point score itself, which the per-step reward only
approximates (a qualified episode needs steady following in the band, no unanswered
Q < 0, ...).
"""

from __future__ import annotations

import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnvWrapper


def _bases() -> dict:
    from agents.controllers.linear import ConstantSpeed, LinearACC

    # stateless laws only: the wrapper evaluates them on a batch of observations at every step
    return {"acc": LinearACC, "constant": ConstantSpeed}


BASES = ("acc", "constant")


def make_base(name: str, kwargs: dict | None = None):
    """The base controller called ``name`` (one of :data:`BASES`), with its settings ``kwargs``
    (e.g. ``{"k1": 0.8, "s0": 0.5}`` for the linear ACC)."""
    bases = _bases()
    if name not in bases:
        raise ValueError(f"unknown residual base {name!r}; use one of {list(bases)}")
    try:
        return bases[name](**(kwargs or {}))
    except TypeError as exc:
        raise ValueError(f"residual base {name!r}: bad settings {kwargs!r} ({exc})") from None


def check_scale(scale) -> float:
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not np.isfinite(scale) or scale <= 0:
        raise ValueError(f"residual_scale must be a number > 0, got {scale!r}")
    return float(scale)


def residual_action(base_action, rl_action, scale: float) -> np.ndarray:
    """``clip(base + scale * clip(rl, -1, 1), -1, 1)`` as float32."""
    rl = np.clip(np.asarray(rl_action, dtype=np.float64), -1.0, 1.0)
    out = np.asarray(base_action, dtype=np.float64) + float(scale) * rl
    return np.clip(out, -1.0, 1.0).astype(np.float32)


SHIELD_DECEL = 2.5  # [m/s^2] the shield's braking: above the score's proper response (2 m/s^2)
SHIELD_B = 8.0  # [m/s^2] b0 = b1 of Gapsafe (the scoring default)


def proper_response_shield(obs, action, decel_max: float = 8.0, decel: float = SHIELD_DECEL) -> np.ndarray:
    """Brake at least ``decel`` while the observed Q = gap - Gapsafe is negative (a vehicle ahead in range,
    moving ego): the proper response of the score's safety item, so the learnt part cannot make it fail."""
    o = np.atleast_2d(np.asarray(obs, dtype=np.float64))
    a = np.asarray(action, dtype=np.float32)
    v, gap, dv, seen, h = o[:, 0], o[:, 2], o[:, 3], o[:, 4] > 0.5, o[:, 6]
    v_lead = v + dv
    gap_safe = v * h + (v ** 2 - v_lead ** 2) / (2.0 * SHIELD_B)
    on = seen & (gap < gap_safe) & (v > 0.5)
    cap = np.float32(-decel / decel_max)
    return np.where(on.reshape((-1,) + (1,) * (a.ndim - 1)), np.minimum(a, cap), a).astype(np.float32)


SPEED_GAIN = 1.0  # [1/s] of the set-speed cap


def speed_cap(obs, action, max_overspeed: float, accel_max: float = 3.0, decel_max: float = 8.0) -> np.ndarray:
    """Cap the desired acceleration at ``SPEED_GAIN (v_set + max_overspeed - v)``: the ego does not
    drive (much) faster than its set speed plus ``max_overspeed``, whatever the learnt part wants."""
    o = np.atleast_2d(np.asarray(obs, dtype=np.float64))
    a = np.asarray(action, dtype=np.float32)
    a_cap = SPEED_GAIN * (o[:, 5] + float(max_overspeed) - o[:, 0])  # [m/s^2]
    cap = np.where(a_cap >= 0, a_cap / accel_max, a_cap / decel_max).reshape((-1,) + (1,) * (a.ndim - 1))
    return np.minimum(a, np.clip(cap, -1.0, 1.0)).astype(np.float32)


def check_overspeed(max_overspeed):
    if max_overspeed is None:
        return None
    if isinstance(max_overspeed, bool) or not isinstance(max_overspeed, (int, float)) or not (
            np.isfinite(max_overspeed) and max_overspeed >= 0):
        raise ValueError(f"max_overspeed must be a number >= 0 or None, got {max_overspeed!r}")
    return float(max_overspeed)


def controller_action(obs, rl_action, base, scale: float, shield: bool = False,
                      max_overspeed: float | None = None) -> np.ndarray:
    """The executed action of a residual policy on raw ``obs`` (a batch or one observation): the base plus
    the scaled residual, then the set-speed cap (``max_overspeed`` not None), then the shield (``shield``)."""
    base_action, _ = base.predict(obs)
    action = residual_action(base_action, np.asarray(rl_action).reshape(np.shape(base_action)), scale)
    if max_overspeed is not None:
        action = speed_cap(obs, action, max_overspeed)
    return proper_response_shield(obs, action) if shield else action


class ResidualVecEnv(VecEnvWrapper):
    """Execute ``controller_action(raw_obs, action, base, scale, shield)`` on the wrapped (raw) vector env."""

    def __init__(self, venv, base: str = "acc", scale: float = 0.3, shield: bool = False,
                 base_kwargs: dict | None = None, max_overspeed: float | None = None):
        super().__init__(venv)
        self.base_name = base
        self.base = make_base(base, base_kwargs)
        self.scale = check_scale(scale)
        self.shield = bool(shield)
        self.max_overspeed = check_overspeed(max_overspeed)
        self._obs: np.ndarray | None = None

    def reset(self):
        self._obs = np.asarray(self.venv.reset())
        return self._obs

    def base_actions(self, obs=None) -> np.ndarray:
        o = self._obs if obs is None else np.asarray(obs)
        return np.asarray(self.base.predict(o)[0], dtype=np.float32).reshape(self.num_envs, -1)

    def step_async(self, actions) -> None:
        if self._obs is None:
            raise RuntimeError("ResidualVecEnv: reset() before step()")
        rl = np.asarray(actions, dtype=np.float32).reshape(self.num_envs, -1)
        self.venv.step_async(controller_action(self._obs, rl, self.base, self.scale, self.shield, self.max_overspeed))

    def step_wait(self):
        obs, reward, done, infos = self.venv.step_wait()
        self._obs = np.asarray(obs)  # after a done: the next episode's first observation (same-step autoreset)
        return obs, reward, done, infos


class ScoreBonusVecEnv(VecEnvWrapper):
    """Add ``bonus * info["score"] / 100`` to the reward of every episode's last step."""

    def __init__(self, venv, bonus: float):
        super().__init__(venv)
        if isinstance(bonus, bool) or not isinstance(bonus, (int, float)) or not np.isfinite(bonus) or bonus < 0:
            raise ValueError(f"score_bonus must be a number >= 0, got {bonus!r}")
        self.bonus = float(bonus)

    def reset(self):
        return self.venv.reset()

    def step_wait(self):
        obs, reward, done, infos = self.venv.step_wait()
        reward = np.array(reward, dtype=np.float32)
        for i in np.flatnonzero(done):
            if "score" in infos[i]:
                reward[i] += self.bonus * infos[i]["score"] / 100.0
        return obs, reward, done, infos
