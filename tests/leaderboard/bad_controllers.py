"""Misbehaving controllers for the leaderboard tests, loaded as ``bad_controllers:NAME``.

The leaderboard loads controllers in a spawned child process; the child gets the
parent's ``sys.path``, so the tests put this directory on ``sys.path`` (pytest's default
import mode already does, and the tests make sure of it) and the child can import it.
"""

import time

import numpy as np


class Raises:
    def predict(self, obs, deterministic=True):
        raise RuntimeError("deliberate failure in predict")


class Hangs:
    """Answers once (the exempt first call), then hangs."""

    def __init__(self):
        self.calls = 0

    def predict(self, obs, deterministic=True):
        self.calls += 1
        if self.calls > 1:
            time.sleep(120.0)
        return np.zeros(1, dtype=np.float32), None


class ReturnsNaN:
    def predict(self, obs, deterministic=True):
        return np.array([np.nan], dtype=np.float32), None


class WrongShape:
    def predict(self, obs, deterministic=True):
        return np.zeros(3, dtype=np.float32), None


class Slow:
    """Within the step budget every step, but far too slow for the total budget."""

    def predict(self, obs, deterministic=True):
        time.sleep(0.3)
        return np.zeros(1, dtype=np.float32), None


class Brakes:
    """A (bad but valid) controller: always brakes gently."""

    def predict(self, obs, deterministic=True):
        return np.array([-0.1], dtype=np.float32), None


class BadTimeGap:
    """Declares a time gap that is not one."""

    time_gap = float("nan")

    def predict(self, obs, deterministic=True):
        return np.zeros(1, dtype=np.float32), None
