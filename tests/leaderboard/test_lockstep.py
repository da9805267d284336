"""The trusted process's one episode runner (acc_gym.leaderboard.batch.Lockstep) against single envs."""

import gymnasium as gym
import numpy as np
import pytest

import acc_gym  # noqa: F401
from acc_gym.evaluation.runner import EpisodeRun
from acc_gym.leaderboard.batch import BadAnswer, Episode, Lockstep, check_answers

ENV_ID = "acc_gym/CarFollowing-v1"


def _policy(obs):
    """A deterministic answer of each row's observation: a crude gap keeper."""
    return np.tanh(0.05 * (obs[:, 2] - 2.0 * obs[:, 0]) + 0.3 * obs[:, 3])


def _scenarios(n):
    env = gym.make(ENV_ID)
    try:
        return [env.unwrapped.core.generator(np.random.default_rng(s)) for s in range(n)]
    finally:
        env.close()


def test_recorded_batch_rows_equal_single_envs_and_slots_are_reused():
    scenarios = _scenarios(3)
    rounds = []

    def exchange(obs, starts, slots):
        rounds.append((starts.copy(), slots.copy()))
        return _policy(obs)

    episodes = [Episode(sc, lambda: gym.make(ENV_ID), ENV_ID, sc.id) for sc in scenarios]
    done = Lockstep(episodes, in_flight=2, time_gap=1.5, first_slot=7, record=True).run(exchange)
    assert set(done) == {0, 1, 2}
    # two rows in slots 7 and 8; the third episode reuses the first slot to free up, with its start flagged
    assert set(np.concatenate([s for _, s in rounds]).tolist()) == {7, 8}
    assert int(sum(st.sum() for st, _ in rounds)) == 3
    for k, sc in enumerate(scenarios):
        env = gym.make(ENV_ID)
        run = EpisodeRun(env, seed=sc.seed, scenario=sc, record=True, time_gap=1.5)
        while not run.done:
            a = np.clip(_policy(np.asarray(run.obs, dtype=float)[None, :]), -1, 1).astype(np.float32)
            run.step(a)
        single, batched = run.trace(), done[k].trace
        assert done[k].info["score"] == pytest.approx(run.info["score"], abs=1e-9)
        for key in ("x", "v", "a", "gap", "lead", "mode"):
            np.testing.assert_allclose(getattr(batched, key), getattr(single, key), atol=1e-9, err_msg=key)
        assert batched.t[-1] == pytest.approx(done[k].info["t"])
        env.close()


def test_bad_answers_name_the_count_or_the_value_and_where():
    with pytest.raises(BadAnswer, match="answered 2 observations with 3 values"):
        check_answers(np.zeros(3), 2, str)
    with pytest.raises(BadAnswer, match=r"action must be finite: inf \(at row 1\)"):
        check_answers(np.array([0.0, np.inf]), 2, lambda k: f"row {k}")
    with pytest.raises(BadAnswer, match="answered 1 observations with 1 values"):
        check_answers(np.array(["0.5"]), 1, str)
    a = check_answers([2.0, -0.25], 2, str)
    assert a.dtype == np.float32 and a.tolist() == [1.0, -0.25]
    sc = _scenarios(1)[0]
    with pytest.raises(BadAnswer, match=rf"action is NaN: nan \(at {sc.id}\)"):
        Lockstep([Episode(sc, lambda: gym.make(ENV_ID), ENV_ID, sc.id)]).run(lambda o, s, sl: np.full(len(sl), np.nan))
