"""Simulate columns of vehicles: a lead on a speed profile, then followers with any model.

Vehicles are arranged as ``(B, n)``: ``B`` independent columns (a Monte Carlo batch; 1
for a single column) of ``n`` vehicles each, vehicle 0 being the lead. Follower slot
``j`` (1..n-1) is driven by a model whose ``n`` equals ``B`` (one vehicle per column),
so a single :class:`~acc_gym.drivers.mpc.MPCDriver` steps every column's follower at once.

Each step has two phases: every model decides from the same snapshot (gaps, speeds and
accelerations at the start of the step), then every vehicle moves (exact integration,
no reversing; :mod:`acc_gym.vehicle`). So the order of the models never matters.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from acc_gym._validation import check_finite, check_positive
from acc_gym.drivers.base import Observation
from acc_gym.simulation.profiles import SpeedProfile
from acc_gym.vehicle import VehicleParams, applied_acceleration, integrate


@dataclass
class Trajectory:
    """Recorded column(s). Arrays are ``(T+1, n)`` for one column, ``(T+1, B, n)`` for a batch.

    Row 0 is the initial state; row ``k`` the state after step ``k`` together with what
    was decided at the start of that step: ``a`` the acceleration applied over it,
    ``a_des`` the one asked for, ``mode``/``path``/``a_req``/``slack`` the driver's
    diagnostics (``-1``/NaN where the model has none, and in row 0). ``gap`` is the
    bumper-to-bumper gap to the vehicle ahead (``inf`` for the lead).
    """

    t: np.ndarray  # (T+1,) [s]
    x: np.ndarray  # front-bumper positions [m]
    v: np.ndarray  # [m/s]
    a: np.ndarray  # [m/s^2] applied
    a_des: np.ndarray  # [m/s^2] requested
    gap: np.ndarray  # [m]
    mode: np.ndarray  # int, -1: none
    path: np.ndarray  # int, -1: none
    a_req: np.ndarray  # [m/s^2]
    slack: np.ndarray  # QP slack used
    lengths: np.ndarray  # (n,) [m]
    solver_stats: dict = field(default_factory=dict)  # slot -> model.stats (if any)

    @property
    def collided(self) -> np.ndarray:
        """Per vehicle (and column): did its gap ever drop to 0 or below."""
        return np.any(self.gap <= 0.0, axis=0)


def _as_batch(a, B: int, n: int, name: str) -> np.ndarray:
    arr = np.asarray(a, dtype=float)
    if arr.ndim == 1 and arr.shape[0] == n:
        arr = np.broadcast_to(arr, (B, n))
    if arr.shape != (B, n):
        raise ValueError(f"{name} must have shape ({n},) or ({B}, {n}), got {arr.shape}")
    check_finite(name, arr)
    return arr.copy()


def simulate_column(lead: SpeedProfile, followers, x0, v0, *, duration: float | None = None, dt: float = 0.2,
                    vehicle: VehicleParams | None = None, a0=None, sensor_range: float = np.inf,
                    stop_position=None, batch: int | None = None) -> Trajectory:
    """Simulate a lead on ``lead``'s speed profile followed by ``followers``.

    Parameters
    ----------
    lead: the lead's speed profile (``speeds`` ``(K,)`` or ``(B, K)`` for a batch).
    followers: models, one per follower slot, each with ``n == B`` (see module docstring).
    x0, v0: initial front-bumper positions [m] and speeds [m/s], ``(n,)`` or ``(B, n)``,
        lead first; followers must start behind the vehicle ahead.
    duration: simulated time [s] (default: the profile's duration).
    dt: step [s].
    vehicle: the vehicles' parameters (scalars, or arrays of shape ``(n,)``; the
        batch shares them).
    a0: initial accelerations [m/s^2] (default 0).
    sensor_range: a vehicle ahead beyond this gap [m] is not seen (``gap = inf``).
    stop_position: optional position [m] where every follower must stop (a stop line),
        scalar or ``(B,)``.
    batch: number of columns ``B`` (default: from the profile, else 1 and squeezed).
    """
    check_positive("dt", dt)
    followers = list(followers)
    n = len(followers) + 1
    lead_speeds = np.asarray(lead.speeds)
    squeeze = batch is None and lead_speeds.ndim == 1
    B = batch if batch is not None else (lead_speeds.shape[0] if lead_speeds.ndim == 2 else 1)
    if lead_speeds.ndim == 2 and lead_speeds.shape[0] != B:
        raise ValueError(f"lead profile has {lead_speeds.shape[0]} rows but batch is {B}")
    for j, m in enumerate(followers, start=1):
        if getattr(m, "n", None) != B:
            raise ValueError(f"follower model in slot {j} controls n={getattr(m, 'n', None)} vehicles; "
                             f"it must control one per column (n={B})")
    duration = lead.duration if duration is None else float(duration)
    check_positive("duration", duration)
    steps = int(round(duration / dt))
    veh = (vehicle if vehicle is not None else VehicleParams()).broadcast(n)
    lengths = np.asarray(veh.length, dtype=float)
    x = _as_batch(x0, B, n, "x0")
    v = _as_batch(v0, B, n, "v0")
    if np.any(v < 0):
        raise ValueError(f"v0 must be >= 0, got {v.min()!r}")
    a = np.zeros((B, n)) if a0 is None else _as_batch(a0, B, n, "a0")
    gaps0 = x[:, :-1] - lengths[:-1] - x[:, 1:]
    if np.any(gaps0 <= 0):
        raise ValueError(f"followers must start behind the vehicle ahead; initial gaps {gaps0.min():.3f} m")
    stop = None
    if stop_position is not None:
        stop = np.broadcast_to(np.asarray(stop_position, dtype=float), (B,)).copy()
        check_finite("stop_position", stop)

    T = steps
    out = {k: np.zeros((T + 1, B, n)) for k in ("x", "v", "a", "a_des", "gap", "a_req", "slack")}
    out["mode"] = np.full((T + 1, B, n), -1, dtype=np.int64)
    out["path"] = np.full((T + 1, B, n), -1, dtype=np.int64)
    out["a_req"][:] = np.nan
    out["slack"][:] = np.nan
    out["a_des"][0] = np.nan

    def gaps_of(x):
        g = np.full((B, n), np.inf)
        g[:, 1:] = x[:, :-1] - lengths[:-1] - x[:, 1:]
        return g

    def record(k, x, v, a, g):
        out["x"][k], out["v"][k], out["a"][k], out["gap"][k] = x, v, a, g

    for m in followers:
        if hasattr(m, "reset"):
            m.reset()
    g = gaps_of(x)
    record(0, x, v, a, g)
    t = np.arange(T + 1) * dt
    # the profile's own clock: step k is its time times[0] + k dt (a profile that starts at t0 = 10 s
    # brakes at its own 10 + 5 s, as ProfileDriver plays it), and the duration runs from there
    prof_next = lead.speed(float(lead.times[0]) + t[1:])  # (T,) or (B, T)
    if prof_next.ndim == 1:
        prof_next = np.broadcast_to(prof_next, (B, T))
    a_des = np.zeros((B, n))
    for k in range(T):
        # phase 1: every driver decides from the same snapshot
        a_des[:, 0] = (prof_next[:, k] - v[:, 0]) / dt
        for j, model in enumerate(followers, start=1):
            seen = g[:, j] <= sensor_range
            gap_j = np.where(seen, g[:, j], np.inf)
            if j >= 2:
                gap2 = x[:, j - 2] - lengths[j - 2] - x[:, j]
                gap2 = np.where(seen & (gap2 <= sensor_range), gap2, np.inf)
                obs2 = dict(gap2=gap2, v_lead2=v[:, j - 2].copy(), a_lead2=a[:, j - 2].copy())
            else:
                obs2 = {}
            obs = Observation(v=v[:, j].copy(), a=a[:, j].copy(), gap=gap_j, v_lead=v[:, j - 1].copy(),
                              a_lead=a[:, j - 1].copy(),
                              stop_gap=None if stop is None else stop - x[:, j], **obs2)
            a_des[:, j] = model.act(obs)
            info = getattr(model, "info", None) or {}
            for key in ("mode", "path", "a_req", "slack"):
                if key in info:
                    out[key][k + 1, :, j] = info[key]
        # phase 2: every vehicle moves
        a = applied_acceleration(a_des, v, veh)
        x, v = integrate(x, v, a, dt)
        g = gaps_of(x)
        out["a_des"][k + 1] = a_des
        record(k + 1, x, v, a, g)
    stats = {j: m.stats for j, m in enumerate(followers, start=1) if hasattr(m, "stats")}
    sq = (lambda arr: arr[:, 0]) if squeeze else (lambda arr: arr)
    return Trajectory(t=t, **{k: sq(val) for k, val in out.items()}, lengths=lengths, solver_stats=stats)
