"""A campaign's summary: paper 004's metrics with confidence intervals.

Over the episodes done so far (``complete`` says whether that is all of them):

* ``collisions``: episodes that ended in a collision -- their count, and the rate per hour
  of traffic (exposure: the scenarios' durations, the traffic they stand for) with an
  exact Poisson interval;
* ``preventable_collisions`` / ``non_preventable_collisions``: UN R157's split of those
  collisions (:mod:`acc_gym.standards.r157`): the careful and competent driver (``cc-driver``)
  avoids the same scenario / collides too (the rows' ``preventable`` column). Decided: plain
  counts, as ``acc-gym evaluate`` and the leaderboard report them; they add up to
  ``collisions.count``. Added keys of summary format ``/1`` (nothing there changed meaning,
  so the format stays; a summary written before has neither key);
* ``share_comfortable`` / ``share_safe_spacing``: share of *time* with comfortable
  acceleration / with safe spacing (Q >= 0), pooled over episodes weighted by their
  simulated time, with a cluster-robust t interval. For safe spacing only episodes that
  ever had a vehicle ahead count, weighted by their whole simulated time (the episode
  report gives the share, not how many of its samples had a vehicle ahead);
* velocity damping: ``speed_overshoot`` (mean with a t interval, and the largest) and
  ``damping_ratio`` (mean with a t interval) over episodes with a lead transient;
* ``mean_score`` (t interval) and ``share_qualified`` (Wilson interval);
* ``min_ttc`` (smallest over the campaign) and ``max_jerk`` (largest).

Each estimate is ``{"estimate", "low", "high", "n"}`` (``n``: episodes it is over); an
interval that cannot be formed is ``None``. The same campaign always gives the same
summary (no random numbers), whatever backend ran it.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from acc_gym.campaigns import stats
from acc_gym.campaigns.errors import CampaignError
from acc_gym.campaigns.plan import HOUR

SUMMARY_FORMAT = "acc_gym.campaign.summary/1"


def _num(x):
    if x is None:
        return None
    x = float(x)
    if math.isnan(x):
        return None
    return x if math.isfinite(x) else None


def _estimate(triple, n: int) -> dict:
    est, low, high = triple
    return {"estimate": _num(est), "low": _num(low), "high": _num(high), "n": int(n)}


def _column(table, name: str) -> np.ndarray:
    import pyarrow as pa

    col = table.column(name)
    if pa.types.is_boolean(col.type):
        return np.array(col.to_pylist(), dtype=bool)
    return np.array([np.nan if v is None else v for v in col.to_pylist()], dtype=float)


def summarise_table(table, confidence: float = 0.95) -> dict:
    """The metrics above for a table of result rows."""
    n = table.num_rows
    duration = _column(table, "duration")
    simulated = _column(table, "simulated")
    collision = _column(table, "collision")
    qualified = _column(table, "qualified")
    score = _column(table, "score")
    safe = _column(table, "share_safe_spacing")
    overshoot = _column(table, "speed_overshoot")
    damping = _column(table, "damping_ratio")
    ttc = _column(table, "min_ttc")
    jerk = _column(table, "max_jerk")
    hours = float(duration.sum()) / HOUR
    k = int(collision.sum())
    verdicts = table.column("preventable").to_pylist()
    rate = stats.poisson_rate_ci(k, hours, confidence) if n else (math.nan,) * 3
    return {
        "episodes": n,
        "traffic_hours": hours,
        "simulated_hours": float(simulated.sum()) / HOUR,
        "collisions": {"count": k, "per_hour": _estimate(rate, n)},
        "preventable_collisions": sum(v is True for v in verdicts),
        "non_preventable_collisions": sum(v is False for v in verdicts),
        "share_comfortable": _estimate(stats.weighted_share_ci(_column(table, "share_comfortable"), simulated,
                                                               confidence), n),
        "share_safe_spacing": _estimate(stats.weighted_share_ci(safe, simulated, confidence),
                                        int(np.sum(~np.isnan(safe)))),
        "speed_overshoot": {**_estimate(stats.mean_ci(overshoot, confidence, (0.0, math.inf)),
                                        int(np.sum(~np.isnan(overshoot)))),
                            "max": _num(np.nanmax(overshoot)) if np.any(~np.isnan(overshoot)) else None},
        "damping_ratio": _estimate(stats.mean_ci(damping, confidence, (0.0, 1.0)), int(np.sum(~np.isnan(damping)))),
        "mean_score": _estimate(stats.mean_ci(score, confidence, (0.0, 100.0)), n),
        "share_qualified": _estimate(stats.wilson_ci(int(qualified.sum()), n, confidence), n),
        "min_ttc": _num(ttc.min()) if n else None,  # None: never closing in (inf) or no episodes
        "max_jerk": _num(jerk.max()) if n else None,
    }


def summarise_campaign(campaign, confidence: float = 0.95) -> dict:
    """The summary of a :class:`~acc_gym.campaigns.campaign.Campaign` (or of its output directory)."""
    from acc_gym.campaigns.campaign import Campaign, load_campaign

    if not isinstance(campaign, Campaign):
        campaign = load_campaign(campaign)
    m = campaign.manifest
    head = {"format": SUMMARY_FORMAT, "fingerprint": m["fingerprint"], "suite": m["suite"],
            "suite_version": m["suite_version"], "suite_hash": m["suite_hash"], "split": m["split"],
            "root_seed": m["root_seed"], "controller": m["controller"], "env_id": m["env_id"], "hours": m["hours"],
            "chunk_size": m["chunk_size"], "complete": campaign.complete, "planned_episodes": m["n_scenarios"],
            "chunks_done": len(campaign.chunks_done), "chunks": m["n_chunks"], "confidence": confidence}
    return {**head, **summarise_table(campaign.table, confidence)}


def load_summary(out_dir) -> dict:
    """``summary.json`` of a campaign directory, checked against its manifest."""
    from acc_gym.campaigns.campaign import load_campaign
    from acc_gym.campaigns.store import SUMMARY, read_json

    campaign = load_campaign(out_dir)
    path = Path(out_dir) / SUMMARY
    if not path.is_file():
        raise CampaignError(f"{path} does not exist (run the campaign, or summarise_campaign({str(out_dir)!r}))")
    summary = read_json(path, "campaign summary")
    if summary.get("format") != SUMMARY_FORMAT or "mean_score" not in summary:
        raise CampaignError(f"campaign summary {path} is corrupted: not a summary of format {SUMMARY_FORMAT!r}")
    if summary.get("fingerprint") != campaign.manifest["fingerprint"]:
        raise CampaignError(f"campaign summary {path} belongs to another campaign (fingerprint "
                            f"{summary.get('fingerprint')!r}, expected {campaign.manifest['fingerprint']!r})")
    return summary


def _ci(e: dict, fmt: str) -> str:
    if e["estimate"] is None:
        return "n/a"
    s = format(e["estimate"], fmt)
    if e["low"] is not None:
        s += f"  [{format(e['low'], fmt)}, {format(e['high'], fmt)}]"
    return s


def format_summary(s: dict) -> str:
    """The summary as a table (what ``acc-gym campaign`` prints)."""
    state = "complete" if s["complete"] else f"INCOMPLETE: {s['chunks_done']} of {s['chunks']} chunks"
    lines = [f"campaign: {s['controller']} on {s['suite']} v{s['suite_version']} ({s['split']}, root seed "
             f"{s['root_seed']}): {s['episodes']} of {s['planned_episodes']} episodes, "
             f"{s['traffic_hours']:.2f} h of traffic ({state})",
             f"{'metric':<26} {'estimate  [' + format(s['confidence'], '.0%') + ' CI]':<34} n"]
    col = s["collisions"]
    os_max = s["speed_overshoot"]["max"]
    rows = [
        ("collisions", str(col["count"]), s["episodes"]),
        ("collisions per hour", _ci(col["per_hour"], ".2f"), col["per_hour"]["n"]),
        ("  preventable (UN R157)", f"{s['preventable_collisions']} preventable, {s['non_preventable_collisions']} not",
         col["count"]),
        ("share comfortable", _ci(s["share_comfortable"], ".1%"), s["share_comfortable"]["n"]),
        ("share safe spacing", _ci(s["share_safe_spacing"], ".1%"), s["share_safe_spacing"]["n"]),
        ("speed overshoot (mean)", _ci(s["speed_overshoot"], ".3f"), s["speed_overshoot"]["n"]),
        ("speed overshoot (max)", "n/a" if os_max is None else f"{os_max:.3f}", s["speed_overshoot"]["n"]),
        ("damping ratio (mean)", _ci(s["damping_ratio"], ".3f"), s["damping_ratio"]["n"]),
        ("mean score", _ci(s["mean_score"], ".1f"), s["mean_score"]["n"]),
        ("share qualified", _ci(s["share_qualified"], ".1%"), s["share_qualified"]["n"]),
        ("min TTC [s]", "none" if s["min_ttc"] is None else f"{s['min_ttc']:.2f}", s["episodes"]),
        ("max jerk [m/s^3]", "n/a" if s["max_jerk"] is None else f"{s['max_jerk']:.2f}", s["episodes"]),
    ]
    lines += [f"  {name:<24} {val:<34} {n}" for name, val, n in rows]
    return "\n".join(lines)
