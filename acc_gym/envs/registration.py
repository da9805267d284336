"""Environment ids under the ``acc_gym/`` namespace (light: imports nothing heavy).

Gymnasium calls :func:`register_envs` through the ``gymnasium.envs`` entry point when it
is imported; ``import acc_gym.envs`` does the same. Every id is the same
:class:`~acc_gym.envs.acc_env.ACCEnv` drawing from one scenario family, with the native
:class:`~acc_gym.envs.vector.ACCVectorEnv` as its ``vector_entry_point``.
"""

from __future__ import annotations

ENV_IDS = {
    "acc_gym/CarFollowing-v0": ("carfollowing",),  # paper 003's test at 60, 90, 120 km/h
    "acc_gym/SingleLane-v0": ("singlelane",),  # paper 004's 22 configurations by occurrence rate
    "acc_gym/NCAP-v0": ("ncap",),  # CCRs, CCRm, CCRb
    "acc_gym/StopAndGo-v0": ("stopandgo",),
}


def register_envs() -> None:
    from gymnasium.envs.registration import register, registry

    for env_id, family in ENV_IDS.items():
        if env_id in registry:
            continue
        register(id=env_id, entry_point="acc_gym.envs.acc_env:ACCEnv",
                 vector_entry_point="acc_gym.envs.vector:ACCVectorEnv", kwargs={"default_scenarios": family})
