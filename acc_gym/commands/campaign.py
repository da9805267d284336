"""``acc-gym campaign``: run or resume a Monte Carlo campaign of a suite's traffic and print
its metrics with confidence intervals (:mod:`acc_gym.campaigns`)."""

from __future__ import annotations

import json


def add_parser(sub) -> None:
    p = sub.add_parser("campaign", help="run or resume a Monte Carlo campaign of a suite's traffic, or every "
                                        "concrete scenario of an OpenSCENARIO variation (needs pyarrow; Dask for "
                                        "--scheduler)")
    p.add_argument("--suite", default=None, help="a suite name (singlelane-v3, carfollowing-v1, ncap-v1, ncap-v2, "
                                                  "malicious-v3)")
    p.add_argument("--hours", type=float, default=None, help="hours of the suite's traffic to simulate")
    p.add_argument("--variation", default=None, metavar="VAR.xosc",
                   help="instead of a suite: an OpenSCENARIO variation file (ParameterValueDistribution), or alks:N "
                        "for the shipped UN R157 bundle's; every concrete scenario of it is run")
    p.add_argument("--scenario", default=None, metavar="FILE.xosc",
                   help="with --variation: the template to vary (default: the variation's own ScenarioFile)")
    p.add_argument("--controller", required=True, help="a built-in controller, module:attribute or a saved model")
    p.add_argument("--out", required=True, help="output directory (resumed if it holds this campaign)")
    p.add_argument("--split", default="test", help="the suite's split: dev or test (default test)")
    p.add_argument("--root-seed", type=int, default=None, help="root seed (default: the split's own)")
    p.add_argument("--workers", type=int, default=None,
                   help="local worker processes (default: the CPU count); with --scheduler local, the "
                        "LocalCluster's size (default 2)")
    p.add_argument("--scheduler", default=None, help="a Dask scheduler address, or 'local' for a LocalCluster")
    p.add_argument("--chunk-size", type=int, default=20, help="scenarios per task and per result file")
    p.add_argument("--max-chunks", type=int, default=None, help="run at most this many missing chunks now")
    p.add_argument("--confidence", type=float, default=0.95, help="confidence level of the intervals")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")


def run(args, parser) -> int:
    import os

    from acc_gym.campaigns import CampaignError, MissingDependencyError, format_summary, run_campaign

    if args.workers is not None and args.scheduler not in (None, "local"):
        parser.error(f"--workers {args.workers} sets the size of --scheduler local only; a running cluster "
                     f"({args.scheduler}) has its own workers")
    workers = args.workers if args.workers is not None else (2 if args.scheduler else (os.cpu_count() or 1))
    suite, hours = args.suite, args.hours
    if args.variation is not None:
        if args.suite is not None or args.hours is not None:
            parser.error("--variation runs every concrete scenario of the variation: give no --suite or --hours")
        suite = _sweep(args, parser)
    elif args.scenario is not None:
        parser.error("--scenario needs --variation (a single file runs with acc-gym run)")
    elif args.suite is None or args.hours is None:
        parser.error("give --suite and --hours, or --variation")
    from acc_gym._progress import progress_bar

    bar = progress_bar(f"campaign {getattr(suite, 'name', suite)}", unit="chunks", enabled=not args.json)

    def progress(number, n_done, total):
        bar.update(completed=n_done, total=total)

    try:
        with bar:  # from the start: the plan, the workers' start-up and the chunks that are already there
            summary = run_campaign(suite, hours, args.controller, args.out, split=args.split,
                                   root_seed=args.root_seed, workers=workers, scheduler=args.scheduler,
                                   chunk_size=args.chunk_size, max_chunks=args.max_chunks,
                                   confidence=args.confidence, on_chunk=progress,
                                   on_start=lambda n_done, total: bar.update(completed=n_done, total=total))
    except MissingDependencyError as exc:
        parser.error(str(exc))
    except (CampaignError, ValueError, TypeError, OSError) as exc:
        parser.error(str(exc))
    if args.json:
        print(json.dumps(summary))
    else:
        print(format_summary(summary))
        print(f"results: {args.out} (summary.json, chunks/*.parquet)")
    return 0


def _sweep(args, parser):
    """The --variation (and --scenario) as a :class:`acc_gym.campaigns.sweep.VariationSweep`."""
    from acc_gym.campaigns.sweep import VariationSweep
    from acc_gym.scenarios.openscenario import OpenScenarioError
    from acc_gym.scenarios.openscenario.bundle import PREFIX, alks_variation, resolve

    try:
        var = args.variation
        if var.startswith(PREFIX):
            found = alks_variation(var[len(PREFIX):])
            if found is None:
                resolve(var)  # an unknown number: the error names the bundle's
                parser.error(f"{var}: the bundle has no variation file for this scenario")
            var = found
        sweep = VariationSweep(var, resolve(args.scenario) if args.scenario else None)
    except (OpenScenarioError, ValueError, OSError) as exc:
        parser.error(str(exc))
    v = sweep.variation
    if not args.json:
        print(f"{sweep.name}: {len(v)} concrete scenarios ({v.kind}); {v.invalid} combinations left out as they "
              f"violate the template's constraints" + (f", e.g. {v.first_invalid.rsplit(': ', 1)[-1]}" if v.invalid
                                                       else ""))
    return sweep
