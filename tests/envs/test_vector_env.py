"""The native vector environment (``acc_gym.envs.vector.ACCVectorEnv``) against
``num_envs`` single environments in gymnasium's ``SyncVectorEnv``, step for step
(next-step autoreset), and its error handling and rendering."""

from __future__ import annotations

import math

import gymnasium
import numpy as np
import pytest

import acc_gym  # noqa: F401  (registers the ids)
from acc_gym.envs.vector import ACCVectorEnv

N = 4
MASKED_KEYS = ("t", "q", "g", "gap_safe", "a_applied", "violation", "fallbacks", "modes")


def make_pair(env_id, **kwargs):
    vec = gymnasium.make_vec(env_id, num_envs=N, vectorization_mode="vector_entry_point", **kwargs)
    sync = gymnasium.vector.SyncVectorEnv([lambda: gymnasium.make(env_id, **kwargs)] * N)
    return vec, sync


def same_report(a: dict, b: dict, path: str) -> None:
    assert a.keys() == b.keys(), path
    for k in a:
        x, y = a[k], b[k]
        if isinstance(x, dict):
            same_report(x, y, f"{path}.{k}")
        elif isinstance(x, float) and math.isnan(x):
            assert isinstance(y, float) and math.isnan(y), f"{path}.{k}"
        else:
            assert x == y, f"{path}.{k}: {x!r} != {y!r}"


def pick(value, i):
    """Env ``i``'s entry of a SyncVectorEnv info value (nested dicts of arrays with ``_key`` masks)."""
    if isinstance(value, dict):
        return {k: pick(v, i) for k, v in value.items() if not k.startswith("_")}
    item = value[i]
    return item.item() if isinstance(item, np.generic) else item


def compare_masked(vi: dict, si: dict, key: str, step: int) -> np.ndarray:
    """The key's mask must agree, and the values where it is set."""
    vm, sm = vi.get("_" + key), si.get("_" + key)
    assert (vm is None) == (sm is None), f"step {step}: mask of {key!r} present in one env only"
    if vm is None:
        return np.zeros(N, dtype=bool)
    assert np.array_equal(vm, sm), f"step {step}: mask of {key!r} {vm} != {sm}"
    if key == "report":
        for i in np.flatnonzero(vm):
            assert isinstance(vi[key][i], dict)
            same_report(vi[key][i], pick(si[key], i), f"step {step} env {i} report")
    else:
        a, b = np.asarray(vi[key])[vm], np.asarray(si[key])[sm]
        assert np.array_equal(a, b), f"step {step}: {key!r} {a} != {b}"
    return vm


def run_lockstep(env_id, steps, seed, **kwargs):
    """Steps both with identical random actions; returns (episodes ended, resets seen, scenario ids)."""
    vec, sync = make_pair(env_id, **kwargs)
    assert isinstance(vec, ACCVectorEnv)
    assert vec.num_envs == N
    assert vec.single_observation_space == sync.single_observation_space
    assert vec.single_action_space == sync.single_action_space
    assert vec.observation_space == sync.observation_space
    vo, vi = vec.reset(seed=seed)
    so, si = sync.reset(seed=seed)
    assert vo.dtype == so.dtype and np.array_equal(vo, so)
    for key in ("scenario", "scenario_seed", "t"):
        assert compare_masked(vi, si, key, -1).all()
    rng = np.random.default_rng(seed)
    ended = resets = 0
    ids = set(vi["scenario"])
    for k in range(steps):
        actions = rng.uniform(-1, 1, (N, 1)).astype(np.float32)
        vo, vr, vt, vtr, vi = vec.step(actions)
        so, sr, st, s_tr, si = sync.step(actions)
        assert vo.dtype == so.dtype and np.array_equal(vo, so), f"step {k}: obs\n{vo}\n{so}"
        assert np.array_equal(vr, sr), f"step {k}: rewards {vr} != {sr}"
        assert np.array_equal(vt, st), f"step {k}: terminated {vt} != {st}"
        assert np.array_equal(vtr, s_tr), f"step {k}: truncated {vtr} != {s_tr}"
        for key in MASKED_KEYS:
            compare_masked(vi, si, key, k)
        done = compare_masked(vi, si, "score", k)
        assert np.array_equal(done, vt | vtr), f"step {k}: scores where episodes ended"
        for key in ("qualified", "report", "episode_return"):
            assert np.array_equal(compare_masked(vi, si, key, k), done)
        # the vector env reports scenario ids where an episode started (the single env has its
        # current id in every step's info): compare where the vector env sets them
        restarted = vi.get("_scenario", np.zeros(N, dtype=bool))
        if restarted.any():
            for key in ("scenario", "scenario_seed"):
                assert np.array_equal(vi["_" + key], restarted)
                assert np.all(si["_" + key][restarted]), f"step {k}: {key}"
                assert np.array_equal(vi[key][restarted], si[key][restarted]), f"step {k}: {key}"
            assert np.all(vi["t"][restarted] == 0.0)
            ids.update(vi["scenario"][restarted])
        for name, v in vi["rewards"].items():
            if name.startswith("_"):
                continue
            mask = vi["_rewards"]
            assert np.array_equal(v[mask], si["rewards"][name][si["_rewards"]]), f"step {k}: rewards[{name!r}]"
        ended += int(done.sum())
        resets += int(restarted.sum())
    return ended, resets, ids


def test_make_vec_returns_the_native_vector_env():
    vec = gymnasium.make_vec("acc_gym/NCAP-v0", num_envs=N, vectorization_mode="vector_entry_point")
    assert type(vec) is ACCVectorEnv
    assert vec.observation_space.shape == (N, 7) and vec.action_space.shape == (N, 1)


def test_vector_reset_seeds_env_i_with_seed_plus_i():
    vec = gymnasium.make_vec("acc_gym/CarFollowing-v0", num_envs=N, vectorization_mode="vector_entry_point",
                             drivers="idm")
    vo, vi = vec.reset(seed=21)
    for i in range(N):
        env = gymnasium.make("acc_gym/CarFollowing-v0", drivers="idm")
        o, info = env.reset(seed=21 + i)
        assert np.array_equal(vo[i], o)
        assert vi["scenario"][i] == info["scenario"] and vi["scenario_seed"][i] == info["scenario_seed"]


def test_ncap_equals_single_envs_through_autoresets():
    ended, resets, ids = run_lockstep("acc_gym/NCAP-v0", 400, seed=7)
    assert ended >= 10 and resets >= 10  # many episodes ended and restarted
    assert len(ids) >= 5


def test_carfollowing_v2v_equals_single_envs_through_autoresets():
    ended, resets, _ = run_lockstep("acc_gym/CarFollowing-v0", 300, seed=3, drivers="idm", v2v=True)
    assert ended >= 2 and resets >= 2


@pytest.mark.parametrize("kwargs", [{}, {"drivers": "malicious", "v2v": True}], ids=["typical", "malicious-v3v"])
def test_singlelane_mpc_drivers_equal_single_envs(kwargs):
    """MPC drivers of all scenes solved in one batch (scenes restarting at different times)
    give the numbers of each scene alone."""
    ended, resets, ids = run_lockstep("acc_gym/SingleLane-v0", 300, seed=7, **kwargs)
    assert ended >= 5 and resets >= 5 and len(ids) >= 4


def test_singlelane_batched_idm_drivers_equal_single_envs():
    """Baseline surrounding drivers step as one law call over every scene and slot (issue
    18); with scenes restarting at different times, each scene still gives the numbers it
    gives alone (per-row reaction delays: tests/drivers/test_slots.py)."""
    ended, resets, ids = run_lockstep("acc_gym/SingleLane-v0", 250, seed=5, drivers="idm")
    assert ended >= 5 and resets >= 5 and len(ids) >= 4


def test_stopandgo_mpc_drivers_equal_single_envs():
    run_lockstep("acc_gym/StopAndGo-v0", 150, seed=1)


def test_autoreset_step_is_inert():
    """Next-step autoreset: the step after an episode's end resets it with reward 0, not done."""
    vec = gymnasium.make_vec("acc_gym/NCAP-v0", num_envs=2, vectorization_mode="vector_entry_point")
    vec.reset(seed=0, options={"scenarios": ["ncap/ccrs/50", "ncap/ccrm/50"]})
    zero = np.zeros((2, 1), np.float32)
    for k in range(20):
        obs, rew, term, trunc, info = vec.step(zero)
    assert term[0] and not trunc[0] and not term[1]  # the stationary target is hit at 4 s
    assert info["_score"][0] and not info["_score"][1]
    obs, rew, term, trunc, info = vec.step(np.ones((2, 1), np.float32))
    assert rew[0] == 0.0 and not term[0] and not trunc[0]
    assert info["_scenario"][0] and not info["_scenario"][1]
    assert info["t"][0] == 0.0 and not info["_q"][0] and info["_q"][1]
    assert obs[0][2] > 0.0


def test_wrong_actions_raise_value_error():
    vec = gymnasium.make_vec("acc_gym/NCAP-v0", num_envs=2, vectorization_mode="vector_entry_point")
    vec.reset(seed=0)
    for bad in (np.zeros((3, 1)), np.zeros((2, 2)), np.zeros((1, 2, 1)), "x"):
        with pytest.raises(ValueError):
            vec.step(bad)
    with pytest.raises(ValueError, match="NaN"):
        vec.step(np.array([[np.nan], [0.0]]))
    vec.step(np.zeros((2, 1), np.float32))  # still usable


def test_step_before_reset_raises():
    vec = gymnasium.make_vec("acc_gym/NCAP-v0", num_envs=2, vectorization_mode="vector_entry_point")
    with pytest.raises(RuntimeError, match="reset"):
        vec.step(np.zeros((2, 1), np.float32))


def test_render_returns_one_frame_per_env():
    vec = gymnasium.make_vec("acc_gym/NCAP-v0", num_envs=3, vectorization_mode="vector_entry_point",
                             render_mode="rgb_array")
    vec.reset(seed=0)
    frames = vec.render()
    assert isinstance(frames, tuple) and len(frames) == 3
    for f in frames:
        assert isinstance(f, np.ndarray) and f.dtype == np.uint8 and f.ndim == 3 and f.shape[2] == 3
    none = gymnasium.make_vec("acc_gym/NCAP-v0", num_envs=2, vectorization_mode="vector_entry_point")
    none.reset(seed=0)
    assert none.render() is None


@pytest.mark.parametrize("num_envs", [0, -1, 1.5])
def test_bad_num_envs(num_envs):
    with pytest.raises(ValueError, match="num_envs"):
        ACCVectorEnv(num_envs=num_envs)


def test_vector_reset_options():
    vec = gymnasium.make_vec("acc_gym/NCAP-v0", num_envs=2, vectorization_mode="vector_entry_point")
    with pytest.raises(ValueError, match="unknown reset option"):
        vec.reset(seed=0, options={"scenario": "ncap/ccrs/30"})  # the vector option is "scenarios"
    with pytest.raises(ValueError, match="2 entries"):
        vec.reset(seed=0, options={"scenarios": ["ncap/ccrs/30"]})
    with pytest.raises(ValueError, match="2 seeds"):
        vec.reset(seed=[1, 2, 3])
    obs, info = vec.reset(seed=[5, 9], options={"scenarios": ["ncap/ccrs/30", None]})
    assert info["scenario"][0] == "ncap/ccrs/30"
    single = gymnasium.make("acc_gym/NCAP-v0")
    o1, i1 = single.reset(seed=9)
    assert np.array_equal(obs[1], o1) and info["scenario"][1] == i1["scenario"]


def test_render_before_reset_is_a_clear_error():
    vec = gymnasium.make_vec("acc_gym/NCAP-v0", num_envs=2, vectorization_mode="vector_entry_point",
                             render_mode="rgb_array")
    with pytest.raises((RuntimeError, gymnasium.error.ResetNeeded), match="reset"):
        vec.render()
