"""Restarting one scene of a world leaves the others untouched; each scene keeps its own clock."""

import numpy as np
import pytest

from acc_gym.drivers import IDM, IDMParams
from acc_gym.simulation.single_lane import LateralPlan, SingleLaneWorld


def make():
    x0 = np.array([[0.0, 40.0], [0.0, 30.0]])
    v0 = np.array([[20.0, 18.0], [15.0, 15.0]])
    plan = LateralPlan(np.array([[0.0, 3.75], [0.0, 0.0]]), np.zeros((2, 2)), np.full((2, 2), 1.0),
                       np.full((2, 2), 2.0))
    return SingleLaneWorld(x0, v0, [None, IDM(IDMParams(v_desired=18.0), n=2)], lateral=plan)


def test_reset_rows_restarts_only_those_scenes_and_their_clocks():
    w, ref = make(), make()
    for _ in range(5):
        w.step([0.5, -0.5])
        ref.step([0.5, -0.5])
    w.reset_rows([1], [[0.0, 50.0]], [[10.0, 12.0]])
    assert w.k.tolist() == [5, 0] and w.t[0] == pytest.approx(1.0) and w.t[1] == 0.0
    assert w.x[1].tolist() == [0.0, 50.0] and w.v[1].tolist() == [10.0, 12.0] and w.a[1].tolist() == [0.0, 0.0]
    np.testing.assert_array_equal(w.x[0], ref.x[0])
    w.step([0.5, -0.5])
    ref.step([0.5, -0.5])
    np.testing.assert_array_equal(w.x[0], ref.x[0])  # scene 0 unaffected
    # scene 0's cut-in runs on its own clock: at t = 1.2 s it is 10 % into its 2 s move
    s = (1.2 - 1.0) / 2.0
    assert w.y[0, 1] == pytest.approx(3.75 * (1 - 0.5 * (1 - np.cos(np.pi * s))))
    assert w.y[1, 1] == 0.0  # the new scene 1 got the default plan: everyone in lane 0


def test_reset_rows_checks_only_the_new_scenes():
    w = make()
    w.x[0] = [0.0, 2.0]  # scene 0 is (artificially) in a crash: not the new scene's problem
    w.reset_rows([1], [[0.0, 30.0]], [[10.0, 10.0]])
    with pytest.raises(ValueError, match="scene 1, slots 0 and 1 overlap"):
        w.reset_rows([1], [[0.0, 3.0]], [[10.0, 10.0]])
