"""The linear ACC law (paper 004, Eq. 1) and a constant-speed floor, on the env's observation.

Observation indices (see :class:`acc_gym.envs.acc_env.ACCEnv`): 0 speed, 1 acceleration,
2 gap, 3 relative speed, 4 vehicle in range, 5 set speed, 6 time gap.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np


@dataclass
class _Policy:
    accel_max: float = 3.0  # [m/s^2] the env's action scaling (EnvConfig.accel_max)
    decel_max: float = 8.0  # [m/s^2] (EnvConfig.decel_max)
    # predict() answers an (n, obs) array row by row: acc_gym.risk batches episodes through it
    vectorised: ClassVar[bool] = True

    def reset(self) -> None:
        pass

    def _to_action(self, a: np.ndarray) -> np.ndarray:
        a = np.clip(a, -self.decel_max, self.accel_max)
        return np.where(a >= 0, a / self.accel_max, a / self.decel_max).astype(np.float32)

    def predict(self, obs, state=None, episode_start=None, deterministic: bool = True):
        o = np.asarray(obs, dtype=float)
        single = o.ndim == 1
        a = self._accel(np.atleast_2d(o))
        act = self._to_action(a)[:, None]
        return (act[0] if single else act), None

    def _accel(self, o: np.ndarray) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError


@dataclass
class LinearACC(_Policy):
    """``a = k2 e_v + k1 e_x`` with ``e_x = gap - s0 - h v`` (h: the observed time gap), limited by a
    cruise law ``k_cruise (v_set - v)`` (paper 004 Eq. 1; tuning from tests/evaluation/test_paper003.py)."""

    k1: float = 0.3  # [1/s^2]
    k2: float = 1.2  # [1/s]
    s0: float = 2.5  # [m]
    k_cruise: float = 0.4  # [1/s]
    a_comfort: float = 2.0  # [m/s^2] cruise-law bound
    brake_limit: float | None = None  # [m/s^2] the most it brakes (None: the env's decel_max)

    def _accel(self, o: np.ndarray) -> np.ndarray:
        v, gap, v_rel, seen, v_set, h = o[:, 0], o[:, 2], o[:, 3], o[:, 4] > 0.5, o[:, 5], o[:, 6]
        cruise = np.clip(self.k_cruise * (v_set - v), -self.a_comfort, self.a_comfort)
        follow = self.k2 * v_rel + self.k1 * (gap - self.s0 - h * v)
        a = np.where(seen, np.minimum(follow, cruise), cruise)
        return a if self.brake_limit is None else np.maximum(a, -float(self.brake_limit))


def iso_acc(brake_limit: float = 3.5) -> LinearACC:
    """The linear ACC with an ACC system's braking authority: ISO 15622 lets an ACC brake at
    most 3.5 m/s^2 (5 m/s^2 at low speed in later editions) and leaves the rest to the
    driver. Not registered by name: ``acc_gym_agents.controllers.linear:iso_acc``
    (``benchmarks/bench_risk.py`` uses it and weaker ones)."""
    return LinearACC(brake_limit=brake_limit)


@dataclass
class ConstantSpeed(_Policy):
    """Holds the set speed and ignores everything ahead: the floor every controller should beat."""

    k: float = 0.5  # [1/s]

    def _accel(self, o: np.ndarray) -> np.ndarray:
        return np.clip(self.k * (o[:, 5] - o[:, 0]), -2.0, 2.0)
