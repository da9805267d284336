"""Writing the package's scenarios as OpenSCENARIO (``acc_gym.scenarios.openscenario.writer``,
``acc-gym export``): every family written as driven under a controller and read back, driven
by the same controller, gives the same trajectories to 1e-6 m; the files pass ASAM's checker."""

import json
import math

import numpy as np
import pytest

pytest.importorskip("scenariogeneration", reason="scenariogeneration is not installed (pip install '.[osc]' or '.[test]'): nothing writes OpenSCENARIO")

from acc_gym import scenarios  # noqa: E402
from acc_gym.cli import main  # noqa: E402
from acc_gym.evaluation.runner import load_controller  # noqa: E402
from acc_gym.reproducibility import SCORE_TOLERANCE  # noqa: E402
from acc_gym.scenarios.openscenario import read, run_file  # noqa: E402
from acc_gym.scenarios.openscenario import model as M  # noqa: E402
from acc_gym.scenarios.openscenario.writer import REAR_AXLE, export, profile_entries  # noqa: E402

TOLERANCE = 1e-6  # [m], [m/s]

# one scenario of every family, and of every kind of lateral event of paper 004's generator (the SV's own lane
# change, a cut-in, a cut-out, both at once), Euro NCAP's targets, stop-and-go
ROUND_TRIP = [
    ("carfollowing/varied", 1, "acc"),
    ("carfollowing/emergency", 2, "ppo"),
    ("ncap/ccrb/2-12", 0, "acc"),
    ("ncap/ccrs/30", 0, "constant"),  # a collision: the never-braking ego runs into the standing target
    ("ncap2026/acc/cut-in/50-10", 0, "acc"),
    ("ncap2026/acc/cut-out/90-70", 0, "mpc"),
    ("singlelane/2/cut-in", 4, "ppo"),
    ("singlelane/2/cut-out", 1, "idm"),
    ("singlelane/3/lane-change+cut-in", 1, "acc"),
    ("singlelane/3/car-following+cut-out", 3, "acc"),
    ("stopandgo", 0, "acc"),
]


def road_frame(sc, ex, trace, name, length):
    """The run's positions of ``name`` in the package's frame: front bumper ``x`` and ``y``."""
    i = trace.names.index(name)
    x = trace.s[:, i] - ex.offset + (1.0 - REAR_AXLE) * length
    y = trace.y[:, i] + (sc.road.n_lanes - 0.5) * sc.road.lane_width
    return x, y


@pytest.mark.parametrize("sid, seed, controller", ROUND_TRIP)
def test_a_scenario_written_and_read_back_drives_the_same_trajectories(tmp_path, sid, seed, controller):
    sc = scenarios.build(sid, seed=seed)
    ex, info, tr = export(sc, controller, tmp_path)
    result, back = run_file(ex.xosc, load_controller(controller))
    assert len(back.t) == len(tr.t)  # the same end: the stop trigger at the episode's last step
    np.testing.assert_allclose(back.t, tr.t, atol=1e-9)
    for j, name in enumerate(ex.names):
        x, y = road_frame(sc, ex, back, name, tr.lengths[0, j])
        np.testing.assert_allclose(x, tr.x[:, 0, j], rtol=0, atol=TOLERANCE, err_msg=f"{sid}: {name}'s x")
        np.testing.assert_allclose(y, tr.y[:, 0, j], rtol=0, atol=TOLERANCE, err_msg=f"{sid}: {name}'s y")
    ego = back.names.index("Ego")
    np.testing.assert_allclose(back.v[:, ego], tr.v[:, 0, 0], rtol=0, atol=TOLERANCE)
    # what the ego's radar saw: the same gaps (the env's definition, the runtime's contours)
    seen = np.isfinite(tr.gap[:, 0, 0])
    np.testing.assert_array_equal(np.isfinite(back.gap), seen)
    np.testing.assert_allclose(back.gap[seen], tr.gap[seen, 0, 0], rtol=0, atol=TOLERANCE)
    # the same score and collision: the ego's scripted drive (written for replay) is ignored, nothing unsupported
    assert result["unsupported"] == []
    assert result["ignored"] and all("on the ego" in s for s in result["ignored"])
    assert result["collided"] == bool(info["report"]["metrics"]["collision"])
    if controller == "constant":
        assert result["collided"]
    # the score: to the reproducibility tolerance, but for the ego's own lane change, whose lateral
    # acceleration the file carries as positions (a second difference, not the environment's half-cosine)
    own_lane_change = np.ptp(tr.y[:, 0, 0]) > 0
    assert result["score"] == pytest.approx(info["score"], abs=0.05 if own_lane_change else SCORE_TOLERANCE)


def test_the_file_describes_the_road_the_vehicles_and_the_ego_settings(tmp_path):
    sc = scenarios.build("singlelane/3/lane-change+cut-in", seed=1)
    ex, _info, tr = export(sc, "acc", tmp_path)
    osc = read(ex.xosc)
    assert osc.version == (1, 2)
    assert "Human-like drivers cannot run outside acc_gym" in osc.description
    # the road: the scenario's lanes, 3.75 m wide, right of the reference line; every vehicle on it
    lanes = sorted(k for k, ln in osc.road.lanes.items() if ln.driving)
    assert lanes == [-sc.road.n_lanes + k for k in range(sc.road.n_lanes)]
    assert all(osc.road.lanes[k].width == pytest.approx(3.75) for k in lanes)
    assert ex.offset == int(ex.offset) and ex.offset > 0
    rear = min(np.min(tr.x[:, 0, j] - tr.lengths[0, j]) for j in range(len(ex.names)))
    assert rear + ex.offset >= 0 and np.max(tr.x) + ex.offset <= osc.road.length
    # the vehicles: dimensions, and the front bumper where the package puts it
    for j, name in enumerate(ex.names):
        e = osc.entities[name]
        assert (e.length, e.width) == (pytest.approx(tr.lengths[0, j]), pytest.approx(tr.width[0, j]))
        assert e.rear == pytest.approx(-REAR_AXLE * e.length)
    props = osc.entities["Ego"].controller_properties
    assert float(props["setSpeed"]) == sc.set_speed and float(props["timeGap"]) == sc.time_gap
    # the SV's lane change and POV2's cut-in are paths; every vehicle has a speed profile
    kinds = {}
    for st in osc.stories:
        for act in st.acts:
            for g in act.groups:
                for m in g.maneuvers:
                    for ev in m.events:
                        for a in ev.actions:
                            kinds.setdefault(g.actors[0], []).append(type(a.payload).__name__)
    assert set(kinds) == set(ex.names)
    assert all(k[0] == "SpeedProfileAction" for k in kinds.values())
    assert "FollowTrajectoryAction" in kinds["Ego"] and "FollowTrajectoryAction" in kinds["POV2"]


def test_without_a_controller_the_ego_is_written_as_it_starts(tmp_path, capsys):
    assert main(["export", "singlelane/2/cut-in", "--seed", "4", "--out", str(tmp_path), "--json", "--no-check"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["controller"] == "acc" and out["ego_motion"] is False
    osc = read(out["xosc"])
    actors = {g.actors[0] for st in osc.stories for act in st.acts for g in act.groups}
    assert "Ego" not in actors and "POV" in actors
    result, _ = run_file(out["xosc"], load_controller("acc"))
    assert result["ignored"] == [] and result["score"] == pytest.approx(out["score"], abs=SCORE_TOLERANCE)


def test_an_export_passes_asams_checker(tmp_path, capsys):
    pytest.importorskip("qc_openscenario", reason="ASAM's checker is not installed (pip install '.[osc]' or '.[test]')")
    assert main(["export", "ncap2026/acc/cut-in/50-10", "--controller", "acc", "--out", str(tmp_path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["checked"] is True and out["issues"] == []


def test_export_exit_codes(tmp_path, capsys):
    assert main(["export", "no/such/scenario", "--out", str(tmp_path)]) == 2
    assert "no/such/scenario" in capsys.readouterr().out
    assert main(["export", str(tmp_path / "missing.json"), "--out", str(tmp_path)]) == 2
    assert "missing.json" in capsys.readouterr().out


def test_a_scenario_json_file_is_exported_as_it_is(tmp_path, capsys):
    sc = scenarios.build("ncap/ccrm/45", seed=3)
    path = tmp_path / "episode.json"
    path.write_text(sc.to_json())
    assert main(["export", str(path), "--controller", "acc", "--out", str(tmp_path / "out"), "--json",
                 "--no-check"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["scenario"] == "ncap/ccrm/45" and out["seed"] == 3
    assert out["xosc"].endswith("ncap_ccrm_45_seed3.xosc")


# --- the speed profile of one step, by hand
def test_a_step_at_constant_acceleration_is_one_entry():
    dt, v0, a = 0.2, 10.0, -2.0
    x = np.array([0.0, v0 * dt + 0.5 * a * dt * dt])
    assert profile_entries(x, np.array([v0, v0 + a * dt]), dt) == [(0.2, pytest.approx(9.6))]


def test_a_vehicle_stopping_inside_a_step_gets_two_entries():
    dt, v0, a = 0.2, 1.0, -8.0  # stops after 0.125 s, 0.0625 m on
    entries = profile_entries(np.array([5.0, 5.0 + v0 * v0 / (2 * -a)]), np.array([v0, 0.0]), dt)
    assert entries[0] == (pytest.approx(0.125), 0.0) and entries[1] == (pytest.approx(0.075), 0.0)
    assert sum(t for t, _ in entries) == pytest.approx(dt)


def test_along_a_path_the_speeds_are_the_path_speeds_with_a_change_at_once():
    dt = 0.2
    x, v = np.array([0.0, 2.0, 4.0]), np.array([10.0, 10.0, 10.0])
    c = 1.0 / math.cos(0.1)
    assert profile_entries(x, v, dt, np.array([c, 1.0])) == [
        (0.0, pytest.approx(10 * c)), (0.2, pytest.approx(10 * c)), (0.0, 10.0), (0.2, 10.0)]


def test_motion_that_is_no_constant_acceleration_is_refused():
    with pytest.raises(ValueError, match="POV: the step from t = 0 s moves 3.0 m from 10.0 to 10.0 m/s"):
        profile_entries(np.array([0.0, 3.0]), np.array([10.0, 10.0]), 0.2, who="POV")


# --- the ego keeps its scripted lateral motion (the runtime's decision the export needs)
def test_the_ego_under_test_keeps_its_scripted_lateral_path(tmp_path):
    sc = scenarios.build("singlelane/1/lane-change", seed=2)
    ex, _info, tr = export(sc, "acc", tmp_path)
    osc = read(ex.xosc)
    paths = [a for st in osc.stories for act in st.acts for g in act.groups if g.actors == ("Ego",)
             for m in g.maneuvers for ev in m.events for a in ev.actions
             if isinstance(a.payload, M.FollowTrajectoryAction)]
    assert len(paths) == 1
    result, back = run_file(ex.xosc, load_controller("acc"))
    _x, y = road_frame(sc, ex, back, "Ego", tr.lengths[0, 0])
    assert np.ptp(tr.y[:, 0, 0]) > 3.0  # it does change lanes
    np.testing.assert_allclose(y, tr.y[:, 0, 0], atol=TOLERANCE)
    assert not any("FollowTrajectoryAction" in s for s in result["ignored"])
