"""``acc-gym conformance``: a controller's verdicts by the standards, printed as Markdown or
JSON and written as JSON, Markdown and HTML (:mod:`acc_gym.standards.conformance`)."""

from __future__ import annotations

import sys

from acc_gym.commands._args import add_onboard_args, onboard_kwargs
from acc_gym.standards import battery as batteries
from acc_gym.standards.conformance import (R157_REFERENCES, STANDARDS, conformance, markdown, to_json, work,
                                           write_reports)


def add_parser(sub) -> None:
    p = sub.add_parser("conformance", help="a controller's verdicts by published standards: ISO 15622's ACC "
                                            "envelope on the iso15622-v1 battery, UN R157's preventability, "
                                            "Euro NCAP 2026's ACC performance score")
    p.add_argument("controller", help="a registered name, module:attribute or a saved model")
    p.add_argument("--standard", default="all", help=f"one of {', '.join(STANDARDS)} or all (default all)")
    p.add_argument("--seeds", type=int, nargs="+", default=list(batteries.SEEDS),
                   help="the battery's seeds (default 0 1 2)")
    p.add_argument("--r157-reference", default="cc-driver", choices=R157_REFERENCES,
                   help="R157's reference driver: cc-driver (the careful and competent driver, default) or "
                        "fsm-driver (the JRC's Fuzzy Safety Model)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--out", default=None, metavar="DIR", help="write conformance.json, .md, .html and envelope.png")
    add_onboard_args(p, v2v=False)  # the controller's car (R157's reference drives without it)


def run(args, parser) -> int:
    standards = list(STANDARDS) if args.standard == "all" else [s.strip() for s in args.standard.split(",")]
    from acc_gym._progress import progress_bar

    try:
        bar = progress_bar("conformance", unit="drives", enabled=not args.json)
        with bar:
            if bar.shown:
                bar.update(total=work(standards, tuple(args.seeds)))

            def tell(stage, n):
                bar.update(description=f"conformance: {stage}")
                bar.advance(n)

            result = conformance(args.controller, standards, tuple(args.seeds), name=args.controller,
                                 r157_reference=args.r157_reference, progress=tell,
                                 car=onboard_kwargs(args, parser) or None)
    except (ValueError, TypeError) as exc:
        parser.error(str(exc))
    files = write_reports(result, args.out) if args.out else None
    if files is not None and result.get("_failures") and "failures" not in files:
        print(f"acc-gym conformance: {len(result['_failures'])} failing drive(s) not written as OpenSCENARIO "
              f"(pip install 'acc-gym[osc]')", file=sys.stderr)
    if args.json:
        print(to_json({**result, **({"files": files} if files else {})}))
    else:
        print(markdown(result))
        if files:
            print("files: " + ", ".join(files.values()))
    return 0
