"""Speed of scoring one episode: ``score_episode`` (compiled) against ``score_episode_reference`` (numpy).

The traces are real episodes of the environments, as they score them at an episode's end:
``--episodes`` of ``acc_gym/SingleLane-v0`` and as many of ``acc_gym/CarFollowing-v0``
(seeds 0, 1, ...; random actions in [-0.3, 0.3]), each the ``EgoTrace`` of
``env.unwrapped.core.trace(0)`` after its last step (about 20 to 400 samples), under the
environments' default ``ScoringConfig``. A timed run scores every trace ``--loops`` times
with one of the two functions (the whole call: the trace's checks, the score and its
``EpisodeReport``; not ``to_dict``); the runs alternate between them, ``--repeats`` each,
after a warm-up (kernels compiled or loaded from numba's cache). Printed: the median over
the runs of the mean microseconds per call, each run's figure, and the ratio
reference / compiled (above 1: the compiled path is faster).

    python benchmarks/bench_score.py            # table
    python benchmarks/bench_score.py --json     # one JSON object
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import gymnasium
import numpy as np

import acc_gym  # noqa: F401  (registers the environments)
from acc_gym.evaluation.scoring import score_episode, score_episode_reference

ENV_IDS = ("acc_gym/SingleLane-v0", "acc_gym/CarFollowing-v0")


def traces(episodes: int) -> list:
    """(trace, config) of ``episodes`` episodes of each environment."""
    out = []
    for env_id in ENV_IDS:
        env = gymnasium.make(env_id)
        rng = np.random.default_rng(0)
        for seed in range(episodes):
            env.reset(seed=seed)
            while True:
                action = rng.uniform(-0.3, 0.3, env.action_space.shape).astype(env.action_space.dtype)
                _, _, terminated, truncated, _ = env.step(action)
                if terminated or truncated:
                    break
            out.append((env.unwrapped.core.trace(0), env.unwrapped.config.scoring))
        env.close()
    return out


def timed_run(fn, work: list, loops: int) -> float:
    """Mean microseconds per call of ``fn`` over every trace of ``work``, ``loops`` times."""
    t0 = time.perf_counter()
    for _ in range(loops):
        for trace, cfg in work:
            fn(trace, cfg)
    return (time.perf_counter() - t0) / (loops * len(work)) * 1e6


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--episodes", type=int, default=25, help="episodes of each environment")
    ap.add_argument("--loops", type=int, default=20, help="calls per trace in a timed run")
    ap.add_argument("--repeats", type=int, default=5, help="timed runs of each function, alternating")
    args = ap.parse_args(argv)
    work = traces(args.episodes)
    for trace, cfg in work:  # warm-up, and the two agree
        if score_episode(trace, cfg).to_dict() != score_episode_reference(trace, cfg).to_dict():
            raise AssertionError("the compiled score differs from the reference")
    runs: dict[str, list[float]] = {"reference": [], "compiled": []}
    for _ in range(args.repeats):
        runs["reference"].append(timed_run(score_episode_reference, work, args.loops))
        runs["compiled"].append(timed_run(score_episode, work, args.loops))
    samples = [trace.n for trace, _ in work]
    ref = statistics.median(runs["reference"])
    fast = statistics.median(runs["compiled"])
    out = {"traces": len(work), "samples_min": min(samples), "samples_median": float(np.median(samples)),
           "samples_max": max(samples), "reference_us": ref, "compiled_us": fast, "ratio": ref / fast,
           "reference_us_runs": [round(x, 1) for x in runs["reference"]],
           "compiled_us_runs": [round(x, 1) for x in runs["compiled"]]}
    if args.json:
        print(json.dumps(out))
    else:
        print(f"{out['traces']} traces of {out['samples_min']}-{out['samples_max']} samples "
              f"(median {out['samples_median']:.0f}), {args.loops} calls each per run, {args.repeats} runs")
        print(f"  score_episode_reference  {ref:8.1f} us per call  (runs {out['reference_us_runs']})")
        print(f"  score_episode            {fast:8.1f} us per call  (runs {out['compiled_us_runs']})")
        print(f"  ratio                    {out['ratio']:8.1f}x")
    return out


if __name__ == "__main__":
    main()
