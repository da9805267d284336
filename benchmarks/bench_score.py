"""Speed of scoring one episode: ``score_episode`` of a trace and ``score_record`` of an environment's record.

The traces are real episodes of the environments, as they score them at an episode's end:
``--episodes`` of ``acc_gym/SingleLane-v0`` and as many of ``acc_gym/CarFollowing-v0``
(seeds 0, 1, ...; random actions in [-0.3, 0.3]), each the ``EgoTrace`` of
``env.unwrapped.core.trace(0)`` after its last step (about 20 to 400 samples), under the
environments' default ``ScoringConfig``. A timed run scores every trace ``--loops`` times
with one of the two functions (the whole call: the checks, the score and its
``EpisodeReport``; not ``to_dict``): ``score_episode(trace)`` or ``score_record`` of the
trace's columns as one ``(columns, samples)`` array (what the environments score at an
episode's end); the runs alternate between them, ``--repeats`` each, after a warm-up
(kernels compiled or loaded from numba's cache). Printed: the median over the runs of the
mean microseconds per call, each run's figure, and the ratio trace / record.

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
from acc_gym.evaluation.scoring import _ARRAY_COLUMNS, score_episode, score_record

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
    records = [(np.array([getattr(tr, c) for c in _ARRAY_COLUMNS]), tr, cfg) for tr, cfg in work]

    def by_record(rec_tr, cfg):
        rec, tr = rec_tr
        return score_record(rec, tr.n, tr.set_speed, tr.time_gap, tr.declared_time_gap, cfg)

    record_work = [((rec, tr), cfg) for rec, tr, cfg in records]
    for (rec_tr, cfg), (trace, _) in zip(record_work, work):  # warm-up, and the two agree
        if by_record(rec_tr, cfg).to_dict() != score_episode(trace, cfg).to_dict():
            raise AssertionError("a record scores differently from its trace")
    runs: dict[str, list[float]] = {"trace": [], "record": []}
    for _ in range(args.repeats):
        runs["trace"].append(timed_run(score_episode, work, args.loops))
        runs["record"].append(timed_run(by_record, record_work, args.loops))
    samples = [trace.n for trace, _ in work]
    by_trace = statistics.median(runs["trace"])
    by_rec = statistics.median(runs["record"])
    out = {"traces": len(work), "samples_min": min(samples), "samples_median": float(np.median(samples)),
           "samples_max": max(samples), "trace_us": by_trace, "record_us": by_rec, "ratio": by_trace / by_rec,
           "trace_us_runs": [round(x, 1) for x in runs["trace"]],
           "record_us_runs": [round(x, 1) for x in runs["record"]]}
    if args.json:
        print(json.dumps(out))
    else:
        print(f"{out['traces']} traces of {out['samples_min']}-{out['samples_max']} samples "
              f"(median {out['samples_median']:.0f}), {args.loops} calls each per run, {args.repeats} runs")
        print(f"  score_episode (trace)    {by_trace:8.1f} us per call  (runs {out['trace_us_runs']})")
        print(f"  score_record (record)    {by_rec:8.1f} us per call  (runs {out['record_us_runs']})")
        print(f"  ratio                    {out['ratio']:8.1f}x")
    return out


if __name__ == "__main__":
    main()
