"""The native vector environment as a stable-baselines3 ``VecEnv``.

SB3 expects same-step autoreset: when an episode ends, ``step_wait`` returns the next
episode's first observation and puts the last one in ``infos[i]["terminal_observation"]``
(with ``"TimeLimit.truncated"`` for truncations). :class:`SB3VecEnv` gives
:class:`~acc_gym.envs.vector.ACCVectorEnv` that shape; the drivers of all environments
are still solved together.
"""

from __future__ import annotations

import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv

from acc_gym.envs.vector import ACCVectorEnv

_PER_STEP = ("q", "a_applied", "violation", "fallbacks")


class SB3VecEnv(VecEnv):
    """``SB3VecEnv(num_envs, **env_settings)`` or ``SB3VecEnv(vector_env=ACCVectorEnv(...))``."""

    def __init__(self, num_envs: int = 1, *, vector_env: ACCVectorEnv | None = None, seed: int | None = None,
                 **settings):
        self.venv = vector_env if vector_env is not None else ACCVectorEnv(num_envs, **settings)
        super().__init__(self.venv.num_envs, self.venv.single_observation_space, self.venv.single_action_space)
        self._seed = seed
        self._actions = None

    # ------------------------------------------------------------------ VecEnv API
    def reset(self):
        seed = self._seed if self._seed is not None else (self._seeds[0] if any(s is not None for s in self._seeds)
                                                          else None)
        obs, _ = self.venv.reset(seed=seed)
        self._seed = None
        self._reset_seeds()
        return obs

    def step_async(self, actions) -> None:
        self._actions = np.asarray(actions, dtype=np.float32).reshape(self.num_envs, 1)

    def step_wait(self):
        obs, reward, term, trunc, info = self.venv.step(self._actions)
        done = term | trunc
        infos = [{} for _ in range(self.num_envs)]
        for key in _PER_STEP:
            for i in range(self.num_envs):
                infos[i][key] = info[key][i]
        if np.any(done):
            rows, new_obs = self.venv.reset_ended()
            for i in rows:
                infos[i]["terminal_observation"] = obs[i]
                infos[i]["TimeLimit.truncated"] = bool(trunc[i] and not term[i])
                infos[i]["score"] = float(info["score"][i])
                infos[i]["qualified"] = bool(info["qualified"][i])
                infos[i]["episode"] = {"r": float(info["episode_return"][i]),
                                       "l": int(round(info["t"][i] / 0.2)), "t": 0.0}
            obs = new_obs
        return obs, reward.astype(np.float32), done, infos

    def close(self) -> None:
        self.venv.close()

    def seed(self, seed: int | None = None):
        self._seed = seed
        return [None if seed is None else seed + i for i in range(self.num_envs)]

    # attributes / methods of the sub-environments are not exposed one by one
    def get_attr(self, attr_name, indices=None):
        return [getattr(self.venv, attr_name)] * len(self._get_indices(indices))

    def set_attr(self, attr_name, value, indices=None) -> None:
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name, *args, indices=None, **kwargs):
        return [getattr(self.venv, method_name)(*args, **kwargs) for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class, indices=None):
        return [False] * len(self._get_indices(indices))

    def get_images(self):
        frames = self.venv.render()
        return list(frames) if frames is not None else [None] * self.num_envs
