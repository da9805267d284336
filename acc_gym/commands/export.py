"""``acc-gym export``: write a scenario of the package, as driven, as ASAM OpenSCENARIO 1.2 on
an OpenDRIVE straight road (:mod:`acc_gym.scenarios.openscenario.writer`; the ``osc`` extra)."""

from __future__ import annotations

import json

DEFAULT_DRIVER = "acc"  # drives the ego when no --controller is given (its motion is then not written)


def add_parser(sub) -> None:
    p = sub.add_parser("export", help="write a scenario (an id with a seed, or a scenario JSON file) as driven, as "
                                      "OpenSCENARIO 1.2 and OpenDRIVE (needs the osc extra)")
    p.add_argument("scenario", help="a scenario id (acc-gym scenarios lists them) or a scenario's JSON file "
                                    "(acc-gym scenarios ID --json prints one)")
    p.add_argument("--seed", type=int, default=0, help="the scenario's seed (for an id; default 0)")
    p.add_argument("--drivers", default="typical", help="surrounding drivers (for an id; default typical)")
    p.add_argument("--controller", default=None,
                   help="the ego's controller; its drive is written too, for a replay in other tools (default: the "
                        f"surrounding traffic is recorded with {DEFAULT_DRIVER!r} as the ego and only the ego's "
                        f"initial state is written)")
    p.add_argument("--out", required=True, help="the directory to write NAME.xosc and NAME.xodr into")
    p.add_argument("--name", default=None, help="the files' name (default: the scenario id and seed)")
    p.add_argument("--no-check", action="store_true", help="do not run ASAM's checker on the file written")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def run(args, parser) -> int:
    """Exit 0 when written (and passing ASAM's checker), 1 when the checker finds an issue,
    2 for bad input."""
    from pathlib import Path

    from acc_gym import scenarios
    from acc_gym.scenarios.openscenario.writer import export
    from acc_gym.scenarios.spec import Scenario

    try:
        if args.scenario.endswith(".json") or Path(args.scenario).is_file():
            path = Path(args.scenario)
            if not path.is_file():
                raise ValueError(f"no such scenario file: {path}")
            sc = Scenario.from_json(path.read_text())
        else:
            sc = scenarios.build(args.scenario, seed=args.seed, drivers=args.drivers)
        ctl = args.controller or DEFAULT_DRIVER
        ex, info, _trace = export(sc, ctl, args.out, name=args.name, ego_motion=args.controller is not None)
    except (ValueError, OSError, RuntimeError) as exc:
        print(f"acc-gym export: {exc}")
        return 2
    report = None
    if not args.no_check:
        from acc_gym.scenarios.openscenario.check import check

        try:
            report = check(ex.xosc)
        except ImportError as exc:
            print(f"acc-gym export: not checked ({exc})")
    out = {"scenario": sc.id, "seed": sc.seed, "xosc": str(ex.xosc), "xodr": str(ex.xodr), "controller": ctl,
           "ego_motion": args.controller is not None, "offset": ex.offset, "entities": list(ex.names),
           "reacts_to_ego": list(ex.reacts_to_ego), "score": info.get("score"),
           "checked": None if report is None else report.passed,
           "issues": [] if report is None else [str(i) for i in report.issues]}
    if args.json:
        print(json.dumps(out))
    else:
        print(f"wrote {ex.xosc} and {ex.xodr}: {sc.id} seed {sc.seed}, the ego driven by {ctl!r}"
              + ("" if args.controller else " (its motion not written)")
              + f", score {info.get('score', float('nan')):.1f}")
        print(f"  positions along the road: s = x + {ex.offset:g} m (x the package's front-bumper position)")
        if ex.reacts_to_ego:
            print(f"  {', '.join(ex.reacts_to_ego)} reacted to the ego: the recorded motion holds for {ctl!r} only")
        if report is not None:
            print(f"  ASAM's checker: {'passed' if report.passed else 'FAILED'} ({report.completed} rules checked)")
            for issue in report.issues:
                print(f"  {ex.xosc}:{issue}")
    return 1 if report is not None and not report.passed else 0
