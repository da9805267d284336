"""Environment ids under the ``acc_gym/`` namespace (light: imports nothing heavy).

``import acc_gym`` registers the ids (:func:`register_envs`). Gymnasium 1.x does **not**
load plugins through the ``gymnasium.envs`` entry point (0.26-0.29 did; the entry point
stays for them), so a process that never imported acc_gym does not know the ids: a worker
of SB3's ``SubprocVecEnv`` started with ``spawn`` or ``forkserver`` (the default on macOS
and Windows, and forkserver on Linux from Python 3.14) raises ``NamespaceNotFound:
Namespace acc_gym not found`` even though the parent imported acc_gym. Two ways that
always work:

* the module-qualified id ``"acc_gym:acc_gym/CarFollowing-v0"`` -- ``gymnasium.make``
  imports the module before the id (:func:`qualified_id` makes it);
* :func:`make_vec_env` -- stable-baselines3's ``make_vec_env`` with the id qualified.

Everything of acc_gym that takes an id (``acc-gym evaluate --env``, ``acc-gym train
--env``, :func:`~acc_gym.evaluation.runner.evaluate`, :func:`make_vec_env`) takes either
form (:func:`resolve_env_id`), and names an unknown id with the registered ones.

Every id of :data:`ENV_IDS` is the same :class:`~acc_gym.envs.acc_env.ACCEnv` drawing from
one scenario family, with the native :class:`~acc_gym.envs.vector.ACCVectorEnv` as its
``vector_entry_point``; :data:`RING_IDS` are the ring road's (``acc_gym/Ring-v1``,
:class:`~acc_gym.envs.ring_env.RingEnv`; Gymnasium's own vector envs).
"""

from __future__ import annotations

import importlib

# The -v1 car-following id trains on varied traffic: paper 003's test drawn wider
# (40-130 km/h, gentle to emergency stops), the test itself, stop-and-go queues and paper
# 004's car-following configuration, behind naturalistic human-like drivers; paper 003's
# test stays what is scored (the carfollowing-v1 suite, CarFollowing-v0).
CARFOLLOWING_V1 = {"carfollowing/varied": 0.5, "carfollowing": 0.2, "stopandgo": 0.15,
                   "singlelane/2/car-following": 0.15}

# id -> (default scenarios, settings)
ENV_IDS = {
    "acc_gym/CarFollowing-v0": (("carfollowing",), {}),  # paper 003's test at 60, 90, 120 km/h
    "acc_gym/SingleLane-v0": (("singlelane",), {}),  # paper 004's 22 configurations by occurrence rate
    "acc_gym/NCAP-v0": (("ncap",), {}),  # CCRs, CCRm, CCRb
    "acc_gym/StopAndGo-v0": (("stopandgo",), {}),
    # version 1: the safety-margin features in the observation, MarginReward
    "acc_gym/CarFollowing-v1": (CARFOLLOWING_V1, {"version": 1, "drivers": "naturalistic"}),
    "acc_gym/SingleLane-v1": (("singlelane",), {"version": 1}),
    "acc_gym/NCAP-v1": (("ncap",), {"version": 1}),
    "acc_gym/StopAndGo-v1": (("stopandgo",), {"version": 1}),
}

# ids of other environment classes: id -> (entry point, settings)
RING_IDS = {
    # one controlled vehicle among 21 human-like drivers (model 6) on a ring of 220-270 m
    "acc_gym/Ring-v1": ("acc_gym.envs.ring_env:RingEnv", {}),
}


class V0IdWarning(DeprecationWarning):
    """Making a ``-v0`` id: what its ``-v1`` changes (once per id and process)."""


def v0_warning_text(env_id: str) -> str:
    """The one sentence a ``-v0`` id warns with: what its ``-v1`` changes. It keeps gymnasium's
    words "is out of date; you should consider upgrading", which the commands that pin ``-v0``
    ids on purpose (the suites) filter."""
    v1 = env_id[:-1] + "1"
    changes = ["adds six safety-margin features to the observation", "rewards with MarginReward"]
    if env_id == "acc_gym/CarFollowing-v0":
        changes.append("draws varied car-following traffic, paper 003's test among it, behind naturalistic drivers")
    said = ", ".join(changes[:-1]) + " and " + changes[-1]
    return (f"{env_id} is out of date; you should consider upgrading to {v1}, which {said} ({env_id} stays "
            f"registered, unchanged).")


_WARNED: set[str] = set()  # the -v0 ids this process has warned about


def _v0_id(kwargs: dict) -> str | None:
    family = tuple(kwargs.get("default_scenarios", ()))
    return next((i for i, (f, s) in ENV_IDS.items() if i.endswith("-v0") and tuple(f) == family), None)


def _warn_v0(kwargs: dict) -> None:
    env_id = _v0_id(kwargs)
    if env_id is not None and env_id not in _WARNED:
        import warnings

        _WARNED.add(env_id)
        # stacklevel: this, make_v0, gymnasium's make, the caller of gymnasium.make
        warnings.warn(v0_warning_text(env_id), V0IdWarning, stacklevel=4)


def make_v0(**kwargs):
    """The ``-v0`` ids' entry point: :class:`~acc_gym.envs.acc_env.ACCEnv`, after the warning."""
    from acc_gym.envs.acc_env import ACCEnv

    _warn_v0(kwargs)
    return ACCEnv(**kwargs)


def make_v0_vector(num_envs: int = 1, **kwargs):
    """The ``-v0`` ids' vector entry point: :class:`~acc_gym.envs.vector.ACCVectorEnv`, after the warning."""
    from acc_gym.envs.vector import ACCVectorEnv

    _warn_v0(kwargs)
    return ACCVectorEnv(num_envs=num_envs, **kwargs)


def register_envs() -> None:
    import warnings

    from gymnasium.envs.registration import register, registry

    # gymnasium's own notice for a -v0 id says only "out of date": ours says what -v1 changes,
    # once per id and process; shown wherever the call is, as gymnasium shows its own deprecations
    warnings.filterwarnings("ignore", message=r"(?s).*The environment acc_gym/\w+-v0 is out of date",
                            category=DeprecationWarning)
    warnings.filterwarnings("always", category=V0IdWarning)
    for env_id, (family, settings) in ENV_IDS.items():
        if env_id in registry:
            continue
        v0 = env_id.endswith("-v0")
        register(id=env_id, entry_point="acc_gym.envs.registration:make_v0" if v0 else "acc_gym.envs.acc_env:ACCEnv",
                 vector_entry_point=("acc_gym.envs.registration:make_v0_vector" if v0
                                     else "acc_gym.envs.vector:ACCVectorEnv"),
                 kwargs={"default_scenarios": family, **settings})
    for env_id, (entry_point, settings) in RING_IDS.items():
        if env_id not in registry:
            register(id=env_id, entry_point=entry_point, kwargs=dict(settings))


def qualified_id(env_id: str) -> str:
    """``"acc_gym:<id>"`` for one of this package's ids (any process can make it: gymnasium
    imports ``acc_gym`` first); other ids, and ids already qualified, as given."""
    if not isinstance(env_id, str):
        raise TypeError(f"an environment id must be a string, got {type(env_id).__name__}")
    return f"acc_gym:{env_id}" if env_id in ENV_IDS or env_id in RING_IDS else env_id


def resolve_env_id(env_id: str) -> str:
    """The registered id that ``env_id`` names, given plain (``"acc_gym/CarFollowing-v0"``)
    or module-qualified (``"acc_gym:acc_gym/CarFollowing-v0"``: the module is imported
    first, as ``gymnasium.make`` does -- ``gymnasium.spec`` takes only the plain form).

    ``ValueError`` naming ``env_id`` when its module cannot be imported or no environment
    is registered under it; the message lists acc_gym's ids and the qualified form that
    subprocess workers need."""
    if not isinstance(env_id, str):
        raise TypeError(f"an environment id must be a string, got {type(env_id).__name__}")
    import gymnasium as gym
    from gymnasium import error

    module, name = env_id.split(":", 1) if ":" in env_id else (None, env_id)
    if module is not None:
        try:
            importlib.import_module(module)
        except ImportError as exc:
            raise ValueError(f"environment id {env_id!r}: cannot import its module {module!r} ({exc})") from None
    try:
        return gym.spec(name).id
    except error.Error as exc:
        raise ValueError(f"unknown environment id {env_id!r} ({exc}); acc_gym's ids: {', '.join(ENV_IDS)} -- "
                         f"in subprocess workers (SB3's SubprocVecEnv with spawn or forkserver) give them as "
                         f"'acc_gym:<id>', e.g. {qualified_id(next(iter(ENV_IDS)))!r}") from None


def make_vec_env(env_id: str, n_envs: int = 1, **kwargs):
    """stable-baselines3's ``make_vec_env`` for an acc_gym id, in any vector env class and
    start method (``vec_env_cls=SubprocVecEnv, vec_env_kwargs={"start_method": "spawn"}``):
    the id is qualified (:func:`qualified_id`) so that every worker imports acc_gym.
    ``env_id`` may be given plain or qualified; an unknown one is a ``ValueError`` naming it
    (:func:`resolve_env_id`), raised here rather than in the workers."""
    env_id = resolve_env_id(env_id)
    try:
        from stable_baselines3.common.env_util import make_vec_env as sb3_make_vec_env
    except ImportError as exc:  # pragma: no cover - the rl extra is not installed
        raise ImportError("acc_gym.make_vec_env needs stable-baselines3: pip install 'acc-gym[rl]'") from exc
    return sb3_make_vec_env(qualified_id(env_id), n_envs=n_envs, **kwargs)
