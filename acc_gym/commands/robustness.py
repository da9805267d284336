"""``acc-gym robustness``: how a controller degrades with its car's actuator lag and dead time
and its radar's errors (:mod:`acc_gym.evaluation.robustness`)."""

from __future__ import annotations

import json

from acc_gym.evaluation import robustness as rb


def add_parser(sub) -> None:
    p = sub.add_parser("robustness", help="score, share qualified, collisions and string stability of a controller "
                                          "under growing actuator lag, dead time and radar noise")
    p.add_argument("controller", help="a built-in name, module:attribute, a run directory or a saved model (as "
                                      "acc-gym evaluate)")
    p.add_argument("--suite", default="ncap-v2", help="the suite whose episodes are driven (default ncap-v2)")
    p.add_argument("--split", default="test", choices=("dev", "test"))
    p.add_argument("--episodes", type=int, default=None, help="the first N episodes of the split (default all)")
    p.add_argument("--lags", type=float, nargs="+", default=list(rb.LAGS), metavar="S",
                   help="actuator lags [s] (default %(default)s)")
    p.add_argument("--delays", type=float, nargs="+", default=list(rb.DELAYS), metavar="S",
                   help="actuator dead times [s] (default %(default)s)")
    p.add_argument("--noise", type=float, nargs="+", default=list(rb.NOISE), metavar="X",
                   help="radar errors and dropouts as multiples of the typical preset's (default %(default)s)")
    p.add_argument("--no-string-stability", action="store_true", help="skip the column at each lag and dead time")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", default=None, metavar="PATH", help="save the degradation curves as a PNG")


def run(args, parser) -> int:
    from acc_gym._progress import progress_bar

    total = len(args.lags) + len(args.delays) + len(args.noise)
    try:
        with progress_bar(f"robustness: {args.controller}", total=total, enabled=not args.json) as bar:
            result = rb.robustness(args.controller, args.suite, args.split, lags=args.lags, delays=args.delays,
                                   noise=args.noise, episodes=args.episodes,
                                   string_stability=not args.no_string_stability,
                                   progress=lambda done, _total: bar.update(completed=done))
    except (ValueError, TypeError) as exc:
        parser.error(str(exc))
    if args.plot:
        from acc_gym.plotting import plot_robustness

        plot_robustness(result, path=args.plot)
        result["plot"] = args.plot
    if args.json:
        print(json.dumps(result))
    else:
        print(rb.format_table(result))
        if args.plot:
            print(f"plot: {args.plot}")
    return 0
