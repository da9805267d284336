"""``acc-gym validate``: check OpenSCENARIO files with ASAM's checker bundle (the schema of
the version each file declares, then ASAM's rules; :mod:`acc_gym.scenarios.openscenario.check`)."""

from __future__ import annotations

import json


def add_parser(sub) -> None:
    p = sub.add_parser("validate", help="check OpenSCENARIO files with ASAM's checker: the schema of their declared "
                                        "version and ASAM's rules (needs the osc extra)")
    p.add_argument("files", nargs="+", help="OpenSCENARIO files (.xosc), or alks:N for a scenario of the shipped "
                                            "UN R157 bundle")
    p.add_argument("--json", action="store_true", help="print one JSON object per file, one per line")


def run(args, parser) -> int:
    """Exit 0 when every file passes, 1 when one has an issue, 2 for a missing file or checker."""
    from acc_gym.scenarios.openscenario import OpenScenarioError
    from acc_gym.scenarios.openscenario.bundle import resolve
    from acc_gym.scenarios.openscenario.check import check

    failed = False
    for name in args.files:
        try:
            report = check(resolve(name))
        except (ImportError, FileNotFoundError, OpenScenarioError) as exc:
            print(f"acc-gym validate: {exc}")
            return 2
        failed |= not report.passed
        if args.json:
            print(json.dumps(report.to_dict()))
            continue
        print(f"{report.file}: {'passed' if report.passed else 'FAILED'} ({report.completed} rules checked, "
              f"{len(report.skipped)} skipped, {len(report.issues)} issue(s))")
        for issue in report.issues:
            print(f"  {report.file}:{issue}")
    return 1 if failed else 0
