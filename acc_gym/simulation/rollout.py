"""Simulate columns of vehicles: a lead on a speed profile, then followers with any model.

Vehicles are arranged as ``(B, n)``: ``B`` independent columns (a Monte Carlo batch; 1
for a single column) of ``n`` vehicles each, vehicle 0 being the lead. Follower slot
``j`` (1..n-1) is driven by a model whose ``n`` equals ``B`` (one vehicle per column),
so a single :class:`~acc_gym.drivers.mpc.MPCDriver` steps every column's follower at once.

Each step has two phases: every model decides from the same snapshot (gaps, speeds and
accelerations at the start of the step), then every vehicle moves (Eq. (3) and the exact
integration, no reversing: the world's compiled move,
:func:`acc_gym.simulation._world_kernel.advance`, on either path). So the order of the models
never matters.

Two ways of deciding (``tests/simulation/test_column_kernel.py``: both equal to a reference
loop with numpy physics within 1e-12):

* a column whose followers are all baseline models (IDM, Gipps, ..., ACC:
  :meth:`~acc_gym.drivers.baselines._Model.compiled_law`) runs in one compiled call for the
  whole run (:func:`acc_gym.simulation._column_kernel.run`): no observation objects, no
  Python per step;
* any other column (an MPC driver, a user's driver object, a baseline model whose delay
  buffer two slots share) steps in Python, each follower's model called with its
  :class:`~acc_gym.drivers.base.Observation`; the observations of a step are built and their
  values checked in one compiled call (:func:`acc_gym.simulation._column_kernel.observe`),
  their shapes once per run (``validate`` on the first step: they are the column's own), and
  baseline models are called through ``act_checked`` (no second check of each field).

Either way a value that goes wrong at run time -- a NaN, e.g. from a driver that asked for a
NaN acceleration -- stops the run with a ``ValueError`` naming the vehicle, the step and
the field. A negative gap is a collision: recorded (:attr:`Trajectory.collided`), not an
error, as before.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from acc_gym._validation import check_finite, check_positive
from acc_gym.drivers.base import Observation
from acc_gym.simulation import _column_kernel as _C
from acc_gym.simulation.profiles import SpeedProfile
from acc_gym.simulation._world_kernel import advance
from acc_gym.vehicle import VehicleParams


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

    for m in followers:
        if hasattr(m, "reset"):
            m.reset()
    out["x"][0], out["v"][0], out["a"][0] = x, v, a
    out["gap"][0, :, 0] = np.inf
    out["gap"][0, :, 1:] = gaps0
    t = np.arange(T + 1) * dt
    # the profile's own clock: step k is its time times[0] + k dt (a profile that starts at t0 = 10 s
    # brakes at its own 10 + 5 s, as ProfileDriver plays it), and the duration runs from there
    prof_next = lead.speed(float(lead.times[0]) + t[1:])  # (T,) or (B, T)
    if prof_next.ndim == 1:
        prof_next = np.broadcast_to(prof_next, (B, T))
    stop_at = np.zeros(B) if stop is None else stop  # [m] (unused without a stop position)
    laws = _compiled_laws(followers)
    fault = np.zeros(4)  # column, vehicle, field (index in Observation) and value of a bad observation value
    vp = np.ascontiguousarray(np.broadcast_to(veh.as_matrix(n), (B, n, 10)))  # the move's vehicle parameters
    if laws is not None:
        column = (lengths, vp, float(sensor_range), stop_at, stop is not None)
        done = _C.run(np.ascontiguousarray(prof_next, dtype=float), float(dt), column, tuple(laws),
                      (out["x"], out["v"], out["a"], out["a_des"], out["gap"]), fault)
        if done < T:
            _raise_bad_value(done, fault, out, dt)
    else:
        _step_each_follower(followers, out, prof_next, dt, vp, lengths, float(sensor_range), stop_at,
                            stop is not None, fault)
    stats = {j: m.stats for j, m in enumerate(followers, start=1) if hasattr(m, "stats")}
    sq = (lambda arr: arr[:, 0]) if squeeze else (lambda arr: arr)
    return Trajectory(t=t, **{k: sq(val) for k, val in out.items()}, lengths=lengths, solver_stats=stats)


def _compiled_laws(followers) -> tuple | None:
    """The followers' laws as :func:`acc_gym.simulation._column_kernel.run` takes them (slot
    ``j - 1`` for follower ``j``), or None if some follower is not a baseline model or shares a
    reaction-delay buffer with another slot (the same model object given twice: its one buffer
    then mixes both slots' scenes, which only the per-follower loop reproduces)."""
    laws = []
    for m in followers:
        law = m.compiled_law() if hasattr(m, "compiled_law") else None
        if law is None or (law.delay_steps > 0 and sum(f is m for f in followers) > 1):
            return None
        laws.append(law)
    return (np.array([law.kind for law in laws], dtype=np.int64),
            np.ascontiguousarray(np.stack([law.params for law in laws])),  # (n-1, B, MAX_PARAMS)
            np.array([law.dt for law in laws]), np.array([law.delay_steps for law in laws], dtype=np.int64),
            np.array([law.two_ahead for law in laws]))


def _step_each_follower(followers, out: dict, prof_next: np.ndarray, dt: float, vp: np.ndarray,
                        lengths: np.ndarray, sensor_range: float, stop: np.ndarray, has_stop: bool,
                        fault: np.ndarray) -> None:
    """Steps ``0 .. T-1`` with each follower's model called in Python on its observation, the
    trajectory recorded into ``out`` (row 0 filled). The observations of a step are one array
    made afresh (a model may keep what it was given, e.g. in a delay buffer), built and checked
    by :func:`acc_gym.simulation._column_kernel.observe`; on the first step each is also
    validated as a model's ``act`` would (shapes and types: the column's, the same every step).
    ``vp``: the vehicles' parameters ``(B, n, 10)`` (``VehicleParams.as_matrix``)."""
    T, B, n = prof_next.shape[1], out["x"].shape[1], out["x"].shape[2]
    x, v, a = out["x"][0], out["v"][0], out["a"][0]
    a_des = np.zeros((B, n))
    present = np.ones((B, n), dtype=np.bool_)
    act = [getattr(m, "act_checked", m.act) for m in followers]
    for k in range(T):
        # phase 1: every driver decides from the same snapshot
        a_des[:, 0] = (prof_next[:, k] - v[:, 0]) / dt
        rows = np.empty((n - 1, len(_C.FIELDS), B))
        if not _C.observe(x, v, a, lengths, sensor_range, stop, has_stop, rows, fault):
            _raise_bad_value(k, fault, out, dt)
        for j, model in enumerate(followers, start=1):
            r = rows[j - 1]
            obs = Observation(*r[:5], *((r[5], r[6], r[7]) if j >= 2 else (None, None, None)),
                              stop_gap=r[8] if has_stop else None)
            if k == 0:
                obs.validate(B)
            a_des[:, j] = act[j - 1](obs)
            info = getattr(model, "info", None) or {}
            for key in ("mode", "path", "a_req", "slack"):
                if key in info:
                    out[key][k + 1, :, j] = info[key]
        # phase 2: every vehicle moves (a NaN request moves it to NaN: the next step's check names it)
        advance(a_des, present, x, v, vp, dt, out["x"][k + 1], out["v"][k + 1], out["a"][k + 1], out["a_des"][k + 1])
        x, v, a = out["x"][k + 1], out["v"][k + 1], out["a"][k + 1]
        out["gap"][k + 1, :, 0] = np.inf
        out["gap"][k + 1, :, 1:] = x[:, :-1] - lengths[:-1] - x[:, 1:]


def _raise_bad_value(k: int, fault: np.ndarray, out: dict, dt: float) -> None:
    """Raise ``ValueError`` for the bad observation value that stopped step ``k`` (``fault``:
    column, vehicle, field, value), naming the vehicle, the step and, when a driver asked for a
    non-finite acceleration the step before (where a NaN comes from), that driver's vehicle."""
    b, j, f = (int(i) for i in fault[:3])
    name = _C.FIELDS[f]
    column = f" in column {b}" if out["x"].shape[1] > 1 else ""
    cause = ""
    bad = np.flatnonzero(~np.isfinite(out["a_des"][k, b])) if k >= 1 else []
    if len(bad):
        who = "the lead's speed profile" if bad[0] == 0 else f"vehicle {bad[0]}'s driver"
        cause = f" ({who} asked for an acceleration of {float(out['a_des'][k, b, bad[0]])!r} m/s^2 at step {k - 1})"
    raise ValueError(f"column simulation stopped at step {k} (t = {k * dt:g} s): vehicle {j}{column} observes "
                     f"{name} = {float(fault[3])!r}, which must be {_RULES[name]}{cause}")


_RULES = {name: ("not NaN or -inf (inf: none)" if name in ("gap", "gap2", "stop_gap") else
                 "finite and >= 0" if name == "v" else "finite") for name in _C.FIELDS}
