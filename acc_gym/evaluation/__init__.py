"""Evaluation: paper 003's Q/D/G/u/j criteria, the 100-point score and extra metrics.

Pure functions over trajectory arrays, usable on any recorded drive::

    from acc_gym.evaluation import EgoTrace, score_episode
    report = score_episode(EgoTrace.from_csv("drive.csv", time_gap=1.5))
    print(report.summary())

Inside the package a simulated world's ego becomes a trace with
``EgoTrace.from_world(world_trace, b, scenario)``. The rules and their defaults are
explained in :mod:`acc_gym.evaluation.scoring`.
"""

from acc_gym.evaluation.indicators import (centre_to_gap, comfort_j, efficiency_u, gap_safe, in_band, safety_q,
                                           time_to_collision)
from acc_gym.evaluation.metrics import damping_ratio, extra_metrics, speed_overshoot
from acc_gym.evaluation.scoring import (EpisodeReport, ItemResult, ScoringConfig, score_episode, score_record,
                                       score_world)
from acc_gym.evaluation.trace import EgoTrace

__all__ = [
    "EgoTrace", "EpisodeReport", "ItemResult", "ScoringConfig", "centre_to_gap", "comfort_j", "damping_ratio",
    "efficiency_u", "extra_metrics", "gap_safe", "in_band", "safety_q", "score_episode", "score_record",
    "score_world", "speed_overshoot", "time_to_collision",
]
