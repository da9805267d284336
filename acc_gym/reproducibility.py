"""What is exactly the same on every machine, what is reproducible to a tolerance, and the
tool that measures the tolerance.

* **Exactly the same on every machine:** the suites' definitions and hashes
  (:mod:`acc_gym.suites`): a suite episode's parameters are rounded to 6 decimals before
  the episode is built from them (:func:`acc_gym.suites.suite.canonical_params`), so the
  last-bit differences of ``exp`` / ``log`` between CPU instruction sets (numpy's AVX-512
  and AVX2 code give different last bits) do not reach the stored data; the content
  digest of the built scenarios is taken on values rounded the same way.
* **Reproducible to a tolerance:** trajectories and scores. What an episode's build
  derives from its seed (the surrounding drivers' sampled parameters, a lead's speed
  profile, starting positions) and the simulation's compiled arithmetic (fused
  multiply-adds, vectorised transcendental functions) may differ by a few units in the
  last place (ulps) between machines. :func:`score_sensitivity` emulates another
  machine by moving every such number of a built scenario by 1-4 ulps and measures how
  far the episode moves: over the 365 test episodes of the four built-in suites, twice
  each, scores moved by at most 3e-8 points (``ppo-acc``; the linear ACC 6e-10, the
  other built-ins 1e-11), ego speeds by at most 5e-8 m/s, and no verdict changed
  (``python benchmarks/reproducibility.py --json --controller NAME``). The tolerance
  promised for a score is :data:`SCORE_TOLERANCE` (1e-6 points, a margin of 30 over the
  worst measured; a verdict, qualified or not, is expected to be the same). The
  emulation moves inputs, not each step's arithmetic, so it bounds what the inputs do,
  not every difference a CPU can make.

The score's one comparison that a last bit could flip has a tolerance: a scripted lead
that cruises exactly at the ego's set speed would be "faster than the set speed" or not
by its last bit (a linear-ACC car-following/120 score moved by 34 points on it), so the
comparison allows 1e-6 m/s (:data:`acc_gym.evaluation.scoring.SPEED_TOL`).
"""

from __future__ import annotations

import numpy as np

SCORE_TOLERANCE = 1e-6  # [points] how far a score may differ between machines
# A scenario's nominal values, not derived from random draws: kept as they are.
NOMINAL_KEYS = ("params", "dt", "duration", "set_speed", "time_gap", "times", "road", "length", "width")


def perturb_ulps(obj, rng: np.random.Generator, skip=NOMINAL_KEYS, max_ulps: int = 4):
    """``obj`` (nested dicts / lists of numbers, e.g. a scenario's ``to_dict()``) with every
    non-zero finite float moved by 1 to ``max_ulps`` units in the last place, up or down
    at random; values under the keys in ``skip`` are kept as they are."""
    if isinstance(obj, dict):
        return {k: (v if k in skip else perturb_ulps(v, rng, skip, max_ulps)) for k, v in obj.items()}
    if isinstance(obj, list):
        return [perturb_ulps(v, rng, skip, max_ulps) for v in obj]
    if isinstance(obj, float) and np.isfinite(obj) and obj != 0.0:
        x = np.float64(obj)
        direction = np.inf if rng.random() < 0.5 else -np.inf
        for _ in range(int(rng.integers(1, max_ulps + 1))):
            x = np.nextafter(x, direction)
        return float(x)
    return obj


def score_sensitivity(scenarios, controller, env_id: str, trials: int = 2, seed: int = 0) -> list[dict]:
    """Run ``controller`` on each scenario and on ``trials`` ulp-perturbed copies of it
    (:func:`perturb_ulps` of everything but its nominal values); one row per copy with
    the score change, the largest ego speed change over the steps both ran, whether the
    episode's length changed (a collision one step earlier or later ends it) and whether
    the verdict changed."""
    import gymnasium as gym

    import acc_gym  # noqa: F401  (registers the ids)
    from acc_gym.evaluation.runner import load_controller, run_episode
    from acc_gym.scenarios.spec import Scenario

    policy = load_controller(controller)
    rng = np.random.default_rng(seed)
    env = gym.make(env_id)
    rows = []
    try:
        for k, sc in enumerate(scenarios):
            info, trace = run_episode(env, policy, scenario=sc)
            for _ in range(int(trials)):
                other = Scenario.from_dict(perturb_ulps(sc.to_dict(), rng))
                info2, trace2 = run_episode(env, policy, scenario=other)
                n = min(len(trace.v), len(trace2.v))
                rows.append({"episode": k, "id": sc.id, "score": float(info["score"]),
                             "score_change": abs(float(info2["score"]) - float(info["score"])),
                             "speed_change": float(np.max(np.abs(trace2.v[:n, 0] - trace.v[:n, 0]))),
                             "length_changed": len(trace.v) != len(trace2.v),
                             "verdict_changed": bool(info["qualified"]) != bool(info2["qualified"])})
    finally:
        env.close()
    return rows
