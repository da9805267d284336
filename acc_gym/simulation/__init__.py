"""Simulation: column rollouts (a lead on a speed profile, then followers), the
single-lane world with lane entries and exits (:mod:`acc_gym.simulation.single_lane`) and
the ring road (:mod:`acc_gym.simulation.ring`)."""

from acc_gym.simulation.profiles import SpeedProfile
from acc_gym.simulation.ring import RingTrace, simulate_ring
from acc_gym.simulation.rollout import Trajectory, simulate_column
from acc_gym.simulation.single_lane import LateralPlan, Road, SingleLaneWorld, WorldTrace, rollout

__all__ = ["LateralPlan", "RingTrace", "Road", "SingleLaneWorld", "SpeedProfile", "Trajectory", "WorldTrace", "rollout",
           "simulate_column", "simulate_ring"]
