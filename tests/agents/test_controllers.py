"""Built-in controllers: one predict() shape, every scenario family, no collision in paper 003's test."""

import numpy as np
import pytest

from acc_gym.evaluation.runner import evaluate, load_controller
from acc_gym_agents.controllers import BUILTINS, LinearACC
from acc_gym_agents.controllers.models import observation

FAMILIES = ("acc_gym/CarFollowing-v0", "acc_gym/SingleLane-v0", "acc_gym/NCAP-v0", "acc_gym/StopAndGo-v0")


@pytest.mark.parametrize("name", sorted(BUILTINS))
def test_every_builtin_runs_every_family(name):
    for env_id in FAMILIES:
        s = evaluate(name, env_id, episodes=1, seed=2, drivers="idm")
        assert s["episodes"] == 1 and 0.0 <= s["mean_score"] <= 100.0


@pytest.mark.parametrize("name", ["acc", "cacc", "idm", "gipps", "mpc"])
def test_no_collision_in_paper_003_test(name):
    for sid in ("carfollowing/60", "carfollowing/90", "carfollowing/120"):
        s = evaluate(name, "acc_gym/CarFollowing-v0", episodes=2, seed=5, scenarios=(sid,))
        assert s["collisions"] == 0, (name, sid, s["scores"])


def test_the_constant_speed_floor_collides_where_the_acc_does_not():
    assert evaluate("constant", "acc_gym/NCAP-v0", episodes=3, seed=0, scenarios=("ncap/ccrs/30",))["collisions"] == 3
    assert evaluate("acc", "acc_gym/NCAP-v0", episodes=3, seed=0, scenarios=("ncap/ccrs/30",))["collisions"] == 0


def test_predict_shapes_and_action_scaling():
    ctrl = LinearACC()
    obs = np.array([[20.0, 0.0, 200.0, 0.0, 0.0, 25.0, 1.5], [20.0, 0.0, 10.0, -5.0, 1.0, 25.0, 1.5]],
                   dtype=np.float32)
    act, state = ctrl.predict(obs, deterministic=True)
    assert act.shape == (2, 1) and state is None
    assert act[0, 0] == pytest.approx(0.4 * 5.0 / 3.0)  # cruise law 0.4 (25 - 20) m/s^2 -> action / accel_max
    assert act[1, 0] == -1.0  # far too close and closing: full braking (clipped at decel_max)
    single, _ = ctrl.predict(obs[0])
    assert single.shape == (1,) and single[0] == act[0, 0]
    for name in BUILTINS:
        a, _ = load_controller(name).predict(obs)
        assert a.shape == (2, 1) and np.all(np.abs(a) <= 1.0)


def test_observation_mapping_with_and_without_v2v():
    o = np.array([[20.0, 0.5, 30.0, -2.0, 1.0, 25.0, 1.5]])
    ob = observation(o)
    assert ob.gap[0] == 30.0 and ob.v_lead[0] == 18.0 and ob.gap2 is None and ob.a_lead[0] == 0.0
    o2 = np.array([[20.0, 0.5, 200.0, 0.0, 0.0, 25.0, 1.5, 0.0, 200.0, 0.0, 0.0]])
    ob = observation(o2)
    assert np.isinf(ob.gap[0]) and np.isinf(ob.gap2[0])
    o3 = np.array([[20.0, 0.5, 30.0, -2.0, 1.0, 25.0, 1.5, -1.5, 60.0, -3.0, 1.0]])
    ob = observation(o3)
    assert ob.a_lead[0] == -1.5 and ob.gap2[0] == 60.0 and ob.v_lead2[0] == 17.0


def test_a_v1_observation_is_read_by_its_width_not_as_v2v():
    """-v1 without V2V has 13 fields: field 7 is a margin feature, not the lead's acceleration."""
    from acc_gym.envs.observation import margin_features

    o7 = np.array([[20.0, 0.5, 30.0, -2.0, 1.0, 25.0, 1.5]])
    o11 = np.array([[20.0, 0.5, 30.0, -2.0, 1.0, 25.0, 1.5, -1.5, 60.0, -3.0, 1.0]])
    for base, width in ((o7, 13), (o11, 23)):
        v1 = margin_features(base)
        assert v1.shape[1] == width
        a, b = observation(base), observation(v1)
        assert a.a_lead[0] == b.a_lead[0] and (a.gap2 is None) == (b.gap2 is None)
    with pytest.raises(ValueError, match="9"):
        observation(np.zeros((1, 9)))
    # every model controller acts on a -v1 observation as on its -v0 fields
    for name in ("cacc", "idm", "gipps", "gm", "fuzzy", "mpc"):
        x, _ = load_controller(name).predict(o7)
        y, _ = load_controller(name).predict(margin_features(o7))
        assert x[0] == y[0], name
