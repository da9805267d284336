"""A trained stable-baselines3 model as a controller: ``predict(obs, deterministic=True)``.

Training normalises observations (``VecNormalize``); the running mean and variance are
saved next to the model (``obs_rms.npz``) and applied here, so a saved model is scored
through the same path as the hand-written controllers.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

ALGOS = ("ppo", "sac", "td3")
MODEL_FILE = "model.zip"
RMS_FILE = "obs_rms.npz"
MANIFEST_FILE = "manifest.json"


class SB3Policy:
    """A loaded model plus its observation normalisation."""

    def __init__(self, model, mean: np.ndarray, var: np.ndarray, clip: float = 10.0, eps: float = 1e-8):
        self.model, self.mean, self.var, self.clip, self.eps = model, mean, var, clip, eps

    def reset(self) -> None:
        pass

    def normalise(self, obs) -> np.ndarray:
        o = np.asarray(obs, dtype=np.float32)
        return np.clip((o - self.mean) / np.sqrt(self.var + self.eps), -self.clip, self.clip).astype(np.float32)

    def predict(self, obs, state=None, episode_start=None, deterministic: bool = True):
        action, _ = self.model.predict(self.normalise(obs), deterministic=deterministic)
        return action, None


def load_policy(path) -> SB3Policy:
    """Load a run directory written by :func:`agents.rl.train.train` (or its ``model.zip``)."""
    path = Path(path)
    run = path.parent if path.suffix == ".zip" else path
    manifest_path = run / MANIFEST_FILE
    if not manifest_path.is_file():
        raise ValueError(f"{run}: no {MANIFEST_FILE}; not a run directory written by `acc-gym train`")
    try:
        manifest = json.loads(manifest_path.read_text())
        algo = manifest["algo"]
    except (json.JSONDecodeError, KeyError) as exc:
        raise ValueError(f"{manifest_path}: broken manifest ({exc})") from None
    if algo not in ALGOS:
        raise ValueError(f"{manifest_path}: unknown algorithm {algo!r}")
    import stable_baselines3 as sb3

    cls = {"ppo": sb3.PPO, "sac": sb3.SAC, "td3": sb3.TD3}[algo]
    model = cls.load(str(path if path.suffix == ".zip" else run / MODEL_FILE), device="cpu")
    rms = np.load(run / RMS_FILE)
    return SB3Policy(model, rms["mean"], rms["var"], float(rms["clip"]))
