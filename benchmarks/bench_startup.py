"""What a fresh Python process pays before its first step: the cost every leaderboard
controller, campaign worker and CLI call pays again.

Each case is timed as a new interpreter (``sys.executable -c ...``), wall clock from
spawn to exit, the cases alternating within each of ``--repeats`` rounds after one
warm-up round (the OS file cache and numba's on-disk cache warm):

==============================  =========================================================
key (medians, [s])              the process
==============================  =========================================================
``startup_import_s``            ``import acc_gym``
``startup_env_s``               ``gymnasium.make("acc_gym/SingleLane-v1")``, ``reset``, one
                                ``step`` (numba's cached kernels loaded)
``startup_env_scipy_integrate`` the same with ``scipy.integrate`` imported first: what every
``_s``                          process paid before acc-gym 0.18.0 imported it only where it
                                is used (the bivariate law's box mass)
==============================  =========================================================

``scipy_integrate_cost_s`` is the difference of the last two medians. ``--json`` prints the
numbers (and every run) as JSON.

    python benchmarks/bench_startup.py --repeats 7
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time

ENV = ("import gymnasium as gym, acc_gym\n"
       "env = gym.make('acc_gym/SingleLane-v1')\n"
       "env.reset(seed=0)\n"
       "env.step(env.action_space.sample())\n")
CASES = {
    "startup_import_s": "import acc_gym\n",
    "startup_env_s": ENV,
    "startup_env_scipy_integrate_s": "import scipy.integrate\n" + ENV,
}


def run_once(code: str) -> float:
    """Wall time [s] of one fresh interpreter running ``code`` (an error is raised, not timed)."""
    t = time.perf_counter()
    subprocess.run([sys.executable, "-W", "ignore", "-c", code], check=True, capture_output=True)
    return time.perf_counter() - t


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=7, help="timed rounds (each case once per round)")
    ap.add_argument("--json", action="store_true", help="print the numbers as JSON")
    args = ap.parse_args(argv)
    if args.repeats < 1:
        ap.error(f"--repeats must be >= 1, got {args.repeats}")
    for code in CASES.values():  # warm-up round
        run_once(code)
    runs = {key: [] for key in CASES}
    for _ in range(args.repeats):
        for key, code in CASES.items():
            runs[key].append(run_once(code))
    out = {key: statistics.median(v) for key, v in runs.items()}
    out["scipy_integrate_cost_s"] = out["startup_env_scipy_integrate_s"] - out["startup_env_s"]
    out.update({f"{key}_runs": v for key, v in runs.items()})
    out["repeats"] = args.repeats
    if args.json:
        print(json.dumps(out))
    else:
        for key in (*CASES, "scipy_integrate_cost_s"):
            print(f"{key:32s} {out[key]:.3f} s")
    return out


if __name__ == "__main__":
    main()
