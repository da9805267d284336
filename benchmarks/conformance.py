"""The built-in controllers' conformance table (the one in the README and docs/standards.md).

    python benchmarks/conformance.py           # the Markdown table (about 2.5 minutes on 2 cores)
    python benchmarks/conformance.py --json    # ... and one JSON object on the last line

Each controller goes through ``acc-gym conformance NAME``: ISO 15622 on the iso15622-v1
battery (seeds 0-2; a cell is the worst measured value, bold where it is outside the limit)
UN R157's preventability on its grid cases (collisions the careful and competent driver
avoids / also has), and Euro NCAP 2026's ACC performance score (the rating calculator's
percentage over the five car-to-car test types; ``-`` without the ``ncap`` extra).
"""

from __future__ import annotations

import argparse
import json

from acc_gym.standards.conformance import conformance, to_json

CONTROLLERS = ("acc", "cacc", "idm", "gipps", "gm", "fuzzy", "mpc", "constant", "ppo-acc", "ppo", "cc-driver",
               "fsm-driver")
SHORT = {"mean automatic deceleration over 2 s": "decel. 2 s [m/s^2]", "mean jerk over 1 s": "jerk 1 s [m/s^3]",
         "mean automatic acceleration over 2 s": "accel. 2 s [m/s^2]", "steady-state time gap": "time gap [s]",
         "standstill gap behind a stopped target": "standstill gap [m]",
         "no automatic go while the target stays stopped": "creep at standstill [m]"}


def _ncap(res: dict) -> str:
    pct = res["standards"]["ncap"]["score_percent"]
    return "-" if pct is None else f"{pct:.1f}"


def table(results: list[dict]) -> str:
    reqs = results[0]["standards"]["iso15622"]["requirements"]
    lines = ["| controller | ISO 15622 | " + " | ".join(SHORT[r["name"]] for r in reqs) + " | collided drives | R157: preventable / non-preventable collisions | Euro NCAP 2026 ACC [%] |",
             "|---|---|" + "---|" * len(reqs) + "---|---|---|"]
    for res in results:
        iso = res["standards"]["iso15622"]
        cells = []
        for r in iso["requirements"]:
            if r["measured"] is None:
                cells.append("-")
            else:
                text = f"{r['measured']:.2f}"
                cells.append(f"**{text}**" if r["passed"] is False else text)
        verdict = {True: "passes", False: "fails", None: "-"}[iso["passed"]]
        r157 = res["standards"]["r157"]
        prev = r157["preventable_collisions"]
        lines.append(f"| {res['controller']} | {verdict} | " + " | ".join(cells) +
                     f" | {len(iso['collisions'])} of {len(iso['drives'])} | {f'**{prev}**' if prev else prev} / "
                     f"{r157['non_preventable_collisions']} of {len(r157['cases'])} | {_ncap(res)} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--controllers", nargs="+", default=list(CONTROLLERS))
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    results = [conformance(c, ("iso15622", "r157", "ncap"), name=c) for c in args.controllers]
    print(table(results))
    if args.json:
        print("[" + ", ".join(to_json(r) for r in results) + "]")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
