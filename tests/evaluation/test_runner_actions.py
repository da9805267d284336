"""A controller's answer becomes the env's action, or a clear error naming the value (issue 20)."""

import numpy as np
import pytest

from acc_gym.envs.acc_env import check_actions
from acc_gym.evaluation.runner import as_action


@pytest.mark.parametrize("out,words", [
    (None, r"returned no action \(None\)"),
    ("0.5", "an action is a real number"),
    (True, "an action is a real number"),
    (0.5 + 1j, "an action is a real number"),
    (np.array([0.1, 0.2]), r"shape \(2,\)"),
    (float("nan"), "that is NaN"),
    (np.array([-np.inf]), "that is infinite"),
])
def test_bad_answers_are_named(out, words):
    with pytest.raises(ValueError, match=words):
        as_action(out, "mine")


def test_finite_answers_are_clipped_as_the_env_clips_them():
    assert as_action(1e300)[0] == 1.0 and as_action(np.array([-1e300]))[0] == -1.0
    assert as_action(np.array([0.25], dtype=np.float64)).dtype == np.float32
    for x in (-0.7, 0.0, 0.3, 1.0):
        assert as_action(np.float32(x))[0] == np.float32(x)  # within [-1, 1]: the same bits


@pytest.mark.parametrize("bad", ["0.5", [True], [0.5 + 1j], np.array(["1"])])
def test_the_env_refuses_actions_that_are_not_real_numbers(bad):
    with pytest.raises(ValueError, match="must be numeric: real numbers"):
        check_actions(bad, (1,))
    assert check_actions([1], (1,))[0] == 1.0  # an integer is a number
