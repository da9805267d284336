"""Models trained with the user's own tooling as controllers: any stable-baselines3 model
file, or an rl-zoo3 run folder.

* **a model file** (``model.zip`` saved by ``PPO(...).save(...)``, SAC, TD3, A2C, DDPG):
  the algorithm is read from the file's ``data`` entry without unpickling anything of it
  -- the policy class's module (``stable_baselines3.sac.policies`` -> SAC,
  ``...td3.policies`` -> TD3, which also loads DDPG's files) and, for the actor-critic
  policies PPO and A2C share, PPO's ``clip_range`` -- unless ``algo`` names it;
* **an rl-zoo3 run folder** (``logs/ppo/acc_gym-CarFollowing-v0_1``): the model is the
  folder's ``<env id>.zip`` (the last model, what ``rl_zoo3.enjoy`` loads; else its only
  ``.zip``), and its ``VecNormalize`` statistics (``vecnormalize.pkl`` in the folder or in
  its ``<env id>/`` subfolder) are applied to every observation as in training: the
  running mean and variance, ``clip_obs`` and ``epsilon`` (observations only; rewards do
  not reach a controller).

A model file's statistics are looked up the same way in its folder
(:func:`vecnormalize_file`): next to it, else in the subfolder named after it, else the
only ``*/vecnormalize.pkl``; several candidates none of which is the model's are an error
naming them, never a guess.

Either becomes an :class:`acc_gym_agents.rl.policy.SB3Policy`, the same ``predict`` path
as runs of ``acc-gym train``. A folder or file that is none of these is not claimed (the
loader returns None and the caller says what it expected).
"""

from __future__ import annotations

import json
import pickle
import zipfile
from pathlib import Path

import numpy as np

ALGOS = ("ppo", "a2c", "sac", "td3", "ddpg")
BY_POLICY_MODULE = {"stable_baselines3.sac.policies": "sac", "stable_baselines3.td3.policies": "td3"}
VECNORMALIZE = "vecnormalize.pkl"


def _data(path: Path) -> dict | None:
    """The JSON ``data`` entry of a stable-baselines3 model file (None if it is not one)."""
    try:
        with zipfile.ZipFile(path) as z:
            if "data" not in z.namelist() or "policy.pth" not in z.namelist():
                return None
            data = json.loads(z.read("data"))
    except (zipfile.BadZipFile, OSError, json.JSONDecodeError, UnicodeDecodeError):
        return None
    return data if isinstance(data, dict) else None


def detect_algo(path) -> str:
    """The algorithm that saved the model file ``path`` (``ValueError`` naming it if unknown)."""
    data = _data(Path(path))
    if data is None:
        raise ValueError(f"{path}: not a stable-baselines3 model file (a zip with 'data' and 'policy.pth')")
    policy = data.get("policy_class")
    module = policy.get("__module__") if isinstance(policy, dict) else None
    if module in BY_POLICY_MODULE:
        return BY_POLICY_MODULE[module]
    if module == "stable_baselines3.common.policies":
        return "ppo" if "clip_range" in data else "a2c"
    raise ValueError(f"{path}: cannot tell which algorithm saved it (policy module {module!r}); pass --algo "
                     f"(one of {', '.join(ALGOS)})")


def zoo_model(folder: Path) -> Path | None:
    """The model an rl-zoo3 run folder holds (None when the folder holds no model file)."""
    zips = sorted(p for p in folder.glob("*.zip") if _data(p) is not None)
    if not zips:
        return None
    named = [p for p in zips if p.name not in ("best_model.zip",) and not p.name.startswith("rl_model_")]
    if len(named) == 1:
        return named[0]
    if len(zips) == 1:
        return zips[0]
    raise ValueError(f"{folder}: more than one model ({', '.join(p.name for p in zips)}); name the .zip to load")


def vecnormalize_file(folder: Path, model: Path | None = None) -> Path | None:
    """The ``vecnormalize.pkl`` that goes with ``model`` in ``folder``, or None:

    * ``folder/vecnormalize.pkl`` (next to the model);
    * else rl-zoo3's layout, ``folder/<model's stem>/vecnormalize.pkl`` (the model
      ``acc_gym-CarFollowing-v0.zip`` beside its ``acc_gym-CarFollowing-v0/`` folder);
    * else the one ``folder/*/vecnormalize.pkl``. Several there, none of them the model's,
      is a ``ValueError`` naming them: which statistics belong to the model cannot be told,
      and the wrong ones would silently change every observation."""
    own = folder / VECNORMALIZE
    if own.is_file():
        return own
    if model is not None and (folder / model.stem / VECNORMALIZE).is_file():
        return folder / model.stem / VECNORMALIZE
    found = sorted(folder.glob(f"*/{VECNORMALIZE}"))
    if len(found) > 1:
        names = ", ".join(str(f.relative_to(folder)) for f in found)
        own_dir = f" or in {model.stem}/" if model is not None else ""
        raise ValueError(f"{folder}: which VecNormalize statistics go with the model is ambiguous: {names} "
                         f"(none next to it{own_dir}); copy the right one next to the model as {VECNORMALIZE}")
    return found[0] if found else None


def vecnormalize_stats(folder: Path, model: Path | None = None) -> tuple[np.ndarray, np.ndarray, float, float] | None:
    """``(mean, var, clip_obs, epsilon)`` of the ``vecnormalize.pkl`` that goes with ``model``
    in ``folder`` (:func:`vecnormalize_file`), or None when there is none or it does not
    normalise observations."""
    path = vecnormalize_file(Path(folder), None if model is None else Path(model))
    if path is None:
        return None
    try:
        with open(path, "rb") as f:
            vn = pickle.load(f)  # the user's own file, loaded in the controller's own process
        if not getattr(vn, "norm_obs", True):
            return None
        rms = vn.obs_rms
        return (np.asarray(rms.mean, dtype=np.float64), np.asarray(rms.var, dtype=np.float64),
                float(vn.clip_obs), float(vn.epsilon))
    except Exception as exc:  # noqa: BLE001  (a broken or foreign pickle: name the file)
        raise ValueError(f"{path}: not a stable-baselines3 VecNormalize file ({type(exc).__name__}: {exc})") \
            from None


def load_foreign(path, algo: str | None = None):
    """A stable-baselines3 model file or rl-zoo3 run folder as a controller, or None if
    ``path`` is neither (see the module docstring)."""
    from acc_gym_agents.rl.policy import SB3Policy

    p = Path(path)
    if p.is_dir():
        model_path = zoo_model(p)
        if model_path is None:
            return None
        stats = vecnormalize_stats(p, model_path)
    elif p.is_file() and _data(p) is not None:
        model_path, stats = p, vecnormalize_stats(p.parent, p)
    else:
        return None
    algo = detect_algo(model_path) if algo is None else str(algo).lower()
    if algo not in ALGOS:
        raise ValueError(f"unknown algorithm {algo!r}; use one of {', '.join(ALGOS)}")
    import stable_baselines3 as sb3

    cls = {"ppo": sb3.PPO, "a2c": sb3.A2C, "sac": sb3.SAC, "td3": sb3.TD3, "ddpg": sb3.DDPG}[algo]
    try:
        model = cls.load(str(model_path), device="cpu")
    except Exception as exc:  # noqa: BLE001  (a wrong --algo, or a damaged file: name it)
        raise ValueError(f"{model_path}: could not load it as {algo.upper()} ({type(exc).__name__}: {exc})") from None
    n = int(np.prod(model.observation_space.shape))
    if stats is None:  # no normalisation: the identity
        return SB3Policy(model, np.zeros(n), np.ones(n), clip=np.inf, eps=0.0)
    mean, var, clip, eps = stats
    return SB3Policy(model, mean, var, clip=clip, eps=eps)
