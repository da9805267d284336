"""``acc-gym risk``: the accelerated collision estimate of one controller on one family.

``--event`` chooses the failure estimated (:data:`acc_gym.risk.run.EVENTS`): ``collision``
(default), ``ttc`` (min TTC < 1 s) or ``preventable-collision`` (a collision UN R157's careful
and competent driver, ``cc-driver``, avoids in the same scenario). The text names the
estimated event on its first line (its estimate is the first below it, the second event's
follows); the JSON's ``event`` names it (``estimate``; ``other`` the second event's). For
the two collision events both say how many of the estimation episodes' collisions were
preventable and how many not (``preventable_collisions``, ``non_preventable_collisions``).
"""

from __future__ import annotations

import json
import math
import os

from acc_gym.commands._args import number_params
from acc_gym.risk.episodes import CHUNK
from acc_gym.risk.run import EVENTS, FAMILIES, RiskResult, estimate_risk


def add_parser(sub) -> None:
    p = sub.add_parser("risk", help="estimate a controller's rare collision probability by importance sampling "
                                    "(accelerated evaluation)")
    p.add_argument("--controller", required=True, help="a registered name, module:attribute or a saved model")
    p.add_argument("--family", default="cut-in", help=f"one of {', '.join(sorted(FAMILIES))} or a scenario id "
                                                      "(default cut-in)")
    p.add_argument("--event", default="collision", choices=sorted(EVENTS),
                   help="the failure estimated first: a collision (default), a preventable-collision (one UN R157's "
                        "careful driver, cc-driver, avoids in the same scenario), or ttc (a time-to-collision "
                        "under 1 s)")
    p.add_argument("--method", default="is", choices=("is", "crude"),
                   help="importance sampling (default) or crude Monte Carlo, for comparison")
    p.add_argument("--target-rhw", type=float, default=0.2, help="stop at this relative half-width of the 95 %% "
                                                                  "interval (default 0.2)")
    p.add_argument("--budget", type=int, default=20000,
                   help="at most this many episodes, adaptive and estimation rounds together (default 20000; at "
                        f"least {CHUNK}, one chunk: an adaptive round runs only if it leaves the estimation a chunk, "
                        f"and the episodes run in whole chunks of {CHUNK}, so a budget that is not a multiple of "
                        f"{CHUNK} is not spent to the last episode)")
    p.add_argument("--round-size", type=int, default=256, help="episodes per round (default 256)")
    p.add_argument("--max-rounds", type=int, default=10, help="adaptive cross-entropy rounds at most (default 10)")
    p.add_argument("--root-seed", type=int, default=0)
    p.add_argument("--drivers", default="typical", help="surrounding drivers (typical, atypical, malicious, ...)")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="hold a scenario parameter fixed (repeatable): the estimate is conditional on it")
    p.add_argument("--workers", type=int, default=None, help="local worker processes (default: the CPU count)")
    p.add_argument("--scheduler", default=None, help="a Dask scheduler address, or 'local' for a LocalCluster")
    p.add_argument("--out", default=None, help="a directory for the finished chunks (a rerun resumes from it) and, "
                                               "with the osc extra, the first collisions as OpenSCENARIO (failures/)")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def _params(items: list[str], parser) -> dict | None:
    return number_params(items, parser) or None  # None: nothing held fixed


def run(args, parser) -> int:
    workers = args.workers if args.workers is not None else (os.cpu_count() or 1)
    try:
        result = estimate_risk(args.controller, args.family, event=args.event, method=args.method,
                               target_rhw=args.target_rhw, budget=args.budget, round_size=args.round_size,
                               max_rounds=args.max_rounds, root_seed=args.root_seed, drivers=args.drivers,
                               workers=workers, scheduler=args.scheduler, out=args.out,
                               progress=not args.json, params=_params(args.param, parser))
    except (ValueError, TypeError, OSError) as exc:
        parser.error(str(exc))
    if args.json:
        print(json.dumps(result.to_dict()))
    else:
        print(format_result(result))
    return 0


def _num(x) -> str:
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else f"{x:.3g}"


NAMES = {"collision": "P(collision)", "ttc": "P(min TTC < 1 s)", "preventable-collision": "P(preventable collision)"}


def format_result(r: RiskResult) -> str:
    """A few lines a person reads: the estimate, its interval, the cost, the warnings."""
    lines = [f"{r.controller} on {r.family} ({r.scenario_id}), {r.method}, event {r.event}: {r.episodes} episodes, "
             f"{r.stop}, {r.wall_time_s:.0f} s"]
    for est in (r.estimate, r.other):
        name = NAMES[est.event]
        if est.failures == 0:
            lines.append(f"  {name} per encounter < {_num(est.upper_bound)} (95 % upper bound: no failure in "
                         f"{est.episodes_total} episodes)")
        else:
            acc = "" if est.acceleration is None else f", {est.acceleration:,.0f}x fewer episodes than crude " \
                                                      "Monte Carlo for this half-width"
            lines.append(f"  {name} per encounter {_num(est.p)} [{_num(est.ci_low)}, {_num(est.ci_high)}] "
                         f"(+-{est.rhw:.0%}; {est.failures} failures, effective {est.ess_failures:.0f}; effective "
                         f"sample size {est.ess:.0f} of {est.episodes}{acc})")
        hour = r.per_hour(est)
        if hour is not None:
            value = f"< {_num(hour['upper_bound'])}" if est.failures == 0 else \
                f"{_num(hour['rate'])} [{_num(hour['ci_low'])}, {_num(hour['ci_high'])}]"
            lines.append(f"    per hour of driving ({_num(r.occurrence_rate)} encounters/h): {value}")
        for w in est.warnings:
            lines.append(f"    warning: {w}")
    if r.preventable_collisions is not None:
        k, m = r.preventable_collisions, r.non_preventable_collisions
        lines.append(f"  UN R157: of the {k + m} collisions in the estimation episodes, {k} preventable (the careful "
                     f"driver, cc-driver, avoids the same scenario), {m} not")
    if r.min_ttc is not None:
        lines.append(f"  smallest time-to-collision seen: {r.min_ttc:.2f} s")
    if r.failures:
        lines.append(f"  the first {len(r.failures)} collision(s) as OpenSCENARIO, in --out: "
                     + ", ".join(f["xosc"] for f in r.failures))
    return "\n".join(lines)
