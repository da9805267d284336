"""A controller's verdicts by the standards, as JSON, Markdown and HTML: what ``acc-gym
conformance`` (:mod:`acc_gym.commands.conformance`) prints and writes.

    acc-gym conformance acc                       # every standard: iso15622, r157, ncap
    acc-gym conformance acc --standard iso15622   # ISO 15622 on the iso15622-v1 battery
    acc-gym conformance mymodule:MyACC --json
    acc-gym conformance acc --out conformance/    # conformance.json, .md, .html and the plots

The JSON object: ``{"controller", "standards": {"iso15622": {"standard", "battery", "passed",
"requirements": [{"name", "measured", "limit", "unit", "passed", "where", ...}], "drives",
"errors"}, "r157": {"cases": [{"family", "params", "controller_collides", "cc_driver_collides",
"preventable"}], "preventable_collisions", "non_preventable_collisions", "errors"}, "ncap":
{"protocol", "calculator", "score_percent", "test_types", "tests": [...], "frontal_collisions",
"out_of_scope", "errors"}}}`` (:mod:`acc_gym.standards.iso15622`, :mod:`~acc_gym.standards.r157`,
:mod:`~acc_gym.standards.ncap`). A drive, case or test the controller fails (it raises,
answers NaN) is named under its standard's ``errors`` and the rest of the report is still
written; Euro NCAP's score needs the ``ncap`` extra (without it the tests are still driven
and reported, ``score_percent`` is null and ``calculator`` says what to install). The
envelope plot draws every 2 s mean deceleration and 1 s mean jerk of the battery against
speed, with the limits.
"""

from __future__ import annotations

import html
import json
import math
from pathlib import Path

import numpy as np

from acc_gym.standards import battery as batteries
from acc_gym.standards import iso15622

STANDARDS = ("iso15622", "r157", "ncap")
NCAP_INSTALL = 'pip install "acc-gym[ncap]"'  # what Euro NCAP's score needs
R157_REFERENCES = ("cc-driver", "fsm-driver")


def work(standards, seeds=batteries.SEEDS) -> int:
    """How many drives, cases and test points :func:`conformance` runs for ``standards`` (what
    its ``progress`` counts to)."""
    n = 0
    if "iso15622" in standards:
        n += len(batteries.battery_cases(batteries.ISO15622_V1, seeds))
    if "r157" in standards:
        from acc_gym.standards.r157 import grid

        n += len(grid())
    if "ncap" in standards:
        from acc_gym.standards.ncap import ACC_POINTS, FC_POINTS

        n += len(ACC_POINTS) + len(FC_POINTS)
    return n


def conformance(controller, standards=("iso15622",), seeds=batteries.SEEDS, name: str | None = None,
                r157_reference: str = "cc-driver", progress=None, car: dict | None = None) -> dict:
    """The verdicts of ``controller`` by each of ``standards`` (JSON-safe), and the drives for plots
    under the key ``"_drives"`` (dropped by :func:`to_json`). ``r157_reference``: R157's reference
    driver, ``cc-driver`` (the careful and competent driver) or ``fsm-driver`` (the JRC's Fuzzy
    Safety Model); the cases' ``cc_driver_collides`` key holds the reference's outcome either way.
    ``progress(stage, n)``: told the standard being judged (``n`` 0) and each ``n`` drives, cases
    or test points done (:func:`work` counts them all). ``car``: the controller's car, as ``gym.make``
    settings (``sensors``, ``actuators``: :mod:`acc_gym.onboard`; None: ideal), recorded under ``"car"``;
    R157's reference drives without it."""
    standards = list(standards)
    unknown = [s for s in standards if s not in STANDARDS]
    if unknown or not standards:
        raise ValueError(f"unknown standard(s) {unknown or standards!r}; choose from {list(STANDARDS)} or 'all'")
    tell = progress if progress is not None else (lambda stage, n: None)
    out = {"controller": name or (controller if isinstance(controller, str) else type(controller).__name__),
           "standards": {}}
    if car:
        from dataclasses import asdict

        from acc_gym.onboard import actuator_config, sensor_config

        out["car"] = {"sensors": asdict(sensor_config(car.get("sensors"))),
                      "actuators": asdict(actuator_config(car.get("actuators")))}
    failures = []  # {"label", "scenario", "trace"} of each failing drive (out["_failures"])
    if "iso15622" in standards:
        tell("ISO 15622", 0)
        drives, errors, traces = batteries.run_battery(controller, batteries.ISO15622_V1, seeds,
                                                       progress=lambda _name: tell("ISO 15622", 1), car=car)
        report = iso15622.check_drives(drives)
        report.errors = errors
        out["standards"]["iso15622"] = {**report.to_dict(), "battery": batteries.ISO15622_V1,
                                        "seeds": list(seeds)}
        out["_drives"] = drives
        # the failing drives (a collision, the worst case of a failed requirement), for write_reports' failures/
        scenarios = {label: sc for label, _seed, sc in batteries.battery_cases(batteries.ISO15622_V1, seeds)}
        failed = list(report.collisions) + [label for r in report.requirements if r.passed is False and r.where
                                            for label in traces if r.where.startswith(label)]
        failures += [{"label": f"iso15622-{label}", "scenario": scenarios[label], "trace": traces[label]}
                     for label in dict.fromkeys(failed) if label in traces and label in scenarios]
    if "r157" in standards:
        from acc_gym.standards.r157 import r157_cases

        if r157_reference not in R157_REFERENCES:
            raise ValueError(f"unknown R157 reference {r157_reference!r}; choose from {list(R157_REFERENCES)}")
        tell("UN R157", 0)
        out["standards"]["r157"] = r157_cases(controller, reference=r157_reference, car=car, keep_failures=True)
        failures += out["standards"]["r157"].pop("_failures")
        tell("UN R157", len(out["standards"]["r157"]["cases"]))
    if "ncap" in standards:
        from acc_gym.standards.ncap import ncap_report

        tell("Euro NCAP", 0)
        out["standards"]["ncap"] = ncap_report(controller, progress=lambda _sid: tell("Euro NCAP", 1), car=car)
    if failures:
        from acc_gym.evaluation.runner import declared_time_gap, load_controller

        tg = declared_time_gap(load_controller(controller))
        out["_failures"] = [{**f, "time_gap": tg} for f in failures]
    return out


def to_json(result: dict) -> str:
    return json.dumps({k: v for k, v in result.items() if not k.startswith("_")})


def _num(x, unit: str = "") -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return f"{x:.3g}{(' ' + unit) if unit else ''}"


def markdown(result: dict) -> str:
    lines = [f"# Conformance: `{result['controller']}`", ""]
    if result.get("car"):
        from acc_gym.onboard import describe

        car = result["car"]
        lines += [f"In a car (acc_gym.onboard): radar {describe(car['sensors'])}; actuators "
                  f"{describe(car['actuators'])}. UN R157's reference drives without it.", ""]
    iso = result["standards"].get("iso15622")
    if iso is not None:
        verdict = {True: "passes", False: "**fails**", None: "not exercised"}[iso["passed"]]
        lines += [f"## {iso['standard']} on `{iso['battery']}` (seeds {', '.join(map(str, iso['seeds']))}): "
                  f"{verdict}", "",
                  "| requirement | measured | limit | verdict | windows or events outside | worst case | source |",
                  "|---|---|---|---|---|---|---|"]
        for r in iso["requirements"]:
            v = {True: "pass", False: "**fail**", None: "not exercised"}[r["passed"]]
            lines.append(f"| {r['name']} | {_num(r['measured'], r['unit'])} | {_num(r['limit'], r['unit'])} | {v} | "
                         f"{r['failures']} | {r['where']} | {r['confidence']} |")
        for e in iso["errors"]:
            lines.append(f"\nFailed drive: {e['drive']}: {e['reason']}")
        if iso["collisions"]:
            lines.append(f"\nNot an envelope requirement: {len(iso['collisions'])} of {len(iso['drives'])} drives ended "
                         f"in a collision ({', '.join(iso['collisions'][:5])}{', ...' if len(iso['collisions']) > 5 else ''}).")
        lines.append("")
    r157 = result["standards"].get("r157")
    if r157 is not None:
        n = len(r157["cases"])
        families = list(dict.fromkeys(c["family"] for c in r157["cases"]))  # in the grid's order
        grids = (", ".join(families[:-1]) + " and " + families[-1]) if len(families) > 1 else "".join(families)
        ref = r157["reference"]
        who = {"cc-driver": "the careful and competent driver", "fsm-driver": "the Fuzzy Safety Model"}.get(ref, ref)
        lines += [f"## UN R157: preventability against {who} (`{ref}`)", "",
                  f"{n} cases{f' ({grids} grids)' if families else ''}: **{r157['preventable_collisions']} preventable** "
                  f"collisions (`{ref}` avoids them), {r157['non_preventable_collisions']} non-preventable "
                  f"(it collides too).", ""]
        hit = [c for c in r157["cases"] if c["controller_collides"]]
        if hit:
            lines += [f"| family | parameters | `{ref}` collides | preventable |", "|---|---|---|---|"]
            for c in hit:
                params = ", ".join(f"{k} {v:g}" for k, v in c["params"].items())
                lines.append(f"| {c['family']} | {params} | {'yes' if c['cc_driver_collides'] else 'no'} | "
                             f"{'**yes**' if c['preventable'] else 'no'} |")
        for e in r157["errors"]:
            lines.append(f"\nFailed case: {e['family']} {e['params']}: {e['reason']}")
        lines.append("")
    ncap = result["standards"].get("ncap")
    if ncap is not None:
        lines += ncap_markdown(ncap)
    return "\n".join(lines)


def ncap_markdown(ncap: dict) -> list:
    """The Euro NCAP section's lines (:func:`acc_gym.standards.ncap.ncap_report`'s result)."""
    pct = ncap["score_percent"]
    if pct is None:  # the rating calculator is not installed: say what is missing and what still counts
        from acc_gym.standards.ncap import DISTRIBUTION as NCAP_DISTRIBUTION

        lines = [f"## {ncap['protocol']}: not scored", "",
                 f"**Not scored: the Euro NCAP score needs Euro NCAP's rating calculator ({NCAP_DISTRIBUTION}), "
                 f"which is not installed: `{NCAP_INSTALL}`.** Still reported below: every test point driven once "
                 "and measured (collision, impact speed, speed reduction) and the frontal-collision points; the "
                 "other standards (ISO 15622's envelope, UN R157's preventability) are judged in full.", ""]
    else:
        lines = [f"## {ncap['protocol']}: **{pct:.1f} %**", "",
                 f"Scored by {ncap['calculator']}, each test point simulated once (a green prediction per point: the "
                 "score is what the measured speed reduction earns).", ""]
    if ncap["test_types"]:
        lines += ["| test type | score | of | % |", "|---|---|---|---|"]
        for name, t in ncap["test_types"].items():
            lines.append(f"| {name} | {t['score']:.3f} | {t['max']:g} | {t['percent']:.1f} |")
        lines.append("")
    lines += ["| test | VUT / target [km/h] | collision | impact [km/h] | v_reduction [km/h] | green above | result |",
              "|---|---|---|---|---|---|---|"]
    for t in ncap["tests"]:
        if t["skip"]:
            result = f"not run: {t['skip']}"
        else:
            result = t.get("colour") or "-"
        coll = "-" if t["collision"] is None else ("**yes**" if t["collision"] else "no")
        lines.append(f"| {t['scenario_id']} | {t['vut_speed']} / {t['target_speed']} | {coll} | "
                     f"{_num(t['impact_speed'])} | {_num(t['v_reduction'])} | {_num(t.get('green_threshold'))} | "
                     f"{result} |")
    fc = ncap["frontal_collisions"]
    hit = [t["scenario_id"] for t in fc if t["collision"]]
    lines += ["", f"Frontal-collision (AEB) points driven by the controller alone (reported, not scored): "
              f"{len(fc) - len(hit)} of {len(fc)} avoided" + (f"; collisions in {', '.join(hit)}." if hit else "."),
              "", "Not run (outside the single-lane longitudinal model): "
              + "; ".join(f"{k} ({v})" for k, v in ncap["out_of_scope"].items()) + "."]
    for e in ncap["errors"]:
        lines.append(f"\nFailed test: {e['scenario_id']}: {e['reason']}")
    lines.append("")
    return lines


def plot_envelope(drives, path=None):
    """Every window's mean deceleration (2 s) and mean jerk (1 s) against its mean speed, with the
    ISO 15622 limits; returns the figure (and saves it to ``path``)."""
    from matplotlib.figure import Figure

    from acc_gym.plotting import save_figure

    fig = Figure(figsize=(10.0, 4.0), layout="constrained")
    ax_d, ax_j = fig.subplots(1, 2)
    speeds = np.linspace(0.0, 40.0, 200)
    for ax, key, label in ((ax_d, "deceleration", "mean deceleration over 2 s [m/s$^2$]"),
                           (ax_j, "jerk", "mean |jerk| over 1 s [m/s$^3$]")):
        limit = iso15622.LIMITS[key]
        for d in drives:
            _, mean_v, mean_a, mean_j = iso15622.window_means(d, limit.window)
            value = -mean_a if key == "deceleration" else np.abs(mean_j)
            keep = value > 0
            over = value > limit.at(mean_v)
            ax.scatter(mean_v[keep & ~over], value[keep & ~over], s=3, color="tab:blue", alpha=0.4)
            ax.scatter(mean_v[over], value[over], s=6, color="tab:red")
        ax.plot(speeds, limit.at(speeds), color="k", lw=1.5, label=f"ISO 15622 limit {limit.confidence}")
        ax.set_xlabel("speed [m/s]")
        ax.set_ylabel(label)
        ax.set_ylim(bottom=0.0)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="upper right")
    if path is not None:
        save_figure(fig, path)
    return fig


def html_report(result: dict, figures: dict | None = None) -> str:
    """The HTML report; ``figures``: ``{"envelope": Figure, "preventability": Figure}`` to embed."""
    from acc_gym.plotting import img

    figures = figures or {}
    e = html.escape
    parts = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
             f"<title>conformance: {e(result['controller'])}</title>",
             "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse}"
             "td,th{border:1px solid #ccc;padding:3px 6px;font-size:13px}.fail{color:#b00}</style></head><body>",
             f"<h1>Conformance: <code>{e(result['controller'])}</code></h1>"]
    iso = result["standards"].get("iso15622")
    if iso is not None:
        verdict = {True: "passes", False: "fails", None: "not exercised"}[iso["passed"]]
        parts.append(f"<h2>{e(iso['standard'])} on {e(iso['battery'])}: {verdict}</h2><table><tr><th>requirement"
                     "</th><th>measured</th><th>limit</th><th>verdict</th><th>outside</th><th>worst case</th>"
                     "<th>source</th></tr>")
        for r in iso["requirements"]:
            v = {True: "pass", False: "fail", None: "not exercised"}[r["passed"]]
            cls = ' class="fail"' if r["passed"] is False else ""
            parts.append(f"<tr{cls}><td>{e(r['name'])}</td><td>{e(_num(r['measured'], r['unit']))}</td>"
                         f"<td>{e(_num(r['limit'], r['unit']))}</td><td>{v}</td><td>{r['failures']}</td>"
                         f"<td>{e(r['where'])}</td><td>{e(r['source'])} {e(r['confidence'])}</td></tr>")
        parts.append("</table>")
        for err in iso["errors"]:
            parts.append(f'<p class="fail">Failed drive: {e(err["drive"])}: {e(err["reason"])}</p>')
        if iso["collisions"]:
            parts.append(f"<p>Not an envelope requirement: {len(iso['collisions'])} of {len(iso['drives'])} drives "
                         f"ended in a collision: {e(', '.join(iso['collisions']))}.</p>")
        if "envelope" in figures:
            parts.append(img(figures["envelope"], "envelope"))
    r157 = result["standards"].get("r157")
    if r157 is not None:
        md = markdown({"controller": result["controller"], "standards": {"r157": r157}})
        body = md.split("\n", 2)[2] if md.count("\n") >= 2 else md
        parts.append("<pre>" + e(body) + "</pre>")
        if "preventability" in figures:
            parts.append(img(figures["preventability"], "preventability map"))
    ncap = result["standards"].get("ncap")
    if ncap is not None:
        parts.append(f"<h2>{e(ncap['protocol'])}</h2><pre>" + e("\n".join(ncap_markdown(ncap)[1:])) + "</pre>")
    parts.append("</body></html>")
    return "\n".join(parts)


FAILURES = "failures"  # write_reports' folder of failing drives as OpenSCENARIO


def write_failures(result: dict, out) -> list:
    """Each failing drive of ``result`` (its ``_failures``: an ISO 15622 drive that collided or
    is the worst case of a failed requirement, a UN R157 case the controller collides in) as
    OpenSCENARIO in ``out/failures/`` (``iso15622-LABEL.xosc``, ``r157-FAMILY-K.xosc`` and their
    ``.xodr``: :func:`acc_gym.scenarios.openscenario.writer.write_episode`, the trajectories driven,
    the controller's too). Needs the ``osc`` extra; without it nothing is written. Returns the
    ``.xosc`` paths."""
    fails = result.get("_failures") or []
    if not fails:
        return []
    from acc_gym.scenarios.openscenario.writer import file_stem, write_episode

    try:
        import scenariogeneration  # noqa: F401
    except ImportError:
        return []
    folder = Path(out) / FAILURES
    return [write_episode(f["scenario"], f["trace"], folder, name=file_stem(f["label"]),
                          controller=str(result["controller"]), time_gap=f.get("time_gap")).xosc for f in fails]


def write_reports(result: dict, out) -> dict:
    """``conformance.json``, ``conformance.md``, ``conformance.html`` (the plots inside),
    ``envelope.png``, ``preventability.png`` and the failing drives as OpenSCENARIO
    (:func:`write_failures`, ``failures/``) in ``out`` (each written atomically); returns the paths."""
    from acc_gym._io import atomic_write
    from acc_gym.plotting import save_figure

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"json": out / "conformance.json", "markdown": out / "conformance.md", "html": out / "conformance.html"}
    figures = {}
    if result.get("_drives"):
        figures["envelope"] = plot_envelope(result["_drives"])
        paths["png"] = save_figure(figures["envelope"], out / "envelope.png")
    if "r157" in result["standards"]:
        from acc_gym.standards.r157 import plot_map

        figures["preventability"] = plot_map(result["standards"]["r157"])
        paths["map"] = save_figure(figures["preventability"], out / "preventability.png")
    written = write_failures(result, out)
    if written:
        paths["failures"] = out / FAILURES
    atomic_write(paths["json"], to_json(result) + "\n")
    atomic_write(paths["markdown"], markdown(result))
    atomic_write(paths["html"], html_report(result, figures))
    return {k: str(v) for k, v in paths.items()}

