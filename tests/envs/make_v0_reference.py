"""Write ``data/v0_reference.json``: reference episodes of every -v0 id (the linear ACC and a
fixed action sequence, a few seeds each), which ``test_v0_reference.py`` replays. Rerun it
only when a -v0 id changes on purpose (a new driver model, a scoring fix), and say so in
the changelog: ``python tests/envs/make_v0_reference.py``."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

IDS = ("acc_gym/CarFollowing-v0", "acc_gym/SingleLane-v0", "acc_gym/NCAP-v0", "acc_gym/StopAndGo-v0")
SEEDS = (0, 1, 2)
EVERY = 25  # record every 25th observation and reward


def wobble(k: int) -> float:
    """A fixed action sequence that is not a controller (accelerates, brakes, coasts)."""
    return float(np.clip(0.6 * np.sin(0.07 * k) - 0.1, -1.0, 1.0))


def episode(env_id: str, seed: int, driver: str) -> dict:
    import acc_gym  # noqa: F401
    from acc_gym.evaluation.runner import load_controller

    env = gym.make(env_id)
    policy = load_controller("acc") if driver == "acc" else None
    obs, _ = env.reset(seed=seed)
    rows, rewards, total, k, done = [], [], 0.0, 0, False
    while not done:
        if policy is not None:
            action, _ = policy.predict(obs, deterministic=True)
        else:
            action = wobble(k)
        obs, r, term, trunc, info = env.step(np.asarray(action, dtype=np.float32).reshape(1))
        total, done = total + r, term or trunc
        if k % EVERY == 0:
            rows.append([float(x) for x in obs])
            rewards.append(float(r))
        k += 1
    env.close()
    return {"env_id": env_id, "seed": seed, "driver": driver, "steps": k, "return": total,
            "score": float(info["score"]), "terminated": bool(term), "scenario": info["scenario"],
            "obs_every": EVERY, "obs": rows, "rewards": rewards}


def main(out=None) -> None:
    episodes = [episode(i, s, d) for i in IDS for s in SEEDS for d in ("acc", "wobble")]
    path = Path(out) if out else Path(__file__).with_name("data") / "v0_reference.json"
    path.write_text(json.dumps({"episodes": episodes}, indent=0) + "\n")
    print(path, len(episodes))


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
