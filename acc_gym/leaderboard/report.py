"""The leaderboard's self-contained HTML report (plots embedded as base64 PNG).

One file, no external assets, readable offline: the manifest (versions, suites and
their hashes, split, settings), the ranking table, the failures with their reasons, per
suite a heat map of each controller's mean score by scenario group (the id; NCAP tests
by kind: ``ncap/ccrs``, ``ncap/ccrm``, ``ncap/ccrb``), and each controller's worst
episode (lowest score) as speed / gap / acceleration / mode traces
(:func:`acc_gym.plotting.plot_episode`). Figures are drawn on bare matplotlib
``Figure`` objects with the Agg canvas (no pyplot, no display needed).
"""

from __future__ import annotations

import html

import numpy as np
from matplotlib.figure import Figure

from acc_gym.leaderboard.results import RANKING_RULE, column_notes, formatted_rows
from acc_gym.plotting import img

CSS = """
body { font-family: system-ui, sans-serif; margin: 2em; color: #222; }
table { border-collapse: collapse; margin: 1em 0; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }
th { background: #f0f0f0; } td:nth-child(2) { text-align: left; font-family: monospace; }
.failed { color: #a00; } code { background: #f4f4f4; padding: 0 0.2em; }
img { max-width: 100%; } .small { font-size: 0.85em; color: #555; }
"""


def score_heatmap(results: dict, suite: str) -> Figure | None:
    """Mean score by scenario group (columns) for each finished controller (rows, ranking order)."""
    by_name = {c["name"]: c for c in results["controllers"]}
    names = [n for n in results["ranking"] if by_name[n]["status"] == "ok"]
    if not names:
        return None
    groups = sorted({g for n in names for g in by_name[n]["summary"]["suites"][suite]["by_group"]})
    z = np.array([[by_name[n]["summary"]["suites"][suite]["by_group"].get(g, np.nan) for g in groups]
                  for n in names])
    fig = Figure(figsize=(max(5.0, 0.55 * len(groups) + 2.5), 0.45 * len(names) + 2.6), layout="constrained")
    ax = fig.subplots()
    im = ax.imshow(z, vmin=0, vmax=100, cmap="RdYlGn", aspect="auto")
    ax.set_xticks(range(len(groups)), [g.replace("singlelane/", "") for g in groups], rotation=60, ha="right",
                  fontsize=8)
    ax.set_yticks(range(len(names)), names, fontsize=8)
    if len(groups) * len(names) <= 400:
        for i in range(len(names)):
            for j in range(len(groups)):
                if np.isfinite(z[i, j]):
                    ax.text(j, i, f"{z[i, j]:.0f}", ha="center", va="center", fontsize=7)
    fig.colorbar(im, ax=ax, label="mean score")
    ax.set_title(f"{suite}: mean score by scenario")
    return fig


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
    headers, rows = formatted_rows(results)
    parts.append("<h2>Ranking</h2><table><tr>" + "".join(f"<th>{e(h)}</th>" for h in headers) + "</tr>")
    for r in rows:
        cls = ' class="failed"' if r[2] != "ok" else ""
        parts.append(f"<tr{cls}>" + "".join(f"<td>{e(c)}</td>" for c in r) + "</tr>")
    parts.append("</table>")
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
            parts.append(f"<h3><code>{e(name)}</code></h3><p class='small'>{e(title)}"
                         f"{'' if not ep['metrics']['collision'] else ' -- collision'}</p>")
            parts.append(img(plot_episode(t["trace"], 0, title=title), f"worst episode of {name}"))
    versions = ", ".join(f"{k} {v}" for k, v in m["versions"].items())
    parts.append(f"<p class='small'>{e(versions)}; {e(m['platform'])}</p></body></html>")
    return "\n".join(parts) + "\n"
