"""A custom scenario: a recorded lead speed trace (CSV) in front of the controller under test.

    python examples/custom_scenario_from_csv.py                                   # examples/data/lead_trace.csv
    python examples/custom_scenario_from_csv.py --trace my_drive.csv --controllers acc idm mymodule:MyACC
    python examples/custom_scenario_from_csv.py --quick                           # the test's run (a few seconds)

The CSV has a header and columns ``t`` [s] and ``v`` [m/s] (more columns are ignored):
the format of ``acc-gym string-stability --lead-trace FILE.csv``, read by the same
function. The steps:

1. the trace becomes a :class:`SpeedProfile` (``SpeedProfile.recorded(t, v)``: linear
   between samples);
2. a built-in scenario gives the road, the ego and the lead's starting gap
   (``singlelane/2/car-following``: the ego follows one vehicle in its lane, its set speed
   the ego's initial speed), with the trace's duration and start speed as parameters;
3. ``Scenario.with_driver("POV", profile)`` replaces the lead's driver by the trace
   (the scenario's ``drivers`` becomes ``"custom"``); the scenario is a plain value, saved
   as JSON and read back;
4. each controller drives it in ``acc_gym/SingleLane-v1`` (``reset(options={"scenario":
   sc})`` under the hood) and the episode is scored by paper 003's criteria.

The same trace drives a column for string stability::

    acc-gym string-stability acc --lead-trace examples/data/lead_trace.csv
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trace", default=str(HERE / "data" / "lead_trace.csv"), help="CSV with columns t, v")
    parser.add_argument("--controllers", nargs="+", default=["acc", "idm", "constant"],
                        help="names, module:attribute or saved models (default: acc idm constant)")
    parser.add_argument("--gap", type=float, default=None, help="initial bumper gap [m] (default: 1.5 s at the "
                                                                "trace's first speed, at least 10 m)")
    parser.add_argument("--out", default=None, help="where the scenario's JSON goes (default: a temporary "
                                                    "directory)")
    parser.add_argument("--quick", action="store_true", help="the trace's first 30 s and one controller (the "
                                                             "test runs this)")
    args = parser.parse_args(argv)

    import gymnasium as gym
    import numpy as np

    import acc_gym  # noqa: F401  (registers the ids)
    from acc_gym import scenarios
    from acc_gym.evaluation.runner import run_episode
    from acc_gym.evaluation.string_stability import lead_trace
    from acc_gym.simulation.profiles import SpeedProfile

    # 1. The recorded trace (the CLI's reader: it names a bad file, line or column).
    profile = lead_trace(args.trace)
    if args.quick:
        keep = profile.times <= profile.times[0] + 30.0
        profile = SpeedProfile.recorded(profile.times[keep], profile.speeds[keep])
    profile = SpeedProfile.recorded(profile.times - profile.times[0], profile.speeds)  # the scenario starts at t = 0
    v0 = float(profile.speeds[0])
    print(f"trace: {len(profile.times)} samples over {profile.duration:.1f} s, speed {profile.speeds.min():.1f}-"
          f"{profile.speeds.max():.1f} m/s")

    # 2.-3. A built-in scenario laid out for the trace, then the lead replaced by it.
    gap = args.gap if args.gap is not None else max(10.0, 1.5 * v0)
    base = scenarios.build("singlelane/2/car-following",
                           {"v_sv": v0, "gap": gap, "v_rel": 0.0, "duration": profile.duration}, seed=0)
    sc = base.with_driver("POV", profile)
    out = Path(args.out or tempfile.mkdtemp(prefix="acc-gym-scenario-"))
    out.mkdir(parents=True, exist_ok=True)
    path = out / "recorded_lead.json"
    path.write_text(sc.to_json(), encoding="utf-8")
    sc = scenarios.Scenario.from_json(path.read_text(encoding="utf-8"))  # a plain, schema-versioned value
    print(f"scenario: {sc.id} with a recorded lead (drivers={sc.drivers!r}), {sc.duration:.1f} s, "
          f"start gap {gap:.1f} m, set speed {sc.set_speed:.1f} m/s -> {path}")

    # 4. Each controller drives the scenario in the single-lane environment and is scored.
    env = gym.make("acc_gym/SingleLane-v1")
    try:
        for ref in args.controllers[:1] if args.quick else args.controllers:
            info, trace = run_episode(env, ref, scenario=sc, seed=0)
            report = info["report"]
            gaps = trace.gap[:, 0, 0]  # the ego's bumper gap to the vehicle ahead, every step
            print(f"{ref}: score {report['score']:.1f} / 100, qualified {report['qualified']}, "
                  f"collision {bool(report['metrics']['collision'])}, smallest gap {np.nanmin(gaps):.1f} m")
    finally:
        env.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
