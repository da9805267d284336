"""Speed of the MPC human-like driver: one driver step, and a batch of 1024 drivers.

Closed loop: the driver follows a lead that accelerates, cruises, brakes hard to a stop,
stands, pulls away again and cruises (about 110 s at 5 Hz), repeated ``--repeats``
times (each a fresh episode: the driver is reset, its solver workspaces start cold).

Prints the per-step cost of one driver (the whole ``act`` call: input checks, targets,
mode logic and the QP), as median / p99 / max in microseconds next to the paper's
figures (MATLAB quadprog on an i9-11900: 920 us mean, 22 ms max), the share of steps
with an active constraint, the share of each solve path, and the batched throughput
of 1024 drivers (sampled typical drivers, each behind its own copy of the lead) in
vehicle-steps per second.

    python benchmarks/bench_driver.py            # table
    python benchmarks/bench_driver.py --json     # one JSON object
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from acc_gym.drivers.mpc import MPCDriver, SolvePath, preset
from acc_gym.drivers.population import sample_drivers
from acc_gym.simulation.profiles import SpeedProfile
from acc_gym.simulation.rollout import simulate_column

PAPER_MEAN_US = 920.0
PAPER_MAX_US = 22000.0


def lead_profile() -> SpeedProfile:
    """Accelerate 10 -> 30 m/s, cruise, brake hard (-5 m/s^2) to a stop, stand, pull away, cruise."""
    return SpeedProfile.from_segments(10.0, [(0.0, 5.0), (1.5, 13.33), (0.0, 30.0), (-5.0, 8.0),
                                             (0.0, 10.0), (2.0, 10.0), (0.0, 30.0)])


class _Timed:
    """Wraps a driver and records the wall time of every ``act`` call."""

    def __init__(self, driver):
        self.driver = driver
        self.n = driver.n
        self.times: list[float] = []
        self.paths: list[np.ndarray] = []

    def reset(self):
        self.driver.reset()

    @property
    def info(self):
        return self.driver.info

    @property
    def stats(self):
        return self.driver.stats

    def act(self, obs):
        t0 = time.perf_counter()
        out = self.driver.act(obs)
        self.times.append(time.perf_counter() - t0)
        self.paths.append(self.driver.info["path"])
        return out


def _start(v_lead: float, c_tg, x_min, length: float = 4.7):
    gap = np.asarray(x_min) + np.asarray(c_tg) * v_lead
    return gap + length


def bench_single(repeats: int) -> dict:
    prof = lead_profile()
    driver = _Timed(MPCDriver(preset("#57", v_desired=32.0)))
    p = driver.driver.params
    x_lead = float(_start(10.0, p.c_tg[0], p.x_min[0]))
    simulate_column(prof, [driver], [x_lead, 0.0], [10.0, 10.0])  # warm-up: compilation, caches
    driver.times.clear()
    driver.paths.clear()
    for _ in range(repeats):
        simulate_column(prof, [driver], [x_lead, 0.0], [10.0, 10.0])
    t = np.array(driver.times) * 1e6
    paths = np.concatenate(driver.paths)
    active = np.isin(paths, [SolvePath.ACTIVE_SET, SolvePath.QP, SolvePath.FALLBACK])
    return {
        "driver_step_us_median": float(np.median(t)),
        "driver_step_us_p99": float(np.percentile(t, 99)),
        "driver_step_us_max": float(t.max()),
        "driver_step_us_mean": float(t.mean()),
        "steps": int(t.size),
        "active_share": float(active.mean()),
        "path_share": {p.name.lower(): float(np.mean(paths == p)) for p in SolvePath},
        "path_median_us": {p.name.lower(): float(np.median(t[paths == p])) for p in SolvePath if np.any(paths == p)},
    }


def bench_batch(n: int, repeats: int, seed: int) -> dict:
    rng = np.random.default_rng(seed)
    params = sample_drivers(rng, n, rng.uniform(28.0, 34.0, n))
    prof = lead_profile()
    driver = _Timed(MPCDriver(params))
    x_lead = _start(10.0, params.c_tg, params.x_min)
    x0 = np.stack([x_lead, np.zeros(n)], axis=1)
    v0 = np.full((n, 2), 10.0)
    # first episode: solver workspaces are built as drivers first meet constraints (cold)
    t0 = time.perf_counter()
    simulate_column(prof, [driver], x0, v0, batch=n)
    cold_wall = time.perf_counter() - t0
    cold_driver = float(np.sum(driver.times))
    driver.times.clear()
    driver.paths.clear()
    wall = []
    for _ in range(repeats):  # later episodes: workspaces kept across reset() (restarted cold-from-guess)
        t0 = time.perf_counter()
        simulate_column(prof, [driver], x0, v0, batch=n)
        wall.append(time.perf_counter() - t0)
    t = np.array(driver.times)
    steps = t.size // repeats
    per_run = t.reshape(repeats, steps).sum(axis=1)
    paths = np.concatenate(driver.paths)
    active = np.isin(paths, [SolvePath.ACTIVE_SET, SolvePath.QP, SolvePath.FALLBACK])
    return {
        "batch_size": n,
        "batch_vehicle_steps_per_s": float(n * steps / np.median(per_run)),
        "batch_rollout_vehicle_steps_per_s": float(n * steps / np.median(wall)),
        "batch_active_share": float(active.mean()),
        "batch_first_episode_vehicle_steps_per_s": float(n * steps / cold_driver),
        "batch_first_episode_rollout_vehicle_steps_per_s": float(n * steps / cold_wall),
        "batch_fallbacks": int(driver.stats["fallback"].sum()),
    }


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--repeats", type=int, default=5, help="episodes for the single-driver timing")
    ap.add_argument("--batch", type=int, default=1024, help="drivers stepped together")
    ap.add_argument("--batch-repeats", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    out = bench_single(args.repeats)
    out.update(bench_batch(args.batch, args.batch_repeats, args.seed))
    out["paper_mean_us"] = PAPER_MEAN_US
    out["paper_max_us"] = PAPER_MAX_US
    out["speedup_vs_paper_mean"] = PAPER_MEAN_US / out["driver_step_us_mean"]
    if args.json:
        print(json.dumps(out))
    else:
        print(f"one driver, {out['steps']} closed-loop steps ({args.repeats} episodes)")
        print(f"  step time  median {out['driver_step_us_median']:8.1f} us   p99 {out['driver_step_us_p99']:8.1f} us"
              f"   max {out['driver_step_us_max']:8.1f} us   mean {out['driver_step_us_mean']:8.1f} us")
        print(f"  paper (MATLAB quadprog, i9-11900): mean {PAPER_MEAN_US:.0f} us, max {PAPER_MAX_US:.0f} us"
              f"  -> mean {out['speedup_vs_paper_mean']:.0f}x faster")
        print(f"  steps with an active constraint: {100 * out['active_share']:.1f} %")
        print("  solve paths: " + ", ".join(f"{k} {100 * v:.1f} %" for k, v in out["path_share"].items()))
        print("  median step by path: " + ", ".join(f"{k} {v:.1f} us" for k, v in out["path_median_us"].items()))
        print(f"{args.batch} drivers stepped together: {out['batch_vehicle_steps_per_s']:,.0f} vehicle-steps/s "
              f"(driver only), {out['batch_rollout_vehicle_steps_per_s']:,.0f} with the whole rollout; "
              f"active share {100 * out['batch_active_share']:.1f} %, fallbacks {out['batch_fallbacks']}")
        print(f"  first episode (solver workspaces built on the way): "
              f"{out['batch_first_episode_vehicle_steps_per_s']:,.0f} vehicle-steps/s (driver only)")
    return out


if __name__ == "__main__":
    main()
