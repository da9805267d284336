"""The leaderboard's results: aggregation, ranking, the files, and reading them back.

Aggregation (per controller): each suite is summarised by
:func:`acc_gym.evaluation.runner.summarise` over its episodes, plus its scheduled hours
(the sum of its scenarios' durations) and collisions per hour (collisions / those
hours: the same denominator for every controller, so a controller that crashes early
is not credited with fewer hours). Over several suites, **every suite weighs the
same**: the overall score, share qualified, share comfortable and share of safe spacing
are the means of the suites' values (otherwise the hour of single-lane traffic, ~270
episodes, would drown the 15 car-following tests); collisions per hour pool all hours;
minimum TTC is the smallest and maximum jerk the largest.

Ranking (:data:`RANKING_RULE`): controllers that finished by overall mean **points**
(descending), then the failed ones (unranked, with their reasons). An episode's points
are its paper 003 100-point score, or **0 if it ended in a preventable collision**: the
paper's score gives a collider the safety item's 45 points, as much as a controller that
never moves off its set speed's safe side, and a crash must cost more than any timid
drive -- unless nobody could have avoided it: a collision that UN R157's careful and
competent driver (the built-in ``cc-driver``, driven on the same scenario by the trusted
simulation) has too is non-preventable and keeps the episode's score (the
collision still counts in the collision columns). Equal
figures (within :data:`~acc_gym.reproducibility.SCORE_TOLERANCE`, what reproduces across
machines) share a rank and are listed by name; there is no tie-break between different
controllers' different figures other than the figures. The table shows mean points,
the mean paper score, share qualified, collisions per hour and minimum TTC side by side;
the string-stability and ISO 15622 columns (:mod:`acc_gym.leaderboard.iso15622`) stand
beside the ranking and change no points and no rank.
Nothing in the scores or the ranking depends on timing or on how many controllers ran
in parallel.

Uncertainty (:mod:`acc_gym.leaderboard.uncertainty`): every mean and share in a summary has
a 95 % interval beside it (``KEY_ci``: ``[low, high]``; a percentile bootstrap over
episodes for means, Clopper-Pearson for shares of episodes, ``collisions_per_hour_ci`` the
collision rate's scaled to hours), and :func:`rank` gives each ranked controller below the
first a ``vs_above``: its mean points minus the row above's over the episodes both ran,
with a 95 % paired bootstrap interval, ``significant`` when that excludes 0. A row whose
difference is not significant is shown as a **tie** (column "vs above") in the text,
Markdown, CSV and HTML tables; the order stays the points ranking's. The tables print an
interval as ``77.7 [75.1, 80.2]``; the CSV keeps numbers, one column per end
(``points_ci_low``, ``points_ci_high``, ...).

Files (all written atomically: a temporary file in the same directory, then
``os.replace``, so a reader sees the old file or the new one, never half of one):

* ``results.json`` -- ``{"format", "sha256", "results"}`` where ``sha256`` is the hash of
  the canonical JSON of ``results``; :func:`load_results` recomputes it, so a truncated,
  damaged or hand-edited file is refused with a ``ValueError`` naming it (and JSON
  errors are re-raised as ``ValueError`` naming the file), never read as empty. A
  checksum only catches damage: whoever rewrites the file can recompute it. So when the
  host sets a key (:data:`KEY_ENV`, the key itself, or :data:`KEY_FILE_ENV`, a file
  holding it), the file also carries ``"hmac": {"alg": "hmac-sha256", "key_id", "value"}``
  over the same canonical JSON, and :func:`load_results` -- with the key set -- refuses a
  file whose HMAC is missing or wrong. The key never reaches a controller (their
  environment is scrubbed); keep its file readable by the host only, and note that a
  controller running under the host's own user id (no per-controller uid: see
  :mod:`acc_gym.leaderboard.sandbox`) could read it from the runner's memory or files;
* ``results.csv`` -- the ranking table, one row per controller;
* ``leaderboard.md`` -- the same as a Markdown table;
* ``report.html`` -- see :mod:`acc_gym.leaderboard.report`;
* ``failures/`` -- each controller's failing worst episode as OpenSCENARIO (with the ``osc``
  extra; :mod:`acc_gym.leaderboard.failures`), named by its entry's ``failing_episode``.
"""

from __future__ import annotations

import csv
import hashlib
import hmac
import io
import json
import os
from pathlib import Path

import numpy as np

from acc_gym._io import atomic_write, json_safe  # noqa: F401  (re-exported)

from acc_gym.evaluation.runner import summarise
from acc_gym.leaderboard import uncertainty

FORMAT = "acc_gym.leaderboard/1"
HOUR = 3600.0
RANKING_RULE = ("controllers rank by mean points (each suite weighs the same); an episode's points are its paper 003 "
                "100-point score, or 0 if it ended in a preventable collision (one UN R157's careful and competent "
                "driver, cc-driver, avoids in the same scenario; a non-preventable collision keeps the score); means "
                "equal within 1e-6 share a rank; a row whose "
                "paired difference in points to the row above has a 95 % paired bootstrap interval containing 0 is "
                "marked a tie (vs_above; the order is unchanged)")


def canonical_json(obj) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False)


def checksum(results: dict) -> str:
    return hashlib.sha256(canonical_json(results).encode("ascii")).hexdigest()


def suite_summary(episodes: list[dict]) -> dict:
    """One suite's summary (see the module docstring) from its episode records."""
    s = summarise([{"score": e["score"], "qualified": e["qualified"], "metrics": e["metrics"]} for e in episodes],
                  [e["scenario"] for e in episodes])
    del s["scores"], s["scenarios"]  # the episode records hold them
    s["mean_points"] = float(np.mean([e["points"] for e in episodes])) if episodes else None
    hours = sum(e["duration"] for e in episodes) / HOUR
    s["hours"] = hours
    s["collisions_per_hour"] = s["collisions"] / hours
    # UN R157: a collision the careful and competent driver avoids in the same scenario is preventable
    s["preventable_collisions"] = sum(e.get("preventable") is True for e in episodes)
    s["non_preventable_collisions"] = sum(e.get("preventable") is False for e in episodes)
    s["by_group"] = {g: float(np.mean([e["score"] for e in episodes if e["group"] == g]))
                     for g in sorted({e["group"] for e in episodes})}
    return s


def overall_summary(per_suite: dict) -> dict:
    """Every suite weighs the same (see the module docstring)."""
    vals = list(per_suite.values())

    def mean(key):
        xs = [v[key] for v in vals if v[key] is not None]
        return float(np.mean(xs)) if xs else None

    ttc = [v["min_ttc"] for v in vals if v["min_ttc"] is not None]
    hours = sum(v["hours"] for v in vals)
    collisions = sum(v["collisions"] for v in vals)
    return {"episodes": sum(v["episodes"] for v in vals), "mean_points": mean("mean_points"),
            "mean_score": mean("mean_score"),
            "share_qualified": mean("share_qualified"), "collisions": collisions, "hours": hours,
            "collisions_per_hour": collisions / hours,
            "preventable_collisions": sum(v.get("preventable_collisions", 0) for v in vals),
            "non_preventable_collisions": sum(v.get("non_preventable_collisions", 0) for v in vals),
            "share_comfortable": mean("share_comfortable"),
            "share_safe_spacing": mean("share_safe_spacing"), "min_ttc": min(ttc) if ttc else None,
            "max_jerk": max(v["max_jerk"] for v in vals)}


def summarise_controller(episodes: list[dict], suites: list[str]) -> dict:
    """Each suite's summary and the overall one, with their 95 % intervals (``*_ci``)."""
    by_suite = {name: [e for e in episodes if e["suite"] == name] for name in suites}
    per_suite = {name: suite_summary(eps) for name, eps in by_suite.items()}
    overall = overall_summary(per_suite)
    uncertainty.add_intervals(per_suite, overall, by_suite)
    return {"overall": overall, "suites": per_suite}


def rank(controllers: list[dict]) -> list[str]:
    """Names in ranking order (see the module docstring); sets each entry's ``rank`` and
    ``vs_above`` (:func:`acc_gym.leaderboard.uncertainty.compare` with the ranked row above;
    ``None`` for the first and the failed ones)."""
    from acc_gym.reproducibility import SCORE_TOLERANCE

    def points(c):
        return c["summary"]["overall"]["mean_points"]

    ok = sorted((c for c in controllers if c["status"] == "ok"), key=lambda c: (-points(c), c["name"]))
    failed = sorted((c for c in controllers if c["status"] != "ok"), key=lambda c: c["name"])
    for c in ok:  # 1 + how many are better by more than the tolerance: equal figures share a rank
        c["rank"] = 1 + sum(points(o) > points(c) + SCORE_TOLERANCE for o in ok)
    for above, c in zip([None, *ok], ok):
        c["vs_above"] = None if above is None else uncertainty.compare(above, c)
    for c in failed:
        c["rank"] = None
        c["vs_above"] = None
    return [c["name"] for c in ok + failed]


# -- tables ---------------------------------------------------------------------------------
COLUMNS = ("rank", "controller", "status", "points", "score", "qualified", "collisions_per_hour", "comfortable",
           "safe_spacing", "min_ttc_s", "max_jerk_mps3", "episodes", "wall_time_s", "reason", "vs_above",
           "vs_above_diff", "vs_above_ci_low", "vs_above_ci_high")
RISK_COLUMNS = ("risk_p", "risk_ci_low", "risk_ci_high", "risk_upper_bound", "risk_episodes")  # with --risk
# the string-stability column (on by default): numbers for the CSV, the verdict's text for the tables
STRING_COLUMNS = ("string_max_gain", "string_stable", "string_disturbance_growth")
# the ISO 15622 column (on by default): the verdict (True / False / empty: not exercised or not run), the failed
# requirements' names joined by ";", and the reason when the controller failed in the battery
ISO15622_COLUMNS = ("iso15622_passed", "iso15622_failed", "iso15622_failed_to_run")
# the wave column (on by default): the ratio of speed sds to the all-human ring's, of mean speeds, the collisions
# on the controller's rings, and the reason when the controller failed in the column
WAVE_COLUMNS = ("waves_ratio", "waves_speed_ratio", "waves_collisions", "waves_failed_to_run")
# the robustness column (on by default): in the typical car, the share qualified, mean score, collisions, preventable
# ones, and the reason when the controller failed in the column
ROBUSTNESS_COLUMNS = ("robustness_qualified", "robustness_score", "robustness_collisions", "robustness_preventable",
                      "robustness_failed_to_run")
# the UN R157 bundle's column (--alks): the share qualified, mean score, collisions, preventable ones, and the reason
# when the controller failed in the column
ALKS_COLUMNS = ("alks_qualified", "alks_score", "alks_collisions", "alks_preventable", "alks_failed_to_run")
#: table columns with an interval, and the summary figure they show
INTERVALS = {"points": "mean_points", "score": "mean_score", "qualified": "share_qualified",
             "collisions_per_hour": "collisions_per_hour", "comfortable": "share_comfortable",
             "safe_spacing": "share_safe_spacing"}


def _interval_columns(results: dict) -> list[tuple[str, str | None, str]]:
    """(column, suite or None for overall, summary key) of every column with an interval."""
    return [(col, None, key) for col, key in INTERVALS.items()] + \
        [(f"points[{s['name']}]", s["name"], "mean_points") for s in results["manifest"]["suites"]]


def table_rows(results: dict) -> list[dict]:
    """One row per controller in ranking order: the overall columns, then each suite's score."""
    by_name = {c["name"]: c for c in results["controllers"]}
    rows = []
    for name in results["ranking"]:
        c = by_name[name]
        o = c["summary"]["overall"] if c["summary"] else None
        row = {"rank": c["rank"], "controller": name, "status": c["status"], "points": o and o["mean_points"],
               "score": o and o["mean_score"], "qualified": o and o["share_qualified"],
               "collisions_per_hour": o and o["collisions_per_hour"], "comfortable": o and o["share_comfortable"],
               "safe_spacing": o and o["share_safe_spacing"], "min_ttc_s": o and o["min_ttc"],
               "max_jerk_mps3": o and o["max_jerk"], "episodes": len(c["episodes"]),
               "collisions": o and o["collisions"],
               "preventable_collisions": o and o.get("preventable_collisions"),
               "non_preventable_collisions": o and o.get("non_preventable_collisions"),
               "collisions_r157": (o.get("preventable_collisions"), o.get("non_preventable_collisions"))
               if o and "preventable_collisions" in o else None,
               "wall_time_s": c["wall_time_s"], "reason": c["reason"]}
        for suite in results["manifest"]["suites"]:
            s = c["summary"]["suites"][suite["name"]] if c["summary"] else None
            row[f"points[{suite['name']}]"] = s and s["mean_points"]
        if _has_risk(results):
            r = c.get("risk") or {}
            row["risk"] = c.get("risk")
            for col in RISK_COLUMNS:
                row[col] = r.get(col[len("risk_"):])
        if _has_string_stability(results):
            cell = c.get("string_stability") or {}
            row["string_stability"] = c.get("string_stability")
            row["string_max_gain"] = cell.get("max_gain")
            row["string_stable"] = cell.get("string_stable")
            row["string_disturbance_growth"] = cell.get("disturbance_growth")
        if _has_iso15622(results):
            cell = c.get("iso15622") or {}
            row["iso15622"] = c.get("iso15622")
            row["iso15622_passed"] = cell.get("passed")
            row["iso15622_failed"] = ";".join(cell.get("failed") or []) if "passed" in cell else None
            row["iso15622_failed_to_run"] = cell.get("failed_to_run")
        if _has_waves(results):
            cell = c.get("waves") or {}
            row["waves"] = c.get("waves")
            for col in WAVE_COLUMNS:
                row[col] = cell.get(col[len("waves_"):])
        if _has_robustness(results):
            cell = c.get("robustness") or {}
            row["robustness"] = c.get("robustness")
            for col in ROBUSTNESS_COLUMNS:
                row[col] = cell.get(col[len("robustness_"):])
        if _has_alks(results):
            cell = c.get("alks") or {}
            row["alks"] = c.get("alks")
            for col in ALKS_COLUMNS:
                row[col] = cell.get(col[len("alks_"):])
        vs = c.get("vs_above")
        row["vs_above"] = uncertainty.verdict(vs)
        row["vs_above_diff"] = vs["diff"] if vs else None
        row["vs_above_ci_low"], row["vs_above_ci_high"] = vs["ci"] if vs else (None, None)
        for col, suite, key in _interval_columns(results):
            part = (c["summary"]["overall"] if suite is None else c["summary"]["suites"][suite]) \
                if c["summary"] else None
            ci = part.get(f"{key}_ci") if part else None
            row[f"{col}_ci_low"], row[f"{col}_ci_high"] = ci if ci else (None, None)
        rows.append(row)
    return rows


def _has_risk(results: dict) -> bool:
    return bool((results["manifest"].get("settings") or {}).get("risk"))


def string_stability_note(results: dict) -> str:
    """What the string-stability column measured and the rule it applies (from the manifest)."""
    st = results["manifest"]["settings"]["string_stability"]
    f = st["frequencies_hz"]
    return (f"string stability: {st['vehicles']} copies of the controller behind a lead oscillating around "
            f"{st['speed']:g} m/s at {len(f)} frequencies ({f[0]:g}-{f[-1]:g} Hz); max gain = the largest "
            f"vehicle-to-vehicle speed gain; stable when it is at most 1 + {st['tolerance']:g} "
            f"(acc-gym string-stability; failed: no steady state or the controller failed)")


def _has_string_stability(results: dict) -> bool:
    return bool((results["manifest"].get("settings") or {}).get("string_stability"))


def _has_iso15622(results: dict) -> bool:
    return bool((results["manifest"].get("settings") or {}).get("iso15622"))


def _has_waves(results: dict) -> bool:
    return bool((results["manifest"].get("settings") or {}).get("waves"))


def _has_robustness(results: dict) -> bool:
    return bool((results["manifest"].get("settings") or {}).get("robustness"))


def _has_alks(results: dict) -> bool:
    return bool((results["manifest"].get("settings") or {}).get("alks"))


def column_notes(results: dict) -> list[str]:
    """The lines under the ranking table: the sandbox's warning if there is one (strangers' code ran as
    root, ``--allow-root``), then the optional columns that ran (string stability, ISO 15622, waves,
    robustness)."""
    from acc_gym.leaderboard import alks, iso15622, robustness, waves

    warning = (results["manifest"].get("sandbox") or {}).get("warning")  # strangers' code ran as root
    from acc_gym.onboard import describe

    car = (results["manifest"].get("settings") or {}).get("car")
    car_note = [f"every episode in a car (acc_gym.onboard, --sensors / --actuators): radar {describe(car['sensors'])}, "
                f"actuators {describe(car['actuators'])}; the ranking is that car's"] if car else []
    return ([warning] if warning else []) + car_note + \
        ([string_stability_note(results)] if _has_string_stability(results) else []) + \
        ([iso15622.note(results)] if _has_iso15622(results) else []) + \
        ([waves.note(results)] if _has_waves(results) else []) + \
        ([robustness.note(results)] if _has_robustness(results) else []) + \
        ([alks.note(results)] if _has_alks(results) else [])


def _fmt(key: str, value) -> str:
    if key == "risk":
        from acc_gym.risk.isolated import format_risk

        return format_risk(value)
    if key == "collisions_r157":
        return "-" if value is None else f"{value[0]} / {value[1]}"
    if key == "string_stability":
        from acc_gym.evaluation.string_stability import format_verdict

        return format_verdict(value)
    if key == "iso15622":
        from acc_gym.leaderboard.iso15622 import format_cell

        return format_cell(value)
    if key == "waves":
        from acc_gym.leaderboard.waves import format_cell as format_waves

        return format_waves(value)
    if key in ("robustness", "alks"):
        from acc_gym.leaderboard.robustness import format_cell as format_robustness

        return format_robustness(value)
    if value is None:
        return "-"
    if key == "vs_above":
        return value
    if key in ("qualified", "comfortable", "safe_spacing"):
        return f"{value:.0%}"
    if key == "wall_time_s":
        return f"{value:.1f}"
    if isinstance(value, float):
        return f"{value:.1f}" if key in ("points", "score") or key.startswith("points[") else f"{value:.2f}"
    return str(value)


HEADERS = {"rank": "#", "controller": "controller", "status": "status", "points": "points", "score": "paper score",
           "qualified": "qualified",
           "collisions_per_hour": "collisions/h", "collisions_r157": "preventable / not (R157)",
           "collisions": "collisions", "preventable_collisions": "preventable",
           "comfortable": "comfortable", "safe_spacing": "safe spacing",
           "min_ttc_s": "min TTC [s]", "max_jerk_mps3": "max jerk [m/s^3]", "episodes": "episodes",
           "wall_time_s": "time [s]", "vs_above": "vs above"}


def display_columns(results: dict) -> list[tuple[str, str]]:
    """(key, header) of the printed / Markdown / HTML ranking table."""
    cols = [(k, HEADERS[k]) for k in ("rank", "controller", "status", "points", "vs_above", "score", "qualified",
                                       "collisions", "collisions_per_hour", "collisions_r157", "min_ttc_s",
                                       "comfortable",
                                       "safe_spacing", "max_jerk_mps3")]
    suites = results["manifest"]["suites"]
    if len(suites) > 1:
        cols += [(f"points[{s['name']}]", s["name"]) for s in suites]
    if _has_risk(results):
        cols.append(("risk", f"P(collision) per {results['manifest']['settings']['risk']['family']}"))
    if _has_string_stability(results):
        cols.append(("string_stability", "string stability (max gain)"))
    if _has_iso15622(results):
        from acc_gym.leaderboard.iso15622 import HEADER

        cols.append(("iso15622", HEADER))
    if _has_waves(results):
        from acc_gym.leaderboard.waves import HEADER as WAVES

        cols.append(("waves", WAVES))
    if _has_robustness(results):
        from acc_gym.leaderboard.robustness import HEADER as ROBUSTNESS

        cols.append(("robustness", ROBUSTNESS))
    if _has_alks(results):
        from acc_gym.leaderboard.alks import HEADER as ALKS

        cols.append(("alks", ALKS))
    return cols + [("episodes", "episodes"), ("wall_time_s", "time [s]")]


def _fmt_interval(key: str, value, low, high) -> str:
    """``value [low, high]`` (a share: ``78% [73, 82]``, its ends in percent)."""
    text = _fmt(key, value)
    if value is None or low is None:
        return text
    if key in ("qualified", "comfortable", "safe_spacing"):
        return f"{text} [{100 * low:.0f}, {100 * high:.0f}]"
    return f"{text} [{_fmt(key, float(low))}, {_fmt(key, float(high))}]"


def formatted_rows(results: dict) -> tuple[list[str], list[list[str]]]:
    """Headers and the rows of text of the ranking table: figures with an interval as
    ``value [low, high]``, ties to the row above as ``tie`` in "vs above"."""
    cols = display_columns(results)
    with_ci = {col for col, _, _ in _interval_columns(results)}
    rows = [[_fmt_interval(k, row[k], row[f"{k}_ci_low"], row[f"{k}_ci_high"]) if k in with_ci else _fmt(k, row[k])
             for k, _ in cols] for row in table_rows(results)]
    return [h for _, h in cols], rows


R157_NOTE = ("preventable / not (R157): collisions that UN R157's careful and competent driver (the built-in "
             "cc-driver) avoids in the same scenario / also has")
COLLISIONS_NOTE = ("collisions: episodes that ended in a collision; preventable: those UN R157's careful and "
                   "competent driver (the built-in cc-driver) avoids in the same scenario -- such an episode scores 0 "
                   "points")
RANK_NOTE = ("rank: by mean points (each suite weighs the same; points = the paper score, 0 for an episode that "
             "ended in a preventable collision); the other columns, collisions among them, do not change it")
UNCERTAINTY_NOTE = ("[low, high]: 95 % intervals (means: percentile bootstrap over episodes; qualified and collisions: "
                    "Clopper-Pearson); vs above: 'tie' when the paired difference in points to the row above is not "
                    "significant (95 % paired bootstrap interval contains 0), 'worse' when it is")


TEXT_WIDTH = 120  # [characters] of the printed table and its notes
NAME_WIDTH = 28  # [characters] a longer controller name is shortened in the printed table (the files keep it)
#: the printed table's columns: always these, then the optional ones while the table fits TEXT_WIDTH
TEXT_COLUMNS = ("rank", "controller", "points", "vs_above", "score", "collisions", "preventable_collisions",
                "min_ttc_s")
TEXT_OPTIONAL = ("qualified", "suites", "string_stability", "iso15622", "waves", "robustness", "alks", "risk", "wall_time_s", "comfortable",
                 "safe_spacing", "max_jerk_mps3", "collisions_per_hour", "episodes")


def _short(name: str, width: int = NAME_WIDTH) -> str:
    """``name`` in at most ``width`` characters (its middle elided with "...")."""
    if len(name) <= width:
        return name
    keep = width - 3
    return name[:keep // 2] + "..." + name[len(name) - (keep - keep // 2):]


def _text_cells(results: dict) -> tuple[list[str], list[str], list[list[str]], list[str]]:
    """Keys, headers and rows of the printed table, and the headers of the columns left out
    (they are in the files): :data:`TEXT_COLUMNS`, then :data:`TEXT_OPTIONAL` in order while the
    table stays within :data:`TEXT_WIDTH`."""
    files = dict(display_columns(results))
    optional = []
    for key in TEXT_OPTIONAL:
        if key == "suites":
            optional += [k for k in files if k.startswith("points[")]
        elif key in files:
            optional.append(key)
    rows = table_rows(results)

    def cells(key: str) -> list[str]:
        if key in ("points", "qualified"):  # the ranked figure and the share qualified with their intervals
            return [_fmt_interval(key, r[key], r[f"{key}_ci_low"], r[f"{key}_ci_high"]) if r["status"] == "ok"
                    else "failed" if key == "points" else "-" for r in rows]
        if key == "controller":
            return [_short(r[key]) for r in rows]
        return [_fmt(key, r[key]) for r in rows]

    def header(key: str) -> str:
        return "points [95 % CI]" if key == "points" else HEADERS.get(key) or files[key]

    def width(key: str, col: list[str]) -> int:
        return max([len(header(key)), *(len(c) for c in col)])

    keys = list(TEXT_COLUMNS)
    columns = {k: cells(k) for k in keys}
    total = sum(width(k, columns[k]) for k in keys) + 2 * (len(keys) - 1)
    left_out = []
    for key in optional:
        col = cells(key)
        if total + 2 + width(key, col) <= TEXT_WIDTH:
            keys.append(key)
            columns[key] = col
            total += 2 + width(key, col)
        else:
            left_out.append(header(key))
    return keys, [header(k) for k in keys], [[columns[k][i] for k in keys] for i in range(len(rows))], left_out


def _wrapped(text: str, width: int = TEXT_WIDTH, indent: str = "  ") -> list[str]:
    import textwrap

    return textwrap.wrap(text, width, subsequent_indent=indent, break_long_words=True, break_on_hyphens=False) \
        or [""]


def text_table(results: dict) -> str:
    """The ranking as aligned plain text (what the CLI prints), at most :data:`TEXT_WIDTH`
    characters wide: the columns of :func:`_text_cells` (the others are named below it: they are
    in results.csv, leaderboard.md and report.html), the notes wrapped, failures listed below."""
    _, headers, rows, left_out = _text_cells(results)
    widths = [max(len(h), *(len(r[k]) for r in rows)) if rows else len(h) for k, h in enumerate(headers)]
    lines = ["  ".join(h.ljust(w) for h, w in zip(headers, widths)).rstrip(),
             "  ".join("-" * w for w in widths)]
    lines += ["  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows]
    notes = [UNCERTAINTY_NOTE, COLLISIONS_NOTE, RANK_NOTE, *column_notes(results)]
    if left_out:
        notes.append(f"in results.csv, leaderboard.md and report.html: {', '.join(left_out)}")
    notes += [f"failed: {c['name']}: {c['reason']}" for c in results["controllers"] if c["status"] != "ok"]
    for note in notes:
        lines += _wrapped(note)
    return "\n".join(lines)


def markdown(results: dict) -> str:
    m = results["manifest"]
    headers, rows = formatted_rows(results)
    suites = ", ".join(f"`{s['name']}` (v{s['version']}, sha256 `{s['hash'][:12]}`, {s['episodes_run']} of "
                       f"{s['episodes_defined']} episodes)" for s in m["suites"])

    def esc(s: str) -> str:
        return s.replace("|", "\\|")

    lines = ["# acc_gym leaderboard", "",
             (f"Split `{m['split']}` of {suites}. Ranking: {RANKING_RULE}. acc_gym {m['versions']['acc_gym']}, "
              f"{m['created']}."), "", UNCERTAINTY_NOTE + ".", "",
             R157_NOTE + ".", "",
             *(line for note in column_notes(results) for line in (note + ".", "")),
             "| " + " | ".join(headers) + " |", "|" + "|".join("---" for _ in headers) + "|"]
    lines += ["| " + " | ".join(esc(c) for c in r) + " |" for r in rows]
    failed = [c for c in results["controllers"] if c["status"] != "ok"]
    if failed:
        lines += ["", "Failed:", ""] + [f"* `{c['name']}`: {esc(c['reason'])}" for c in failed]
    return "\n".join(lines) + "\n"


def csv_text(results: dict) -> str:
    rows = table_rows(results)
    buf = io.StringIO()
    nested = ("risk", "string_stability", "iso15622", "waves", "robustness", "collisions_r157")  # as their numeric columns
    fields = [f for f in rows[0] if f not in nested] if rows else list(COLUMNS)
    writer = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: "" if v is None else v for k, v in row.items() if k not in nested})
    return buf.getvalue()


# -- results.json -----------------------------------------------------------------------------
KEY_ENV = "ACC_GYM_RESULTS_KEY"
KEY_FILE_ENV = "ACC_GYM_RESULTS_KEY_FILE"
_NO_KEY = object()


def results_key(run: bool = False) -> bytes | None:
    """The host's key for signing results (``None`` if neither variable is set). Its file must be
    readable by its owner only (:func:`acc_gym.suites.private.read_private_file`); for a ``run``
    (controllers will run) the key itself in :data:`KEY_ENV` is refused: a process of the
    host's user could read it in the runner's environment."""
    from acc_gym.suites.private import read_private_file

    value, path = os.environ.get(KEY_ENV), os.environ.get(KEY_FILE_ENV)
    if value is not None and path is not None:
        raise ValueError(f"set one of {KEY_ENV} and {KEY_FILE_ENV}, not both")
    if run and value is not None:
        raise ValueError(f"the results key is in the environment ({KEY_ENV}), where a process of the same user can "
                         f"read it: put it in a file only you can read (mode 0600) and name it in {KEY_FILE_ENV}")
    if path is not None:
        value = read_private_file(path, "the results key")
    if value is None:
        return None
    key = value.encode("utf-8") if isinstance(value, str) else value
    key = key.strip()
    if len(key) < 16:
        raise ValueError(f"the results key (${KEY_FILE_ENV if path else KEY_ENV}) is {len(key)} bytes long; "
                         f"use at least 16")
    return key


def signature(results: dict, key: bytes) -> dict:
    body = canonical_json(results).encode("ascii")
    return {"alg": "hmac-sha256", "key_id": hashlib.sha256(b"acc_gym.results.key\0" + key).hexdigest()[:16],
            "value": hmac.new(key, body, hashlib.sha256).hexdigest()}


def results_text(results: dict, key=_NO_KEY) -> str:
    """The text of results.json: checksummed, and signed when a key is given (default: the
    host's key from the environment, :func:`results_key`)."""
    key = results_key() if key is _NO_KEY else key
    doc = {"format": FORMAT, "sha256": checksum(results), "results": results}
    if key is not None:
        doc["hmac"] = signature(results, key)
    return json.dumps(doc, indent=1, allow_nan=False) + "\n"


def load_results(path, key=_NO_KEY) -> dict:
    """The results of a ``results.json``, its checksum verified, and its HMAC too when a key
    is set (``key``, default the host's from the environment): ``ValueError`` naming the
    file if either fails or a key is set and the file is unsigned."""
    key = results_key() if key is _NO_KEY else key
    path = Path(path)
    if path.is_dir():
        path = path / "results.json"
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"leaderboard results {str(path)!r} are corrupted (not UTF-8 text: {exc})") from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"leaderboard results {str(path)!r} are truncated or corrupted (invalid JSON: {exc})") \
            from None
    if not isinstance(doc, dict) or set(doc) - {"hmac"} != {"format", "sha256", "results"}:
        raise ValueError(f"leaderboard results {str(path)!r} are not an {FORMAT} file "
                         f"(expected the keys format, sha256, results and an optional hmac)")
    if doc["format"] != FORMAT:
        raise ValueError(f"leaderboard results {str(path)!r} have format {doc['format']!r}; this version reads "
                         f"{FORMAT!r}")
    try:
        actual = checksum(doc["results"])
    except (TypeError, ValueError) as exc:
        raise ValueError(f"leaderboard results {str(path)!r} are corrupted ({exc})") from None
    if actual != doc["sha256"]:
        raise ValueError(f"leaderboard results {str(path)!r} are corrupted: their checksum does not match "
                         f"(stored {str(doc['sha256'])[:12]}..., computed {actual[:12]}...)")
    try:
        uncertainty.check_results(doc["results"])
    except ValueError as exc:
        raise ValueError(f"leaderboard results {str(path)!r} are malformed: {exc}") from None
    if key is not None:
        if "hmac" not in doc:
            raise ValueError(f"leaderboard results {str(path)!r} are not signed, and a results key is set: they "
                             f"were not written by this host's runner")
        expected = signature(doc["results"], key)
        stored = doc["hmac"]
        if not isinstance(stored, dict) or not hmac.compare_digest(str(stored.get("value")), expected["value"]):
            raise ValueError(f"leaderboard results {str(path)!r} fail verification: their HMAC does not match the "
                             f"results key (rewritten after the run, or signed with another key: key id "
                             f"{stored.get('key_id') if isinstance(stored, dict) else None}, this key's "
                             f"{expected['key_id']})")
    return doc["results"]


def write_files(results: dict, out, html: str | None = None, key=_NO_KEY) -> dict[str, Path]:
    """Write results.json (signed with ``key``, default the host's), results.csv,
    leaderboard.md (and report.html) into ``out``, each atomically."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"results.json": atomic_write(out / "results.json", results_text(results, key)),
             "results.csv": atomic_write(out / "results.csv", csv_text(results)),
             "leaderboard.md": atomic_write(out / "leaderboard.md", markdown(results))}
    if html is not None:
        paths["report.html"] = atomic_write(out / "report.html", html)
    return paths
