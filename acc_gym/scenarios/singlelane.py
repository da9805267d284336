"""Paper 004's single-lane traffic: 22 configurations of at most three vehicles.

Roles: SV (the ego, slot 0), POV (the first vehicle ahead), POV2 (the one ahead of the
POV). Configurations (ids ``singlelane/<vehicles>/<SV-POV>[+<POV-POV2>]``):

* 1 vehicle: ``free-flow``, ``lane-change`` (2);
* 2 vehicles: ``car-following``, ``cut-in``, ``cut-out``, ``lane-change``, ``approach`` (5);
* 3 vehicles: SV-POV in {car-following, approach, lane-change} x POV-POV2 in
  {car-following, cut-in, cut-out, lane-change, approach} (15);
* plus ``singlelane/2/separate`` (the POV drives away): paper 004 names the subscenario
  but lists no configuration for it; ours, flagged ``in_paper=False``.

What each subscenario means for a follower F and its leader L (decided here, after the
paper's Section III.C and its Example 1): *car-following*: same lane, small relative
speed; *approach*: same lane, F faster; *separate*: same lane, L faster; *cut-in*: L moves
from the adjacent lane into F's lane; *cut-out*: L leaves F's lane; *lane change*: the
follower changes lane -- the SV merges into the POV's lane behind it, and the POV (in
POV-POV2) leaves the lane so that the SV must follow POV2, as in the paper's Example 1.

Geometry: a three-lane carriageway; the traffic under study drives in lane 1, vehicles
cut in from and out to lane 2 (the left), and a merging SV comes from lane 0 (the right),
so no two lateral moves share a lane and nobody in the ego's merge lane affects it
before it enters. Lateral moves are half-cosine, starting at ``t_lc`` and lasting
``lc_duration`` (``t_lc2``/``lc_duration2`` for the POV-POV2 event); a vehicle becomes
a target when its contour crosses the lane line, at phase ``acos(width / lane_width) /
pi`` (0.34) of the move.

Gaps are bumper to bumper. For a lane entry (cut-in, SV lane change) ``gap`` is the gap
*when the entering vehicle becomes the follower's target*, placed assuming constant
speeds until then (exact: neither has anything ahead in its lane) -- except that an SV
merging behind a POV that already reacts to POV2 is placed from a short simulation of
the others. An entry the follower could not survive is made survivable: the gap is
raised, if needed, to ``closing 0.5 s + closing^2 / (2 x 6 m/s^2) + 2 m`` (react in
0.5 s, then brake at 6 m/s^2, well inside the tyre limit). Paper 004 traced 7 of its
CACC's 9 collisions in an hour to "unrealistic environment settings"; this floor keeps
the generator from making unavoidable collisions. Speeds: the SV's set speed is its
initial speed ``v_sv``; every surrounding driver's desired speed is its initial speed.

Parameter laws (paper 004 Eqs. 6-9; the paper publishes no fitted values, so the
defaults below are ours, each with its source or reasoning -- calibrate them to your own
data with :mod:`acc_gym.scenarios.calibration`):

* ``v_sv`` [m/s]: normal, mean 27 (about 100 km/h, motorway traffic), sd 4, in [8, 40].
* car-following / cut-out ``(v_sv, gap)``: bivariate normal, means (27 m/s, 40 m), sds
  (4, 12), correlation 0.6: gaps grow with speed (a time gap near 1.5 s, the usual median
  of motorway car-following headways), in [8, 40] x [8, 120].
* car-following ``v_rel`` = v_POV - v_SV [m/s]: Laplace(0, 0.8) in [-4, 4] -- steady
  following is sharply peaked at zero relative speed with heavy tails, the reason the
  paper offers the Laplace law.
* approach ``closing`` = v_SV - v_POV [m/s]: log-normal, median 6, S 0.45, in [1, 20];
  ``gap`` log-normal median 80 m, S 0.35, in [30, 180] (inside the 200 m radar range).
* cut-in ``gap`` at entry: log-normal median 18 m, S 0.4, in [5, 60]; ``v_rel`` normal
  (-1, 2.5) in [-8, 6] (cutting-in vehicles are on average slightly slower).
* lane changes: ``lc_duration`` normal (4.6 s, 0.8) in [2.5, 7] (mean lane-change
  duration in Toledo and Zohar, 2007); ``t_lc`` normal (3 s, 1) in [1, 6].
* ``duration`` [s]: log-normal, median 12 s, S 0.35, in [6, 40], then extended to at least
  4 s after the last lateral move ends. Mean about 12.7 s: with the default occurrence
  rates (280 configurations per hour, paper 004's "1 hour = 280 scenarios") an hour of
  sampled traffic lasts about an hour.
* ``time_gap`` [s]: the ego's nominal time gap, 1.5 (constant; a common middle ACC
  setting, ISO 15622 requires at least 0.8 s).
* occurrence rates [1/h] (:data:`OCCURRENCE_RATES`): assumed shares, car-following the
  most frequent, summing to 280 per hour.
"""

from __future__ import annotations

import itertools
import math
import threading

import numpy as np

from acc_gym.scenarios.distributions import BivariateNormal, Constant, Laplace, LogNormal, Normal
from acc_gym.scenarios.registry import ScenarioType, driver_for, register
from acc_gym.scenarios.spec import LaneChange, Scenario, VehicleSpec
from acc_gym.simulation.single_lane import VEHICLE_WIDTH, Road

LENGTH = 4.7  # [m] every vehicle
ROAD = Road(lane_width=3.75, n_lanes=3)
MERGE_LANE, EGO_LANE, SIDE_LANE = 0, 1, 2  # the SV merges from the right; others enter and leave on the left
DT = 0.2  # [s]
ENTRY_REACTION = 0.5  # [s] } the smallest entry gap: react, then brake at ENTRY_DECEL,
ENTRY_DECEL = 6.0  # [m/s^2] } stopping the closing ENTRY_MARGIN short of the entering vehicle
ENTRY_MARGIN = 2.0  # [m]   }

SV_POV_3 = ("car-following", "approach", "lane-change")
POV_POV2 = ("car-following", "cut-in", "cut-out", "lane-change", "approach")

OCCURRENCE_RATES = {  # [1/h]
    "singlelane/1/free-flow": 40.0, "singlelane/1/lane-change": 10.0,
    "singlelane/2/car-following": 70.0, "singlelane/2/cut-in": 20.0, "singlelane/2/cut-out": 15.0,
    "singlelane/2/lane-change": 15.0, "singlelane/2/approach": 25.0,
    "singlelane/3/car-following+car-following": 20.0, "singlelane/3/car-following+cut-in": 6.0,
    "singlelane/3/car-following+cut-out": 5.0, "singlelane/3/car-following+lane-change": 6.0,
    "singlelane/3/car-following+approach": 6.0,
    "singlelane/3/approach+car-following": 8.0, "singlelane/3/approach+cut-in": 4.0,
    "singlelane/3/approach+cut-out": 3.0, "singlelane/3/approach+lane-change": 4.0,
    "singlelane/3/approach+approach": 4.0,
    "singlelane/3/lane-change+car-following": 8.0, "singlelane/3/lane-change+cut-in": 3.0,
    "singlelane/3/lane-change+cut-out": 2.0, "singlelane/3/lane-change+lane-change": 3.0,
    "singlelane/3/lane-change+approach": 3.0,
}
SEPARATE_RATE = 10.0  # [1/h] of the added separate configuration (not in the 280)

V_SV = Normal(27.0, 4.0, low=8.0, high=40.0)
SPEED_GAP = BivariateNormal((27.0, 40.0), ((16.0, 0.6 * 4 * 12), (0.6 * 4 * 12, 144.0)), low=(8.0, 8.0),
                            high=(40.0, 120.0))
GAP_FOLLOW = Normal(40.0, 12.0, low=8.0, high=120.0)  # POV-POV2 gap (the gap marginal of SPEED_GAP)
V_REL_FOLLOW = Laplace(0.0, 0.8, low=-4.0, high=4.0)
CLOSING = LogNormal(float(np.log(6.0)), 0.45, low=1.0, high=20.0)
GAP_APPROACH = LogNormal(float(np.log(80.0)), 0.35, low=30.0, high=180.0)
GAP_CUT_IN = LogNormal(float(np.log(18.0)), 0.4, low=5.0, high=60.0)
V_REL_CUT_IN = Normal(-1.0, 2.5, low=-8.0, high=6.0)
GAP_MERGE = LogNormal(float(np.log(35.0)), 0.4, low=10.0, high=100.0)
V_REL_MERGE = Normal(-1.0, 2.0, low=-6.0, high=4.0)
OPENING = LogNormal(float(np.log(3.0)), 0.5, low=0.5, high=12.0)
GAP_SEPARATE = LogNormal(float(np.log(25.0)), 0.4, low=8.0, high=80.0)
T_LC = Normal(3.0, 1.0, low=1.0, high=6.0)
LC_DURATION = Normal(4.6, 0.8, low=2.5, high=7.0)
DURATION = LogNormal(float(np.log(12.0)), 0.35, low=6.0, high=40.0)
TIME_GAP = Constant(1.5)

UNITS = {"v_sv": "[m/s] SV initial speed and set speed", "gap": "[m] SV-POV bumper gap",
         "v_rel": "[m/s] v_POV - v_SV", "closing": "[m/s] v_SV - v_POV", "opening": "[m/s] v_POV - v_SV",
         "gap2": "[m] POV-POV2 bumper gap", "v_rel2": "[m/s] v_POV2 - v_POV", "closing2": "[m/s] v_POV - v_POV2",
         "t_lc": "[s] start of the SV-POV lateral move", "lc_duration": "[s] its duration",
         "t_lc2": "[s] start of the POV-POV2 lateral move", "lc_duration2": "[s] its duration",
         "duration": "[s] scenario length", "time_gap": "[s] ego's nominal time gap"}


POSITIVE = frozenset({"gap", "gap2", "closing", "closing2", "opening", "lc_duration", "lc_duration2", "duration",
                      "time_gap"})
NONNEGATIVE = frozenset({"v_sv", "t_lc", "t_lc2"})


def _pair_laws(kind: str, suffix: str = "", joint_speed: bool = True) -> dict:
    """Laws of one follower-leader pair's parameters (``suffix`` "2" for POV-POV2)."""
    g, vr = f"gap{suffix}", f"v_rel{suffix}"
    laws: dict = {}
    if kind in ("car-following", "cut-out"):
        if joint_speed:
            laws[("v_sv", g)] = SPEED_GAP
        else:
            laws[g] = GAP_FOLLOW
        laws[vr] = V_REL_FOLLOW
    elif kind == "approach":
        laws[g] = GAP_APPROACH
        laws[f"closing{suffix}"] = CLOSING
    elif kind == "separate":
        laws[g] = GAP_SEPARATE
        laws["opening"] = OPENING
    elif kind == "cut-in":
        laws[g] = GAP_CUT_IN
        laws[vr] = V_REL_CUT_IN
    elif kind == "lane-change":
        laws[g] = GAP_MERGE
        laws[vr] = V_REL_MERGE
    if kind in ("cut-in", "cut-out", "lane-change"):
        laws[f"t_lc{suffix}"] = T_LC
        laws[f"lc_duration{suffix}"] = LC_DURATION
    return laws


def _leader_speed(kind: str, v_follower: float, p: dict, suffix: str = "") -> float:
    if kind == "approach":
        return max(v_follower - p[f"closing{suffix}"], 1.0)
    if kind == "separate":
        return v_follower + p["opening"]
    return max(v_follower + p[f"v_rel{suffix}"], 1.0)


def entry_phase(road: Road = ROAD, width: float = VEHICLE_WIDTH) -> float:
    """Phase of a one-lane half-cosine move at which the mover's contour enters the other
    vehicle's corridor (|dy| < (lane_width + width) / 2): ``acos(width / lane_width) / pi``."""
    return math.acos(width / road.lane_width) / math.pi


def entry_gap(gap: float, v_follower: float, v_leader: float) -> float:
    """``gap`` raised, if needed, to the smallest entry gap a follower survives: reacting in
    ``ENTRY_REACTION`` s, then braking at ``ENTRY_DECEL`` m/s^2 stops the closing ``ENTRY_MARGIN`` m short."""
    closing = v_follower - v_leader
    if closing <= 0:
        return gap
    return max(gap, closing * ENTRY_REACTION + closing ** 2 / (2.0 * ENTRY_DECEL) + ENTRY_MARGIN)


def _ahead(x_follower: float, v_follower: float, v_leader: float, gap: float, t_entry: float | None) -> float:
    """Front bumper of the leader at t = 0: ``gap`` ahead now, or at ``t_entry`` for a lane entry
    (both at constant speed until then: the entering vehicle has nothing ahead in its lane)."""
    if t_entry is None:
        return x_follower + gap + LENGTH
    return x_follower + entry_gap(gap, v_follower, v_leader) + LENGTH - (v_leader - v_follower) * t_entry


_PROBES = threading.local()  # one probe world per thread and step, reused by every pre-simulation


def _probe_world(dt: float):
    """A one-scene world with replaceable surrounding drivers (the environments' slots), kept
    for reuse: building fresh MPC drivers for every pre-simulation cost more than the run."""
    from acc_gym.drivers.slots import SlotDrivers, SlotView  # late: the drivers import the scenarios' registry
    from acc_gym.simulation.single_lane import SingleLaneWorld

    worlds = _PROBES.__dict__.setdefault("worlds", {})
    if dt not in worlds:
        joint = SlotDrivers(2, dt)  # both surrounding slots, one driver call per step (as the environments)
        slots = [SlotView(joint, 0, 1), SlotView(joint, 1, 1)]
        worlds[dt] = (SingleLaneWorld(np.array([[-1.0e6, -5.0e5, 0.0]]), np.zeros((1, 3)), [None, *slots], dt=dt,
                                      joint=joint), slots)
    return worlds[dt]


def _presimulate_pov(vehicles: list, t_entry: float, dt: float) -> tuple[float, float]:
    """The POV's position and speed at ``t_entry`` [s] without the ego (which, in its own lane,
    cannot influence anyone before it enters theirs)."""
    from acc_gym.scenarios.world import scene_arrays  # late: the world module builds drivers

    far = min(v.x0 for v in vehicles[1:]) - 1.0e5
    probe = Scenario(id="probe", seed=0, params={}, duration=t_entry + dt, set_speed=1.0, time_gap=1.0, road=ROAD,
                     dt=dt, vehicles=(VehicleSpec("SV", far, 0.0, MERGE_LANE, None, None, LENGTH), *vehicles[1:]))
    arr = scene_arrays([probe], ROAD)
    world, slots = _probe_world(dt)
    world.reset_rows([0], arr.x0, arr.v0, present=arr.present, lateral=arr.lateral, lengths=arr.length,
                     width=arr.width)
    for s, slot in enumerate(slots, start=1):
        slot.assign(0, arr.drivers[s][0])
    steps = int(math.ceil(t_entry / dt))
    xs, vs = world.coast(steps, 0.0)  # one compiled call with baseline drivers
    times = np.arange(steps + 1) * dt
    return float(np.interp(t_entry, times, xs[:, 0, 1])), float(np.interp(t_entry, times, vs[:, 0, 1]))


def _leader_lanes(kind: str, p: dict, suffix: str = "") -> tuple[int, LaneChange | None]:
    """The leader's start lane and lateral move in a pair: it cuts in from the side lane, cuts out
    to it, or keeps the lane under study."""
    if kind == "cut-in":
        return SIDE_LANE, LaneChange(EGO_LANE, p[f"t_lc{suffix}"], p[f"lc_duration{suffix}"])
    if kind == "cut-out":
        return EGO_LANE, LaneChange(SIDE_LANE, p[f"t_lc{suffix}"], p[f"lc_duration{suffix}"])
    return EGO_LANE, None


def _build(stype: ScenarioType, p: dict, rng: np.random.Generator, drivers: str, seed: int) -> Scenario:
    n, rel = stype.id.split("/")[1:]
    parts = rel.split("+")
    sv_pov = parts[0]
    pov_pov2 = parts[1] if len(parts) > 1 else None
    v_sv = p["v_sv"]
    phase = entry_phase()
    sv_changes = sv_pov == "lane-change"
    sv_lane = MERGE_LANE if sv_changes else EGO_LANE
    sv_lc = LaneChange(EGO_LANE, p["t_lc"], p["lc_duration"]) if sv_changes else None
    moves = [p["t_lc"] + p["lc_duration"]] if "t_lc" in p else []
    t_entry = p["t_lc"] + phase * p["lc_duration"] if sv_pov in ("cut-in", "lane-change") else None
    x_sv = 0.0
    vehicles = [VehicleSpec("SV", x_sv, v_sv, sv_lane, None, sv_lc, LENGTH)]
    if int(n) >= 2:
        v_pov = _leader_speed(sv_pov, v_sv, p)
        x_pov = _ahead(x_sv, v_sv, v_pov, p["gap"], t_entry)
        pov_lane, pov_lc = _leader_lanes(sv_pov, p)
        if pov_pov2 == "lane-change":  # the POV leaves: the SV is left behind POV2 (paper 004, Example 1)
            pov_lc = LaneChange(SIDE_LANE, p["t_lc2"], p["lc_duration2"])
        vehicles.append(VehicleSpec("POV", x_pov, v_pov, pov_lane, driver_for(rng, drivers, v_pov), pov_lc, LENGTH))
    if pov_pov2 is not None:
        v_pov2 = _leader_speed(pov_pov2, v_pov, p, "2")
        t_entry2 = p["t_lc2"] + phase * p["lc_duration2"] if pov_pov2 == "cut-in" else None
        x_pov2 = _ahead(x_pov, v_pov, v_pov2, p["gap2"], t_entry2)
        pov2_lane, pov2_lc = _leader_lanes(pov_pov2, p, "2")
        if "t_lc2" in p:
            moves.append(p["t_lc2"] + p["lc_duration2"])
        vehicles.append(VehicleSpec("POV2", x_pov2, v_pov2, pov2_lane, driver_for(rng, drivers, v_pov2), pov2_lc,
                                    LENGTH))
        if sv_changes:  # the POV may already react to POV2: place the ego where the POV really is at entry
            x_e, v_e = _presimulate_pov(vehicles, t_entry, DT)
            x_sv = x_e - LENGTH - entry_gap(p["gap"], v_sv, v_e) - v_sv * t_entry
            vehicles[0] = VehicleSpec("SV", x_sv, v_sv, sv_lane, None, sv_lc, LENGTH)
    duration = max(p["duration"], max(moves, default=0.0) + 4.0)
    return Scenario(id=stype.id, seed=seed, params=p, vehicles=tuple(vehicles), duration=duration,
                    set_speed=v_sv, time_gap=p["time_gap"], road=ROAD, dt=DT, drivers=drivers,
                    description=stype.description)


def _describe(n: int, sv_pov: str, pov_pov2: str | None) -> str:
    text = {
        "free-flow": "the SV drives alone",
        "car-following": "the SV follows the POV at a steady speed",
        "approach": "the SV approaches a slower POV in its lane",
        "separate": "the POV drives away from the SV",
        "cut-in": "the POV cuts in from the adjacent lane in front of the SV",
        "cut-out": "the POV leaves the SV's lane",
        "lane-change": "the SV changes lane" + ("" if n == 1 else " into the POV's lane, behind it"),
    }[sv_pov]
    if pov_pov2 is not None:
        text += "; " + {
            "car-following": "the POV follows POV2",
            "approach": "the POV approaches a slower POV2",
            "cut-in": "POV2 cuts in in front of the POV",
            "cut-out": "POV2 leaves the POV's lane",
            "lane-change": "the POV changes lane, leaving the SV behind POV2",
        }[pov_pov2]
    return text[0].upper() + text[1:] + "."


def _register_all() -> None:
    configs = [(1, "free-flow", None), (1, "lane-change", None)]
    configs += [(2, k, None) for k in ("car-following", "cut-in", "cut-out", "lane-change", "approach")]
    configs += [(3, a, b) for a, b in itertools.product(SV_POV_3, POV_POV2)]
    for n, a, b in configs:
        sid = f"singlelane/{n}/{a}" + (f"+{b}" if b else "")
        laws: dict = {}
        if n == 1:
            laws["v_sv"] = V_SV
            if a == "lane-change":
                laws["t_lc"], laws["lc_duration"] = T_LC, LC_DURATION
        else:
            pair = _pair_laws(a)
            if not any(isinstance(k, tuple) for k in pair):
                laws["v_sv"] = V_SV
            laws.update(pair)
            if b is not None:
                laws.update(_pair_laws(b, "2", joint_speed=False))
        laws["duration"] = DURATION
        laws["time_gap"] = TIME_GAP
        register(ScenarioType(sid, "singlelane", _describe(n, a, b), laws, _build,
                              occurrence_rate=Constant(OCCURRENCE_RATES[sid]), units=UNITS,
                              positive=POSITIVE, nonnegative=NONNEGATIVE))
    laws = {"v_sv": V_SV, **_pair_laws("separate"), "duration": DURATION, "time_gap": TIME_GAP}
    register(ScenarioType("singlelane/2/separate", "singlelane", _describe(2, "separate", None), laws, _build,
                          occurrence_rate=Constant(SEPARATE_RATE), in_paper=False, units=UNITS,
                          positive=POSITIVE, nonnegative=NONNEGATIVE))


_register_all()
