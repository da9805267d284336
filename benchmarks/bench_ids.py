"""Speed of the environment ids as users make them (``gym.make`` / ``gym.make_vec`` defaults).

Unlike ``bench_env.py`` (three-vehicle single-lane scenes only), this times each id with
its default scenario mix -- ``acc_gym/SingleLane-v0`` draws all 22 configurations, a third
of them with one or two vehicles -- single (``gym.make``, wrappers included, resets
included) and as a 256-env vector env (``vectorization_mode="vector_entry_point"``),
random actions in [-0.3, 0.3]. Each measurement runs in a fresh process; with
``--against DIR`` (another checkout, e.g. ``git worktree add ../prev HEAD~1``) the two
alternate ``--repeats`` times and the medians and their ratio are printed.

    python benchmarks/bench_ids.py --json [--repeats 3] [--against ../prev]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
IDS = ("acc_gym/SingleLane-v0", "acc_gym/CarFollowing-v0", "acc_gym/NCAP-v0")


def measure(steps: int, vector_steps: int, num_envs: int) -> dict:
    import gymnasium as gym
    import numpy as np

    import acc_gym  # noqa: F401  (registers the ids)

    out = {}
    for env_id in IDS:
        env = gym.make(env_id)
        rng = np.random.default_rng(0)
        env.reset(seed=0)
        actions = rng.uniform(-0.3, 0.3, (steps + 300, 1)).astype(np.float32)
        for k, a in enumerate(actions):
            if k == 300:  # after a warm-up
                t0 = time.perf_counter()
            _, _, term, trunc, _ = env.step(a)
            if term or trunc:
                env.reset()
        single = steps / (time.perf_counter() - t0)
        venv = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point")
        venv.reset(seed=0)
        acts = rng.uniform(-0.3, 0.3, (vector_steps + 10, num_envs, 1)).astype(np.float32)
        for k, a in enumerate(acts):
            if k == 10:
                t0 = time.perf_counter()
            venv.step(a)
        out[env_id] = {"single_steps_per_s": single,
                       "vector_steps_per_s": num_envs * vector_steps / (time.perf_counter() - t0)}
    return out


def run_in(source: Path, args) -> dict:
    env = dict(os.environ, PYTHONPATH=str(source))
    done = subprocess.run([sys.executable, __file__, "--child", "--steps", str(args.steps), "--vector-steps",
                           str(args.vector_steps), "--num-envs", str(args.num_envs)], env=env, check=True,
                          capture_output=True, text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--vector-steps", type=int, default=100)
    ap.add_argument("--num-envs", type=int, default=256)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--against", default=None)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        print(json.dumps(measure(args.steps, args.vector_steps, args.num_envs)))
        return 0
    sources = {"this": ROOT} | ({"against": Path(args.against).resolve()} if args.against else {})
    runs = {name: [] for name in sources}
    for _ in range(args.repeats):
        for name, src in sources.items():
            runs[name].append(run_in(src, args))
    result = {}
    for env_id in IDS:
        for key in ("single_steps_per_s", "vector_steps_per_s"):
            entry = {name: statistics.median(r[env_id][key] for r in rs) for name, rs in runs.items()}
            entry["runs"] = [r[env_id][key] for r in runs["this"]]
            if args.against:
                entry["ratio"] = entry["this"] / entry["against"]
            result[f"{env_id} {key}"] = entry
    if args.json:
        print(json.dumps(result))
    else:
        for k, e in result.items():
            extra = f"  against {e['against']:>10.0f}  ratio {e['ratio']:.2f}" if args.against else ""
            print(f"{k:45} {e['this']:>10.0f}{extra}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
