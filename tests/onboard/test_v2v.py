"""The V2V link: latency, period, burst loss and timeout as declared; CACC without messages
drives as its own ACC law."""

import gymnasium as gym
import numpy as np
import pytest

import acc_gym  # noqa: F401
from acc_gym.controllers import make_controller
from acc_gym.onboard import V2V_PRESETS, Link, V2VConfig

DT = 0.2
R = 200.0


def _fields(k: int, n: int = 1) -> np.ndarray:
    """True V2V fields at step k: an acceleration and a second vehicle that change every step."""
    out = np.empty((n, 4))
    out[:, 0] = np.sin(0.3 * k)
    out[:, 1] = 40.0 + k
    out[:, 2] = -0.1 * k
    out[:, 3] = 1.0
    return out


def _run(cfg: V2VConfig, steps: int, seed: int = 0) -> np.ndarray:
    link = Link(cfg, 1, DT, R)
    link.reset([0], [np.random.default_rng(seed)])
    return np.array([link.receive(_fields(k))[0] for k in range(steps)])


def test_a_latency_of_k_steps_delays_every_message_by_exactly_k_steps_and_none_shows_before():
    for latency, k in ((0.0, 0), (0.1, 1), (0.4, 2)):
        out = _run(V2VConfig(latency=latency), 30)
        assert np.array_equal(out[k:], np.array([_fields(j)[0] for j in range(30 - k)]))
        assert np.all(out[:k] == [0.0, R, 0.0, 0.0])  # nothing has arrived yet: no V2V data


def test_messages_come_every_period_and_are_held_in_between():
    out = _run(V2VConfig(period=0.6), 30)  # every 3 steps
    for k in range(30):
        assert np.array_equal(out[k], _fields(3 * (k // 3))[0])


def test_losses_follow_the_declared_chain_and_a_stale_message_times_out():
    cfg = V2VConfig(loss_share=0.25, loss_burst=0.4, timeout=10.0)  # r = 1/2 per step
    link = Link(cfg, 1, DT, R)
    link.reset([0], [np.random.default_rng(3)])
    got = np.array([link.receive(_fields(k))[0, 1] == 40.0 + k for k in range(40_000)])  # a fresh message?
    lost = ~got
    assert lost.mean() == pytest.approx(0.25, abs=0.015)
    edges = np.flatnonzero(np.diff(np.r_[0, lost.astype(int), 0]))
    assert (edges[1::2] - edges[::2]).mean() == pytest.approx(2.0, rel=0.06)  # bursts of 0.4 s
    # a timeout of 0.4 s: after two steps without a message the link is lost
    out = _run(V2VConfig(loss_share=0.5, loss_burst=1.0, timeout=0.4), 4000, seed=1)
    fresh = out[:, 1] == 40.0 + np.arange(4000)
    none = np.all(out == [0.0, R, 0.0, 0.0], axis=1)
    run = 0
    for k in range(4000):
        run = 0 if fresh[k] else run + 1
        assert none[k] == (run > 2), k
    assert none.any() and fresh.any()


def _drive(controller, **kw):
    env = gym.make("acc_gym/CarFollowing-v0", v2v=True, **kw)  # paper 003's test at 120 km/h: the lead brakes
    obs, info = env.reset(seed=4)
    assert info["scenario"] == "carfollowing/120"
    gaps, done = [], False
    while not done:
        obs, _, term, trunc, info = env.step(np.asarray(controller.predict(obs)[0], dtype=np.float32).reshape(1))
        gaps.append(env.unwrapped.core.world.neighbours.gap[0, 0])
        done = term or trunc
    return np.array(gaps), info["score"]


def test_cacc_with_every_message_lost_drives_as_its_own_acc_law():
    from acc_gym_agents.controllers.models import cacc

    silent, score_silent = _drive(make_controller("cacc"), v2v_link={"loss_share": 1.0})
    acc_law, score_acc = _drive(cacc(k3=0.0))  # the same law without the feed-forward, the link ideal
    np.testing.assert_allclose(silent, acc_law, rtol=1e-9, atol=1e-9)
    assert score_silent == pytest.approx(score_acc, abs=1e-6)
    linked, score_linked = _drive(make_controller("cacc"))
    assert np.abs(linked - silent).max() > 1.0  # with messages the feed-forward changes the drive
    # a typical link: close to the ideal one, not to the silent one
    typical, _ = _drive(make_controller("cacc"), v2v_link="typical")
    assert np.abs(typical - linked).max() < np.abs(silent - linked).max()


def test_configs_are_validated_and_presets_resolve():
    with pytest.raises(ValueError, match="V2VConfig.loss_share must be a share in .* got 1.5"):
        V2VConfig(loss_share=1.5)
    with pytest.raises(ValueError, match="loss_burst must be > 0"):
        V2VConfig(loss_share=0.1)
    with pytest.raises(ValueError, match="unknown v2v_link preset 'lossy'"):
        gym.make("acc_gym/CarFollowing-v1", v2v=True, v2v_link="lossy")
    assert V2VConfig().ideal and not V2V_PRESETS["typical"].ideal
