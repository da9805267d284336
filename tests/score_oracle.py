"""The 100-point score written with numpy (paper 003 Table 3 under a ``ScoringConfig``): the test
oracle the compiled :func:`acc_gym.evaluation.scoring.score_episode` is checked against
(``tests/evaluation/test_score_kernel.py``). Kept in the tests: the package has one score."""

from __future__ import annotations

import math

import numpy as np

from acc_gym.evaluation.indicators import comfort_j, efficiency_u, gap_safe, in_band, safety_q
from acc_gym.evaluation.metrics import extra_metrics
from acc_gym.evaluation.scoring import ITEM_POINTS, SPEED_TOL, EpisodeReport, ItemResult, ScoringConfig, judged_tau1
from acc_gym.evaluation.trace import EgoTrace


def _after_transients(trace: EgoTrace, transient: float) -> np.ndarray:
    """True at samples at least ``transient`` s after the start and after any change of the vehicle ahead."""
    t = trace.t
    has = trace.has_lead
    if trace.lead_id is not None:
        ident = np.where(has, trace.lead_id, -1.0)
        change = np.concatenate([[False], ident[1:] != ident[:-1]])
    else:  # no identities: a new target shows as an appearing/disappearing vehicle or a gap jump
        expected = (trace.v_lead - trace.v)[:-1] * np.diff(t)
        jump = np.abs(np.diff(np.where(has, trace.gap, 0.0)) - np.where(has[:-1] & has[1:], expected, 0.0)) > 3.0
        change = np.concatenate([[False], (has[1:] != has[:-1]) | (has[1:] & has[:-1] & jump)])
    last_event = np.maximum.accumulate(np.where(change, t, t[0]))
    return t - last_event >= transient


def _closing_in(v, v0, d1, gs, set_speed, cfg: ScoringConfig) -> np.ndarray:
    """Samples where the ego closes in on its leader as fast as it should (module docstring).

    Faster than the leader by more than ``steady_dv``, and either at its set speed or
    already within the distance in which it must brake at ``approach_decel`` to stop
    closing before the band's far edge ``(1 + band_width) Gapsafe``.
    """
    dv = v - v0
    excess = d1 - (1.0 + cfg.band_width) * gs  # [m] beyond the band's far edge
    braking_phase = dv ** 2 >= 2.0 * cfg.approach_decel * excess
    cruising = np.zeros(v.shape, dtype=bool) if set_speed is None else v >= set_speed - cfg.steady_dv
    return (dv > cfg.steady_dv) & (cruising | braking_phase)


def _proper_response_violations(t, q, seen, a, v, cfg: ScoringConfig, grace: float) -> np.ndarray:
    """Samples where Q < 0 has outlasted the grace time without a proper response."""
    neg = seen & (q < 0)
    responding = (a <= -cfg.response_decel) | (v <= cfg.stop_speed)
    start = np.concatenate([[True], ~neg[:-1]]) & neg
    run_start = np.maximum.accumulate(np.where(start, np.arange(t.size), 0))
    late = neg & (t - t[run_start] > grace)
    return late & ~responding




def score_oracle(trace: EgoTrace, config: ScoringConfig | None = None) -> EpisodeReport:
    """Score one episode (paper 003 Table 3 under ``config``; defaults: module docstring).

    The numpy definition the compiled score is tested against."""
    cfg = config if config is not None else ScoringConfig()
    if not isinstance(trace, EgoTrace):
        raise TypeError(f"score_episode needs an EgoTrace, got {type(trace).__name__}")
    tau1 = judged_tau1(trace.time_gap, trace.declared_time_gap, cfg)
    has = trace.has_lead
    d1 = np.where(has, trace.gap, np.inf)
    v0 = np.where(has, trace.v_lead, 0.0)
    gs = gap_safe(trace.v, v0, tau1, cfg.b0, cfg.b1)
    q = safety_q(d1, gs)  # +inf without a vehicle ahead
    seen = has

    # safety
    collision = bool(np.any(has & (trace.gap <= 0.0)))
    if cfg.safety == "literal":
        bad = seen & (q < 0)
        safe_ok = not np.any(bad)
        rule = "Q >= 0"
    else:
        grace = cfg.response_time if cfg.response_time is not None else tau1
        bad = _proper_response_violations(trace.t, q, seen, trace.a, trace.v, cfg, grace) | (has & (trace.gap <= 0))
        safe_ok = not np.any(bad) and not collision
        rule = "Q >= 0 or proper response"
    safety = ItemResult("safety", rule, bool(safe_ok), detail={
        "violations": int(np.sum(bad)),
        "first_violation_t": float(trace.t[np.argmax(bad)]) if np.any(bad) else None,
        "min_q": float(np.min(q[seen])) if np.any(seen) else None,
        "collision": collision})

    # car-following band and efficiency
    band = in_band(q, gs, cfg.band_width)
    u_t = efficiency_u(q, gs, cfg.band_width, clip=cfg.clip)
    moving = (trace.v > cfg.moving_speed) & (v0 > cfg.moving_speed)
    too_fast = np.zeros(trace.n, dtype=bool) if trace.set_speed is None else v0 > trace.set_speed + cfg.lead_margin + SPEED_TOL
    followable = has & (v0 > cfg.moving_speed) & ~too_fast  # a vehicle ahead the ego could follow
    free = ~(has & (trace.gap <= cfg.sensor_range)) | (has & too_fast)  # nothing in view to follow
    if cfg.band == "literal":
        candidates = seen & (gs > 0)
        following = candidates
        share_needed = 1.0
    else:
        settled = _after_transients(trace, cfg.transient)
        candidates = followable & settled
        following = candidates & moving & (np.abs(v0 - trace.v) <= cfg.steady_dv) & (gs > 0)
        share_needed = cfg.band_share
    applicable = bool(np.any(candidates))
    approaching = False  # closing in efficiently at every candidate, never following steadily
    if not applicable:
        band_ok, share = True, float("nan")
    elif not np.any(following):
        share = 0.0
        approaching = cfg.band != "literal" and bool(np.all(
            _closing_in(trace.v, v0, d1, gs, trace.set_speed, cfg)[candidates]))
        band_ok = approaching
    else:
        share = float(np.mean(band[following]))
        band_ok = share >= share_needed - 1e-12
    car_following = ItemResult("car_following", f"0 < G < {cfg.band_width:g} Gapsafe", bool(band_ok), applicable,
                               {"share_in_band": share, "samples": int(np.sum(following)),
                                "share_needed": share_needed, "approaching": approaching})
    if np.any(following):
        u = float(np.mean(u_t[following]))
    elif trace.set_speed is not None and (approaching or not applicable) and np.any(free | candidates):
        keeping = free | candidates if approaching else free
        u_speed = ((trace.set_speed - trace.v) / (cfg.band_width * trace.set_speed))[keeping]
        u = float(np.mean(np.clip(u_speed, 0.0, 1.0) if cfg.clip else u_speed))
    else:
        u = float("nan")
    r1 = 0.0 if math.isnan(u) else (1.0 - u) * 20.0

    # lane items
    d2, d3 = trace.edge_distance, trace.line_distance
    edge = ItemResult("road_edge", "D2 > 0", bool(np.all(d2 > 0)), detail={"min_d2": float(d2.min())})
    line = ItemResult("boundary_line", "D3 > 0", bool(np.all(d3 > 0)), detail={"min_d3": float(d3.min())})

    # comfort
    j_x = comfort_j(trace.a, cfg.a_x_comfort, clip=cfg.clip)
    j_y = comfort_j(trace.lateral_accel, cfg.a_y_comfort, clip=cfg.clip)
    r2 = (1.0 - j_x) * 10.0 + (1.0 - j_y) * 10.0

    items = (safety, car_following, edge, line)
    qualified = all(it.qualified for it in items)
    score = 60.0 + r1 + r2 if qualified else ITEM_POINTS * sum(it.qualified for it in items)
    metrics = extra_metrics(trace, q, seen, cfg.a_x_comfort)
    return EpisodeReport(score=float(score), qualified=bool(qualified), items=items, r1=float(r1), r2=float(r2),
                         u=u, j_x=float(j_x), j_y=float(j_y), tau1=float(tau1), metrics=metrics, config=cfg)


