"""The leaderboard's wave column: a controller in one position of a ring of human-like drivers,
its rings' speed sd over the all-human rings' (the same other drivers), measured through the
sandbox with the numbers of the same rings run here; failures confined to the cell."""

from types import SimpleNamespace

import numpy as np
import pytest

from acc_gym.evaluation.runner import load_controller
from acc_gym.evaluation.string_stability import _Copies
from acc_gym.leaderboard import run_leaderboard
from acc_gym.leaderboard import waves as W
from acc_gym.leaderboard.results import csv_text, markdown, text_table
from acc_gym.simulation.ring import ring_layout, simulate_ring


def local_cell(name: str, baseline: dict) -> dict:
    ctl = load_controller(name)
    return W.cell(W._ring(lambda cells: _Copies(ctl, cells), getattr(ctl, "time_gap", None)), baseline)


@pytest.fixture(scope="module")
def baseline():
    return W.human_baseline()


def test_the_cell_is_the_ratio_of_the_mean_speed_sds():
    rep = lambda sd, v, hits=0: SimpleNamespace(speed_sd=sd, mean_speed=v, braking_events=3, collisions=hits)  # noqa: E731
    base = W._summary([rep(2.0, 2.0), rep(3.0, 2.5)])
    got = W.cell([rep(0.5, 3.0), rep(1.5, 3.5, hits=1)], base)
    assert got["ratio"] == pytest.approx((0.5 + 1.5) / (2.0 + 3.0))  # means over the seeds, then the ratio
    assert got["speed_ratio"] == pytest.approx((3.0 + 3.5) / (2.0 + 2.5))
    assert got["collisions"] == 1 and got["speed_sd"] == [0.5, 1.5]


def test_formatting_of_each_kind_of_cell():
    assert W.format_cell(None) == "-"
    assert W.format_cell({"failed_to_run": "RuntimeError: x"}) == "failed"
    assert W.format_cell({"ratio": 0.4, "collisions": 0}) == "damps (0.40)"
    assert W.format_cell({"ratio": 1.08, "collisions": 0}) == "amplifies (1.08)"
    assert W.format_cell({"ratio": 0.99, "collisions": 0}) == "neutral (0.99)"
    # a ring that collided says nothing of damping
    assert W.format_cell({"ratio": 0.0, "collisions": 5}) == "COLLIDES (5, 0.00)"


def test_the_all_human_rings_jam_and_differ_from_the_controlled_ones_only_at_its_position(baseline):
    # the five all-human rings carry a wave (Stern's ring: sd of about 2 m/s), with no collision
    assert min(baseline["speed_sd"]) > 1.0 and baseline["collisions"] == 0
    # the stand-in drives the controller's position: with a controller there, the 21 others are the same drivers.
    # What the controlled vehicle does reaches its follower (vehicle 0) one step later, vehicle k k + 1 steps later:
    # over 10 steps vehicles 10..20 drive exactly as in the all-human ring
    n, pos = W.RING["vehicles"], W.RING["position"]
    kw = dict(layout=ring_layout(n, (pos,)), drivers=W.RING["drivers"], seeds=[W.SEEDS[0]], duration=2.0,
              driver_model=W.RING["driver_model"], standins=True)
    human = simulate_ring(W.RING["length"], n, **kw)
    ctl = simulate_ring(W.RING["length"], n, controller=load_controller("constant"), **kw)
    assert np.array_equal(human.v[:, 0, 10:pos], ctl.v[:, 0, 10:pos])
    assert not np.array_equal(human.v[:, 0, 0], ctl.v[:, 0, 0])
    assert not np.array_equal(human.v[:, 0, pos], ctl.v[:, 0, pos])


def test_stern_pi_saturation_damps_the_wave_and_the_linear_acc_does_not(baseline):
    pi = local_cell("pi-saturation", baseline)
    assert pi["ratio"] < 0.5 and pi["collisions"] == 0  # Stern et al.: one such car damps the wave
    assert pi["speed_ratio"] > 1.0  # and the ring flows faster
    acc = local_cell("acc", baseline)
    # Gunter et al. 2020: commercial ACCs do not damp waves; the linear ACC at 1.5 s passes it on
    assert acc["ratio"] > 1.0 and acc["collisions"] == 0


def test_through_the_sandbox_the_cell_is_the_rings_run_here(baseline):
    r = run_leaderboard("ncap-v1", "test", ["acc"], episodes=1, workers=1, string_stability=False,
                        iso15622=False, allow_root=True)
    (c,) = r["controllers"]
    assert c["status"] == "ok"
    st = r["manifest"]["settings"]["waves"]
    assert st["human"] == baseline and st["seeds"] == list(W.SEEDS) and st["driver_model"] == 6
    local = local_cell("acc", baseline)
    assert c["waves"] == local  # the same rings, the same actions: the same numbers
    assert f"| {W.format_cell(local)} |" in markdown(r)  # the printed table shows it when it fits its width
    header = csv_text(r).splitlines()[0].split(",")
    assert {"waves_ratio", "waves_speed_ratio", "waves_collisions", "waves_failed_to_run"} <= set(header)
    row = dict(zip(header, csv_text(r).splitlines()[1].split(",")))
    assert float(row["waves_ratio"]) == pytest.approx(local["ratio"])


def test_without_the_column_there_is_no_cell_setting_or_column():
    r = run_leaderboard("ncap-v1", "test", ["constant"], episodes=1, workers=1, string_stability=False,
                        iso15622=False, waves=False, robustness=False, allow_root=True)
    assert "waves" not in r["controllers"][0] and r["manifest"]["settings"]["waves"] is None
    assert "waves" not in text_table(r) and "waves_ratio" not in csv_text(r)
