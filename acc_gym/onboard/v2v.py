"""The V2V link between the vehicles ahead and a cooperative controller (``v2v=True`` ids).

Without a link model (``V2VConfig()``, the ``ideal`` preset) the observation's V2V fields
(7-10: the vehicle ahead's acceleration, the second vehicle ahead's gap, relative speed and
in-range flag) are the true ones of the current step. With one:

1. **Messages** are sent every ``period`` seconds (rounded up to whole steps; 0: every step)
   and carry the sender's state of that step (the V2V fields as the ideal link shows them).
2. **Loss** comes in bursts: a two-state Markov chain per scene (as the radar's dropouts,
   :mod:`acc_gym.onboard.sensors`) with a long-run lost share ``loss_share`` and a mean burst
   length ``loss_burst`` [s]; a message sent while the chain is in its lost state never arrives.
3. **Latency**: a message arrives ``ceil(latency / dt)`` steps after it was sent.
4. **Timeout**: the controller sees the newest message that has arrived while it is at most
   ``timeout`` seconds old; older than that (or none yet) the link is lost and the V2V fields
   show no V2V data: acceleration 0, no second vehicle (gap the sensor range, relative speed
   0, flag 0).

**Decided: no link flag.** A lost link shows as a vehicle ahead that sends nothing, not as a
new observation field (which would change every ``v2v`` id's observation space). A CACC law
``a = ACC(...) + k3 a_lead`` then drives as its own ACC law (``k3`` acting on 0): the
built-in ``cacc`` with every message lost drives as ``cacc`` with ``k3 = 0`` (tested). The
radar's fields (2-4) are the radar's (:mod:`acc_gym.onboard.sensors`), link or not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

V2V_FIELDS = (7, 8, 9, 10)  # a_lead, gap2, v_rel2, lead2_in_range


def _seconds(name: str, value, top: float = 60.0) -> float:
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    if not ok or not (math.isfinite(value) and 0.0 <= value <= top):
        raise ValueError(f"V2VConfig.{name} must be a number of seconds in [0, {top:g}], got {value!r}")
    return float(value)


@dataclass(frozen=True)
class V2VConfig:
    """A V2V link's message period, latency, burst loss and timeout; validated on construction
    (a bad value is a ``ValueError`` naming it). The defaults are the ideal link."""

    period: float = 0.0  # [s] between messages (0: every step)
    latency: float = 0.0  # [s] from sending to arrival
    loss_share: float = 0.0  # [-] long-run share of messages lost
    loss_burst: float = 0.0  # [s] mean length of a loss burst
    timeout: float = 1.0  # [s] an older message is not used: the link is lost

    def __post_init__(self) -> None:
        for name in ("period", "latency", "loss_burst"):
            object.__setattr__(self, name, _seconds(name, getattr(self, name)))
        object.__setattr__(self, "timeout", _seconds("timeout", self.timeout))
        s = self.loss_share
        if isinstance(s, bool) or not isinstance(s, (int, float, np.integer, np.floating)) or not (
                math.isfinite(s) and 0.0 <= s <= 1.0):
            raise ValueError(f"V2VConfig.loss_share must be a share in [0, 1], got {s!r}")
        object.__setattr__(self, "loss_share", float(s))
        if 0.0 < self.loss_share < 1.0 and self.loss_burst <= 0:
            raise ValueError(f"V2VConfig.loss_burst must be > 0 s when 0 < loss_share < 1 "
                             f"(got loss_share={self.loss_share!r}, loss_burst={self.loss_burst!r})")

    @property
    def ideal(self) -> bool:
        return self.period == 0.0 and self.latency == 0.0 and self.loss_share == 0.0

    def steps(self, dt: float) -> tuple[int, int, int]:
        """``(every, latency, timeout)`` in steps: a message every ``every`` steps, arriving
        ``latency`` steps later, used while at most ``timeout`` steps old."""
        every = max(1, int(math.ceil(self.period / dt - 1e-9)))
        return every, int(math.ceil(self.latency / dt - 1e-9)), int(math.floor(self.timeout / dt + 1e-9))

    def chain(self, dt: float) -> tuple[float, float]:
        """``(p, r)``: per-step probabilities of a loss burst starting and ending."""
        if self.loss_share == 0.0:
            return 0.0, 1.0
        if self.loss_share == 1.0:
            return 1.0, 0.0
        r = min(1.0, dt / self.loss_burst)
        return min(1.0, r * self.loss_share / (1.0 - self.loss_share)), r


class Link:
    """The V2V links of ``n`` scenes (module docstring); fields ``(n, 4)`` in :data:`V2V_FIELDS` order."""

    def __init__(self, config: V2VConfig, n: int, dt: float, obs_range: float):
        self.config = config
        self.n = int(n)
        self.every, self.L, self.timeout = config.steps(dt)
        self._p, self._r = config.chain(dt)
        self._none = np.array([0.0, float(obs_range), 0.0, 0.0])  # what a lost link shows
        self._sent = np.zeros((self.L + 1, self.n, 4))  # messages in flight, by their send step mod L + 1
        self._ok = np.zeros((self.L + 1, self.n), dtype=bool)  # sent and not lost
        self._held = np.tile(self._none, (self.n, 1))  # the newest arrived message
        self._age = np.full(self.n, np.iinfo(np.int64).max // 2, dtype=np.int64)  # [steps] since it was sent
        self.lost = np.zeros(self.n, dtype=bool)  # the loss chain's state
        self.k = np.zeros(self.n, dtype=np.int64)  # steps since the scene's start
        self._rngs: list[np.random.Generator | None] = [None] * self.n

    def reset(self, rows, rngs) -> None:
        """Start scenes ``rows`` with their links' generators ``rngs``: nothing sent yet, the
        chain in its long-run distribution."""
        rows = np.atleast_1d(np.asarray(rows, dtype=np.int64))
        for j, r in enumerate(rows.tolist()):
            self._rngs[r] = rngs[j]
            self.lost[r] = rngs[j].random() < self.config.loss_share
        self._sent[:, rows] = 0.0
        self._ok[:, rows] = False
        self._held[rows] = self._none
        self._age[rows] = np.iinfo(np.int64).max // 2
        self.k[rows] = 0

    def receive(self, truth: np.ndarray, rows=None) -> np.ndarray:
        """One step of scenes ``rows`` (default all): ``truth`` ``(n, 4)`` the true V2V fields of
        this step; returns what the controllers see ``(len(rows), 4)``."""
        rows = np.arange(self.n) if rows is None else np.atleast_1d(np.asarray(rows, dtype=np.int64))
        out = np.empty((rows.shape[0], 4))
        size = self.L + 1
        for j, r in enumerate(rows.tolist()):
            k = int(self.k[r])
            u = self._rngs[r].random()
            self.lost[r] = (u >= self._r) if self.lost[r] else (u < self._p)
            slot = k % size
            if k % self.every == 0:  # a message goes out now, and arrives L steps later
                self._sent[slot, r] = truth[r]
                self._ok[slot, r] = not self.lost[r]
            else:
                self._ok[slot, r] = False
            arriving = (k - self.L) % size
            self._age[r] += 1
            if k >= self.L and self._ok[arriving, r]:
                self._held[r] = self._sent[arriving, r]
                self._age[r] = self.L
            out[j] = self._held[r] if self._age[r] <= self.timeout else self._none
            self.k[r] = k + 1
        return out
