"""Train PPO with stable-baselines3 on ``acc_gym/CarFollowing-v1``, save it, score it like any controller.

    python examples/sb3_train_evaluate.py --timesteps 200000 --out runs/sb3_ppo   # a few minutes on one core
    python examples/sb3_train_evaluate.py --quick                                 # a smoke run (about 10 s)

Needs the ``rl`` extra (``pip install ".[rl]"``; install a CPU build of torch first on a
CPU-only machine). This is your own training loop with plain SB3; ``acc-gym train ppo``
does the same with the tuned settings, checkpoints and a manifest (docs/training.md).

The saved files are what the package's loaders read: ``model.zip`` with
``vecnormalize.pkl`` beside it is a controller by path, so ``acc-gym evaluate
runs/sb3_ppo/model.zip --env acc_gym/CarFollowing-v1`` applies the same observation
normalisation as training did. The deterministic policy is scored on seeds it never
trained on (training uses ``--seed``, the evaluation ``--seed + 1000``).

Decision: a plain SB3 model file takes the observation it was trained on (a ``-v1`` id's
13 fields), so this one runs on the ``-v1`` ids only. The leaderboard's suites run the
``-v0`` ids: for it, train on a ``-v0`` id (``--env acc_gym/CarFollowing-v0``), or use
``acc-gym train``, whose runs compute the ``-v1`` features from ``-v0`` fields.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="acc_gym/CarFollowing-v1")
    parser.add_argument("--timesteps", type=int, default=200_000)
    parser.add_argument("--num-envs", type=int, default=8)
    parser.add_argument("--eval-episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default=None, help="where model.zip and vecnormalize.pkl go (default: a temporary "
                                                    "directory)")
    parser.add_argument("--quick", action="store_true", help="1024 steps, 2 evaluation episodes (the test runs this)")
    args = parser.parse_args(argv)
    if args.quick:
        args.timesteps, args.num_envs, args.eval_episodes = 1024, 4, 2

    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    import acc_gym
    from acc_gym.evaluation.runner import evaluate

    torch.set_num_threads(1)  # small MLPs: more threads only slow them down (docs/training.md)

    # acc_gym.make_vec_env is SB3's make_vec_env with the id qualified ("acc_gym:acc_gym/...")
    # so that subprocess workers import acc_gym too; the observation is normalised online.
    venv = VecNormalize(acc_gym.make_vec_env(args.env, n_envs=args.num_envs, seed=args.seed),
                        norm_obs=True, norm_reward=True, gamma=0.99)
    model = PPO("MlpPolicy", venv, n_steps=256 if not args.quick else 128, batch_size=128, learning_rate=3e-4,
                gamma=0.99, gae_lambda=0.95, seed=args.seed, verbose=0)
    t0 = time.monotonic()
    model.learn(total_timesteps=args.timesteps)
    train_s = time.monotonic() - t0

    out = Path(args.out or tempfile.mkdtemp(prefix="acc-gym-sb3-"))
    out.mkdir(parents=True, exist_ok=True)
    model.save(out / "model.zip")
    venv.save(str(out / "vecnormalize.pkl"))  # the statistics the loader applies to each observation
    venv.close()

    # The saved model by path, as acc-gym evaluate and the leaderboard load it, on the id it
    # trained on (a plain SB3 model file takes the observation it trained on: the 13 fields
    # of a -v1 id), on held-out seeds; every episode is scored by paper 003's criteria.
    summary = evaluate(str(out / "model.zip"), env_id=args.env, episodes=args.eval_episodes, seed=args.seed + 1000)
    print(json.dumps({"env_id": args.env, "timesteps": int(model.num_timesteps), "train_wall_time_s": round(train_s, 1),
                      "model": str(out / "model.zip"), "episodes": summary["episodes"],
                      "mean_score": summary["mean_score"], "share_qualified": summary["share_qualified"],
                      "collisions": summary["collisions"]}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
