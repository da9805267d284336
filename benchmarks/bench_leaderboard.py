"""Leaderboard speed: the default leaderboard's wall time, and the controller pipe's cost.

* ``leaderboard_wall_s``: ``acc-gym leaderboard`` as a user runs it (every built-in and
  the shipped policy, the four suites, test split, report included), in a fresh
  process, median of ``--repeats`` runs. With ``--against DIR`` (another checkout of
  acc_gym, e.g. a ``git worktree`` of the previous release) the two run alternately and
  ``ratio`` is this one's median over the other's (below 1: faster).
* ``pipe_us_per_round_trip`` / ``pipe_us_per_row``: the cost of the trust boundary alone:
  the trusted side sends ``--rows`` observation rows to a sandboxed ``constant``
  controller and waits for its actions, ``--round-trips`` times; median per round trip
  and per row (one controller step).

    python benchmarks/bench_leaderboard.py --json [--repeats 3] [--against ../previous]

A quick run (what ``tests/test_benchmarks.py`` checks; the figures then mean little)::

    python benchmarks/bench_leaderboard.py --json --repeats 1 --round-trips 20 \
        --leaderboard-args "--suite ncap-v1 --controllers constant --episodes 1 --no-report"
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def leaderboard_once(source: Path, extra: list[str]) -> float:
    out = tempfile.mkdtemp(prefix="acc-gym-bench-lb-")
    env = dict(os.environ, PYTHONPATH=str(source))
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", "import sys; from acc_gym.cli import main; sys.exit(main(sys.argv[1:]))",
                    "leaderboard", "--out", os.path.join(out, "board"), *extra], env=env, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=out)
    return time.perf_counter() - t0


def pipe_cost(rows: int, round_trips: int) -> tuple[float, float]:
    from acc_gym.leaderboard import protocol
    from acc_gym.leaderboard.sandbox import ControllerProcess

    log = tempfile.NamedTemporaryFile(suffix=".log", delete=False)
    ctl = ControllerProcess("constant", log_path=log.name, budget=600.0, uid=None)
    try:
        protocol.recv_hello(ctl.sock, time.monotonic() + 120)
        obs = np.tile(np.array([20.0, 0.0, 50.0, 0.0, 1.0, 25.0, 1.5]), (rows, 1))
        slots = np.arange(rows)
        starts = np.ones(rows, dtype=bool)
        times = []
        for k in range(round_trips + 10):
            t0 = time.perf_counter()
            protocol.send_observations(ctl.sock, obs, starts if k == 0 else ~starts, slots)
            protocol.recv_actions(ctl.sock, rows, None)
            if k >= 10:  # after a warm-up
                times.append(time.perf_counter() - t0)
    finally:
        ctl.close()
        os.unlink(log.name)
    per_trip = statistics.median(times) * 1e6
    return per_trip, per_trip / rows


def constant_predict_us(rows: int, repeats: int = 2000) -> float:
    """What the controller side spends in ``predict`` itself per row (to subtract)."""
    from acc_gym.evaluation.runner import load_controller

    c = load_controller("constant")
    o = np.array([20.0, 0.0, 50.0, 0.0, 1.0, 25.0, 1.5], dtype=np.float32)
    t0 = time.perf_counter()
    for _ in range(repeats):
        c.predict(o, deterministic=True)
    return (time.perf_counter() - t0) / repeats * 1e6


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="leaderboard runs per version (default 3)")
    ap.add_argument("--against", type=Path, default=None, help="another acc_gym checkout to time alternately")
    ap.add_argument("--leaderboard-args", default="", help="extra arguments for acc-gym leaderboard (quoted)")
    ap.add_argument("--rows", type=int, default=16, help="rows per round trip for the pipe figure (default 16)")
    ap.add_argument("--round-trips", type=int, default=2000)
    ap.add_argument("--skip-leaderboard", action="store_true", help="only the pipe figures")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args(argv)
    out: dict = {}
    per_trip, per_row = pipe_cost(args.rows, args.round_trips)
    out.update(pipe_rows=args.rows, pipe_us_per_round_trip=per_trip, pipe_us_per_row=per_row,
               predict_us_per_row=constant_predict_us(args.rows))
    if not args.skip_leaderboard:
        extra = args.leaderboard_args.split()
        mine, theirs = [], []
        for _ in range(args.repeats):
            mine.append(leaderboard_once(ROOT, extra))
            if args.against is not None:
                theirs.append(leaderboard_once(args.against.resolve(), extra))
        out.update(leaderboard_wall_s=statistics.median(mine), leaderboard_wall_s_runs=mine)
        if theirs:
            out.update(against=str(args.against), against_wall_s=statistics.median(theirs),
                       against_wall_s_runs=theirs, ratio=statistics.median(mine) / statistics.median(theirs))
    if args.json:
        print(json.dumps(out))
    else:
        for key, value in out.items():
            print(f"{key:26s} {value}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
