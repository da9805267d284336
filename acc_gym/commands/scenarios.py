"""``acc-gym scenarios``: list the scenario ids, or describe one (:mod:`acc_gym.scenarios`)."""

from __future__ import annotations


def add_parser(sub) -> None:
    p = sub.add_parser("scenarios", help="list scenario ids, or describe one")
    p.add_argument("id", nargs="?", help="a scenario id (omit to list them)")
    p.add_argument("--family", help="list only this family (singlelane, carfollowing, ncap, ncap2026, stopandgo)")
    p.add_argument("--seed", type=int, default=0, help="seed for --json")
    p.add_argument("--drivers", default="typical", help="surrounding drivers for --json")
    p.add_argument("--json", action="store_true", help="print the built scenario as JSON")


def run(args, parser) -> int:
    try:
        print(_text(args))
    except (ValueError, OSError) as exc:
        parser.error(str(exc))
    return 0


def _text(args) -> str:
    from acc_gym import scenarios

    if args.id is None:
        return "\n".join(scenarios.list_scenarios(args.family))
    if args.json:
        return scenarios.build(args.id, seed=args.seed, drivers=args.drivers).to_json(indent=1)
    return scenarios.describe(args.id)
