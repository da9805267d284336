"""Compiled per-step criteria, reward and episode record of the environment core.

:meth:`acc_gym.envs.core.EpisodeBatch.step` evaluates, for every scene, the same
per-sample definitions the 100-point score uses (:mod:`acc_gym.evaluation.scoring`):
Gapsafe and Q, the band, car-following and free samples, ``u_t``, the proper-response
safety check and a collision. On a few scenes that is dozens of tiny numpy operations
per step; :func:`criteria` does them in one pass, :func:`criteria_reward_rows` weighs them as
the default :class:`~acc_gym.envs.reward.CriteriaReward`, :func:`settle` ends the step
(termination, truncation, returns, the scenes whose episode ended), :func:`record` writes
the step into the episode records and :func:`action_to_accel` maps the actions.
``tests/envs/test_env_kernel.py`` checks them against numpy oracles kept in the tests
(``tests/envs/reward_oracle.py``, ``tests/score_oracle.py``).

A step is two calls, :func:`step` (the world's move, the criteria, a built-in reward) and
:func:`finish` (the end of the step, the records, the observations), with the caller's reward
between them when it is not built in. Both read the core's state as one :data:`CORE` record
of five named records: the world (:data:`acc_gym.simulation._world_kernel.WORLD`), the
scenes' episodes (:data:`SCENES`), the step's settings (:data:`PLAN`), its outputs
(:data:`OUT`) and the ego's car (:data:`CAR`: its actuators, applied to the command before the
move, and its radar, stepped at the step's end; both off without a car); only what changes
every step (the commands, the state before and after the move, the fresh observation arrays)
is passed beside it.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba.core import types
from numba.experimental import structref

from acc_gym.evaluation.scoring import SPEED_TOL
from acc_gym.envs import observation as _O
from acc_gym.onboard import _actuator_kernel as _A, _radar_kernel as _R
from acc_gym.simulation import _world_kernel as _W

# rows of criteria()'s float output
F_V, F_A, F_JERK, F_GAP, F_GS, F_Q, F_U, F_VLEAD, F_ALEAD = range(9)
N_FLOAT = 9
F_T = N_FLOAT  # the scene's time [s]: the extra row step() writes after criteria()'s
# rows of its boolean output
B_HAS, B_IN_BAND, B_FOLLOWING, B_FREE, B_VIOLATION, B_COLLISION, B_FOLLOWABLE = range(7)
N_BOOL = 7
# the reward terms of criteria_reward_rows(), in info["rewards"] order
TERMS = ("band", "efficiency", "speed", "comfort", "jerk", "safety", "collision", "lag")
# step()'s reward: none (a reward object computes it), CriteriaReward's, MarginReward's
REWARD_NONE, REWARD_CRITERIA, REWARD_MARGIN = 0, 1, 2
RADAR_LO = 2  # the observation's radar fields: gap, relative speed, in range (columns 2-4)
# the episode record's rows (EgoTrace columns)
RECORD = ("t", "v", "a", "gap", "v_lead", "a_lead", "lead_id", "a_y", "d2", "d3")


# ---------------------------------------------------------------------------------------
# The step's records: named fields, each a few arguments of the kernels
# ---------------------------------------------------------------------------------------

class _Fields(types.StructRef):
    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(t)) for name, t in fields)


@structref.register
class ScenesType(_Fields):
    """numba's type of a :data:`SCENE_FIELDS` record."""


@structref.register
class PlanType(_Fields):
    """numba's type of a :data:`PLAN_FIELDS` record."""


@structref.register
class OutType(_Fields):
    """numba's type of an :data:`OUT_FIELDS` record."""


@structref.register
class CarType(_Fields):
    """numba's type of a :data:`CAR_FIELDS` record."""


@structref.register
class CoreType(_Fields):
    """numba's type of a :data:`CORE_FIELDS` record."""


class Record(structref.StructRefProxy):
    """A record of the environment core's step, as the kernels read it (fields: the ``*_FIELDS``
    tables); Python keeps its own references to the same arrays (:class:`acc_gym.envs.core.EpisodeBatch`)."""


for _t in (ScenesType, PlanType, OutType, CarType, CoreType):
    structref.define_boxing(_t, Record)

_F1, _F2, _F3 = types.float64[::1], types.float64[:, ::1], types.float64[:, :, ::1]
_B1, _B2, _I1 = types.bool_[::1], types.bool_[:, ::1], types.int64[::1]
# each scene's episode: (n,) arrays unless noted
SCENE_FIELDS = (
    ("set_speed", _F1),  # [m/s]
    ("tau1", _F1),  # [s] the time gap the episode is judged at
    ("grace", _F1),  # [s] the proper response's grace
    ("lead_prev", _I1),  # the vehicle ahead at the last step (-1 none)
    ("last_change", _F1),  # [s] when it last changed
    ("neg_since", _F1),  # [s] when Q last turned negative (nan: it is not)
    ("steps", _I1),  # the step budget
    ("episode_return", _F1),
    ("ego_width", _F1),  # [m]
    ("lane_width", _F1),  # [m]
    ("n_lanes", _F1),
    ("time_gap", _F1),  # [s] the scenario's (the observation's)
    ("rec", _F3),  # (RECORD, n, steps) the episode records
)
# what a step needs that changes only with the reward and the observation's bounds
PLAN_FIELDS = (
    ("cfg", _F1),  # the scoring constants criteria() reads
    ("code", types.int64),  # REWARD_NONE, REWARD_CRITERIA or REWARD_MARGIN
    ("a_comfort", types.float64),  # [m/s^2]
    ("weights", _F1),  # the built-in reward's (TERMS' or MARGIN_W)
    ("terminate", types.bool_),  # a violation ends the episode
    ("obs_range", types.float64),  # [m] the observation's sensor range
    ("v2v", types.bool_),
    ("low", _F1), ("high", _F1),  # the v0 fields' bounds (empty: no observation made)
    ("f_low", _F1), ("f_high", _F1),  # the safety-margin features' (empty for version 0)
)
# the step's outputs, the core's own arrays (overwritten by the next step)
OUT_FIELDS = (
    ("fl", _F2),  # (N_FLOAT + 1, n) criteria() rows, then the time F_T
    ("bo", _B2),  # (N_BOOL, n)
    ("terms", _F2),  # (terms, n) the built-in reward's
    ("reward", _F1),
    ("terminated", _B1), ("truncated", _B1),
    ("rows", _I1), ("ended", _I1),  # the scenes stepped and those whose episode ended (first counts)
)
# the ego's car (acc_gym.envs.car.Car): its actuators and its radar, the records and arrays of
# acc_gym.onboard's kernels (a part not modelled is off and holds empty arrays)
CAR_FIELDS = (
    ("actuated", types.bool_),  # the actuators are modelled
    ("vehicles", numba.typeof(np.zeros(1, dtype=_A.VEHICLE))),  # (n,) each ego's actuator
    ("hist", _F2),  # (H, n) [m/s^2] the last commands
    ("head", _I1),  # (1,) the newest row of hist
    ("realised", _F1),  # (n,) [m/s^2] what the vehicles are asked to realise this step
    ("sensing", types.bool_),  # the radar is modelled
    ("radar", numba.typeof(np.zeros(1, dtype=_R.RADAR))),  # (1,) its constants and clock
    ("tracks", numba.typeof(np.zeros(1, dtype=_R.SCENE))),  # (n,) each scene's track and dropout chain
    ("reports", _F3),  # (latency + 1, n, 3)
    ("draws", _F3),  # (n, BLOCK, 3)
    ("every", _I1),  # (n,) every scene, the rows the radar steps
    ("sensed", _F2),  # (n, 3) its step's reports
    ("pos_max", _I1),  # (1,) the largest next draw position after its last step
    ("seen", _F2),  # (n, 11) the last observed v0 fields the car changes
    ("fields", _F2),  # (n, m) float64 scratch: an observation's v0 fields
)
SCENES, PLAN, OUT = ScenesType(list(SCENE_FIELDS)), PlanType(list(PLAN_FIELDS)), OutType(list(OUT_FIELDS))
CAR = CarType(list(CAR_FIELDS))
CORE_FIELDS = (("world", _W.WORLD), ("scenes", SCENES), ("plan", PLAN), ("out", OUT), ("car", CAR))
CORE = CoreType(list(CORE_FIELDS))


@numba.njit(cache=True)
def make_scenes(f):  # pragma: no cover - compiled
    """A :data:`SCENES` record of the values ``f``, in :data:`SCENE_FIELDS` order."""
    r = structref.new(SCENES)
    r.set_speed, r.tau1, r.grace, r.lead_prev, r.last_change, r.neg_since, r.steps = f[0], f[1], f[2], f[3], f[4], f[5], f[6]
    r.episode_return, r.ego_width, r.lane_width, r.n_lanes, r.time_gap, r.rec = f[7], f[8], f[9], f[10], f[11], f[12]
    return r


@numba.njit(cache=True)
def make_plan(f):  # pragma: no cover - compiled
    """A :data:`PLAN` record of the values ``f``, in :data:`PLAN_FIELDS` order."""
    r = structref.new(PLAN)
    r.cfg, r.code, r.a_comfort, r.weights, r.terminate, r.obs_range = f[0], f[1], f[2], f[3], f[4], f[5]
    r.v2v, r.low, r.high, r.f_low, r.f_high = f[6], f[7], f[8], f[9], f[10]
    return r


@numba.njit(cache=True)
def make_out(f):  # pragma: no cover - compiled
    """An :data:`OUT` record of the values ``f``, in :data:`OUT_FIELDS` order."""
    r = structref.new(OUT)
    r.fl, r.bo, r.terms, r.reward, r.terminated, r.truncated, r.rows, r.ended = f[0], f[1], f[2], f[3], f[4], f[5], f[6], f[7]
    return r


@numba.njit(cache=True)
def make_car(f):  # pragma: no cover - compiled
    """A :data:`CAR` record of the values ``f``, in :data:`CAR_FIELDS` order."""
    r = structref.new(CAR)
    r.actuated, r.vehicles, r.hist, r.head, r.realised = f[0], f[1], f[2], f[3], f[4]
    r.sensing, r.radar, r.tracks, r.reports, r.draws, r.every = f[5], f[6], f[7], f[8], f[9], f[10]
    r.sensed, r.pos_max, r.seen, r.fields = f[11], f[12], f[13], f[14]
    return r


@numba.njit(cache=True)
def make_core(world, scenes, plan, out, car):  # pragma: no cover - compiled
    """A :data:`CORE` record of these five."""
    r = structref.new(CORE)
    r.world, r.scenes, r.plan, r.out, r.car = world, scenes, plan, out, car
    return r


def no_car() -> dict:
    """:data:`CAR_FIELDS`' values of a car that models nothing (both parts off, empty arrays)."""
    return dict(actuated=False, vehicles=np.zeros(0, dtype=_A.VEHICLE), hist=np.zeros((1, 0)),
                head=np.zeros(1, dtype=np.int64), realised=np.zeros(0), sensing=False,
                radar=np.zeros(1, dtype=_R.RADAR), tracks=np.zeros(0, dtype=_R.SCENE), reports=np.zeros((1, 0, 3)),
                draws=np.zeros((0, 1, 3)), every=np.zeros(0, dtype=np.int64), sensed=np.zeros((0, 3)),
                pos_max=np.zeros(1, dtype=np.int64), seen=np.zeros((0, 11)), fields=np.zeros((0, 7)))


def record_of(fields: tuple, values: dict):
    """The record of ``fields`` (a ``*_FIELDS`` table) holding ``values`` by name: the one place
    their order is read (a C-contiguous array is shared, not copied)."""
    make = {SCENE_FIELDS: make_scenes, PLAN_FIELDS: make_plan, OUT_FIELDS: make_out, CAR_FIELDS: make_car}[fields]
    out = []
    for name, t in fields:
        value = values[name]
        if isinstance(t, types.Array):
            if not (isinstance(value, np.ndarray) and value.flags.c_contiguous and value.ndim == t.ndim):
                raise ValueError(f"record field {name} must be a C-contiguous {t.ndim}-d array, got {value!r}")
        out.append(value)
    return make(tuple(out))


@numba.njit(cache=True, error_model="numpy")
def criteria(t, v, a, lead_all, gap_all, a_prev, dt, scenes, cfg, fl, bo):  # pragma: no cover - compiled
    """One step's criteria of the ego (slot 0) of every scene.

    ``v``, ``a`` ``(n, S)`` and ``lead_all``, ``gap_all`` the world's neighbours; ``scenes`` the
    episodes (a :data:`SCENES` record: set speeds, tau1, grace, and the memory of the vehicle
    ahead and of Q below zero, which this updates); ``cfg`` the scoring constants ``(b0, b1,
    band_width, steady_dv, moving_speed, transient, sensor_range, response_decel, stop_speed,
    lead_margin)``. Writes ``fl`` (:data:`N_FLOAT`, n) and ``bo`` (:data:`N_BOOL`, n).
    """
    b0, b1, bw, steady_dv, moving, transient, sensor, resp_decel, stop_speed, lead_margin = (
        cfg[0], cfg[1], cfg[2], cfg[3], cfg[4], cfg[5], cfg[6], cfg[7], cfg[8], cfg[9])
    set_speed, tau1, grace = scenes.set_speed, scenes.tau1, scenes.grace
    lead_prev, last_change, neg_since = scenes.lead_prev, scenes.last_change, scenes.neg_since
    n = v.shape[0]
    for i in range(n):
        ti = t[i]
        v1 = v[i, 0]
        a1 = a[i, 0]
        lead = lead_all[i, 0]
        gap = gap_all[i, 0]
        has = lead >= 0
        v0 = v[i, lead] if has else 0.0
        fl[F_VLEAD, i] = v0
        fl[F_ALEAD, i] = a[i, lead] if has else 0.0
        fl[F_V, i] = v1
        fl[F_A, i] = a1
        fl[F_JERK, i] = (a1 - a_prev[i]) / dt
        fl[F_GAP, i] = gap
        if lead != lead_prev[i]:
            last_change[i] = ti
        lead_prev[i] = lead
        gs = v1 * tau1[i] + v1 ** 2 / (2.0 * b1) - v0 ** 2 / (2.0 * b0)
        q = gap - gs if has else np.inf
        fl[F_GS, i] = gs
        fl[F_Q, i] = q
        bo[B_HAS, i] = has
        bo[B_IN_BAND, i] = has and gs > 0 and q > 0 and q < bw * gs
        too_fast = v0 > set_speed[i] + lead_margin + SPEED_TOL  # as score_episode
        followable = has and v0 > moving and not too_fast
        bo[B_FOLLOWABLE, i] = followable
        settled = ti - last_change[i] >= transient
        bo[B_FOLLOWING, i] = (followable and settled and v1 > moving and abs(v0 - v1) <= steady_dv and gs > 0)
        # nothing to follow: none in view, or one faster than the set speed -- and none followable
        bo[B_FREE, i] = ((not (has and gap <= sensor)) or (has and too_fast)) and not followable
        if has and gs > 0:
            fl[F_U, i] = min(max(q / (bw * gs), 0.0), 1.0)
        else:
            fl[F_U, i] = np.nan
        neg = has and q < 0
        if neg:
            if math.isnan(neg_since[i]):
                neg_since[i] = ti
        else:
            neg_since[i] = np.nan
        responding = a1 <= -resp_decel or v1 <= stop_speed
        collision = has and gap <= 0.0
        bo[B_COLLISION, i] = collision
        bo[B_VIOLATION, i] = (neg and ti - neg_since[i] > grace[i] and not responding) or collision


@numba.njit(cache=True, error_model="numpy")
def criteria_reward_rows(fl, bo, set_speed, tau1, a_comfort, w, terms, reward):  # pragma: no cover - compiled
    """The default reward's terms (:data:`TERMS` rows of ``terms``) and their sum ``reward``, from
    the rows of :func:`criteria`'s outputs ``fl`` and ``bo``.

    ``w``: weights ``(band, efficiency, speed, comfort, jerk, safety, collision, lag,
    jerk_scale)``; the formulas of :class:`acc_gym.envs.reward.CriteriaReward`'s table.
    """
    n = fl.shape[1]
    for i in range(n):
        vs = set_speed[i]
        following = bo[B_FOLLOWING, i]
        speed_err = min(abs(fl[F_V, i] - vs) / (0.2 * vs), 1.0)
        ui = fl[F_U, i]
        terms[0, i] = w[0] * (1.0 if (following and bo[B_IN_BAND, i]) else 0.0)
        terms[1, i] = w[1] * ((1.0 - (1.0 if math.isnan(ui) else ui)) if following else 0.0)
        terms[2, i] = w[2] * ((1.0 - speed_err) if bo[B_FREE, i] else 0.0)
        terms[3, i] = -w[3] * (fl[F_A, i] / a_comfort) ** 2
        terms[4, i] = -w[4] * (fl[F_JERK, i] / w[8]) ** 2
        terms[5, i] = -w[5] * (1.0 if bo[B_VIOLATION, i] else 0.0)
        terms[6, i] = -w[6] * (1.0 if bo[B_COLLISION, i] else 0.0)
        if bo[B_FOLLOWABLE, i]:
            far = 1.2 * tau1[i] * fl[F_VLEAD, i] + 5.0  # [m]
            terms[7, i] = -w[7] * min(max((fl[F_GAP, i] - far) / far, 0.0), 1.0)
        else:
            terms[7, i] = -w[7] * 0.0
        total = 0.0
        for k in range(terms.shape[0]):
            total += terms[k, i]
        reward[i] = total


@numba.njit(cache=True, error_model="numpy")
def settle(idle, reward, bo, k, steps, terminate_on_violation, episode_return, terminated, truncated, rows,
           ended):  # pragma: no cover - compiled
    """The end of a step for every scene, from :func:`criteria`'s boolean output ``bo``.

    Writes ``terminated`` (a collision, or a violation with ``terminate_on_violation``) and
    ``truncated`` (the step budget ``steps`` reached at step ``k``, not terminated); adds
    ``reward`` to ``episode_return`` of the active scenes (those not ``idle``: the core's
    ``done`` flags, or a vector env's scenes about to be reset); lists the active scenes in
    ``rows`` and those of them whose episode ended in ``ended``. Returns both counts.
    """
    n_rows = 0
    n_ended = 0
    for i in range(idle.shape[0]):
        term = bo[B_COLLISION, i] or (bo[B_VIOLATION, i] and terminate_on_violation)
        trunc = k[i] >= steps[i] and not term
        terminated[i] = term
        truncated[i] = trunc
        if not idle[i]:
            rows[n_rows] = i
            n_rows += 1
            episode_return[i] += reward[i]
            if term or trunc:
                ended[n_ended] = i
                n_ended += 1
    return n_rows, n_ended


@numba.njit(cache=True, error_model="numpy")
def record(rows, k, t, state, scenes):  # pragma: no cover - compiled
    """Write the current state of scenes ``rows`` at their step ``k[row]`` into their episode
    records (``scenes.rec``: :data:`RECORD` rows, scenes, steps). ``state``: the world's ``(v,
    a, lead, gap, a_y, y)`` arrays ``(n, S)``; ``t`` the scenes' times [s]."""
    v, a, lead_all, gap_all, a_y, y = state
    width0, lane_width, n_lanes, rec = scenes.ego_width, scenes.lane_width, scenes.n_lanes, scenes.rec
    for r in range(rows.shape[0]):
        i = rows[r]
        kk = k[i]
        lead = lead_all[i, 0]
        has = lead >= 0
        half = 0.5 * width0[i]
        yi = y[i, 0]
        rec[0, i, kk] = t[i]
        rec[1, i, kk] = v[i, 0]
        rec[2, i, kk] = a[i, 0]
        rec[3, i, kk] = gap_all[i, 0]
        rec[4, i, kk] = v[i, lead] if has else 0.0
        rec[5, i, kk] = a[i, lead] if has else 0.0
        rec[6, i, kk] = float(lead)
        rec[7, i, kk] = a_y[i, 0]
        rec[8, i, kk] = yi + 0.5 * lane_width[i] - half
        rec[9, i, kk] = (n_lanes[i] - 0.5) * lane_width[i] - yi - half


@numba.njit(cache=True, error_model="numpy")
def observe(o, set_speed, time_gap, sensor_range, v2v, low, high, out):  # pragma: no cover - compiled
    """The environment observations (the table in :class:`acc_gym.envs.acc_env.ACCEnv`), clipped
    to ``[low, high]`` and written into ``out`` ``(n, 7)`` or ``(n, 11)`` (any float dtype).

    ``o`` ``(8, n)``: the ego's :class:`~acc_gym.drivers.base.Observation` fields in
    :data:`acc_gym.simulation._world_kernel.OBS_FIELDS` order (gap ``inf``: nothing seen).
    """
    n = o.shape[1]
    m = out.shape[1]
    row = np.empty(m)
    for i in range(n):
        v = o[0, i]
        gap = o[2, i]
        seen = math.isfinite(gap)
        row[0] = v
        row[1] = o[1, i]
        row[2] = min(max(gap, 0.0), sensor_range) if seen else sensor_range
        row[3] = o[3, i] - v if seen else 0.0
        row[4] = 1.0 if seen else 0.0
        row[5] = set_speed[i]
        row[6] = time_gap[i]
        if v2v:
            gap2 = o[5, i]
            seen2 = math.isfinite(gap2)
            row[7] = o[4, i] if seen else 0.0
            row[8] = min(max(gap2, 0.0), sensor_range) if seen2 else sensor_range
            row[9] = o[6, i] - v if seen2 else 0.0
            row[10] = 1.0 if seen2 else 0.0
        for j in range(m):
            out[i, j] = min(max(row[j], low[j]), high[j])


@numba.njit(cache=True)
def clip_columns(src, dst, lo, hi, low, high):  # pragma: no cover - compiled
    """``dst[:, lo:hi] = np.minimum(np.maximum(src[:, lo:hi], low[lo:hi]), high[lo:hi])`` with
    numpy's rules (NaN kept; of two equal values, the bound), in one pass: the car's observed
    fields into an observation (:meth:`acc_gym.envs.car.Car.apply`)."""
    for i in range(src.shape[0]):
        for j in range(lo, hi):
            x = src[i, j]
            x = x if (x > low[j] or x != x) else low[j]
            dst[i, j] = x if (x < high[j] or x != x) else high[j]


def accel_of_action(x: float, accel_max: float, decel_max: float) -> float:
    """One finite action to a desired acceleration [m/s^2]: clipped to [-1, 1], then
    ``x * accel_max`` for ``x >= 0`` and ``x * decel_max`` below. The one definition: the single
    env calls it on a Python float, :func:`action_to_accel` compiled on arrays."""
    x = min(max(x, -1.0), 1.0)
    return x * accel_max if x >= 0 else x * decel_max


_accel_of_action = numba.njit(cache=True, error_model="numpy")(accel_of_action)


@numba.njit(cache=True, error_model="numpy")
def action_to_accel(action, accel_max, decel_max, out):  # pragma: no cover - compiled
    """:func:`accel_of_action` of every action ``(n,)``, into ``out``."""
    for i in range(action.shape[0]):
        out[i] = _accel_of_action(action[i], accel_max, decel_max)


@numba.njit(cache=True, error_model="numpy")
def step(a_des, x, v, a, F, I, obs_all, obs, obs32, idle, core):  # pragma: no cover - compiled
    """The world's move and the step's judgement, after the drivers decided (``a_des`` ``(n,
    S)`` [m/s^2]): :func:`acc_gym.simulation._world_kernel.move` from the state ``x``, ``v``,
    ``a`` into ``F``, ``I``, ``obs_all`` (``core.world``), :func:`criteria` into ``core.out``'s
    ``fl`` (plus the scenes' new times in row :data:`F_T`) and ``bo``, and the built-in reward
    ``core.plan.code`` names: :data:`REWARD_CRITERIA` (:func:`criteria_reward_rows`),
    :data:`REWARD_MARGIN` (:func:`margin_reward_rows`), :data:`REWARD_NONE` none (the caller's
    reward fills ``core.out.reward``). With a built-in reward nothing comes between this and
    the step's end, so it ends the step too (:func:`finish` of ``idle``, ``obs``, ``obs32``)
    and returns finish's counts; with :data:`REWARD_NONE` it returns ``(-1, -1)`` and the
    caller calls :func:`finish` after its reward."""
    w, sc, p, o, car = core.world, core.scenes, core.plan, core.out, core.car
    n = w.k.shape[0]
    a_prev = np.empty(n)
    for i in range(n):
        a_prev[i] = a[i, 0]  # the ego's applied acceleration before the step [m/s^2]
    if car.actuated:  # the egos' commands as their actuators realise them
        u = np.empty(n)
        for i in range(n):
            u[i] = a_des[i, 0]
        _A.command(car.vehicles, car.hist, car.head, u, a_prev, car.realised)
        for i in range(n):
            a_des[i, 0] = car.realised[i]
    t = o.fl[F_T]
    _W.move(a_des, x, v, w, F, I, obs_all, t)
    criteria(t, F[1], F[2], I[0], F[6], a_prev, w.dt, sc, p.cfg, o.fl, o.bo)
    if p.code == REWARD_CRITERIA:
        criteria_reward_rows(o.fl, o.bo, sc.set_speed, sc.tau1, p.a_comfort, p.weights, o.terms, o.reward)
    elif p.code == REWARD_MARGIN:
        margin_reward_rows(o.fl, o.bo, sc.set_speed, sc.tau1, sc.steps, w.k, p.a_comfort, p.weights, o.terms, o.reward)
    else:
        return -1, -1
    return finish(idle, F, I, obs_all, obs, obs32, core)


@numba.njit(cache=True, error_model="numpy")
def finish(idle, F, I, obs_all, obs, obs32, core):  # pragma: no cover - compiled
    """The end of a step (by :func:`step` itself, or after it and the caller's reward, in ``core.out.reward``):
    :func:`settle` of the scenes not ``idle``, :func:`record` of them, and the ego's
    :func:`observe` of the new state (``F``, ``I``, ``obs_all``) into ``obs`` (``(n, m)``, or
    nothing when it has no rows); with feature bounds (``core.plan.f_low``, ``f_high``; version
    1, empty for version 0) the observation with the safety-margin features as the environments
    emit it, :func:`features32` of ``obs`` into ``obs32``. Returns :func:`settle`'s counts."""
    w, sc, p, o = core.world, core.scenes, core.plan, core.out
    n_rows, n_ended = settle(idle, o.reward, o.bo, w.k, sc.steps, p.terminate, sc.episode_return, o.terminated,
                             o.truncated, o.rows, o.ended)
    record(o.rows[:n_rows], w.k, o.fl[F_T], (F[1], F[2], I[0], F[6], F[5], F[4]), sc)
    car = core.car
    if obs.shape[0] > 0:
        observe(obs_all[0], sc.set_speed, sc.time_gap, p.obs_range, p.v2v, p.low, p.high, obs)
        if p.f_low.shape[0] > 0 and not car.sensing:  # (with a radar: from its fields, below)
            features32(obs, p.obs_range, _O.B0, _O.B1, p.f_low, p.f_high, obs32)
    if car.sensing:
        radar_step(car, obs_all[0], F[4], w.width, I[0], I[1], p, obs, obs32)
    return n_rows, n_ended


@numba.njit(cache=True, error_model="numpy")
def radar_step(car, truth, y, width, lead, lead2, p, obs, obs32):  # pragma: no cover - compiled
    """The egos' radars after the world's move (:func:`acc_gym.onboard._radar_kernel.sense` of
    every scene, in the new state: ``truth`` the egos' observation rows ``(8, n)``, ``y``,
    ``width``, ``lead``, ``lead2`` ``(n, S)``), their reports into ``car.seen``; with an
    observation made (``obs`` the true v0 fields, rows), the emitted one ``obs32``: the true
    fields rounded as emitted, the radar's replacing theirs (clipped to ``p.low``, ``p.high``)
    and, with feature bounds, the ``-v1`` features computed from those fields
    (:func:`features32`)."""
    car.pos_max[0] = _R.sense(car.radar, car.tracks, car.reports, car.draws, truth, y, width, lead, lead2, car.every,
                              False, car.sensed)
    n = car.sensed.shape[0]
    seen, sensed = car.seen, car.sensed
    for i in range(n):
        for j in range(3):
            seen[i, RADAR_LO + j] = sensed[i, j]
    if obs.shape[0] == 0:
        return
    fields = car.fields
    m = fields.shape[1]
    for i in range(n):
        for j in range(m):
            fields[i, j] = np.float32(obs[i, j])  # as emitted
    clip_columns(seen, fields, RADAR_LO, RADAR_LO + 3, p.low, p.high)
    if p.f_low.shape[0] > 0:
        features32(fields, p.obs_range, _O.B0, _O.B1, p.f_low, p.f_high, obs32)
    else:
        for i in range(n):
            for j in range(m):
                obs32[i, j] = fields[i, j]


REACH_BAND = 0.2  # [-] MarginReward's reach term: the score's band, 0 < Q < 0.2 Gapsafe (ScoringConfig.band_width)
# the terms of margin_reward_rows() (MarginReward.TERMS), in info["rewards"] order
MARGIN_TERMS = ("band", "efficiency", "speed", "response", "comfort", "jerk", "safety", "collision", "lag", "overspeed",
                "reach", "behind", "standstill", "demand", "release", "let_go", "stop_demand")
# margin_reward_rows()'s weights and constants, in the order MarginReward._w holds them
MARGIN_W = ("band", "efficiency", "speed", "response", "comfort", "jerk", "safety", "collision", "lag", "peak",
            "slope", "response_decel", "jerk_scale", "max_step_cost", "A_COUNTED", "JERK_COUNTED", "E_COUNTED",
            "overspeed", "overspeed_scale", "reach", "behind", "standstill", "standstill_gap", "STOPPED", "demand",
            "release", "let_go", "stop_demand", "behind_outside_margin")


@numba.njit(cache=True, error_model="numpy")
def margin_reward_rows(fl, bo, set_speed, tau1, steps, k, a_comfort, w, terms, reward):  # pragma: no cover
    """:class:`~acc_gym.envs.reward.MarginReward`'s terms (:data:`MARGIN_TERMS` rows of
    ``terms``) and their sum ``reward``, from the rows of :func:`criteria`'s outputs ``fl``
    and ``bo`` and the scenes' step budgets ``steps`` and steps taken ``k`` (the steps left
    the collision term charges).

    ``w``: :data:`MARGIN_W`. The formulas are those of :class:`~acc_gym.envs.reward.MarginReward`'s
    table, one scene at a time (``tests/envs/test_v1_fast_paths.py`` checks them against a numpy
    oracle, ``tests/envs/reward_oracle.py``).
    """
    (band_w, eff_w, speed_w, resp_w, comfort_w, jerk_w, safety_w, coll_w, lag_w, peak, slope, resp_decel,
     jerk_scale, max_cost, a_counted, jerk_counted, e_counted, over_w, over_scale, reach_w, behind_w, stand_w, stand_gap,
     stopped, demand_w, release_w, let_go_w, stop_w, outside_only) = (
        w[0], w[1], w[2], w[3], w[4], w[5], w[6], w[7], w[8], w[9], w[10], w[11], w[12], w[13], w[14], w[15], w[16],
        w[17], w[18], w[19], w[20], w[21], w[22], w[23], w[24], w[25], w[26], w[27], w[28] != 0.0)
    width = max(peak, 1.0 - peak)
    n = fl.shape[1]
    for i in range(n):
        v = fl[F_V, i]
        a = fl[F_A, i]
        gap = fl[F_GAP, i]
        following = bo[B_FOLLOWING, i]
        far = 1.2 * tau1[i] * fl[F_VLEAD, i] + 5.0  # [m]
        behind = bo[B_FOLLOWABLE, i] and gap > far and not (outside_only and fl[F_Q, i] < 0.0)
        lag = 0.0
        if behind:
            x = (gap - far) / far
            lag = x / (1.0 + x) if math.isfinite(x) else 1.0
        vs = set_speed[i]
        e = abs(v - vs) / (0.2 * vs)
        speed = 1.0 - e if e <= 1.0 else -slope * (min(e, e_counted) - 1.0)
        u = fl[F_U, i]
        if math.isnan(u):
            u = 1.0
        tent = max(0.0, 1.0 - abs(u - peak) / width)
        response = 0.0
        if fl[F_Q, i] < 0.0:
            response = min(max((a + resp_decel) / resp_decel, 0.0), 1.0)
        steps_left = max(float(steps[i] - k[i]), 0.0)
        terms[0, i] = band_w * (1.0 if (following and bo[B_IN_BAND, i]) else 0.0)
        terms[1, i] = eff_w * (tent if following else 0.0)
        terms[2, i] = speed_w * (speed if (bo[B_FREE, i] or behind) else 0.0)
        terms[3, i] = -resp_w * response
        terms[4, i] = -comfort_w * (min(abs(a), a_counted) / a_comfort) ** 2
        terms[5, i] = -jerk_w * (min(abs(fl[F_JERK, i]), jerk_counted) / jerk_scale) ** 2
        terms[6, i] = -safety_w * (1.0 if bo[B_VIOLATION, i] else 0.0)
        terms[7, i] = -(1.0 if bo[B_COLLISION, i] else 0.0) * (coll_w + max_cost * steps_left)
        terms[8, i] = -lag_w * lag
        terms[9, i] = -over_w * min(max(v - vs, 0.0) / (over_scale * vs), e_counted)
        reach = 0.0
        gs = fl[F_GS, i]
        if following and gs > 0.0:
            reach = min(max(fl[F_Q, i] / gs - REACH_BAND, 0.0) / REACH_BAND, 1.0)
        terms[10, i] = -reach_w * reach
        terms[11, i] = -behind_w * (1.0 if behind else 0.0)
        stand = 0.0
        if math.isfinite(gap) and fl[F_VLEAD, i] < stopped:  # a stopped vehicle ahead
            stop_gap = gap - v * v / (2.0 * resp_decel)  # [m] left if the ego braked at the proper response from now
            stand = min(max((stand_gap - stop_gap) / stand_gap, 0.0), 1.0)
        terms[12, i] = -stand_w * stand
        demand = 0.0
        vl = fl[F_VLEAD, i]
        if fl[F_Q, i] < 0.0 and gap > 0.0 and math.isfinite(gap) and v > vl:
            a_req = min((v - vl) * (v - vl) / (2.0 * gap), a_counted)  # [m/s^2] paper 001's, counted up to 9
            if a_req > resp_decel:
                demand = min(max((a + a_req) / (a_req - resp_decel), 0.0), 1.0)
        terms[13, i] = -demand_w * demand
        # the acceleration rising (the brake let go, or accelerating) inside Gapsafe; let_go: where it then is
        # weaker than the proper response
        rise = (min(max(fl[F_JERK, i], 0.0), jerk_counted) / jerk_scale) ** 2
        inside = fl[F_Q, i] < 0.0
        terms[14, i] = -release_w * (rise if inside else 0.0)
        terms[15, i] = -let_go_w * (rise if (inside and a > -resp_decel) else 0.0)
        # the deceleration that stops the ego behind a braking vehicle ahead (its own stop counted)
        stop = 0.0
        al = fl[F_ALEAD, i]
        if inside and gap > 0.0 and math.isfinite(gap) and al < 0.0:
            a_stop = min(v * v / (2.0 * (gap + vl * vl / (2.0 * -al))), a_counted)  # [m/s^2]
            if a_stop > resp_decel:
                stop = min(max((a + a_stop) / (a_stop - resp_decel), 0.0), 1.0)
        terms[16, i] = -stop_w * stop
        total = 0.0
        for j in range(terms.shape[0]):
            total += terms[j, i]
        reward[i] = total


@numba.njit(cache=True, error_model="numpy")
def features32(obs, sensor_range, b0, b1, low, high, out):  # pragma: no cover - compiled
    """The version-1 observation as the environments emit it (float32): the v0 fields
    ``obs`` ``(n, m)`` (float64, clipped) rounded to float32, then the safety-margin
    features computed from those rounded fields (:func:`acc_gym.envs.observation.append_features`,
    clipped to ``[low, high]``) and rounded in turn, into ``out`` ``(n, m + len(low))``
    float32 -- what ``append_features(obs.astype(float32).astype(float64), ...).astype(float32)``
    gives, in one call instead of four array conversions."""
    n, m = obs.shape
    fields = np.empty((n, m))
    for i in range(n):
        for j in range(m):
            fields[i, j] = np.float32(obs[i, j])
    full = np.empty((n, m + low.shape[0]))
    _O.append_features(fields, sensor_range, b0, b1, low, high, full)
    for i in range(n):
        for j in range(full.shape[1]):
            out[i, j] = np.float32(full[i, j])
