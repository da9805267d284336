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
``shield="base"`` also keeps it braking at least as hard as the base controller while
Q < 0, so that it avoids every collision the base avoids, also in scenarios it never
trained on (with the plain shield, a policy trained on car-following and single-lane
traffic ran into stationary NCAP targets that the linear ACC stops for).
``max_overspeed`` caps the desired acceleration at ``v_set + max_overspeed - v`` per
second (:func:`speed_cap`): under acc_gym 0.1.0's score, which counted leads up to 1 m/s
above the set speed as followable, policies learnt to drive above the set speed to close
gaps to them; the cap keeps that out whatever the score rewards.

:class:`ResidualVecEnv` applies it during training; it sits directly on
:class:`acc_gym_agents.rl.vec_env.SB3VecEnv`, *below* ``VecNormalize``, so it sees raw
observations. :class:`acc_gym_agents.rl.policy.SB3Policy` applies the same function at inference
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

from acc_gym_agents.rl.residual_law import (  # noqa: F401  (re-exported: the law is part of this module's interface)
    BASES,
    SHIELD_B,
    SHIELD_DECEL,
    SHIELDS,
    SPEED_GAIN,
    check_overspeed,
    check_scale,
    check_shield,
    controller_action,
    make_base,
    proper_response_shield,
    residual_action,
    speed_cap,
)


class ResidualVecEnv(VecEnvWrapper):
    """Execute ``controller_action(raw_obs, action, base, scale, shield)`` on the wrapped (raw) vector env."""

    def __init__(self, venv, base: str = "acc", scale: float = 0.3, shield: str | bool | None = None,
                 base_kwargs: dict | None = None, max_overspeed: float | None = None):
        super().__init__(venv)
        self.base_name = base
        self.base = make_base(base, base_kwargs)
        self.scale = check_scale(scale)
        self.shield = check_shield(shield)
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
