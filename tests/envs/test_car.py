"""The ego's car inside the environments' step (acc_gym/envs/car.py): its actuators and radar as
the step kernel runs them, against the onboard components run alone on the same inputs."""

import gymnasium as gym
import numpy as np
import pytest

import acc_gym  # noqa: F401 - registers the ids
from acc_gym.envs.car import _child
from acc_gym.envs.observation import margin_features
from acc_gym.onboard import ActuatorConfig, Actuators, SensorConfig

DT = 0.2


@pytest.mark.parametrize("kind", [np.random.PCG64, np.random.Philox])
def test_a_child_made_alone_draws_what_spawn_gives_it(kind):
    for entropy in (0, 12345, 2**70 + 3):
        parent = np.random.SeedSequence(entropy).spawn(1)[0]
        spawned = np.random.Generator(kind(np.random.SeedSequence(entropy).spawn(1)[0])).spawn(3)
        for k in range(3):
            assert np.array_equal(_child((kind, parent), k).random(20), spawned[k].random(20))


def _steps(env, actions, seed):
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for a in actions:
        obs, _, term, trunc, _ = env.step(a)
        out.append(obs)
        if term or trunc:
            break
    return out


def test_the_ego_is_asked_to_realise_what_its_actuators_make_of_each_command():
    cfg = ActuatorConfig(lag=0.5, dead_time=0.3)
    env = gym.make("acc_gym/CarFollowing-v1", actuators=cfg)
    core = env.unwrapped.core
    env.reset(seed=4)
    alone = Actuators(cfg, 1, DT)
    alone.reset([0], core.world.a[0, 0])
    rng = np.random.default_rng(0)
    a0 = core.world.a[0, 0]
    asked, expected, commands = [], [], []
    for _ in range(60):
        action = rng.uniform(-1, 1, (1,)).astype(np.float32)
        a_prev = core.world.a[:, 0].copy()
        command = np.array([float(action[0]) * (env.unwrapped.config.accel_max if action[0] >= 0
                                                else env.unwrapped.config.decel_max)])
        _, _, term, trunc, _ = env.step(action)
        asked.append(core.world.a_des[0, 0])
        expected.append(alone.command(command, a_prev)[0])
        commands.append(command[0])
        if term or trunc:
            break
    assert len(asked) > 20
    assert np.array_equal(asked, expected)
    # the dead time (1.5 steps) holds the first command back: the vehicle is asked for what it did
    assert commands[0] != a0 and asked[0] == a0
    assert not np.array_equal(asked, commands)


def test_the_radar_delays_the_observed_gap_by_its_latency_and_the_features_follow_it():
    radar = SensorConfig(latency=0.4, far_range=1e4)  # two steps late, nothing else modelled
    ideal = gym.make("acc_gym/CarFollowing-v1")
    late = gym.make("acc_gym/CarFollowing-v1", sensors=radar)
    actions = np.random.default_rng(1).uniform(-0.3, 0.3, (80, 1)).astype(np.float32)
    true, seen = _steps(ideal, actions, 9), _steps(late, actions, 9)  # the radar does not change the world
    assert len(true) == len(seen) > 30
    true, seen = np.array(true), np.array(seen)
    m = 7
    assert np.array_equal(seen[2:, 2], true[:-2, 2])  # the gap, two steps late
    assert np.array_equal(seen[2:, 3], true[:-2, 3])  # the relative speed
    assert np.array_equal(seen[:, [0, 1, 5, 6]], true[:, [0, 1, 5, 6]])  # the ego's own fields are not the radar's
    assert not np.array_equal(seen[:, m:], true[:, m:])
    # the -v1 features are those of the fields as observed
    expected = margin_features(seen[:, :m].astype(np.float64)).astype(np.float32)
    assert np.array_equal(seen, expected)
