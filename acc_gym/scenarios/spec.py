"""A scenario as a plain, serialisable value.

A :class:`Scenario` says everything needed to run a test: the road, each vehicle's
initial state, lane and scripted lane change, the surrounding drivers' models with all
their parameters, the ego's set speed and nominal time gap, the duration and step. It
round-trips through JSON (``to_json`` / ``from_json``, with ``schema_version``) and also
records the ``(id, params, seed)`` it was built from, so
``acc_gym.scenarios.build(s.id, s.params, s.seed) == s``.

Vehicles are listed ego first (role ``"SV"``), then ``"POV"`` and ``"POV2"``. Positions
are front bumpers [m]; ``lane`` is a lane index of :class:`~acc_gym.simulation.single_lane.Road`
(0 the rightmost); speeds [m/s]. A driver is ``{"model": name, "params": {...}}`` where the
model is ``"mpc"`` (:class:`~acc_gym.drivers.mpc.MPCDriverParams` fields), a baseline name
of :data:`acc_gym.drivers.baselines.MODELS`, or ``"profile"`` with ``times``/``speeds``
(a scripted or recorded speed trace).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, fields, replace

import numpy as np

from acc_gym.drivers.baselines import MODELS
from acc_gym.drivers.mpc import MPCDriverParams
from acc_gym.simulation.profiles import SpeedProfile
from acc_gym.simulation.single_lane import VEHICLE_WIDTH, Road

SCHEMA_VERSION = 1
ROLES = ("SV", "POV", "POV2")
DRIVER_MODELS = ("mpc", "profile", *sorted(MODELS))


# Physical bounds of a scenario's values (decided here; the limit is in each message):
MAX_DURATION = 7200.0  # [s] two hours: the env allocates the episode's record at reset
MAX_SPEED = 70.0  # [m/s] 252 km/h: initial speeds, profile speeds, the set speed (the observation's bound)
MAX_TIME_GAP = 10.0  # [s]
# |x0| [m]: float64 keeps positions to 1.2e-10 m there (at 1e15 m only to 0.125 m, and scores drift)
MAX_POSITION = 1e6
MAX_LENGTH = 50.0  # [m] a vehicle's length (a road train is about 25 m)
MAX_WIDTH = 5.0  # [m] a vehicle's width (a lane is about 3.5 m)
MAX_PROFILE_ACCEL = 20.0  # [m/s^2] |dv/dt| between a speed profile's points: 2 g, beyond any road vehicle
MAX_DRIVER_PARAM = 1e9  # |value| of any driver-model parameter: the MPC cost weights of the populations reach ~1e7 (q1)
# driver parameters that are speeds [m/s] (desired / set / top speed): bounded like the vehicles' speeds
DRIVER_SPEED_PARAMS = ("v_desired", "v_max", "v_set")
_NUMBER = (int, float, np.integer, np.floating)
_PARAM_NAMES: dict = {}  # a driver model's parameter dataclass -> its fields' names


def _finite(name: str, value, *, positive=False, nonnegative=False, at_most: float | None = None,
            magnitude: float | None = None) -> float:
    """``value`` as a float: a real number (not a bool, not text), finite, within the bounds
    (``magnitude``: ``|value|`` at most that)."""
    if (type(value) is float and value - value == 0.0 and (not positive or value > 0) and (not nonnegative or value >= 0)
            and (at_most is None or value <= at_most) and (magnitude is None or abs(value) <= magnitude)):
        return value  # a finite Python float within the bounds (the usual case): what the checks below return
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, _NUMBER):
        raise ValueError(f"{name} must be a number, got {value!r} ({type(value).__name__})")
    x = float(value)
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite, got {value!r}")
    if positive and x <= 0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
    if nonnegative and x < 0:
        raise ValueError(f"{name} must be >= 0, got {value!r}")
    if at_most is not None and x > at_most:
        raise ValueError(f"{name} must be at most {at_most:g}, got {value!r}")
    if magnitude is not None and abs(x) > magnitude:
        raise ValueError(f"{name} must be within -{magnitude:g} and {magnitude:g}, got {value!r}")
    return x


def _integer(name: str, value, minimum: int = 0) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < minimum:
        what = "a non-negative integer" if minimum == 0 else f"an integer >= {minimum}"
        raise ValueError(f"{name} must be {what}, got {value!r}")
    return int(value)


def _exact_keys(name: str, data, required: set, optional: set = frozenset()) -> None:
    if not isinstance(data, dict):
        raise ValueError(f"{name} must be a JSON object, got {type(data).__name__}")
    missing = required - set(data)
    extra = set(data) - required - set(optional)
    if missing:
        raise ValueError(f"{name} is missing key(s) {sorted(missing)}")
    if extra:
        raise ValueError(f"{name} has unknown key(s) {sorted(extra)}")


@dataclass(frozen=True)
class DriverSpec:
    """A surrounding vehicle's driver: model name and parameters (or a speed trace)."""

    model: str
    params: dict = field(default_factory=dict)
    times: tuple | None = None  # [s] for model "profile"
    speeds: tuple | None = None  # [m/s]

    def __post_init__(self) -> None:
        if self.model not in DRIVER_MODELS:
            raise ValueError(f"unknown driver model {self.model!r}; known: {list(DRIVER_MODELS)}")
        if not isinstance(self.params, dict):
            raise ValueError(f"driver params must be a JSON object, got {type(self.params).__name__}")
        params = self.params
        if all(type(k) is str and type(v) is float and -MAX_DRIVER_PARAM <= v <= MAX_DRIVER_PARAM
               for k, v in params.items()):
            params = dict(params)  # finite floats by name within the bound (a builder's): as below
        else:
            params = {str(k): _finite(f"driver params[{k!r}]", v) for k, v in params.items()}
        for name in DRIVER_SPEED_PARAMS:
            if name in params and not 0.0 <= params[name] <= MAX_SPEED:
                _finite(f"driver params[{name!r}] (a speed of model {self.model!r})", params[name], nonnegative=True,
                        at_most=MAX_SPEED)
        for k, v in params.items():
            if not -MAX_DRIVER_PARAM <= v <= MAX_DRIVER_PARAM:
                _finite(f"driver params[{k!r}] (MAX_DRIVER_PARAM)", v, magnitude=MAX_DRIVER_PARAM)
        if self.model == "profile" and params:
            raise ValueError(f"a 'profile' driver takes no parameters, got {sorted(params)}")
        object.__setattr__(self, "params", params)
        if self.model == "profile":
            if self.times is None or self.speeds is None:
                raise ValueError("a 'profile' driver needs times and speeds")
            t = tuple(_finite("profile time", v) for v in self.times)
            s = tuple(_finite("profile speed", v, nonnegative=True, at_most=MAX_SPEED) for v in self.speeds)
            SpeedProfile(np.array(t), np.array(s))  # validates ordering and lengths
            for k in range(len(t) - 1):
                rate = abs(s[k + 1] - s[k]) / (t[k + 1] - t[k])
                if rate > MAX_PROFILE_ACCEL:
                    raise ValueError(f"profile speed changes from {s[k]:g} to {s[k + 1]:g} m/s between t = {t[k]:g} "
                                     f"and {t[k + 1]:g} s: {rate:g} m/s^2, more than a road vehicle's "
                                     f"{MAX_PROFILE_ACCEL:g} m/s^2 (MAX_PROFILE_ACCEL)")
            object.__setattr__(self, "times", t)
            object.__setattr__(self, "speeds", s)
        elif self.times is not None or self.speeds is not None:
            raise ValueError(f"times/speeds are only for 'profile' drivers, not {self.model!r}")
        else:  # validate the parameter names and values now; the (frozen) result kept for params_object()
            object.__setattr__(self, "_params_object", self._make_params_object())

    def params_object(self):
        """The model's parameter dataclass (validated; made once, when the spec is)."""
        made = self.__dict__.get("_params_object")
        return made if made is not None else self._make_params_object()

    def _make_params_object(self):
        cls = MPCDriverParams if self.model == "mpc" else MODELS[self.model].params_type
        names = _PARAM_NAMES.get(cls)
        if names is None:
            names = _PARAM_NAMES[cls] = frozenset(f.name for f in fields(cls))
        unknown = set(self.params) - names
        if unknown:
            raise ValueError(f"unknown parameter(s) {sorted(unknown)} for driver model {self.model!r}")
        return cls(**self.params)

    def profile(self) -> SpeedProfile:
        return SpeedProfile(np.array(self.times), np.array(self.speeds))

    @classmethod
    def mpc(cls, params: MPCDriverParams) -> "DriverSpec":
        """From one driver's parameters (``size == 1``)."""
        values = {}
        for f in fields(params):
            value = getattr(params, f.name)
            if value is not None:
                values[f.name] = float(np.asarray(value, float).reshape(-1)[0])
        return cls("mpc", values)

    @classmethod
    def from_profile(cls, profile: SpeedProfile) -> "DriverSpec":
        return cls("profile", {}, tuple(map(float, profile.times)), tuple(map(float, profile.speeds)))

    def to_dict(self) -> dict:
        out = {"model": self.model, "params": dict(self.params)}
        if self.model == "profile":
            out["times"], out["speeds"] = list(self.times), list(self.speeds)
        return out

    @classmethod
    def from_dict(cls, d) -> "DriverSpec":
        _exact_keys("driver", d, {"model", "params"}, {"times", "speeds"})
        return cls(d["model"], d["params"], None if "times" not in d else tuple(d["times"]),
                   None if "speeds" not in d else tuple(d["speeds"]))


@dataclass(frozen=True)
class LaneChange:
    """A scripted lateral move to ``to_lane`` starting at ``t_start`` [s], lasting ``duration`` [s]."""

    to_lane: int
    t_start: float
    duration: float

    def __post_init__(self) -> None:
        if int(self.to_lane) != self.to_lane or self.to_lane < 0:
            raise ValueError(f"LaneChange.to_lane must be a lane index >= 0, got {self.to_lane!r}")
        object.__setattr__(self, "to_lane", int(self.to_lane))
        object.__setattr__(self, "t_start", _finite("LaneChange.t_start", self.t_start, nonnegative=True))
        object.__setattr__(self, "duration", _finite("LaneChange.duration", self.duration, positive=True))


@dataclass(frozen=True)
class VehicleSpec:
    """One vehicle at ``t = 0``; the ego has no driver (the controller under test drives it)."""

    role: str
    x0: float  # [m] front bumper
    v0: float  # [m/s]
    lane: int = 0
    driver: DriverSpec | None = None
    lane_change: LaneChange | None = None
    length: float = 4.7  # [m]
    width: float = VEHICLE_WIDTH  # [m]

    def __post_init__(self) -> None:
        if self.role not in ROLES:
            raise ValueError(f"unknown vehicle role {self.role!r}; use one of {ROLES}")
        x0, v0, length, width = self.x0, self.v0, self.length, self.width
        if (type(x0) is float and type(v0) is float and type(length) is float and type(width) is float
                and type(self.lane) is int and -MAX_POSITION <= x0 <= MAX_POSITION and 0.0 <= v0 <= MAX_SPEED
                and 0.0 < length <= MAX_LENGTH and 0.0 < width <= MAX_WIDTH and self.lane >= 0):
            pass  # plain numbers within the bounds (a builder's): what the checks below would store
        else:
            self._check_numbers()
        if self.role == "SV" and self.driver is not None:
            raise ValueError("the SV (ego) is driven by the controller under test; give it no driver")
        if self.role != "SV" and self.driver is None:
            raise ValueError(f"{self.role} needs a driver")

    def _check_numbers(self) -> None:
        object.__setattr__(self, "x0", _finite(f"{self.role}.x0", self.x0, magnitude=MAX_POSITION))
        object.__setattr__(self, "v0", _finite(f"{self.role}.v0 (initial speed)", self.v0, nonnegative=True,
                                               at_most=MAX_SPEED))
        object.__setattr__(self, "length", _finite(f"{self.role}.length", self.length, positive=True,
                                                   at_most=MAX_LENGTH))
        object.__setattr__(self, "width", _finite(f"{self.role}.width", self.width, positive=True,
                                                  at_most=MAX_WIDTH))
        object.__setattr__(self, "lane", _integer(f"{self.role}.lane (a lane index)", self.lane))

    def to_dict(self) -> dict:
        return {"role": self.role, "x0": self.x0, "v0": self.v0, "lane": self.lane,
                "driver": None if self.driver is None else self.driver.to_dict(),
                "lane_change": None if self.lane_change is None else asdict(self.lane_change),
                "length": self.length, "width": self.width}

    @classmethod
    def from_dict(cls, d) -> "VehicleSpec":
        _exact_keys("vehicle", d, {"role", "x0", "v0", "lane", "driver", "lane_change", "length", "width"})
        lc = d["lane_change"]
        if lc is not None:
            _exact_keys("lane_change", lc, {"to_lane", "t_start", "duration"})
            lc = LaneChange(**lc)
        return cls(d["role"], d["x0"], d["v0"], d["lane"],
                   None if d["driver"] is None else DriverSpec.from_dict(d["driver"]), lc, d["length"], d["width"])


@dataclass(frozen=True)
class Scenario:
    """A complete, reproducible test scenario (see the module docstring)."""

    id: str
    seed: int
    params: dict  # the parameters it was built from (name -> value)
    vehicles: tuple  # VehicleSpec, ego first
    duration: float  # [s]
    set_speed: float  # [m/s] the ego's cruise set speed
    time_gap: float  # [s] the ego's nominal time gap (the scoring's default reaction time tau1)
    road: Road = field(default_factory=Road)
    dt: float = 0.2  # [s]
    drivers: str = "typical"  # how the surrounding drivers were chosen (see acc_gym.scenarios.build)
    description: str = ""
    schema_version: int = SCHEMA_VERSION

    def __post_init__(self) -> None:
        if not isinstance(self.id, str) or not self.id:
            raise ValueError(f"Scenario.id must be a non-empty string, got {self.id!r}")
        object.__setattr__(self, "seed", _integer("Scenario.seed", self.seed))
        if not isinstance(self.params, dict):
            raise ValueError(f"Scenario.params must be a JSON object, got {type(self.params).__name__}")
        params = self.params
        if all(type(k) is str and type(v) is float and v - v == 0.0 for k, v in params.items()):
            object.__setattr__(self, "params", dict(params))  # finite floats by name (a builder's): as below
        else:
            object.__setattr__(self, "params", {str(k): _finite(f"Scenario.params[{k!r}]", v)
                                                for k, v in params.items()})
        if not isinstance(self.drivers, str):
            raise ValueError(f"Scenario.drivers must be a string, got {self.drivers!r}")
        object.__setattr__(self, "vehicles", tuple(self.vehicles))
        if not self.vehicles or self.vehicles[0].role != "SV":
            raise ValueError("Scenario.vehicles must start with the SV (ego)")
        roles = [v.role for v in self.vehicles]
        if len(set(roles)) != len(roles):
            raise ValueError(f"Scenario.vehicles has repeated roles {roles}")
        object.__setattr__(self, "dt", _finite("Scenario.dt", self.dt, positive=True, at_most=1.0))
        duration = _finite("Scenario.duration", self.duration, positive=True, at_most=MAX_DURATION)
        if duration < 2 * self.dt:
            raise ValueError(f"Scenario.duration must be at least two steps ({2 * self.dt:g} s), got {self.duration!r}")
        object.__setattr__(self, "duration", duration)
        object.__setattr__(self, "set_speed", _finite("Scenario.set_speed", self.set_speed, positive=True,
                                                      at_most=MAX_SPEED))
        object.__setattr__(self, "time_gap", _finite("Scenario.time_gap", self.time_gap, positive=True,
                                                     at_most=MAX_TIME_GAP))
        if type(self.schema_version) is not int or self.schema_version != SCHEMA_VERSION:
            raise ValueError(f"Scenario.schema_version {self.schema_version!r} is not supported "
                             f"(this version of acc_gym reads {SCHEMA_VERSION})")
        ego = self.vehicles[0]
        for v in self.vehicles:
            lanes = [v.lane] + ([v.lane_change.to_lane] if v.lane_change else [])
            if max(lanes) >= self.road.n_lanes:
                raise ValueError(f"{v.role} uses lane {max(lanes)} but the road has {self.road.n_lanes} lane(s)")
            if v is not ego and v.lane == ego.lane and v.lane_change is None and v.x0 - v.length <= ego.x0:
                raise ValueError(f"{v.role} starts behind or overlapping the ego in its lane (x0 {v.x0:g} m, rear "
                                 f"{v.x0 - v.length:g} m, ego front {ego.x0:g} m): it would run into the ego, which "
                                 f"would be blamed")

    @property
    def steps(self) -> int:
        return int(round(self.duration / self.dt))

    @property
    def n_vehicles(self) -> int:
        return len(self.vehicles)

    def vehicle(self, role: str) -> VehicleSpec:
        for v in self.vehicles:
            if v.role == role:
                return v
        raise KeyError(f"scenario {self.id!r} has no {role}")

    def with_driver(self, role: str, driver) -> "Scenario":
        """The same scenario with ``role``'s driver replaced: a :class:`DriverSpec`, a
        :class:`~acc_gym.simulation.profiles.SpeedProfile` (scripted or recorded, e.g.
        ``SpeedProfile.recorded(t, v)``) or one driver's :class:`MPCDriverParams`."""
        if isinstance(driver, SpeedProfile):
            driver = DriverSpec.from_profile(driver)
        elif isinstance(driver, MPCDriverParams):
            driver = DriverSpec.mpc(driver)
        if not isinstance(driver, DriverSpec):
            raise TypeError("driver must be a DriverSpec, SpeedProfile or MPCDriverParams, "
                            f"got {type(driver).__name__}")
        vehicle = self.vehicle(role)
        if role == "SV":
            raise ValueError("the SV (ego) is driven by the controller under test")
        vehicles = tuple(replace(v, driver=driver) if v is vehicle else v for v in self.vehicles)
        return replace(self, vehicles=vehicles, drivers="custom")

    def to_dict(self) -> dict:
        road = {"lane_width": self.road.lane_width, "n_lanes": self.road.n_lanes,
                "length": None if math.isinf(self.road.length) else self.road.length}
        return {"schema_version": self.schema_version, "id": self.id, "seed": self.seed,
                "params": dict(self.params), "duration": self.duration, "dt": self.dt, "drivers": self.drivers,
                "set_speed": self.set_speed, "time_gap": self.time_gap, "road": road,
                "description": self.description, "vehicles": [v.to_dict() for v in self.vehicles]}

    def to_json(self, **kwargs) -> str:
        return json.dumps(self.to_dict(), **kwargs)

    @classmethod
    def from_dict(cls, d) -> "Scenario":
        _exact_keys("scenario", d, {"schema_version", "id", "seed", "params", "duration", "dt", "set_speed",
                                    "time_gap", "road", "drivers", "description", "vehicles"})
        if type(d["schema_version"]) is not int or d["schema_version"] != SCHEMA_VERSION:
            raise ValueError(f"scenario schema_version {d['schema_version']!r} is not supported "
                             f"(this version of acc_gym reads the integer {SCHEMA_VERSION})")
        r = d["road"]
        _exact_keys("road", r, {"lane_width", "n_lanes", "length"})
        road = Road(_finite("road.lane_width", r["lane_width"], positive=True),
                    _integer("road.n_lanes", r["n_lanes"], minimum=1),
                    float("inf") if r["length"] is None else _finite("road.length", r["length"], positive=True))
        if not isinstance(d["vehicles"], list):
            raise ValueError("scenario.vehicles must be a list")
        return cls(id=d["id"], seed=d["seed"], params=d["params"], duration=d["duration"], dt=d["dt"],
                   set_speed=d["set_speed"], time_gap=d["time_gap"], road=road, drivers=d["drivers"],
                   description=d["description"],
                   vehicles=tuple(VehicleSpec.from_dict(v) for v in d["vehicles"]))

    @classmethod
    def from_json(cls, text: str) -> "Scenario":
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ValueError(f"malformed scenario JSON: {exc}") from None
        except RecursionError:
            raise ValueError("malformed scenario JSON: nested too deeply") from None
        return cls.from_dict(data)
