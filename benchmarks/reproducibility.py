"""How far suite episodes' scores move when their derived numbers move by a few last bits.

Emulates another machine (see :mod:`acc_gym.reproducibility`): every float of each
built suite episode except its stored parameters and nominal values is moved by 1-4
units in the last place, and the controller runs on the original and the perturbed
episode. Prints the largest and median score change, the largest ego speed change and
the number of verdicts (qualified or not) that changed; the tolerance promised for
scores across machines (``acc_gym.reproducibility.SCORE_TOLERANCE``) rests on it.

    python benchmarks/reproducibility.py --json [--per-suite N] [--trials 2] [--controller acc]
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from acc_gym.reproducibility import SCORE_TOLERANCE, score_sensitivity
from acc_gym.suites import get_suite, list_suites


def measure(per_suite: int | None, trials: int, controller: str, seed: int) -> dict:
    rows = []
    for name in list_suites():
        suite = get_suite(name)
        episodes = suite.episodes("test")[:per_suite]
        rows += [dict(r, suite=name) for r in score_sensitivity(episodes, controller, suite.env_id, trials, seed)]
    changes = np.array([r["score_change"] for r in rows])
    return {"controller": controller, "episodes": len(rows) // trials, "trials": trials,
            "max_score_change": float(changes.max()), "median_score_change": float(np.median(changes)),
            "max_speed_change": max(r["speed_change"] for r in rows),
            "lengths_changed": sum(r["length_changed"] for r in rows),
            "verdicts_changed": sum(r["verdict_changed"] for r in rows), "score_tolerance": SCORE_TOLERANCE,
            "worst": sorted(rows, key=lambda r: -r["score_change"])[:3]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--per-suite", type=int, default=None, help="first N test episodes of each suite (default all)")
    ap.add_argument("--trials", type=int, default=2, help="perturbed copies of each episode (default 2)")
    ap.add_argument("--controller", default="acc")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args(argv)
    out = measure(args.per_suite, args.trials, args.controller, args.seed)
    if args.json:
        print(json.dumps(out))
        return 0
    for key, value in out.items():
        if key != "worst":
            print(f"{key:20s} {value}")
    for r in out["worst"]:
        print(f"  {r['suite']} #{r['episode']} {r['id']}: score {r['score']:.6f}, change {r['score_change']:.3g}, "
              f"largest speed change {r['speed_change']:.3g} m/s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
