"""``acc-gym driver-demo``: an MPC human-like driver behind a lead that accelerates, cruises,
brakes to a stop and pulls away, and what the driver did (:mod:`acc_gym.drivers.mpc`)."""

from __future__ import annotations

import numpy as np


def add_parser(sub) -> None:
    p = sub.add_parser("driver-demo", help="simulate an MPC human-like driver and print what it did")
    p.add_argument("--driver", default="#57", help="paper 001 Table 4 preset: #23, #57, #61 or #13")
    p.add_argument("--speed", type=float, default=25.0, help="the lead's cruise speed [m/s]")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def run(args, parser) -> int:
    import json

    try:
        summary = driver_demo(args.driver, args.speed)
    except ValueError as exc:
        parser.error(str(exc))
    if args.json:
        print(json.dumps(summary))
    else:
        _print_driver_demo(summary)
    return 0


def _segments(mode: np.ndarray, t: np.ndarray) -> list[tuple[str, float, float]]:
    from acc_gym.drivers.mpc import Mode

    out = []
    start = 0
    for k in range(1, len(mode) + 1):
        if k == len(mode) or mode[k] != mode[start]:
            out.append((Mode(int(mode[start])).name, float(t[start]), float(t[k - 1])))
            start = k
    return out


def driver_demo(driver: str = "#57", speed: float = 25.0) -> dict:
    """Run the MPC driver demo and return its summary (what ``acc-gym driver-demo --json`` prints)."""
    import time

    from acc_gym.drivers.mpc import MPCDriver, SolvePath, preset
    from acc_gym.simulation.profiles import SpeedProfile
    from acc_gym.simulation.rollout import simulate_column

    if not (np.isfinite(speed) and 5.0 <= speed <= 40.0):
        raise ValueError(f"--speed must be within [5, 40] m/s, got {speed!r}")
    params = preset(driver, v_desired=speed + 3.0)
    lead = SpeedProfile.from_segments(0.0, [(0.0, 3.0), (1.5, speed / 1.5), (0.0, 25.0), (-2.0, speed / 2.0),
                                            (0.0, 10.0), (1.0, 10.0), (0.0, 15.0)])
    from acc_gym.drivers.base import Observation

    mpc = MPCDriver(params)
    t0 = time.perf_counter()
    mpc.act(Observation.build(v=10.0, a=0.0, gap=30.0, v_lead=10.0))  # loads (first run: compiles) the kernel
    ready = time.perf_counter() - t0
    gap0 = float(params.x_min)
    t0 = time.perf_counter()
    tr = simulate_column(lead, [mpc], [gap0 + 4.7, 0.0], [0.0, 0.0])
    wall = time.perf_counter() - t0
    mode = tr.mode[1:, 1]
    t = tr.t[1:]
    jerk = np.diff(tr.a[:, 1]) / (tr.t[1] - tr.t[0])
    stats = {k: int(v[0]) for k, v in mpc.stats.items()}
    return {
        "driver": driver if driver.startswith("#") else f"#{driver}",
        "duration_s": float(tr.t[-1]),
        "modes": [{"mode": m, "from_s": a, "to_s": b} for m, a, b in _segments(mode, t)],
        "min_gap_m": float(tr.gap[:, 1].min()),
        "x_min_m": float(params.x_min),
        "final_gap_m": float(tr.gap[-1, 1]),
        "max_speed_mps": float(tr.v[:, 1].max()),
        "max_accel_mps2": float(tr.a[:, 1].max()),
        "min_accel_mps2": float(tr.a[:, 1].min()),
        "max_abs_jerk_mps3": float(np.abs(jerk).max()),
        "collided": bool(tr.collided[1]),
        "solver": stats,
        "solve_paths": {p.name.lower(): int(np.sum(tr.path[1:, 1] == p)) for p in SolvePath},
        "wall_time_s": wall,
        "kernel_ready_s": ready,
    }


def _print_driver_demo(s: dict) -> None:
    print(f"MPC human-like driver {s['driver']} behind a lead that accelerates, cruises, brakes to a stop "
          f"and pulls away ({s['duration_s']:.0f} s at 5 Hz)")
    print("modes:")
    for seg in s["modes"]:
        print(f"  {seg['from_s']:6.1f} - {seg['to_s']:6.1f} s  {seg['mode']}")
    print(f"gap: min {s['min_gap_m']:.2f} m (x_min {s['x_min_m']:.2f} m), final {s['final_gap_m']:.2f} m; "
          f"collision: {'yes' if s['collided'] else 'no'}")
    print(f"speed max {s['max_speed_mps']:.1f} m/s; acceleration {s['min_accel_mps2']:.2f} .. "
          f"{s['max_accel_mps2']:.2f} m/s^2; max |jerk| {s['max_abs_jerk_mps3']:.2f} m/s^3")
    paths = ", ".join(f"{k} {v}" for k, v in s["solve_paths"].items())
    print(f"QP steps: {paths}; fallbacks {s['solver']['fallback']}; simulated in {s['wall_time_s'] * 1e3:.0f} ms")
    if s["kernel_ready_s"] > 1.0:
        print(f"(the driver kernel took {s['kernel_ready_s']:.1f} s to compile; numba caches it for later runs)")
