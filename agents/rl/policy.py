"""A trained stable-baselines3 model as a controller: ``predict(obs, deterministic=True)``.

Training normalises observations (``VecNormalize``); the running mean and variance are
saved next to the model (``obs_rms.npz``) and applied here, so a saved model is scored
through the same path as the hand-written controllers. A residual run (``residual`` in
its manifest, :mod:`acc_gym_agents.rl.residual`) executes ``clip(base(obs) + scale * model(obs),
-1, 1)`` with the base controller on the raw observation (and the proper-response shield
when ``shield`` is set), as in training. A PPO run also holds its actor exported to
numpy (``policy.npz``, :mod:`acc_gym_agents.rl.mlp`), which :func:`load_policy` prefers: it needs
neither torch nor stable-baselines3.

**A ``-v1`` policy drives anywhere.** A run trained on a ``-v1`` id saw the ``-v0`` fields
followed by the safety-margin features (:mod:`acc_gym.envs.observation`), which are a pure
function of those fields and the sensor range. Given the ``-v0`` fields alone (a ``-v0``
id, a suite, the leaderboard), such a policy computes the features itself with its
training env's sensor range and acts exactly as on the ``-v1`` observation; given the
``-v1`` observation it uses it as it is. Any other width is an error naming both.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from acc_gym_agents.rl.residual_law import check_overspeed, check_scale, check_shield, controller_action, make_base

ALGOS = ("ppo", "sac", "td3", "tqc", "crossq")  # tqc, crossq: sb3-contrib's
MODEL_FILE = "model.zip"
RMS_FILE = "obs_rms.npz"
MANIFEST_FILE = "manifest.json"


def algorithm_class(algo: str):
    """The stable-baselines3 (``ppo``, ``sac``, ``td3``) or sb3-contrib (``tqc``, ``crossq``)
    class of ``algo``; ValueError naming an unknown one."""
    if algo not in ALGOS:
        raise ValueError(f"unknown algorithm {algo!r}; use one of {', '.join(ALGOS)}")
    if algo in ("tqc", "crossq"):
        import sb3_contrib

        return {"tqc": sb3_contrib.TQC, "crossq": sb3_contrib.CrossQ}[algo]
    import stable_baselines3 as sb3

    return {"ppo": sb3.PPO, "sac": sb3.SAC, "td3": sb3.TD3}[algo]


class SB3Policy:
    """A loaded model plus its observation normalisation (and, for a residual run, its base controller).

    ``model`` is anything with stable-baselines3's ``predict(obs, deterministic=...)``: the
    stable-baselines3 model itself or its numpy export (:class:`acc_gym_agents.rl.mlp.NumpyActor`).
    """

    vectorised = True  # predict() answers an (n, obs) array row by row (acc_gym.risk batches through it)

    def __init__(self, model, mean: np.ndarray, var: np.ndarray, clip: float = 10.0, eps: float = 1e-8,
                 residual: str | None = None, residual_scale: float | None = None, shield: str | bool | None = None,
                 residual_kwargs: dict | None = None, max_overspeed: float | None = None,
                 sensor_range: float | None = None):
        self.model, self.mean, self.var, self.clip, self.eps = model, mean, var, clip, eps
        self.sensor_range = None if sensor_range is None else float(sensor_range)  # [m] set: a -v1 policy
        self.residual, self.residual_scale, self.base = residual, residual_scale, None
        self.shield = check_shield(shield)
        self.max_overspeed = None
        if (self.shield or max_overspeed is not None or residual_kwargs) and residual is None:
            raise ValueError("shield, max_overspeed and residual_kwargs are options of residual policies")
        if residual is not None:
            self.base = make_base(residual, residual_kwargs)
            self.max_overspeed = check_overspeed(max_overspeed)
            self.residual_scale = check_scale(residual_scale)

    def reset(self) -> None:
        pass

    def inputs(self, obs) -> np.ndarray:
        """The observation as the model was trained on it: a ``-v1`` policy given the ``-v0``
        fields gets the margin features appended (computed in float64 from the float32 fields,
        as the env computes them)."""
        o = np.asarray(obs, dtype=np.float32)
        width = self.mean.shape[-1]
        if o.shape[-1] != width and self.sensor_range is not None and o.shape[-1] in (7, 11):
            from acc_gym.envs.observation import margin_features

            o = margin_features(o, self.sensor_range).astype(np.float32)
        if o.shape[-1] != width:
            kind = "the -v0 fields or the -v1 observation" if self.sensor_range is not None else "its training observation"
            raise ValueError(f"observation has {o.shape[-1]} fields (shape {o.shape}); this policy takes {width} "
                             f"({kind})")
        return o

    def normalise(self, obs) -> np.ndarray:
        o = self.inputs(obs)
        return np.clip((o - self.mean) / np.sqrt(self.var + self.eps), -self.clip, self.clip).astype(np.float32)

    def predict(self, obs, state=None, episode_start=None, deterministic: bool = True):
        action, _ = self.model.predict(self.normalise(obs), deterministic=deterministic)
        if self.base is not None:
            action = controller_action(obs, action, self.base, self.residual_scale, self.shield, self.max_overspeed)
        return action, None


def read_manifest(run) -> dict:
    """The manifest of a run directory; a missing or broken one is an error naming the file."""
    manifest_path = Path(run) / MANIFEST_FILE
    if not manifest_path.is_file():
        raise ValueError(f"{run}: no {MANIFEST_FILE}; not a run directory written by `acc-gym train`")
    try:
        manifest = json.loads(manifest_path.read_text())
        algo = manifest["algo"]
    except (json.JSONDecodeError, KeyError, TypeError) as exc:
        raise ValueError(f"{manifest_path}: broken manifest ({exc})") from None
    if algo not in ALGOS:
        raise ValueError(f"{manifest_path}: unknown algorithm {algo!r}")
    return manifest


BACKENDS = ("numpy", "sb3")


def load_policy(path, backend: str | None = None) -> SB3Policy:
    """Load a run directory written by :func:`acc_gym_agents.rl.train.train` (or its ``model.zip``).

    ``backend``: ``"sb3"`` loads ``model.zip`` with stable-baselines3 (needs torch);
    ``"numpy"`` evaluates the exported actor ``policy.npz`` (:mod:`acc_gym_agents.rl.mlp`; no
    torch, deterministic actions only). ``None``: numpy when the run has a ``policy.npz``
    and the path is not the ``model.zip`` itself, else stable-baselines3.
    """
    from acc_gym_agents.rl.mlp import POLICY_FILE, NumpyActor

    path = Path(path)
    run = path.parent if path.suffix == ".zip" else path
    manifest = read_manifest(run)
    if backend is None:
        backend = "numpy" if path.suffix != ".zip" and (run / POLICY_FILE).is_file() else "sb3"
    if backend not in BACKENDS:
        raise ValueError(f"unknown policy backend {backend!r}; use one of {BACKENDS}")
    if backend == "numpy":
        if not (run / POLICY_FILE).is_file():
            raise ValueError(f"{run}: no {POLICY_FILE}; export it with acc_gym_agents.rl.mlp.export({str(run)!r})")
        model = NumpyActor.load(run / POLICY_FILE)
    else:
        model = algorithm_class(manifest["algo"]).load(str(path if path.suffix == ".zip" else run / MODEL_FILE), device="cpu")
    rms = np.load(run / RMS_FILE)
    residual = manifest.get("residual")
    return SB3Policy(model, rms["mean"], rms["var"], float(rms["clip"]), residual=residual,
                     residual_scale=manifest.get("residual_scale") if residual is not None else None,
                     shield=manifest.get("shield"), residual_kwargs=manifest.get("residual_kwargs"),
                     max_overspeed=manifest.get("max_overspeed"), sensor_range=sensor_range_of(manifest))


def sensor_range_of(manifest: dict) -> float | None:
    """The sensor range [m] of a run trained on a ``-v1`` observation (its training env
    settings' ``version`` 1), else None."""
    settings = manifest.get("train_env_settings") or manifest.get("env_settings") or {}  # what it was trained on
    if settings.get("version", 0) != 1:
        return None
    from acc_gym.envs.config import EnvConfig

    return float(settings.get("sensor_range", EnvConfig.sensor_range))


def load_run(path, algo: str | None = None):
    """A saved model as a controller (the ``acc_gym.controller_loaders`` entry point): a run
    directory of ``acc-gym train`` or its ``model.zip``; else any stable-baselines3 model
    file or rl-zoo3 run folder (:mod:`acc_gym_agents.rl.foreign`); None when ``path`` is
    none of these. ``algo`` names the algorithm of a foreign model (read from the file when
    omitted)."""
    p = Path(path)
    ours = (p.is_dir() and (p / MANIFEST_FILE).is_file()) or \
        (p.suffix == ".zip" and p.is_file() and (p.parent / MANIFEST_FILE).is_file())
    if ours:
        return load_policy(p)
    from acc_gym_agents.rl.foreign import load_foreign

    return load_foreign(p, algo=algo)
