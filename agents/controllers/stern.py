"""Stern et al.'s two wave-damping controllers (Stern et al. 2018, "Dissipation of stop-and-go
waves via control of autonomous vehicles: field experiments", Transp. Res. C 89:205-221,
arXiv 1705.01693), on the environment's observation (0 speed, 1 acceleration, 2 gap, 3
relative speed ``v_lead - v``, 4 vehicle in range, 5 set speed, 6 time gap).

Both compute a commanded speed ``v_cmd`` and track it as Flow's implementation does
(``flow/controllers/velocity_controllers.py``): ``a = (v_cmd - v) / dt`` with ``dt`` the
environment's step, limited to ``[-decel_limit, accel_limit]`` (ours: 1.5 and 3.0 m/s^2; Flow
takes its vehicle type's limits).

* :class:`FollowerStopper`: with ``dv_- = min(v_lead - v, 0)`` and the thresholds ``dx_k =
  dx_k^0 + dv_-^2 / (2 d_k)`` (``dx^0 = 4.5, 5.25, 6.0`` m, ``d = 1.5, 1.0, 0.5`` m/s^2), and
  ``w = min(max(v_lead, 0), U)``: ``v_cmd = 0`` below ``dx_1``, ``w (dx - dx_1)/(dx_2 - dx_1)``
  up to ``dx_2``, ``w + (U - w)(dx - dx_2)/(dx_3 - dx_2)`` up to ``dx_3`` (the paper's form;
  Flow blends from the own speed instead of ``w``), ``U`` beyond, and ``U`` with nothing in
  range. ``U`` is the commanded speed the experimenters set; here ``v_des``, default the
  observation's set speed.
* :class:`PISaturation`: ``U`` is the mean of its own speed over the last 38 s; ``v_target =
  U + v_catch min(max((dx - g_l)/(g_u - g_l), 0), 1)``; ``alpha = min(max((dx - dx_s)/gamma, 0),
  1)``, ``dx_s = max(2 (v_lead - v), 4)`` m, ``beta = 1 - alpha / 2``; ``v_cmd = beta (alpha
  v_target + (1 - alpha) v_lead) + (1 - beta) v_cmd_prev`` (``gamma = 2`` m, ``g_l = 7`` m,
  ``g_u = 30`` m, ``v_catch = 1`` m/s). Its state (the speed history and ``v_cmd``) is kept
  per row of the batch it is called with, so one copy answers the same vehicle in every ring
  of a batch (``vectorised``); ``reset()`` forgets it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from acc_gym_agents.controllers.linear import _Policy

DT = 0.2  # [s] the environments' step


@dataclass
class FollowerStopper(_Policy):
    """Stern et al.'s FollowerStopper (module docstring)."""

    v_des: float | None = None  # [m/s] U; None: the observation's set speed
    dt: float = DT  # [s]
    accel_limit: float = 1.5  # [m/s^2]
    decel_limit: float = 3.0  # [m/s^2]
    dx0: tuple = (4.5, 5.25, 6.0)  # [m]
    d: tuple = (1.5, 1.0, 0.5)  # [m/s^2]

    def _accel(self, o: np.ndarray) -> np.ndarray:
        v, dx, seen = o[:, 0], o[:, 2], o[:, 4] > 0.5
        u = o[:, 5] if self.v_des is None else np.full(len(o), float(self.v_des))
        v_lead = v + o[:, 3]
        dv_minus = np.minimum(o[:, 3], 0.0)
        dx1, dx2, dx3 = (x0 + dv_minus ** 2 / (2.0 * dk) for x0, dk in zip(self.dx0, self.d))
        w = np.minimum(np.maximum(v_lead, 0.0), u)
        v_cmd = np.where(dx <= dx1, 0.0,
                         np.where(dx <= dx2, w * (dx - dx1) / (dx2 - dx1),
                                  np.where(dx <= dx3, w + (u - w) * (dx - dx2) / (dx3 - dx2), u)))
        v_cmd = np.where(seen, v_cmd, u)
        return np.clip((v_cmd - v) / self.dt, -self.decel_limit, self.accel_limit)


@dataclass
class PISaturation(_Policy):
    """Stern et al.'s PI controller with saturation (module docstring)."""

    dt: float = DT  # [s]
    history: float = 38.0  # [s] the own-speed average that sets U
    gamma: float = 2.0  # [m]
    g_l: float = 7.0  # [m]
    g_u: float = 30.0  # [m]
    v_catch: float = 1.0  # [m/s]
    accel_limit: float = 1.5  # [m/s^2]
    decel_limit: float = 3.0  # [m/s^2]
    _hist: list = field(default_factory=list, repr=False)
    _v_cmd: np.ndarray | None = field(default=None, repr=False)

    def reset(self) -> None:
        self._hist = []
        self._v_cmd = None

    def _accel(self, o: np.ndarray) -> np.ndarray:
        v, dx, dv = o[:, 0], o[:, 2], o[:, 3]
        if self._v_cmd is None or self._v_cmd.shape != v.shape:
            self._hist, self._v_cmd = [], np.zeros_like(v)
        v_lead = v + dv
        self._hist.append(v.copy())
        keep = max(1, int(round(self.history / self.dt)))
        if len(self._hist) > keep:
            del self._hist[0]
        u = np.mean(self._hist, axis=0)
        v_target = u + self.v_catch * np.clip((dx - self.g_l) / (self.g_u - self.g_l), 0.0, 1.0)
        dx_s = np.maximum(2.0 * dv, 4.0)
        alpha = np.clip((dx - dx_s) / self.gamma, 0.0, 1.0)
        beta = 1.0 - 0.5 * alpha
        self._v_cmd = beta * (alpha * v_target + (1.0 - alpha) * v_lead) + (1.0 - beta) * self._v_cmd
        return np.clip((self._v_cmd - v) / self.dt, -self.decel_limit, self.accel_limit)
