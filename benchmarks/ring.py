"""Ring-road benchmark (acc_gym.simulation.ring, acc_gym.evaluation.waves): the field's cases
and the simulation's speed. Seeds 1000-1009 (the tests use none of them); every seed reported.

* Sugiyama: 22 naturalistic human-like drivers on 230 m, uniform start from rest, 600 s:
  jam yes/no, onset, wave speed, speed sd (target: a jam within 300 s on >= 9 of 10 seeds,
  the wave backward at 12-25 km/h).
* density: the same 22 drivers on 1,500 m (target: no jam, speed sd < 0.5 m/s).
* Stern: one follower-stopper (and, separately, one pi-saturation) among 21 human drivers on
  260 m against 22 human drivers, the same seeds (target: speed sd down >= 50 %, no collision);
  braking events and energy. The follower-stopper's commanded speed ``U`` is the all-human
  ring's mean speed on the same seed (Stern et al.'s experimenters set ``U`` from the speed the
  ring was driving); PI-saturation finds its own from its speed history.
* timings (CPU seconds, process time, and wall): 10 minutes of one 22-vehicle ring (the median of
  ``--repeats`` runs, each run listed); 100 rings at once (``--timing-rings``, ``--timing-duration``
  make both cheaper; the keys keep their names and record ``rings`` and ``duration_s``).
* ``--timing-only``: the timings alone. ``--against DIR``: the timings of this checkout and of the
  checkout in DIR (e.g. the previous release: ``git worktree add /tmp/prev v0.31.0``), one subprocess
  each, alternating ``--repeats`` times, with the medians and their ratios (``against``:
  ``{key: {"this", "other", "ratio", "paired_ratio", "this_runs", "other_runs"}}``, CPU seconds).

    python benchmarks/ring.py --json
    python benchmarks/ring.py --timing-only --against /tmp/prev --repeats 3 --json
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

from acc_gym.evaluation.waves import WARMUP, ring_waves
from acc_gym.simulation.ring import controlled_positions, ring_layout, simulate_ring

SEEDS = tuple(range(1000, 1010))


def _rings(length, seeds, duration, controller=None):
    layout = ring_layout(22, controlled_positions(22, None) if controller is not None else ())
    tr = simulate_ring(length, 22, layout=layout, seeds=list(seeds), duration=duration, controller=controller)
    after = tr.t >= WARMUP
    # how fast vehicles leave the jam (Sugiyama's: up to about 40 km/h): the 95th percentile of
    # every vehicle's speed after the warm-up
    return [dict(seed=s, leave_speed_kmh=3.6 * float(np.percentile(tr.v[after, b], 95)), **w.to_dict())
            for b, (s, w) in enumerate(zip(seeds, ring_waves(tr)))]


def _timed(fn):
    c, w = time.process_time(), time.perf_counter()
    out = fn()
    return out, time.process_time() - c, time.perf_counter() - w


TIMINGS = ("timing_one_ring_10min", "timing_100_rings_10min")


def timings(rings: int = 100, duration: float = 600.0, repeats: int = 1) -> dict:
    """CPU and wall seconds of one 22-vehicle ring (median of ``repeats`` runs after a short
    warm-up run) and of ``rings`` rings at once, each over ``duration`` seconds of traffic."""
    simulate_ring(230.0, 22, seeds=[2000], duration=10.0)  # the kernels compiled or loaded
    one = [_timed(lambda: simulate_ring(230.0, 22, seeds=[2000], duration=duration))[1:] for _ in range(repeats)]
    _, cpu, wall = _timed(lambda: simulate_ring(230.0, 22, seeds=list(range(2000, 2000 + rings)), duration=duration))
    return {TIMINGS[0]: {"cpu_s": float(np.median([c for c, _ in one])), "wall_s": float(np.median([w for _, w in one])),
                         "cpu_runs": [c for c, _ in one], "target_s": 2.0, "rings": 1, "duration_s": duration},
            TIMINGS[1]: {"cpu_s": cpu, "wall_s": wall, "target_s": 30.0, "rings": rings, "duration_s": duration}}


def against(args) -> dict:
    """This checkout's timings and ``args.against``'s, alternating, one subprocess each per repeat."""
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from bench_env import paired_ratio

    cmd = [sys.executable, os.path.abspath(__file__), "--timing-only", "--json", "--repeats", "1",
           "--timing-rings", str(args.timing_rings), "--timing-duration", str(args.timing_duration)]
    other_env = {**os.environ, "PYTHONPATH": os.path.abspath(args.against)}
    runs: dict = {"this": [], "other": []}
    for _ in range(args.repeats):
        for who, env in (("this", None), ("other", other_env)):
            r = subprocess.run(cmd, capture_output=True, text=True, check=True, env=env,
                               cwd=os.path.dirname(os.path.abspath(__file__)))
            runs[who].append(json.loads(r.stdout.strip().splitlines()[-1]))
    table = {}
    for k in TIMINGS:
        this_runs, other_runs = [r[k]["cpu_s"] for r in runs["this"]], [r[k]["cpu_s"] for r in runs["other"]]
        this, other = float(np.median(this_runs)), float(np.median(other_runs))
        table[k] = {"this": this, "other": other, "ratio": this / other,
                    "paired_ratio": paired_ratio(this_runs, other_runs), "this_runs": this_runs,
                    "other_runs": other_runs}
    return {"against": table, "against_dir": os.path.abspath(args.against), "repeats": args.repeats}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--duration", type=float, default=600.0)
    ap.add_argument("--skip-timing", action="store_true")
    ap.add_argument("--timing-only", action="store_true", help="only the timings")
    ap.add_argument("--timing-rings", type=int, default=100, help="rings of the batch timing")
    ap.add_argument("--timing-duration", type=float, default=600.0, help="simulated seconds of each timing")
    ap.add_argument("--repeats", type=int, default=1, help="runs of the one-ring timing (or --against pairs)")
    ap.add_argument("--against", default=None, metavar="DIR", help="also time the checkout in DIR, alternating")
    args = ap.parse_args(argv)
    if args.repeats < 1 or args.timing_rings < 1 or not args.timing_duration > 0:
        ap.error("--repeats and --timing-rings must be >= 1, --timing-duration > 0")
    if args.against:
        out = against(args)
        print(json.dumps(out) if args.json else "\n".join(
            f"{k}: this {row['this']:.2f} s, other {row['other']:.2f} s, ratio {row['ratio']:.2f}"
            for k, row in out["against"].items()))
        return out
    if args.timing_only:
        out = timings(args.timing_rings, args.timing_duration, args.repeats)
        print(json.dumps(out) if args.json else "\n".join(f"{k} {v}" for k, v in out.items()))
        return out
    from acc_gym_agents.controllers import FollowerStopper, PISaturation

    out: dict = {"seeds": list(SEEDS), "duration_s": args.duration}
    sug = _rings(230.0, SEEDS, args.duration)
    out["sugiyama"] = {"rings": sug, "jams": sum(r["jam"] for r in sug),
                       "jams_within_300s": sum(bool(r["jam"] and r["jam_onset_s"] <= 300) for r in sug)}
    dens = _rings(1500.0, SEEDS, args.duration)
    out["density_1500m"] = {"rings": dens, "jams": sum(r["jam"] for r in dens),
                            "max_speed_sd": max(r["speed_sd"] for r in dens)}
    human = _rings(260.0, SEEDS, args.duration)
    stern = {"human": human}
    for name in ("follower-stopper", "pi-saturation"):
        if name == "follower-stopper":  # U set by the experimenters: the all-human ring's mean speed there
            rings = [_rings(260.0, [h["seed"]], args.duration, controller=FollowerStopper(v_des=h["mean_speed"]))[0]
                     for h in human]
        else:
            rings = _rings(260.0, SEEDS, args.duration, controller=PISaturation())
        for r, h in zip(rings, human):
            r["speed_sd_ratio"] = r["speed_sd"] / h["speed_sd"] if h["speed_sd"] > 0 else None
        stern[name] = rings
    out["stern_260m"] = stern
    if not args.skip_timing:
        out.update(timings(args.timing_rings, args.timing_duration, args.repeats))
    if args.json:
        print(json.dumps(out))
    else:
        for case in ("sugiyama", "density_1500m"):
            print(case, "jams", out[case]["jams"], "of", len(SEEDS))
            for r in out[case]["rings"]:
                print(f"  seed {r['seed']}: jam {r['jam']} onset {r['jam_onset_s']} wave {r['wave_speed_kmh']} "
                      f"sd {r['speed_sd']:.3f} mean {r['mean_speed']:.2f}")
        for name, rings in stern.items():
            print("stern", name, [round(r["speed_sd"], 3) for r in rings])
        for k in ("timing_one_ring_10min", "timing_100_rings_10min"):
            if k in out:
                print(k, out[k])
    return out


if __name__ == "__main__":
    main()
