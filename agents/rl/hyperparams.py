"""Tuned hyperparameters of plain PPO and SAC per environment id, in rl-zoo3's format.

``hyperparams/ppo.yml`` and ``hyperparams/sac.yml`` (next to this module) are keyed by
environment id, as rl-zoo3's files are, and usable as they stand with

    python -m rl_zoo3.train --algo ppo --env acc_gym/CarFollowing-v0 --gym-packages acc_gym \\
        -conf <path of acc_gym_agents/rl/hyperparams/ppo.yml>

(:func:`path` gives the path). ``acc-gym train`` takes them as its defaults when no
``--algo-kwargs`` are given (:func:`defaults`); how they were found and the learning
curves they give are in the README (``benchmarks/rl_curves.py`` regenerates the curves).

rl-zoo3 keys that are not keyword arguments of the algorithm:

* ``n_envs`` -- ``acc-gym train``'s ``num_envs``;
* ``n_timesteps`` -- its default ``timesteps``;
* ``policy`` -- always ``MlpPolicy`` here;
* ``normalize`` -- rl-zoo3's ``VecNormalize`` settings: ``acc-gym train`` always
  normalises observations; ``"dict(norm_obs=True, norm_reward=True)"`` scales the training
  rewards too, ``clip_obs=C`` bounds each normalised observation at ``C`` standard
  deviations (default 10) (:func:`normalize_settings`);
* ``env_kwargs`` -- keyword arguments of ``gym.make`` for the *training* environments
  (:func:`env_kwargs`), e.g. the scenario mixture trained on,
  ``default_scenarios: {carfollowing/varied: 0.4, singlelane/1/free-flow: 0.1, ...}`` (shares
  of scenario ids or families, as the ``-v1`` ids declare theirs). ``acc-gym train`` scores
  its checkpoints on the id's own scenarios, the distribution a user is scored on;
  rl-zoo3 passes them to its evaluation environment too (its selection only).

Values rl-zoo3 writes as strings are converted as rl-zoo3 converts them: ``"lin_3e-4"``
is a learning rate (or clip range) falling linearly from 3e-4 to 0 over training, and
``policy_kwargs`` is a Python expression such as ``"dict(log_std_init=-1, net_arch=[64, 64])"``
(evaluated with only ``dict`` and ``torch.nn`` as ``nn`` in scope).
"""

from __future__ import annotations

import math
from pathlib import Path

DIRECTORY = Path(__file__).resolve().parent / "hyperparams"
ZOO_ONLY = ("n_envs", "n_timesteps", "policy", "normalize", "env_kwargs")  # rl-zoo3 keys that are not algorithm kwargs
SCHEDULED = ("learning_rate", "clip_range")  # keys rl-zoo3 accepts "lin_<x>" for


def path(algo: str) -> Path:
    """The rl-zoo3 hyperparameter file of ``algo`` (``ppo`` or ``sac``)."""
    p = DIRECTORY / f"{algo}.yml"
    if not p.is_file():
        raise ValueError(f"no tuned hyperparameters for {algo!r}; there are {sorted(x.stem for x in DIRECTORY.glob('*.yml'))}")
    return p


def load(algo: str) -> dict:
    """The whole file of ``algo``: ``{env_id: {rl-zoo3 key: value}}``."""
    import yaml

    with open(path(algo)) as fh:
        data = yaml.safe_load(fh)
    if not isinstance(data, dict):
        raise ValueError(f"{path(algo)}: expected a mapping of environment ids")
    return data


def available(algo: str) -> list[str]:
    """The environment ids ``algo`` has tuned hyperparameters for (``[]`` for none)."""
    try:
        return sorted(load(algo))
    except ValueError:
        return []


class LinearSchedule:
    """``initial * progress_remaining`` (rl-zoo3's ``lin_<initial>``; picklable, unlike a lambda)."""

    def __init__(self, initial: float):
        self.initial = float(initial)

    def __call__(self, progress_remaining: float) -> float:
        return progress_remaining * self.initial

    def __repr__(self) -> str:
        return f"lin_{self.initial:g}"


def _value(key: str, value):
    if key in SCHEDULED and isinstance(value, str):
        kind, _, initial = value.partition("_")
        if kind != "lin" or not initial:
            raise ValueError(f"{key}: only linear schedules 'lin_<initial>' are supported, got {value!r}")
        return LinearSchedule(float(initial))
    if key == "policy_kwargs" and isinstance(value, str):
        import torch.nn as nn

        return eval(value, {"__builtins__": {}}, {"dict": dict, "nn": nn})  # rl-zoo3's convention
    if key == "train_freq" and isinstance(value, list):
        return tuple(value)
    return value


CLIP_OBS = 10.0  # VecNormalize's default bound on a normalised observation [standard deviations]


def normalize_settings(value, gamma: float = 0.99) -> dict:
    """rl-zoo3's ``normalize`` as :class:`~stable_baselines3.common.vec_env.VecNormalize`
    settings besides ``norm_obs=True`` (always on), read as rl-zoo3 reads it: absent (None)
    -- observations only (what ``acc-gym train`` always did: ``norm_reward=False``);
    ``"dict(norm_obs=True, norm_reward=False)"`` -- the same, and what the shipped files
    say, so that rl-zoo3 trains the same way; ``True`` (rl-zoo3: VecNormalize's defaults) or
    ``"dict(norm_obs=True, norm_reward=True)"`` -- returns scaled by their running standard
    deviation too (discounted with the algorithm's ``gamma``), in training only; evaluations
    and the saved policy see unscaled rewards and only the observation statistics.

    ``clip_obs`` (VecNormalize's own keyword, so rl-zoo3 reads it the same way; default
    :data:`CLIP_OBS`, 10): the bound on each normalised observation, in standard deviations,
    kept with the run's statistics (``obs_rms.npz``) and applied by the saved policy too.
    Why it is a setting: a feature that is 0 on most steps has a small standard deviation,
    and 10 of them can be far short of its range -- the ``-v1`` ids' ``a_req`` has a
    standard deviation of 0.23 m/s^2 in the shipped PPO's statistics, so a policy trained
    with the default sees every required deceleration beyond 2.3 m/s^2 as 2.3
    (docs/rl-training.md)."""
    if value is None:
        return {"norm_reward": False, "clip_obs": CLIP_OBS}
    if value is True:
        value = {"norm_obs": True, "norm_reward": True}
    if isinstance(value, str):
        value = eval(value, {"__builtins__": {}}, {"dict": dict})  # rl-zoo3's convention
    if (not isinstance(value, dict) or value.get("norm_obs", True) is not True
            or set(value) - {"norm_obs", "norm_reward", "clip_obs"}):
        raise ValueError(f"normalize: acc-gym train always normalises observations; give True or "
                         f"'dict(norm_obs=True, norm_reward=True|False[, clip_obs=C])', got {value!r}")
    clip = value.get("clip_obs", CLIP_OBS)
    if isinstance(clip, bool) or not isinstance(clip, (int, float)) or not (math.isfinite(clip) and clip > 0):
        raise ValueError(f"normalize: clip_obs must be a positive finite number of standard deviations, got {clip!r}")
    out = {"norm_reward": bool(value.get("norm_reward", False)), "clip_obs": float(clip)}
    if out["norm_reward"]:
        out["gamma"] = float(gamma)
    return out


def env_kwargs(entry: dict) -> dict:
    """The entry's ``env_kwargs`` (``{}`` without), checked to be a mapping of setting names."""
    value = entry.get("env_kwargs") or {}
    if isinstance(value, str):
        value = eval(value, {"__builtins__": {}}, {"dict": dict})  # rl-zoo3's convention
    if not isinstance(value, dict) or not all(isinstance(k, str) for k in value):
        raise ValueError(f"env_kwargs must be a mapping of environment settings, got {value!r}")
    return dict(value)


def to_sb3(entry: dict) -> dict:
    """An rl-zoo3 entry (or ``--algo-kwargs``) as keyword arguments of the SB3 algorithm."""
    out = {}
    for key, value in entry.items():
        if key in ZOO_ONLY:
            continue
        out[key] = _value(key, value)
    return out


def defaults(algo: str, env_id: str) -> dict | None:
    """``{"entry": rl-zoo3 entry, "algo_kwargs": SB3 kwargs, "num_envs": n, "timesteps": n,
    "file": path}`` of ``algo`` on ``env_id``, or None if it has none."""
    try:
        data = load(algo)
    except ValueError:
        return None
    entry = data.get(env_id)
    if entry is None:
        return None
    if entry.get("policy", "MlpPolicy") != "MlpPolicy":
        raise ValueError(f"{path(algo)}: {env_id}: acc-gym train uses MlpPolicy, got {entry['policy']!r}")
    normalize_settings(entry.get("normalize"))  # a ValueError for settings acc-gym train cannot honour
    return {"entry": dict(entry), "algo_kwargs": to_sb3(entry), "num_envs": int(entry.get("n_envs", 8)),
            "timesteps": int(entry["n_timesteps"]), "file": str(path(algo)), "env_kwargs": env_kwargs(entry)}
