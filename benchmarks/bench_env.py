"""Speed of the environments: single-env and vector-env steps per second.

Both run paper 004's single-lane generator restricted to its 15 three-vehicle
configurations, so every scene has two human-like MPC drivers (POV, POV2), with random
actions and episodes ending and restarting as they come (resets included in the time):

* ``env_steps_per_s``: one ``gymnasium.make("acc_gym/SingleLane-v0")`` environment,
  wrappers included (order enforcing, passive checker);
* ``vector_env_steps_per_s``: the native vector env with ``--num-envs`` (256)
  environments, counting every sub-environment step.

Each figure is the median of ``--repeats`` timed runs after a warm-up run (numba
kernels compiled, caches warm); the spread is printed too. ``--workers K`` (default: the
number of cores, if more than one) also times the vector env split over ``K`` worker
processes (``make_vec(..., workers=K)``, :mod:`acc_gym.envs.shards`) as
``vector_env_workers_steps_per_s``; ``--workers 1`` skips it. ``--parallel`` runs the
vector env's MPC drivers on numba's thread pool (``MPCSettings(parallel=None)``; off by
default, see :class:`acc_gym.drivers.mpc.MPCSettings`) and reports that figure as well.
``--policy`` times the vector env as training runs it, with stable-baselines3's default
PPO policy sampling every action from the observations (one torch thread), in process
and over ``--workers`` processes (``vector_env_policy_steps_per_s``,
``vector_env_workers_policy_steps_per_s``): each worker draws its next episodes while the
policy runs (:meth:`acc_gym.envs.vector.ACCVectorEnv.prepare_resets`).

    python benchmarks/bench_env.py            # table
    python benchmarks/bench_env.py --json     # one JSON object
"""

from __future__ import annotations

import argparse
import json
import os
import time

import gymnasium as gym
import numpy as np

import acc_gym  # noqa: F401  (registers the ids)
from acc_gym.drivers.mpc import MPCSettings
from acc_gym.envs.config import SINGLELANE

THREE_VEHICLES = tuple(i for i in SINGLELANE if i.startswith("singlelane/3/"))


def single_env_rate(steps: int, seed: int) -> float:
    env = gym.make("acc_gym/SingleLane-v0", scenarios=THREE_VEHICLES)
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    actions = rng.uniform(-0.3, 0.3, (steps, 1)).astype(np.float32)
    t0 = time.perf_counter()
    for k in range(steps):
        _, _, term, trunc, _ = env.step(actions[k])
        if term or trunc:
            env.reset()
    return steps / (time.perf_counter() - t0)


def vector_env_rate(num_envs: int, steps: int, seed: int, parallel: bool = False, workers: int = 1) -> float:
    kwargs = {"mpc_settings": MPCSettings(parallel=None)} if parallel else {}
    envs = gym.make_vec("acc_gym/SingleLane-v0", num_envs=num_envs, vectorization_mode="vector_entry_point",
                        scenarios=THREE_VEHICLES, workers=workers, **kwargs)
    rng = np.random.default_rng(seed)
    envs.reset(seed=seed)
    actions = rng.uniform(-0.3, 0.3, (steps, num_envs, 1)).astype(np.float32)
    t0 = time.perf_counter()
    for k in range(steps):
        envs.step(actions[k])
    rate = num_envs * steps / (time.perf_counter() - t0)
    envs.close()
    return rate


def vector_policy_rate(num_envs: int, steps: int, seed: int, workers: int = 1) -> float:
    """The vector env with a policy in the loop, as in training: stable-baselines3's default
    PPO policy (64-64 MLP, one torch thread) samples every action from the observations."""
    import torch
    from stable_baselines3.common.policies import ActorCriticPolicy

    torch.set_num_threads(1)
    envs = gym.make_vec("acc_gym/SingleLane-v0", num_envs=num_envs, vectorization_mode="vector_entry_point",
                        scenarios=THREE_VEHICLES, workers=workers)
    torch.manual_seed(seed)
    policy = ActorCriticPolicy(envs.single_observation_space, envs.single_action_space, lambda _: 3e-4)
    obs, _ = envs.reset(seed=seed)
    t0 = time.perf_counter()
    for _ in range(steps):
        with torch.no_grad():
            actions, _, _ = policy(torch.as_tensor(obs))
        obs = envs.step(np.clip(actions.numpy(), -1.0, 1.0))[0]
    rate = num_envs * steps / (time.perf_counter() - t0)
    envs.close()
    return rate


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=3000, help="single-env steps per timed run")
    parser.add_argument("--vector-steps", type=int, default=200, help="vector-env steps per timed run")
    parser.add_argument("--num-envs", type=int, default=256)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--parallel", action="store_true", help="also time the vector env with threaded MPC drivers")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                        help="also time the vector env over this many worker processes (1: skip)")
    parser.add_argument("--policy", action="store_true",
                        help="also time the vector env (in-process and with --workers) with a PPO policy in the loop")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    single_env_rate(300, 99)  # warm-up: compile and cache
    vector_env_rate(min(args.num_envs, 16), 20, 99)
    singles = [single_env_rate(args.steps, r) for r in range(args.repeats)]
    vectors = [vector_env_rate(args.num_envs, args.vector_steps, r) for r in range(args.repeats)]
    out = {
        "env_steps_per_s": float(np.median(singles)),
        "env_steps_per_s_runs": [round(x) for x in singles],
        "vector_env_steps_per_s": float(np.median(vectors)),
        "vector_env_steps_per_s_runs": [round(x) for x in vectors],
        "num_envs": args.num_envs,
        "vector_over_single": float(np.median(vectors) / np.median(singles)),
    }
    if args.workers > 1:
        work = [vector_env_rate(args.num_envs, args.vector_steps, r, workers=args.workers) for r in range(args.repeats)]
        out["workers"] = args.workers
        out["vector_env_workers_steps_per_s"] = float(np.median(work))
        out["vector_env_workers_steps_per_s_runs"] = [round(x) for x in work]
    if args.policy:
        cases = [(1, "vector_env_policy_steps_per_s")]
        if args.workers > 1:
            cases.append((args.workers, "vector_env_workers_policy_steps_per_s"))
        for workers, key in cases:
            runs = [vector_policy_rate(args.num_envs, args.vector_steps, r, workers) for r in range(args.repeats)]
            out[key] = float(np.median(runs))
            out[key + "_runs"] = [round(x) for x in runs]
    if args.parallel:
        vector_env_rate(min(args.num_envs, 16), 20, 99, parallel=True)
        par = [vector_env_rate(args.num_envs, args.vector_steps, r, parallel=True) for r in range(args.repeats)]
        out["vector_env_parallel_steps_per_s"] = float(np.median(par))
        out["vector_env_parallel_steps_per_s_runs"] = [round(x) for x in par]
    if args.json:
        print(json.dumps(out))
    else:
        print(f"single env (gymnasium.make, wrappers): {out['env_steps_per_s']:,.0f} steps/s "
              f"(runs {out['env_steps_per_s_runs']}; target >= 10,000)")
        print(f"vector env, {args.num_envs} envs:            {out['vector_env_steps_per_s']:,.0f} steps/s "
              f"(runs {out['vector_env_steps_per_s_runs']}; target >= 100,000)")
        if args.workers > 1:
            print(f"vector env, {args.workers} worker processes:  {out['vector_env_workers_steps_per_s']:,.0f} steps/s "
                  f"(runs {out['vector_env_workers_steps_per_s_runs']})")
        if args.policy:
            print(f"vector env + PPO policy in the loop:  {out['vector_env_policy_steps_per_s']:,.0f} steps/s "
                  f"(runs {out['vector_env_policy_steps_per_s_runs']})")
            if args.workers > 1:
                print(f"  the same, {args.workers} worker processes: "
                      f"{out['vector_env_workers_policy_steps_per_s']:,.0f} steps/s "
                      f"(runs {out['vector_env_workers_policy_steps_per_s_runs']})")
        if args.parallel:
            print(f"vector env, threaded MPC drivers:    {out['vector_env_parallel_steps_per_s']:,.0f} steps/s "
                  f"(runs {out['vector_env_parallel_steps_per_s_runs']})")
        print(f"vector / single: {out['vector_over_single']:.1f}x")
    return out


if __name__ == "__main__":
    main()
