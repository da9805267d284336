"""Gymnasium environments: ``gymnasium.make("acc_gym/CarFollowing-v0")`` and friends.

Ids (:data:`~acc_gym.envs.registration.ENV_IDS`): ``acc_gym/CarFollowing-v0``,
``acc_gym/SingleLane-v0``, ``acc_gym/NCAP-v0``, ``acc_gym/StopAndGo-v0``, and their ``-v1``
versions (the safety-margin features in the observation, :class:`MarginReward`) -- one
:class:`ACCEnv` class configured by an :class:`EnvConfig`; ``gymnasium.make_vec(id,
num_envs, vectorization_mode="vector_entry_point")`` gives the native
:class:`ACCVectorEnv`. ``acc_gym/Ring-v1`` (:data:`~acc_gym.envs.registration.RING_IDS`):
:class:`RingEnv`, one controlled vehicle damping the waves of a ring of human-like drivers.
The classes load lazily so that registering stays cheap.
"""

from acc_gym.envs.registration import ENV_IDS, RING_IDS, register_envs

register_envs()

_LAZY = {"ACCEnv": "acc_gym.envs.acc_env", "ACCVectorEnv": "acc_gym.envs.vector", "EnvConfig": "acc_gym.envs.config",
         "ScenarioSampler": "acc_gym.envs.config", "CounterScenarioSampler": "acc_gym.envs.config",
         "CriteriaReward": "acc_gym.envs.reward",
         "MarginReward": "acc_gym.envs.reward",
         "StepIndicators": "acc_gym.envs.reward",
         "RingEnv": "acc_gym.envs.ring_env"}


def __getattr__(name):
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'acc_gym.envs' has no attribute {name!r}")


__all__ = ["ENV_IDS", "RING_IDS", "register_envs", *_LAZY]
