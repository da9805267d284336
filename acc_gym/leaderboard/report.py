"""The leaderboard's self-contained HTML report (plots embedded as base64 PNG).

One file, no external assets, readable offline: the manifest (versions, suites and
their hashes, split, settings), the ranking table (rank, points, paper score, collisions and
the preventable ones, min TTC; intervals under their figures), the points by suite and the other
measures in tables of their own (so each fits a 1400 px window), the failures with their
reasons, per suite a heat map of each controller's mean score by scenario group (the id; NCAP
tests by kind), its columns in numeric order and in rows of at most :data:`GROUP_COLUMNS`, and
each controller's worst episode (lowest score) as speed / gap / acceleration (/ mode) traces
(:func:`acc_gym.plotting.plot_episode`) under a list of what cost its points
(:func:`points_lost`). Figures are drawn on bare matplotlib
``Figure`` objects with the Agg canvas (no pyplot, no display needed).
"""

from __future__ import annotations

import html
import re

import numpy as np
from matplotlib.figure import Figure

from acc_gym.leaderboard.results import (COLLISIONS_NOTE, RANK_NOTE, RANKING_RULE, UNCERTAINTY_NOTE, _fmt,
                                         _fmt_interval, _interval_columns, column_notes, display_columns, table_rows)
from acc_gym.plotting import img

CSS = """
body { font-family: system-ui, sans-serif; margin: 2em; color: #222; max-width: 1320px; }
table { border-collapse: collapse; margin: 1em 0; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; vertical-align: top; }
th { background: #f0f0f0; } td.name { text-align: left; font-family: monospace; max-width: 18em;
  overflow-wrap: anywhere; }
.ci { display: block; font-size: 0.8em; color: #666; white-space: nowrap; }
.failed { color: #a00; } code { background: #f4f4f4; padding: 0 0.2em; overflow-wrap: anywhere; }
img { max-width: 100%; } .small { font-size: 0.85em; color: #555; } .lost { margin: 0.3em 0 0.8em 1.2em; }
"""

#: the ranking table's columns (the others go into the tables below it)
RANKING_KEYS = ("rank", "controller", "status", "points", "vs_above", "score", "qualified", "collisions",
                "preventable_collisions", "collisions_per_hour", "min_ttc_s")
GROUP_COLUMNS = 30  # a heat map with more scenario groups is drawn in rows of at most this many


def natural_key(text: str) -> list:
    """Sort key that orders the numbers in ``text`` by value ("ccrs/60" before "ccrs/120")."""
    return [(0, int(part), "") if part.isdigit() else (1, 0, part) for part in re.split(r"(\d+)", text) if part]


def _cell(key: str, row: dict, with_ci: set) -> str:
    e = html.escape
    if key in with_ci and row.get(f"{key}_ci_low") is not None:
        full = _fmt_interval(key, row[key], row[f"{key}_ci_low"], row[f"{key}_ci_high"])
        value, _, ci = full.partition(" [")
        return f"{e(value)}<span class='ci'>[{e(ci)}</span>"
    return e(_fmt(key, row.get(key)))


def html_table(results: dict, keys) -> str:
    """A table of ``keys`` (columns of :func:`acc_gym.leaderboard.results.display_columns` or
    table rows), one row per controller in ranking order; intervals under their figures."""
    e = html.escape
    headers = {**dict(display_columns(results)), "collisions": "collisions", "preventable_collisions": "preventable"}
    with_ci = {col for col, _, _ in _interval_columns(results)}
    keys = [k for k in keys if k in headers]
    out = ["<table><tr>" + "".join(f"<th>{e(headers[k])}</th>" for k in keys) + "</tr>"]
    for row in table_rows(results):
        cls = ' class="failed"' if row["status"] != "ok" else ""
        out.append(f"<tr{cls}>" + "".join(f"<td class='name'>{e(row[k])}</td>" if k == "controller" else
                                          f"<td>{_cell(k, row, with_ci)}</td>" for k in keys) + "</tr>")
    return "\n".join(out + ["</table>"])


def points_lost(episode: dict, report=None) -> list[str]:
    """What cost ``episode`` (a results record) its points, one line each: a preventable
    collision (all of them), then -- from ``report`` (its re-scored
    :class:`~acc_gym.evaluation.scoring.EpisodeReport`, when it reproduces the recorded score)
    -- each failed item (15) and the efficiency and comfort points short of 20 each; without
    it, what the score alone tells (paper 003: 60 + R1 + R2 when all four items qualify, else
    15 per qualified item)."""
    from acc_gym.evaluation.scoring import ITEM_POINTS

    lines = []
    m = episode["metrics"]
    if m.get("collision"):
        if episode.get("preventable") is False:
            lines.append("collision, not preventable (UN R157's careful driver collides too): the score is kept")
        else:
            lines.append(f"preventable collision (UN R157's careful driver avoids it): all {episode['score']:.1f} "
                         f"points of its score lost, 0 points")
    score = float(episode["score"])
    if report is not None:
        failed = [it for it in report.items if not it.qualified]
        for it in failed:
            lines.append(f"item {it.name} ({it.requirement}) not qualified: -{ITEM_POINTS:g}")
        if failed:
            lines.append("efficiency and comfort (R1 + R2, 40 points) not counted: not every item qualified")
        else:
            if report.r1 < 20 - 1e-9:
                lines.append(f"efficiency R1 = {report.r1:.1f} of 20: -{20 - report.r1:.1f}")
            if report.r2 < 20 - 1e-9:
                lines.append(f"comfort R2 = {report.r2:.1f} of 20: -{20 - report.r2:.1f}")
    elif episode["qualified"]:
        lines.append(f"efficiency and comfort (R1 + R2) {score - 60:.1f} of 40: -{100 - score:.1f}")
    else:
        ok = int(round(score / ITEM_POINTS))
        lines.append(f"{4 - ok} of the 4 items not qualified: -{(4 - ok) * ITEM_POINTS:g}; efficiency and comfort "
                     f"(40) not counted")
    return lines or ["nothing: a full score"]


def _rescored(t: dict):
    """The worst episode's :class:`~acc_gym.evaluation.scoring.EpisodeReport`, scored again from its
    trace here (trusted code on the simulation's trace), or None unless it reproduces the score."""
    from acc_gym.evaluation.scoring import score_world

    if t.get("scenario") is None:
        return None
    try:
        report = score_world(t["trace"], [t["scenario"]])[0]
    except (ValueError, TypeError):
        return None
    return report if abs(report.score - float(t["score"])) <= 1e-9 else None


def score_heatmap(results: dict, suite: str) -> Figure | None:
    """Mean score by scenario group (columns) for each finished controller (rows, ranking order)."""
    by_name = {c["name"]: c for c in results["controllers"]}
    names = [n for n in results["ranking"] if by_name[n]["status"] == "ok"]
    if not names:
        return None
    groups = heatmap_groups(results, suite)
    prefix = _common_prefix(groups)
    z = np.array([[by_name[n]["summary"]["suites"][suite]["by_group"].get(g, np.nan) for g in groups]
                  for n in names])
    chunks = [list(range(k, min(k + GROUP_COLUMNS, len(groups)))) for k in range(0, len(groups), GROUP_COLUMNS)]
    width = min(GROUP_COLUMNS, len(groups))
    fig = Figure(figsize=(max(5.0, 0.42 * width + 3.0), len(chunks) * (0.32 * len(names) + 1.6) + 0.6),
                 layout="constrained")
    axes = np.atleast_1d(fig.subplots(len(chunks), 1, squeeze=False)[:, 0])
    for ax, cols in zip(axes, chunks):
        im = ax.imshow(z[:, cols], vmin=0, vmax=100, cmap="RdYlGn", aspect="auto")
        ax.set_xticks(range(len(cols)), [groups[j][len(prefix):] for j in cols], rotation=60, ha="right",
                      fontsize=8)
        ax.set_yticks(range(len(names)), names, fontsize=8)
        ax.set_xlim(-0.5, width - 0.5)  # every row of the same cell width
        if len(cols) * len(names) <= 400:
            for i in range(len(names)):
                for jj, j in enumerate(cols):
                    if np.isfinite(z[i, j]):
                        ax.text(jj, i, f"{z[i, j]:.0f}", ha="center", va="center", fontsize=7)
    fig.colorbar(im, ax=list(axes), label="mean score", shrink=0.8)
    axes[0].set_title(f"{suite}: mean score by scenario" + (f" ({prefix}...)" if prefix else ""))
    return fig


def heatmap_groups(results: dict, suite: str) -> list[str]:
    """The heat map's columns: the scenario groups of ``suite``, numbers in order of value."""
    groups = {g for c in results["controllers"] if c["status"] == "ok" for g in c["summary"]["suites"][suite]["by_group"]}
    return sorted(groups, key=natural_key)


def _common_prefix(groups: list[str]) -> str:
    """The path prefix (up to a "/") every group shares, left off the labels (said in the title)."""
    if len(groups) < 2:
        return ""
    first, last = min(groups), max(groups)
    k = 0
    while k < min(len(first), len(last)) and first[k] == last[k]:
        k += 1
    return first[:first.rfind("/", 0, k) + 1] if "/" in first[:k] else ""


def render_html(results: dict, traces: dict | None = None) -> str:
    """The report; ``traces``: ``{controller: {"position", "score", "trace"}}`` of the worst episodes."""
    from acc_gym.plotting import plot_episode

    m = results["manifest"]
    e = html.escape
    parts = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
             "<title>acc_gym leaderboard</title>", f"<style>{CSS}</style></head><body>",
             "<h1>acc_gym leaderboard</h1>",
             (f"<p>Split <code>{e(m['split'])}</code>. Ranking: {e(RANKING_RULE)}. Created "
              f"{e(m['created'])}.</p>")]
    parts.append("<table><tr><th>suite</th><th>version</th><th>sha256 (split)</th><th>root seed</th>"
                 "<th>episodes</th><th>hours</th></tr>")
    for s in m["suites"]:
        parts.append(f"<tr><td>{e(s['name'])}</td><td>{s['version']}</td><td><code>{e(s['hash'][:16])}</code></td>"
                     f"<td>{s['root_seed']}</td><td>{s['episodes_run']} / {s['episodes_defined']}</td>"
                     f"<td>{s['hours']:.2f}</td></tr>")
    parts.append("</table>")
    parts.append("<h2>Ranking</h2>" + html_table(results, RANKING_KEYS))
    parts += [f"<p class='small'>{e(note)}.</p>" for note in (RANK_NOTE, COLLISIONS_NOTE, UNCERTAINTY_NOTE)]
    all_keys = [k for k, _ in display_columns(results)]
    suite_keys = [k for k in all_keys if k.startswith("points[")]
    if suite_keys:
        parts.append("<h2>Points by suite</h2>" + html_table(results, ["rank", "controller", *suite_keys]))
    other = [k for k in all_keys if k not in RANKING_KEYS and k not in suite_keys and k != "collisions_r157"]
    parts.append("<h2>Other measures</h2>" + html_table(results, ["rank", "controller", *other]))
    parts += [f"<p class='small'>{e(note)}.</p>" for note in column_notes(results)]
    failed = [c for c in results["controllers"] if c["status"] != "ok"]
    if failed:
        parts.append("<h2>Failed</h2><ul>")
        parts += [f'<li class="failed"><code>{e(c["name"])}</code>: {e(c["reason"])}</li>' for c in failed]
        parts.append("</ul>")
    parts.append("<h2>Score by scenario</h2>")
    for s in m["suites"]:
        fig = score_heatmap(results, s["name"])
        if fig is not None:
            parts.append(f"<h3>{e(s['name'])}</h3>" + img(fig, f"mean score by scenario, {s['name']}"))
    if traces:
        parts.append("<h2>Worst episode of each controller</h2>")
        by_name = {c["name"]: c for c in results["controllers"]}
        for name in results["ranking"]:
            t = traces.get(name)
            if t is None:
                continue
            ep = by_name[name]["episodes"][t["position"]]
            title = (f"{name}: {ep['suite']} #{ep['episode']} {ep['scenario']} (seed {ep['scenario_seed']}), "
                     f"score {ep['score']:.1f}")
            lost = points_lost(ep, _rescored(t))
            parts.append(f"<h3><code>{e(name)}</code></h3><p class='small'>{e(title)}, {ep['points']:.1f} points. "
                         f"What cost the points:</p><ul class='lost small'>"
                         + "".join(f"<li>{e(line)}</li>" for line in lost) + "</ul>")
            parts.append(img(plot_episode(t["trace"], 0, title=title), f"worst episode of {name}"))
    versions = ", ".join(f"{k} {v}" for k, v in m["versions"].items())
    parts.append(f"<p class='small'>{e(versions)}; {e(m['platform'])}</p></body></html>")
    return "\n".join(parts) + "\n"
