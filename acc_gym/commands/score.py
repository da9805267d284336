"""``acc-gym score``: score a recorded drive (a CSV, :mod:`acc_gym.evaluation.trace`) by paper
003's criteria and print the episode report."""

from __future__ import annotations


def add_parser(sub) -> None:
    p = sub.add_parser("score", help="score a recorded drive (CSV) by paper 003's criteria")
    p.add_argument("trace", help="CSV with columns t, v, a, gap, v_lead (optional a_lead, lead_id, a_y, d2, d3)")
    p.add_argument("--time-gap", type=float, default=None, help="nominal time gap [s] (the reaction time tau1)")
    p.add_argument("--set-speed", type=float, default=None, help="the ego's set speed [m/s]")
    p.add_argument("--literal", action="store_true", help="paper 003's rules read literally")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def run(args, parser) -> int:
    try:
        print(_text(args))
    except (ValueError, OSError) as exc:
        parser.error(str(exc))
    return 0


def _text(args) -> str:
    import json

    from acc_gym.evaluation import EgoTrace, ScoringConfig, score_episode

    trace = EgoTrace.from_csv(args.trace, set_speed=args.set_speed, time_gap=args.time_gap)
    report = score_episode(trace, ScoringConfig.literal() if args.literal else ScoringConfig())
    return json.dumps(report.to_dict()) if args.json else report.summary()
