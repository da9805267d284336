"""Simulation: column rollouts (a lead on a speed profile, then followers) and the
single-lane world with lane entries and exits (:mod:`acc_gym.simulation.single_lane`)."""

from acc_gym.simulation.profiles import SpeedProfile
from acc_gym.simulation.rollout import Trajectory, simulate_column
from acc_gym.simulation.single_lane import LateralPlan, Road, SingleLaneWorld, WorldTrace, rollout

__all__ = ["LateralPlan", "Road", "SingleLaneWorld", "SpeedProfile", "Trajectory", "WorldTrace", "rollout",
           "simulate_column"]
