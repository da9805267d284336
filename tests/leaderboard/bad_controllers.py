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


BrakesAgain = Brakes  # the same controller under a second name: its figures tie with Brakes's


_calls = {"ShortAnswer": 0, "ExitsEarly": 0}  # per process: the episodes in flight are copies of one instance


class ShortAnswer:
    """On its first call writes an answer frame of one action to its socket (the round trip
    carries one row per episode in flight, so with two or more that is too few)."""

    def predict(self, obs, deterministic=True):
        _calls["ShortAnswer"] += 1
        if _calls["ShortAnswer"] == 1:
            import os
            import socket
            import struct
            import sys

            s = socket.socket(fileno=os.dup(int(sys.argv[1])))  # the sandbox's socket (its first argument)
            s.sendall(struct.pack("<4sII", b"ACCA", 1, 0) + struct.pack("<d", 0.0))
        return np.zeros(1, dtype=np.float32), None


class ExitsEarly:
    """Answers a few round trips, then ends its process with exit code 0 (a "clean" exit mid-run)."""

    def predict(self, obs, deterministic=True):
        _calls["ExitsEarly"] += 1
        if _calls["ExitsEarly"] > 20:
            import os

            os._exit(0)
        return np.zeros(1, dtype=np.float32), None


class ShortGapACC:
    """The linear ACC declaring a 0.6 s time gap: string unstable (its threshold is 0.76 s)."""

    time_gap = 0.6
    vectorised = True

    def __init__(self):
        from acc_gym_agents.controllers.linear import LinearACC

        self.law = LinearACC()

    def predict(self, obs, deterministic=True):
        return self.law.predict(obs, deterministic=deterministic)


class FailsInAColumn:
    """Fine in every episode, raises when it is asked about more than one row at once
    (only the string-stability column does that)."""

    vectorised = True

    def __init__(self):
        from acc_gym_agents.controllers.linear import LinearACC

        self.law = LinearACC()

    def predict(self, obs, deterministic=True):
        o = np.asarray(obs)
        if o.ndim == 2 and o.shape[0] > 1:
            raise RuntimeError("deliberate failure on a batch")
        return self.law.predict(obs, deterministic=deterministic)


class FailsAtSpeed:
    """The linear ACC that raises once its speed passes 20 m/s: fine in ncap-v1's first test
    episodes (slow CCRs approaches), fails in the ISO 15622 battery (following at 90 and 120 km/h)."""

    def __init__(self):
        from acc_gym_agents.controllers.linear import LinearACC

        self.law = LinearACC()

    def predict(self, obs, deterministic=True):
        if obs[0] > 20.0:
            raise RuntimeError("too fast for me")
        return self.law.predict(obs, deterministic=deterministic)
