"""Files written for another tool: esmini's example scenarios (MPL-2.0, ``data/esmini``, see its
NOTICE.md) read and run here, and the controllers behave as physics says on them."""

from pathlib import Path

import numpy as np
import pytest

from acc_gym.evaluation.runner import load_controller
from acc_gym.scenarios.openscenario import read, run_file

DATA = Path(__file__).parent / "data" / "esmini" / "xosc"
# a lead slower than the ego, braking or standing in its lane: cruise control runs into it, ACC does not
LEADS = ["acc-test", "cut-in_simple", "slow-lead-vehicle", "straight_500m"]


def _run(name, controller, **kw):
    path = DATA / f"{name}.xosc"
    return run_file(path, load_controller(controller), duration=60, **kw)


@pytest.mark.parametrize("name", LEADS)
def test_acc_stops_short_of_what_cruise_control_runs_into(name):
    acc, tr = _run(name, "acc")
    assert not acc["collided"] and acc["min_gap"] > 0, acc
    assert np.all(np.isfinite(tr.s)) and np.all(tr.v >= 0)
    cc, ctr = _run(name, "constant")
    # cruise control hits its target: a gap reaching 0, or the contours touching (or passing through each other)
    # inside a step, after which the lead is no longer ahead of the ego's front
    assert cc["collided"] and (cc["min_gap"] <= 0 or cc["collision_with"] in tr.names), cc


def test_a_lead_that_brakes_hard_to_a_stop():
    res, tr = _run("alks_decelerate", "acc")  # its Act's StartTrigger is empty: it starts with the story
    j = tr.names.index("TargetDecelerate")
    assert tr.a[:, j].min() == pytest.approx(-7.0) and tr.v[-1, j] == 0.0  # the lead brakes at 7 m/s^2 to a stop
    assert not res["collided"] and res["min_gap"] > 2.0 and tr.v[-1, tr.ego_index] < 0.1 * tr.v[0, tr.ego_index]
    cc, _ = _run("alks_decelerate", "constant")
    assert cc["collided"]


def test_a_negative_rate_is_read_as_its_magnitude_and_said():
    sc = read(DATA / "cut-in_simple.xosc")
    notes = [n for n in sc.out_of_scope if "negative rate (-5)" in n]
    assert notes and "cut-in_simple.xosc:127" in notes[0]
    res, tr = _run("cut-in_simple", "acc")
    j = tr.names.index("OverTaker")
    assert tr.a[:, j].min() == pytest.approx(-5.0)  # it brakes at 5 m/s^2, as the file means
    assert tr.v[-1, j] == pytest.approx(0.0)


def test_a_linear_transition_over_no_time_is_a_step_and_init_order_does_not_matter():
    res, tr = _run("override_bb", "acc")  # Init: SpeedAction linear, time 0, before the TeleportAction
    assert tr.v[0, tr.ego_index] == pytest.approx(90 / 3.6)
    sc = read(DATA / "straight_500m.xosc")  # Init: the ego's SpeedAction is written before its position
    res, tr = _run("straight_500m", "acc", scenario=sc)
    assert tr.v[0, tr.ego_index] == pytest.approx(20.0) and tr.v[0, tr.names.index("Target")] == 0.0


def test_a_trajectory_in_init_places_its_entity_at_the_first_vertex():
    sc = read(DATA / "alks_pedestrian.xosc")  # the pedestrian's Init has only a FollowTrajectoryAction
    res, tr = _run("alks_pedestrian", "acc", scenario=sc)
    j = tr.names.index("Pedestrian")
    assert float(sc.parameters["PedestrianS"]) == 110.0
    assert (tr.s[0, j], tr.y[0, j]) == pytest.approx((110.0, -4.0))
    walking = tr.t > 2.0 + 1e-9  # its SpeedAction (1 m/s) starts when SimulationTime > 2 s
    assert np.all(tr.y[~walking, j] == -4.0)
    assert np.diff(tr.y[walking, j]) == pytest.approx(1.0 * 0.2)  # then it walks along the polyline at 1 m/s
    assert not res["collided"]
