"""A hand-written ACC controller: evaluated with acc_gym's evaluator, then put on the leaderboard.

    python examples/hand_written_controller.py               # 20 episodes, then carfollowing-v1 and ncap-v1
    python examples/hand_written_controller.py --quick       # a few episodes of each (about 15 s)
    python examples/hand_written_controller.py --out board/  # also keep the leaderboard's files

A controller is any object with stable-baselines3's ``predict(obs, deterministic=True)``:
it gets the observation row and returns ``(action, state)``, the action a ``(1,)`` array
in [-1, 1] (``+1`` asks for the environment's ``accel_max``, 3 m/s^2; ``-1`` for its
``decel_max``, 8 m/s^2). The same class runs under ``acc-gym evaluate``, the leaderboard
and ``acc-gym string-stability``::

    acc-gym evaluate hand_written_controller:TimeGapACC --env acc_gym/CarFollowing-v1 --episodes 20   # from examples/
    acc-gym leaderboard --controllers acc hand_written_controller:TimeGapACC

The leaderboard runs each controller in its own sandboxed process and loads it there by
reference (``"module:attribute"``), so the class lives in an importable module (this
file; the sandbox gets this process's ``sys.path``) and the leaderboard call sits under
``if __name__ == "__main__":`` (the sandbox starts fresh interpreters).
"""

from __future__ import annotations

import argparse
import sys
import tempfile

import numpy as np

ACCEL_MAX, DECEL_MAX = 3.0, 8.0  # [m/s^2] what the action's ends ask for (acc_gym.envs.EnvConfig's defaults)


class TimeGapACC:
    """Hold the driver's set time gap behind a lead, cruise at the set speed without one.

    The first seven observation fields are the same on every id (``-v1`` appends more):
    speed [m/s], acceleration [m/s^2], gap [m], relative speed (lead minus ego) [m/s],
    lead in range (0 or 1), set speed [m/s], set time gap [s].
    """

    def __init__(self, k_gap: float = 0.25, k_speed: float = 0.7, standstill: float = 4.0):
        self.k_gap, self.k_speed, self.standstill = k_gap, k_speed, standstill

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        v, _, gap, dv, in_range, v_set, tau = (float(x) for x in np.asarray(obs)[:7])
        cruise = 0.5 * (v_set - v)  # approach the set speed
        if in_range > 0.5:
            # constant time-gap policy: the gap error and the closing speed, never faster than cruising
            follow = self.k_gap * (gap - self.standstill - tau * v) + self.k_speed * dv
            a = min(cruise, follow)
        else:
            a = cruise
        # desired acceleration [m/s^2] -> the env's action in [-1, 1] (asymmetric ends)
        action = a / ACCEL_MAX if a >= 0 else a / DECEL_MAX
        return np.clip(np.array([action], dtype=np.float32), -1.0, 1.0), state


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a few episodes only (the test runs this)")
    parser.add_argument("--out", default=None, help="keep the leaderboard's files here (default: a temporary "
                                                    "directory)")
    args = parser.parse_args(argv)

    from acc_gym.evaluation.runner import evaluate
    from acc_gym.leaderboard import run_leaderboard
    from acc_gym.leaderboard.results import text_table

    # 1. The evaluator: car-following traffic (paper 003's test among it), scored by paper 003's
    #    100-point criteria. The object itself is passed (a name or "module:attribute" works too).
    summary = evaluate(TimeGapACC(), env_id="acc_gym/CarFollowing-v1", episodes=2 if args.quick else 20, seed=0)
    print(f"evaluate: mean score {summary['mean_score']:.1f} / 100, qualified "
          f"{summary['share_qualified']:.0%}, collisions {summary['collisions']} in {summary['episodes']} episodes")

    # 2. The leaderboard: beside the built-in linear ACC on two versioned suites (test split).
    #    The controller is given by reference and loaded in its own process.
    out = args.out or tempfile.mkdtemp(prefix="acc-gym-example-")
    results = run_leaderboard(["carfollowing-v1", "ncap-v1"], "test", ["acc", "hand_written_controller:TimeGapACC"],
                              out=out, workers=1 if args.quick else 2, episodes=2 if args.quick else None,
                              report=not args.quick, string_stability=not args.quick)
    print(text_table(results))
    for entry in results["controllers"]:
        if entry["status"] == "ok":
            print(f"leaderboard: {entry['name']} rank {entry['rank']}, mean points "
                  f"{entry['summary']['overall']['mean_points']:.1f}")
        else:
            print(f"leaderboard: {entry['name']} failed: {entry['reason']}")
    print(f"leaderboard files: {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
