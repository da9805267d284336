"""The search behind the safety item's default rule: candidate rules on paper 003's test.

Every built-in car-following controller, plus a 0.5 s tailgater and a collider, drives
paper 003's car-following test (``carfollowing/60``, ``/90``, ``/120``) for ``--seeds``
seeds starting at ``--first-seed`` (default 100-111: seeds the tests do not use), each
episode through :func:`acc_gym.evaluation.runner.run_episode` (so a controller that
declares a time gap is judged at it; ``gipps`` is also judged at 1.5 s). Each recorded
trace is then judged by every candidate rule of the family the scoring docs discuss:

* ``literal`` -- Q >= 0 at every sample (paper 003 read literally);
* ``proper-response`` -- the default (:mod:`acc_gym.evaluation.scoring`): Q < 0 tolerated
  for tau1, then only while braking at 2 m/s^2 or harder (or standing); a collision fails;
* ``reacted-gap`` -- Gapsafe's reaction distance ``v tau1`` only until the ego reacts:
  once it brakes at 2 m/s^2 the braking distances alone must fit (``D1 >= v1^2 / 2 b1 -
  v0^2 / 2 b0``), before that Q < 0 for at most tau1;
* ``proper-response + TTC >= T`` for T = 1.5, 2.0, 2.5 s -- a minimum time-to-collision floor;
* ``proper-response + Q < 0 for at most T`` for T = 3, 5 s, braking or not.

It prints, per controller and speed, the share of episodes each rule qualifies on the
safety item, and the medians of the margins that decide them (minimum TTC, the longest
stretch of Q < 0, the smallest braking-distance margin while braking)::

    python benchmarks/safety_rules.py [--seeds 12] [--first-seed 100] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict

import gymnasium as gym
import numpy as np

import acc_gym  # noqa: F401  (registers the ids)
from acc_gym import scenarios
from acc_gym.evaluation import ScoringConfig, score_episode
from acc_gym.evaluation.indicators import gap_safe
from acc_gym.evaluation.runner import EpisodeRun, _action, as_action, declared_time_gap, load_controller
from acc_gym.evaluation.scoring import judged_tau1

IDS = ("carfollowing/60", "carfollowing/90", "carfollowing/120")
CONTROLLERS = ("acc", "cacc", "idm", "gipps", "gm", "fuzzy", "mpc", "constant")
RESPONSE = 2.0  # [m/s^2]
STAND = 0.5  # [m/s]


class Tailgater:
    """The linear ACC at a 0.5 s time gap (it does not declare it: judged at the scenario's)."""

    def __init__(self):
        self.inner = load_controller("acc")

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        o = np.array(obs, dtype=np.float32)
        o[..., 6] = 0.5
        return self.inner.predict(o, state, episode_start, deterministic)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return list(zip(edges[::2], edges[1::2]))


def judge(trace, tau1: float) -> dict:
    """Every candidate's safety verdict on one trace, and the margins behind them."""
    cfg = ScoringConfig(tau1=tau1)
    b0, b1 = cfg.b0, cfg.b1
    has = trace.has_lead
    d1 = np.where(has, trace.gap, np.inf)
    v0 = np.where(has, trace.v_lead, 0.0)
    v, a, t = trace.v, trace.a, trace.t
    q = d1 - gap_safe(v, v0, tau1, b0, b1)
    q_brake = d1 - (v ** 2 / (2 * b1) - v0 ** 2 / (2 * b0))
    closing = has & (v - v0 > 1e-9)
    ttc = np.where(closing, d1 / np.where(closing, v - v0, 1.0), np.inf)
    collision = bool(np.any(has & (trace.gap <= 0)))
    standing = v <= STAND
    reacted_ok, longest, worst_brake = not collision, 0.0, np.inf
    for i, j in _runs(has & (q < 0)):
        longest = max(longest, float(t[j - 1] - t[i]))
        for k in range(i, j):
            if standing[k]:
                continue
            if a[k] <= -RESPONSE:
                worst_brake = min(worst_brake, float(q_brake[k]))
                reacted_ok &= bool(q_brake[k] >= 0)
            elif t[k] - t[i] > tau1:
                reacted_ok = False
    proper = score_episode(trace, cfg).item("safety").qualified
    min_ttc = float(ttc.min()) if np.isfinite(ttc.min()) else float("inf")
    out = {"literal": bool(not np.any(has & (q < 0))), "proper-response": bool(proper), "reacted-gap": reacted_ok}
    for floor in (1.5, 2.0, 2.5):
        out[f"+TTC>={floor:g}"] = bool(proper and min_ttc >= floor)
    for cap in (3.0, 5.0):
        out[f"+Q<0 <={cap:g}s"] = bool(proper and longest <= cap)
    out.update(min_ttc=min_ttc, longest_negative_s=longest, min_brake_margin=worst_brake, collision=collision)
    return out


RULES = ("literal", "proper-response", "reacted-gap", "+TTC>=1.5", "+TTC>=2", "+TTC>=2.5", "+Q<0 <=3s", "+Q<0 <=5s")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=12)
    ap.add_argument("--first-seed", type=int, default=100)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    env = gym.make("acc_gym/CarFollowing-v0")
    cfg = ScoringConfig()
    rows = defaultdict(list)
    for name in (*CONTROLLERS, "tailgater"):
        policy = Tailgater() if name == "tailgater" else load_controller(name)
        declared = declared_time_gap(policy)
        for sid in IDS:
            for seed in range(args.first_seed, args.first_seed + args.seeds):
                sc = scenarios.build(sid, seed=seed)
                run = EpisodeRun(env, scenario=sc, record=False, time_gap=declared)
                if hasattr(policy, "reset"):
                    policy.reset()
                while not run.step(as_action(_action(policy, run.obs), name)):
                    pass
                trace = env.unwrapped.core.trace(0)
                own = judged_tau1(sc.time_gap, declared, cfg)
                rows[name, sid, own].append(judge(trace, own))
                if declared is not None:
                    rows[name, sid, 1.5].append(judge(trace, 1.5))
    table = []
    for (name, sid, tau1), judged in rows.items():
        entry = {"controller": name, "scenario": sid, "tau1": tau1, "n": len(judged),
                 "seeds": [args.first_seed, args.first_seed + args.seeds - 1]}
        entry.update({r: float(np.mean([j[r] for j in judged])) for r in RULES})
        for m in ("min_ttc", "longest_negative_s", "min_brake_margin"):
            entry[f"median_{m}"] = float(np.median([j[m] for j in judged]))
        entry["collisions"] = int(sum(j["collision"] for j in judged))
        table.append(entry)
    if args.json:
        print(json.dumps(table, indent=1, allow_nan=True))
        return 0
    head = f"{'controller':<10} {'test':>4} {'tau1':>4} " + " ".join(f"{r:>15}" for r in RULES)
    print(f"share of episodes qualified on safety, n = {args.seeds} per row (seeds {args.first_seed}-"
          f"{args.first_seed + args.seeds - 1})")
    print(head + f" {'min TTC':>8} {'Q<0 max':>8} {'brake m':>8} coll")
    for e in table:
        print(f"{e['controller']:<10} {e['scenario'].split('/')[1]:>4} {e['tau1']:>4.1f} "
              + " ".join(f"{e[r]:>15.2f}" for r in RULES)
              + f" {e['median_min_ttc']:>8.2f} {e['median_longest_negative_s']:>8.1f} "
                f"{e['median_min_brake_margin']:>8.1f} {e['collisions']:>4}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
