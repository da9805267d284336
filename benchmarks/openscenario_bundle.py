"""Every built-in controller on every scenario of the shipped UN R157 (ALKS) OpenSCENARIO bundle
that the reader covers (:mod:`acc_gym.scenarios.openscenario`): collision, R157 preventability
(the cc-driver on the same file), paper 003's score, the minimum gap and time to collision.

    python benchmarks/openscenario_bundle.py --table        # the table of docs/openscenario.md
    python benchmarks/openscenario_bundle.py --json out.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", default=None, metavar="PATH", help="write the results as JSON")
    ap.add_argument("--table", action="store_true", help="print a Markdown table")
    ap.add_argument("--controllers", nargs="*", default=None, help="default: every registered controller")
    args = ap.parse_args(argv)
    from acc_gym._io import atomic_write
    from acc_gym.controllers import registered_controllers
    from acc_gym.evaluation.runner import load_controller
    from acc_gym.scenarios.openscenario import OpenScenarioError, read, run_file
    from acc_gym.scenarios.openscenario.bundle import alks_scenarios

    covered, skipped = {}, {}
    for num, path in alks_scenarios().items():
        try:
            covered[num] = read(path)
        except OpenScenarioError as exc:
            skipped[num] = str(exc).rsplit("/", 1)[-1]
    names = args.controllers or sorted(registered_controllers())
    ref = {num: run_file(sc.path, load_controller("cc-driver"), scenario=sc)[0]["collided"]
           for num, sc in covered.items()}
    out = {"scenarios": sorted(covered), "not_read": skipped, "cc_driver_collides": ref, "results": {}}
    t0 = time.perf_counter()
    for name in names:
        ctl = load_controller(name)
        rows = {}
        for num, sc in covered.items():
            r, _ = run_file(sc.path, ctl, scenario=sc)
            rows[num] = {"collided": r["collided"], "preventable": (not ref[num]) if r["collided"] else None,
                         "score": r["score"], "min_gap": r["min_gap"], "min_ttc": r["min_ttc"]}
        out["results"][name] = rows
        print(f"{name}: {sum(v['collided'] for v in rows.values())} collisions", file=sys.stderr)
    out["wall_s"] = time.perf_counter() - t0
    if args.json:
        atomic_write(args.json, json.dumps(out, indent=1))
    if args.table:
        print(table(out))
    return out


def table(out: dict) -> str:
    """Markdown: a row per controller, a column per scenario; a cell is the score, or ``X`` for a
    preventable collision and ``x`` for one the cc-driver has too."""
    nums = out["scenarios"]
    rows = ["| controller | " + " | ".join(nums) + " | collisions (preventable) |",
            "|---|" + "---:|" * len(nums) + "---:|"]
    for name, res in out["results"].items():
        cells = []
        for n in nums:
            r = res[n]
            cells.append(("**X**" if r["preventable"] else "x") if r["collided"] else f"{r['score']:.0f}")
        coll = sum(r["collided"] for r in res.values())
        prev = sum(bool(r["preventable"]) for r in res.values())
        rows.append(f"| {name} | " + " | ".join(cells) + f" | {coll} ({prev}) |")
    return "\n".join(rows)


if __name__ == "__main__":
    main()
