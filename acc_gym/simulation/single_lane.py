"""A single-lane traffic world: the ego and up to a few surrounding vehicles, with lane entries and exits.

Paper 004's single-lane scenario has at most three vehicles: the subject vehicle (SV,
the ego, slot 0), the primary other vehicle ahead (POV, slot 1) and a second one
(POV2, slot 2). Cut-ins, cut-outs and lane changes are *longitudinal* events for the
vehicles behind: a vehicle enters or leaves the lane ahead of them at some gap and speed.
This module simulates ``B`` such scenes at once as ``(B, S)`` arrays (``S`` slots).

Geometry (decided here; see :class:`Road`): lanes of width ``lane_width`` numbered 0
(rightmost) to ``n_lanes - 1``; lateral coordinate ``y`` [m] is the vehicle centre's
offset from lane 0's centre line. Lateral motion is scripted (the controllers under test
are longitudinal): each vehicle has a :class:`LateralPlan`, a half-cosine move from
``y0`` to ``y1`` starting at ``t_start`` and lasting ``duration`` [s], whose peak
lateral acceleration is ``|y1 - y0| pi^2 / (2 duration^2)``.

*Who is ahead* (decided here): for each vehicle, the nearest vehicle whose front bumper is
ahead of its own and whose contour overlaps its lane corridor -- a band of one lane width
centred on the vehicle -- that is ``|y_j - y_i| < (lane_width + width_j) / 2``. So a
cutting-in vehicle becomes the target as soon as its contour crosses the lane line, and
stays one until its contour has left the lane entirely on a cut-out (conservative, as
an ACC's target selection should be). The same rule serves the ego during its own
lane change (its corridor moves with it) and the surrounding drivers.

Each step has two phases: every model decides from the same snapshot, then every
vehicle moves (exact integration, no reversing; :mod:`acc_gym.vehicle`). Slot 0 is
driven by the caller's action (or by a model); the other slots by driver models that
each control one vehicle per scene (``n == B``, e.g. a
:class:`~acc_gym.drivers.slots.SlotDrivers`). Absent vehicles (``present`` false) are
never anyone's target and do not move.
"""

from __future__ import annotations

import math
import operator
from dataclasses import dataclass, field

import numpy as np
from numba.core import types as _types

from acc_gym._validation import check_finite, check_nonnegative, check_positive
from acc_gym.drivers.base import Observation
from acc_gym.simulation import _world_kernel as _K
from acc_gym.vehicle import VEHICLE_COLUMNS, VehicleParams

DEFAULT_SENSOR_RANGE = 200.0  # [m] an ACC radar's range (paper 004: "about 200 m")
VEHICLE_WIDTH = 1.8  # [m]


@dataclass(frozen=True)
class Road:
    """Straight road: ``n_lanes`` lanes in the direction of travel, lane 0 the rightmost.

    ``D2`` (paper 003) is the distance from a vehicle's contour to the road edge (the
    right edge of lane 0); ``D3`` the distance to the carriageway's boundary line (the
    left edge of the leftmost lane, the centre line on a two-way road). A lane change
    within the carriageway keeps both positive.
    """

    lane_width: float = 3.75  # [m] paper 003 Table 2
    n_lanes: int = 2  # [-]
    length: float = float("inf")  # [m] (informational: where the road ends)

    def __post_init__(self) -> None:
        check_positive("Road.lane_width", self.lane_width)
        if int(self.n_lanes) != self.n_lanes or self.n_lanes < 1:
            raise ValueError(f"Road.n_lanes must be a positive integer, got {self.n_lanes!r}")
        if not self.length > 0:
            raise ValueError(f"Road.length must be > 0, got {self.length!r}")

    def lane_centre(self, lane) -> np.ndarray:
        return np.asarray(lane, dtype=float) * self.lane_width

    def d2(self, y, width=VEHICLE_WIDTH):
        """Contour to the road edge [m]."""
        return np.asarray(y) + 0.5 * self.lane_width - 0.5 * np.asarray(width)

    def d3(self, y, width=VEHICLE_WIDTH):
        """Contour to the carriageway's boundary line [m]."""
        return (self.n_lanes - 0.5) * self.lane_width - np.asarray(y) - 0.5 * np.asarray(width)


@dataclass(frozen=True)
class LateralPlan:
    """Scripted lateral moves, arrays broadcastable to ``(B, S)``: half-cosine from ``y0`` to ``y1``."""

    y0: np.ndarray  # [m] lateral position before the move
    y1: np.ndarray  # [m] after
    t_start: np.ndarray  # [s]
    duration: np.ndarray  # [s] > 0

    def __post_init__(self) -> None:
        for name in ("y0", "y1", "t_start", "duration"):
            value = np.asarray(getattr(self, name), dtype=float)
            check_finite(f"LateralPlan.{name}", value)
            object.__setattr__(self, name, value)
        check_positive("LateralPlan.duration", self.duration)

    @classmethod
    def checked(cls, y0: np.ndarray, y1: np.ndarray, t_start: np.ndarray, duration: np.ndarray) -> "LateralPlan":
        """A plan of float arrays whose values were checked where they came from (finite, and
        ``duration > 0``: :func:`acc_gym.scenarios.world.scene_arrays` lays out validated
        scenarios), made without checking them again."""
        plan = object.__new__(cls)
        for name, value in (("y0", y0), ("y1", y1), ("t_start", t_start), ("duration", duration)):
            object.__setattr__(plan, name, value)
        return plan

    @classmethod
    def still(cls, y) -> "LateralPlan":
        y = np.asarray(y, dtype=float)
        return cls(y, y, np.zeros_like(y), np.ones_like(y))

    def _phase(self, t):
        return np.clip((t - self.t_start) / self.duration, 0.0, 1.0)

    def position(self, t) -> np.ndarray:
        s = self._phase(t)
        return self.y0 + (self.y1 - self.y0) * 0.5 * (1.0 - np.cos(np.pi * s))

    def acceleration(self, t) -> np.ndarray:
        s = self._phase(t)
        moving = (s > 0.0) & (s < 1.0)
        return np.where(moving, (self.y1 - self.y0) * 0.5 * (np.pi / self.duration) ** 2 * np.cos(np.pi * s), 0.0)

    def peak_acceleration(self) -> np.ndarray:
        """``|y1 - y0| pi^2 / (2 duration^2)`` [m/s^2]."""
        return np.abs(self.y1 - self.y0) * np.pi ** 2 / (2.0 * self.duration ** 2)


def _as_bs(value, B: int, S: int, name: str, dtype=float) -> np.ndarray:
    arr = np.asarray(value, dtype=dtype)
    try:
        arr = np.broadcast_to(arr, (B, S)).copy()
    except ValueError:
        raise ValueError(f"{name} must broadcast to ({B}, {S}), got shape {np.shape(value)}") from None
    if dtype is float:
        check_finite(name, arr)
    return arr


@dataclass
class Neighbours:
    """For each vehicle ``(B, S)``: the vehicle ahead (``-1``: none) and the one after it."""

    lead: np.ndarray  # int slot, -1 none
    gap: np.ndarray  # [m] bumper to bumper, inf none (regardless of sensor range)
    lead2: np.ndarray
    gap2: np.ndarray


class SingleLaneWorld:
    """``B`` single-lane scenes of ``S`` vehicles (slot 0 the ego), stepped together.

    Parameters
    ----------
    x0, v0: initial front-bumper positions [m] and speeds [m/s], broadcastable to ``(B, S)``.
    drivers: one entry per slot; ``drivers[0]`` is ``None`` when the ego is driven by the
        caller's actions, other entries are models with ``n == B`` (``None`` for a slot
        absent from every scene).
    present: which vehicles exist, ``(B, S)`` bool (default: all).
    lateral: the scripted lateral moves (default: everyone keeps lane 0).
    vehicle: vehicle parameters, fields broadcastable to ``(B, S)``.
    width: vehicle widths [m].
    road: the road geometry.
    dt: step [s].
    sensor_range: vehicles further ahead are not seen (``gap = inf`` in observations).
    a0: initial accelerations [m/s^2].
    joint: optional model acting for slots ``1 .. S-1`` at once, ``n == B (S - 1)`` with row
        ``(s - 1) B + b`` for slot ``s`` of scene ``b`` and an ``act_world(obs, a_des)`` method
        that reads the observation array ``(S, 8, B)`` and writes ``a_des[:, 1:]`` (a
        :class:`~acc_gym.drivers.slots.SlotDrivers` over all surrounding slots, whose
        :class:`~acc_gym.drivers.slots.SlotView` s are then the ``drivers`` entries of those
        slots): one model call per step instead of one per slot.
    """

    def __init__(self, x0, v0, drivers, *, present=None, lateral: LateralPlan | None = None,
                 vehicle: VehicleParams | None = None, width=VEHICLE_WIDTH, road: Road | None = None,
                 dt: float = 0.2, sensor_range: float = DEFAULT_SENSOR_RANGE, a0=None, joint=None):
        check_positive("dt", dt)
        if not sensor_range > 0:
            raise ValueError(f"sensor_range must be > 0, got {sensor_range!r}")
        x_arr = np.asarray(x0, dtype=float)
        if x_arr.ndim != 2:
            raise ValueError(f"x0 must have shape (B, S), got {x_arr.shape}")
        B, S = x_arr.shape
        self.B, self.S = B, S
        self.drivers = list(drivers)
        if len(self.drivers) != S:
            raise ValueError(f"drivers must have one entry per slot ({S}), got {len(self.drivers)}")
        for s, model in enumerate(self.drivers):
            if model is not None and getattr(model, "n", None) != B:
                raise ValueError(f"driver of slot {s} controls n={getattr(model, 'n', None)} vehicles; "
                                 f"it must control one per scene (n={B})")
        if joint is not None and (getattr(joint, "n", None) != B * (S - 1) or not hasattr(joint, "act_world")):
            raise ValueError(f"joint drivers must control n={B * (S - 1)} vehicles (every slot but the ego's) "
                             f"and have act_world, got n={getattr(joint, 'n', None)}")
        self.joint = joint
        self.x0 = _as_bs(x0, B, S, "x0")
        self.v0 = _as_bs(v0, B, S, "v0")
        check_nonnegative("v0", self.v0)
        self.a0 = _as_bs(0.0 if a0 is None else a0, B, S, "a0")
        self.present = _as_bs(True if present is None else present, B, S, "present", dtype=bool)
        self.road = road if road is not None else Road()
        plan = lateral if lateral is not None else LateralPlan.still(np.zeros((B, S)))
        # the lateral plan as mutable (B, S) arrays, so that one scene can be replaced (reset_rows)
        self.lateral = LateralPlan(*(np.broadcast_to(getattr(plan, f), (B, S)).copy()
                                     for f in ("y0", "y1", "t_start", "duration")))
        self.width = _as_bs(width, B, S, "width")
        check_positive("width", self.width)
        self.vehicle = vehicle if vehicle is not None else VehicleParams()
        self.lengths = _as_bs(self.vehicle.length, B, S, "vehicle.length")
        # the vehicle parameters per vehicle for the compiled step, (B, S, 10) in VEHICLE_COLUMNS order
        self._vp = np.ascontiguousarray(np.stack(
            [np.broadcast_to(np.asarray(getattr(self.vehicle, c), float), (B, S)) for c in VEHICLE_COLUMNS], axis=-1))
        self.dt = float(dt)
        self.sensor_range = float(sensor_range)
        self._buffer_sets = None  # reused_buffers()'s two sets, made on first use
        self._kernel_record = None  # kernel_record()'s (the arrays it holds, the record), made on first use
        self.reset()
        self._check_apart()

    def _check_apart(self, rows=None) -> None:
        """Vehicles sharing a lane corridor must not overlap lengthwise at the start (of scenes ``rows``)."""
        rows = np.arange(self.B) if rows is None else np.atleast_1d(rows)
        x, y, present, width = self.x[rows], self.y[rows], self.present[rows], self.width[rows]
        rear = x - self.lengths[rows]
        both = present[:, None, :] & present[:, :, None] & ~np.eye(self.S, dtype=bool)
        half = 0.5 * (self.road.lane_width + width[:, None, :])
        corridor = np.abs(y[:, None, :] - y[:, :, None]) < half
        overlap = (rear[:, :, None] < x[:, None, :]) & (rear[:, None, :] < x[:, :, None])
        bad = np.argwhere(both & corridor & overlap)
        if bad.size:
            j0, i, j = bad[0]
            b = rows[j0]
            raise ValueError(f"vehicles must start apart: in scene {b}, slots {i} and {j} overlap "
                             f"(front bumpers at {x[j0, i]:.2f} m and {x[j0, j]:.2f} m, lengths "
                             f"{self.lengths[b, i]:.2f} and {self.lengths[b, j]:.2f} m)")

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Back to the initial state; models are reset too."""
        self.k = np.zeros(self.B, dtype=np.int64)  # each scene's step count (its own clock)
        self.x = self.x0.copy()
        self.v = np.where(self.present, self.v0, 0.0)
        self.a = np.where(self.present, self.a0, 0.0)
        self.a_des = np.full((self.B, self.S), np.nan)
        self.collided = np.zeros((self.B, self.S), dtype=bool)  # sticky: ever gap <= 0
        for model in self.drivers:
            if model is not None and hasattr(model, "reset"):
                model.reset()
        self._refresh(mark=False)

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_kernel_record"] = None  # a compiled record: made again after unpickling
        return state

    def kernel_record(self):
        """What the compiled move reads besides the state (presence, vehicle parameters, clocks,
        lateral plan, sizes, collision flags, the step, lane width and sensor range), as one
        :data:`~acc_gym.simulation._world_kernel.WORLD` record holding the world's own arrays:
        made again when one of these attributes has been given another array or value since."""
        lat = self.lateral
        fields = (self.present, self._vp, self.dt, self.k, lat.y0, lat.y1, lat.t_start, lat.duration,
                  self.lengths, self.width, self.road, self.collided, self.sensor_range)
        made = self._kernel_record
        if made is not None and all(map(operator.is_, fields, made[0])):
            return made[1]
        # the kernels write k and collided: an array given in another layout or type is replaced by one the
        # record shares; the arrays they only read may be copies
        for name, dtype in (("k", np.int64), ("collided", np.bool_)):
            value = getattr(self, name)
            own = np.ascontiguousarray(value, dtype=dtype)
            if own is not value:
                setattr(self, name, own)
        fields = fields[:3] + (self.k,) + fields[4:11] + (self.collided, self.sensor_range)
        values = [np.ascontiguousarray(v, dtype=t.dtype.name) if isinstance(t, _types.Array) else v
                  for v, (_, t) in zip(fields, _K.WORLD_FIELDS)]
        values[10] = float(self.road.lane_width)
        self._kernel_record = (fields, _K.make_world(tuple(values)))
        return self._kernel_record[1]

    @property
    def t(self) -> np.ndarray:
        """Each scene's time [s], ``(B,)``."""
        return self.k * self.dt

    def _refresh(self, mark: bool) -> None:
        """Lateral positions, neighbours (and, with ``mark``, collision flags) for the current
        positions, in one compiled pass (:func:`acc_gym.simulation._world_kernel.refresh`;
        the numpy reference is :meth:`_neighbours` with :class:`LateralPlan`)."""
        B, S = self.B, self.S
        self.y, self.a_y, gap, gap2 = np.empty((4, B, S))  # fresh arrays (one allocation) every state
        lead, lead2 = np.empty((2, B, S), dtype=np.int64)
        _K.refresh(self.t, self.kernel_record(), self.x, self.y, self.a_y, lead, gap, lead2, gap2, mark)
        self.neighbours = Neighbours(lead=lead, gap=gap, lead2=lead2, gap2=gap2)
        self._obs = None  # observations of this state, made on first use

    def reset_rows(self, rows, x0, v0, *, present=None, lateral: LateralPlan | None = None, lengths=None,
                   width=None, a0=None) -> None:
        """Start scenes ``rows`` afresh with new initial states (arrays ``(len(rows), S)``); the
        other scenes are untouched. The caller restarts those scenes' driver models.

        Inputs that are already float arrays ``(len(rows), S)`` (what
        :func:`acc_gym.scenarios.world.scene_arrays` gives, with a :class:`LateralPlan`)
        take one compiled pass (:func:`acc_gym.simulation._world_kernel.place` and
        :func:`~acc_gym.simulation._world_kernel.first_overlap`) that writes the same
        values; anything else, or any invalid value, takes the numpy path below, which
        names what is wrong."""
        rows = np.atleast_1d(np.asarray(rows, dtype=np.int64))
        m = rows.size
        shape = (m, self.S)
        args = (x0, v0, a0, lengths, width)
        if (lateral is not None and present is not None and type(present) is np.ndarray and present.shape == shape
                and present.dtype == np.bool_ and all(type(arg) is np.ndarray and arg.shape == shape
                                                     and arg.dtype == np.float64 for arg in args if arg is not None)):
            plan = lateral
            plan_arrays = [a if type(a) is np.ndarray and a.shape == shape else np.broadcast_to(a, shape)
                           for a in (plan.y0, plan.y1, plan.t_start, plan.duration)]
            zeros = np.zeros(shape)
            new = (x0, v0, zeros if a0 is None else a0, present, self.lengths[rows] if lengths is None else lengths,
                   self.width[rows] if width is None else width, *plan_arrays)
            if _K.place(rows, new, (self.x0, self.v0, self.a0), self.kernel_record(), self.x, self.v, self.a,
                        self.a_des):
                self._refresh(mark=False)
                if _K.first_overlap(rows, self.x, self.y, self.present, self.width, self.lengths,
                                    float(self.road.lane_width))[0] >= 0:
                    self._check_apart(rows)  # raises, naming the pair
                return
        x0 = _as_bs(x0, m, self.S, "x0")
        v0 = _as_bs(v0, m, self.S, "v0")
        check_nonnegative("v0", v0)
        self.x0[rows], self.v0[rows] = x0, v0
        self.a0[rows] = _as_bs(0.0 if a0 is None else a0, m, self.S, "a0")
        self.present[rows] = _as_bs(True if present is None else present, m, self.S, "present", dtype=bool)
        if lengths is not None:
            self.lengths[rows] = _as_bs(lengths, m, self.S, "lengths")
        if width is not None:
            self.width[rows] = _as_bs(width, m, self.S, "width")
        plan = lateral if lateral is not None else LateralPlan.still(np.zeros((m, self.S)))
        for f in ("y0", "y1", "t_start", "duration"):
            getattr(self.lateral, f)[rows] = np.broadcast_to(getattr(plan, f), (m, self.S))
        self.k[rows] = 0
        self.x[rows] = self.x0[rows]
        self.v[rows] = np.where(self.present[rows], self.v0[rows], 0.0)
        self.a[rows] = np.where(self.present[rows], self.a0[rows], 0.0)
        self.a_des[rows] = np.nan
        self.collided[rows] = False
        self._refresh(mark=False)
        self._check_apart(rows)

    def _neighbours(self) -> Neighbours:
        """Who is ahead, written with numpy over ``(B, S, S)`` (the reference for the compiled
        :func:`~acc_gym.simulation._world_kernel.refresh` the world uses)."""
        x, y = self.x, self.y
        gap = (x - self.lengths)[:, None, :] - x[:, :, None]  # [b, i, j]: i's front to j's rear
        ahead = x[:, None, :] > x[:, :, None]
        both = self.present[:, None, :] & self.present[:, :, None]
        corridor = np.abs(y[:, None, :] - y[:, :, None]) < 0.5 * (self.road.lane_width + self.width[:, None, :])
        g = np.where(ahead & both & corridor, gap, np.inf)
        order = np.argsort(g, axis=2, kind="stable")
        first = np.take_along_axis(g, order[..., :1], axis=2)[..., 0]
        lead = np.where(np.isfinite(first), order[..., 0], -1)
        if self.S > 1:
            second = np.take_along_axis(g, order[..., 1:2], axis=2)[..., 0]
            lead2 = np.where(np.isfinite(second), order[..., 1], -1)
        else:
            second = np.full_like(first, np.inf)
            lead2 = np.full_like(lead, -1)
        return Neighbours(lead=lead, gap=first, lead2=lead2, gap2=second)

    def observe(self, slot: int) -> Observation:
        """What the vehicles of ``slot`` (one per scene) see now (sensor range applied)."""
        o = self.observation_array(slot)
        return Observation(o[0], o[1], o[2], o[3], o[4], o[5], o[6], o[7])

    def observation_array(self, slot: int) -> np.ndarray:
        """What :meth:`observe` returns, as one read-only array ``(8, B)`` (rows
        :data:`acc_gym.simulation._world_kernel.OBS_FIELDS`)."""
        return self._observations()[slot]

    def _observations(self) -> np.ndarray:
        """Every slot's observation of this state, ``(S, 8, B)``, read-only: made on first use
        after a change of state (one compiled call)."""
        obs = self._obs
        if obs is None:
            nb = self.neighbours
            obs = self._obs = np.empty((self.S, len(_K.OBS_FIELDS), self.B))
            _K.observe_all(self.v, self.a, nb.lead, nb.gap, nb.lead2, nb.gap2, self.sensor_range, obs)
            obs.setflags(write=False)  # shared by the slots' observations of this state
        return obs

    # ------------------------------------------------------------------ dynamics
    def step(self, ego_a_des=None) -> None:
        """Advance one step: every driver decides from the current snapshot, then all move.

        ``ego_a_des`` [m/s^2], shape ``(B,)`` (or scalar), is the ego's desired
        acceleration; it is required when slot 0 has no model.
        """
        self.move(self.decide(ego_a_des))

    def coast(self, steps: int, ego_a_des: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Run ``steps`` steps with the ego asking for the constant ``ego_a_des`` [m/s^2] (as
        :meth:`step` with it each step); returns every state's positions and speeds, ``(steps +
        1, B, S)`` (row 0 the current state). When the surrounding drivers decide in one compiled
        call (``joint``'s :meth:`~acc_gym.drivers.slots.SlotDrivers.compiled_laws`: baseline
        models, profiles, absent vehicles) the whole run is one compiled call
        (:func:`acc_gym.simulation._rollout_kernel.coast`), else :meth:`step` after step; the
        same numbers either way (``tests/simulation/test_world_kernel.py``). A scenario's
        pre-simulation of its vehicles (:mod:`acc_gym.scenarios.singlelane`) runs this."""
        steps = int(steps)
        if steps < 0:
            raise ValueError(f"steps must be >= 0, got {steps!r}")
        ego = float(ego_a_des)
        check_finite("ego_a_des", ego)
        xs, vs = np.empty((2, steps + 1, self.B, self.S))
        joint = self.joint
        laws = joint.compiled_laws() if (joint is not None and steps > 0) else None
        if laws is not None:
            from acc_gym.simulation import _rollout_kernel  # late: it joins the drivers' kernels

            F, I, obs = _rollout_kernel.coast(steps, ego, self._observations().copy(), laws, self.kernel_record(), self.x, self.v,
                                              xs, vs)
            self.adopt(F, I, obs)
            return xs, vs
        xs[0], vs[0] = self.x, self.v
        for i in range(steps):
            self.step(ego)
            xs[i + 1], vs[i + 1] = self.x, self.v
        return xs, vs

    def decide(self, ego_a_des=None) -> np.ndarray:
        """Phase one of :meth:`step`: every model's desired acceleration ``(B, S)`` [m/s^2]
        from the current snapshot (slot 0 ``ego_a_des`` when given); nothing moves."""
        a_des = np.zeros((self.B, self.S))
        if ego_a_des is not None:  # first: a bad command raises before any driver has decided (or ticked)
            ego = ego_a_des
            if type(ego) is float and math.isfinite(ego):  # a plain number (pre-simulations pass 0.0)
                a_des[:, 0] = ego
            else:
                if not (type(ego) is np.ndarray and ego.shape == (self.B,) and ego.dtype == np.float64):
                    ego = np.broadcast_to(np.asarray(ego_a_des, dtype=float), (self.B,))
                if self.B == 1:  # the single env's command: one number
                    e = float(ego[0])
                    if not math.isfinite(e):
                        check_finite("ego_a_des", ego)  # raises, naming the value
                    a_des[0, 0] = e
                else:
                    if not np.isfinite(ego).all():
                        check_finite("ego_a_des", ego)
                    a_des[:, 0] = ego
        elif self.drivers[0] is None:
            raise ValueError("the ego has no model: pass ego_a_des to step()")
        joint = self.joint
        if joint is not None:  # every surrounding slot in one call: rows (s - 1) B + b
            joint.act_world(self._observations(), a_des)
            if ego_a_des is not None:
                return a_des
        for s in range(1 if joint is not None else self.S):  # the slots the joint drivers do not hold
            model = self.drivers[s]
            if (s == 0 and ego_a_des is not None) or model is None:
                continue
            act_rows = getattr(model, "act_rows", None)  # drivers that read the observation rows directly
            a_des[:, s] = act_rows(self.observation_array(s)) if act_rows is not None else model.act(self.observe(s))
        return a_des

    def move(self, a_des: np.ndarray) -> None:
        """Phase two of :meth:`step`: Eq. (3) and exact integration of every vehicle for the
        desired accelerations ``a_des`` ``(B, S)`` (from :meth:`decide`), then the lateral
        positions, neighbours and collision flags of the new state -- one compiled call
        (:func:`acc_gym.simulation._world_kernel.move`, which also makes the new state's
        observations)."""
        F, I, obs = self.move_buffers()
        _K.move(a_des, self.x, self.v, self.kernel_record(), F, I, obs, np.empty(self.B))
        self.adopt(F, I, obs)

    def move_buffers(self) -> tuple:
        """Fresh output arrays for one :meth:`move` done by a caller's compiled kernel
        (:func:`acc_gym.simulation._world_kernel.move`): ``(F, I, obs)`` with ``F``
        ``(8, B, S)`` floats (x, v, a, a_des, y, a_y, gap, gap2), ``I`` ``(2, B, S)`` ints
        (lead, lead2) and ``obs`` ``(S, 8, B)`` (:meth:`observation_array`'s). Hand them to
        :meth:`adopt` afterwards."""
        B, S = self.B, self.S
        return np.empty((8, B, S)), np.empty((2, B, S), dtype=np.int64), np.empty((S, len(_K.OBS_FIELDS), B))

    def reused_buffers(self) -> "StateBuffers":
        """:meth:`move_buffers` from two sets kept for reuse: the one that does not hold the
        current state (the other after every :meth:`adopt_buffers`). Hand it to
        :meth:`adopt_buffers` after the move. The state it replaces is then overwritten by the
        move after next: a caller that reuses buffers (the environments' core) promises that
        nobody keeps this world's state arrays for more than one step."""
        sets = self._buffer_sets
        if sets is None or sets[0].F.shape[1:] != (self.B, self.S):
            sets = self._buffer_sets = (StateBuffers(*self.move_buffers()), StateBuffers(*self.move_buffers()))
        return sets[1] if self.x.base is sets[0].F else sets[0]

    def adopt_buffers(self, buf: "StateBuffers") -> None:
        """:meth:`adopt` of a set from :meth:`reused_buffers` (its views made once)."""
        self.x, self.v, self.a, self.a_des, self.y, self.a_y = buf.rows
        self.neighbours = buf.neighbours
        self._obs = buf.obs_view

    def adopt(self, F: np.ndarray, I: np.ndarray, obs: np.ndarray) -> None:
        """Take the state a compiled :func:`~acc_gym.simulation._world_kernel.move` wrote into
        :meth:`move_buffers` (``k`` and the collision flags it updated in place): what
        :meth:`move` leaves, without its separate kernel calls."""
        self.x, self.v, self.a, self.a_des, self.y, self.a_y, gap, gap2 = F
        self.neighbours = Neighbours(lead=I[0], gap=gap, lead2=I[1], gap2=gap2)
        obs.setflags(write=False)
        self._obs = obs

    def driver_info(self, slot: int) -> dict:
        model = self.drivers[slot]
        return dict(getattr(model, "info", None) or {}) if model is not None else {}


class StateBuffers:
    """One set of :meth:`SingleLaneWorld.move_buffers` kept for reuse, with the state's views
    into it made once (:meth:`SingleLaneWorld.reused_buffers`): ``obs`` is the observation
    array a move writes, ``obs_view`` a read-only view of it, what the world hands out."""

    __slots__ = ("F", "I", "obs", "obs_view", "rows", "neighbours")

    def __init__(self, F: np.ndarray, I: np.ndarray, obs: np.ndarray):
        self.F, self.I, self.obs = F, I, obs
        self.obs_view = obs.view()
        self.obs_view.setflags(write=False)  # shared by the slots' observations of the state
        x, v, a, a_des, y, a_y, gap, gap2 = F
        self.rows = (x, v, a, a_des, y, a_y)
        self.neighbours = Neighbours(lead=I[0], gap=gap, lead2=I[1], gap2=gap2)

    def __reduce__(self):  # the views made again after a copy or unpickling (pickle copies a view's data)
        return _unpickle_buffers, (self.F, self.I, self.obs)


def _unpickle_buffers(F: np.ndarray, I: np.ndarray, obs: np.ndarray) -> StateBuffers:
    # obs copied into memory of its own: an unpickled array's data may be the pickle's bytes, which numpy
    # does not let a move write
    return StateBuffers(F, I, np.array(obs))


@dataclass
class WorldTrace:
    """A recorded world: arrays ``(T+1, B, S)`` (row 0 the initial state; row ``k`` after step ``k``)."""

    t: np.ndarray  # (T+1,) [s]
    x: np.ndarray  # [m] front bumper
    v: np.ndarray  # [m/s]
    a: np.ndarray  # [m/s^2] applied over the step ending at row k
    a_des: np.ndarray  # [m/s^2] asked for
    y: np.ndarray  # [m] lateral position
    a_y: np.ndarray  # [m/s^2] lateral acceleration
    lead: np.ndarray  # int slot ahead, -1 none
    gap: np.ndarray  # [m] bumper gap to it (inf none)
    mode: np.ndarray  # driver mode (-1 none)
    present: np.ndarray  # (B, S)
    lengths: np.ndarray  # (B, S) [m]
    width: np.ndarray  # (B, S) [m]
    road: Road = field(default_factory=Road)
    solver_stats: dict = field(default_factory=dict)

    @property
    def collided(self) -> np.ndarray:
        """``(B, S)``: did the vehicle's gap to the one ahead ever reach 0."""
        return np.any(self.gap <= 0.0, axis=0)


class SceneRecord:
    """Scene ``row`` of ``world`` (every vehicle) kept after each step, as a :class:`WorldTrace`
    ``(T+1, 1, S)``: the one recorder of a stepped episode's scene (the single env's
    :class:`~acc_gym.evaluation.runner.EpisodeRun`, the leaderboard's
    :class:`~acc_gym.leaderboard.batch.BatchRuns`). Made at the episode's start (its first row,
    modes -1)."""

    STATE = ("x", "v", "a", "a_des", "y", "a_y")  # the world's (B, S) state arrays kept

    def __init__(self, world: SingleLaneWorld, row: int = 0):
        self.world, self.row = world, int(row)
        self.rows: dict[str, list] = {k: [] for k in (*self.STATE, "lead", "gap", "mode")}
        self.snap(np.full(2, -1, dtype=np.int64))

    def snap(self, modes: np.ndarray) -> None:
        """Keep the scene's state now; ``modes``: the surrounding drivers' (POV, POV2)."""
        world, r = self.world, self.row
        for key in self.STATE:
            self.rows[key].append(getattr(world, key)[r:r + 1].copy())
        self.rows["lead"].append(world.neighbours.lead[r:r + 1].copy())
        self.rows["gap"].append(world.neighbours.gap[r:r + 1].copy())
        self.rows["mode"].append(np.concatenate([[-1], modes])[None, :])

    def trace(self, road: Road) -> WorldTrace:
        """The scene so far, on ``road``."""
        world, r = self.world, self.row
        arr = {k: np.stack(v) for k, v in self.rows.items()}
        return WorldTrace(t=np.arange(len(self.rows["x"])) * world.dt, **arr, present=world.present[r:r + 1].copy(),
                          lengths=world.lengths[r:r + 1].copy(), width=world.width[r:r + 1].copy(), road=road)


def rollout(world: SingleLaneWorld, steps: int, ego=None) -> WorldTrace:
    """Reset ``world`` and run it ``steps`` steps; the ego is driven by model ``ego`` (``n == B``)
    if given, else by ``world.drivers[0]``."""
    if int(steps) != steps or steps < 0:
        raise ValueError(f"steps must be a non-negative integer, got {steps!r}")
    if ego is not None and getattr(ego, "n", None) != world.B:
        raise ValueError(f"ego model controls n={getattr(ego, 'n', None)} vehicles; it must control B={world.B}")
    world.reset()
    if ego is not None and hasattr(ego, "reset"):
        ego.reset()
    T = int(steps)
    shape = (T + 1, world.B, world.S)
    rec = {k: np.zeros(shape) for k in ("x", "v", "a", "a_des", "y", "a_y", "gap")}
    rec["lead"] = np.zeros(shape, dtype=np.int64)
    rec["mode"] = np.full(shape, -1, dtype=np.int64)
    rec["a_des"][0] = np.nan

    def record(k):
        for key in ("x", "v", "a", "y", "a_y"):
            rec[key][k] = getattr(world, key)
        rec["gap"][k] = world.neighbours.gap
        rec["lead"][k] = world.neighbours.lead

    record(0)
    for k in range(1, T + 1):
        world.step(None if ego is None else ego.act(world.observe(0)))
        record(k)
        rec["a_des"][k] = world.a_des
        for s in range(world.S):
            model = ego if (s == 0 and ego is not None) else world.drivers[s]
            info = getattr(model, "info", None) or {}
            if "mode" in info:
                rec["mode"][k, :, s] = info["mode"]
    stats = {s: m.stats for s, m in enumerate(world.drivers) if m is not None and getattr(m, "stats", None)}
    return WorldTrace(t=np.arange(T + 1) * world.dt, **rec, present=world.present.copy(),
                      lengths=world.lengths.copy(), width=world.width.copy(), road=world.road,
                      solver_stats=stats)
