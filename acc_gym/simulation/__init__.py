"""Column rollouts: a lead on a scripted or recorded speed profile, then followers."""

from acc_gym.simulation.profiles import SpeedProfile
from acc_gym.simulation.rollout import Trajectory, simulate_column

__all__ = ["SpeedProfile", "Trajectory", "simulate_column"]
