"""Wrappers for using acc_gym's environments with other tools.

:class:`ScoreOnTruncation` puts the episode's evaluation (``score``, ``qualified``,
``report``, ``episode_return``, ``scenario_seed``) into the ``info`` of the step where an
*inner* wrapper -- typically ``gymnasium.wrappers.TimeLimit`` or
``gymnasium.make(id, max_episode_steps=N)`` -- ends the episode before the scenario does::

    env = ScoreOnTruncation(gymnasium.wrappers.TimeLimit(gymnasium.make("acc_gym/CarFollowing-v0"), 50))
    env = ScoreOnTruncation(gymnasium.make("acc_gym/CarFollowing-v0", max_episode_steps=50))

Stable-baselines3's ``DummyVecEnv`` and ``SubprocVecEnv`` do not need it: they mark such a
step's info (``info["TimeLimit.truncated"]``) and reset the env in the same step, and that
reset completes the info (see :class:`~acc_gym.envs.acc_env.ACCEnv`, *Episode End*). Your
own loop and gymnasium's vector envs do.
"""

from __future__ import annotations

import gymnasium as gym


class ScoreOnTruncation(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Score the episode in the info of the step that ends it, whichever wrapper ends it.

    Apply it outside the time limit (it must see the truncation). The score is that of what
    was driven (:meth:`ACCEnv.episode_report <acc_gym.envs.acc_env.ACCEnv.episode_report>`),
    the same as the env's own last step gives when the scenario ends there. An info that
    already has a ``score`` (the env ended the episode itself) is left as it is."""

    def __init__(self, env: gym.Env):
        gym.utils.RecordConstructorArgs.__init__(self)
        gym.Wrapper.__init__(self, env)
        if not callable(getattr(env.unwrapped, "episode_info", None)):
            raise TypeError(f"ScoreOnTruncation needs an acc_gym environment (ACCEnv, with episode_info()), "
                            f"got {type(env.unwrapped).__name__}")

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        if (terminated or truncated) and "score" not in info:
            info.update(self.env.unwrapped.episode_info())
        return obs, reward, terminated, truncated, info


class MarginObservation(gym.ObservationWrapper, gym.utils.RecordConstructorArgs):
    """Append the safety-margin features (:mod:`acc_gym.envs.observation`: Gapsafe, Q,
    Q / Gapsafe, time headway, inverse TTC, required deceleration; with ``v2v`` also for
    the second vehicle ahead) to an acc_gym environment's ``-v0`` observation, computed
    from that observation's own fields with the env's sensor range::

        env = MarginObservation(gymnasium.make("acc_gym/CarFollowing-v0"))
        env.observation_space.shape      # (13,): the 7 fields, then the 6 features

    The observation space's bounds are the v0 fields' followed by the features'."""

    def __init__(self, env: gym.Env):
        gym.utils.RecordConstructorArgs.__init__(self)
        gym.ObservationWrapper.__init__(self, env)
        import numpy as np
        from gymnasium import spaces

        from acc_gym.envs.observation import feature_bounds

        config = getattr(env.unwrapped, "config", None)
        space = env.observation_space
        if config is None or not isinstance(space, spaces.Box) or space.shape not in ((7,), (11,)):
            raise TypeError(f"MarginObservation needs an acc_gym -v0 environment (7 or 11 observation fields), got "
                            f"{type(env.unwrapped).__name__} with observation space {space}")
        self._range = float(config.sensor_range)
        low, high = feature_bounds(space.shape[0] == 11)
        self.observation_space = spaces.Box(np.concatenate([space.low, low.astype(np.float32)]),
                                            np.concatenate([space.high, high.astype(np.float32)]), dtype=np.float32)

    def observation(self, observation):
        from acc_gym.envs.observation import margin_features

        return margin_features(observation, self._range).astype(self.observation_space.dtype)
