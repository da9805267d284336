"""Scenario ``i`` and its seed depend only on (suite, split, root seed, i): never on workers, chunks or order."""

import numpy as np
import pytest

from acc_gym.campaigns import load_campaign, run_campaign, scenario_at, seed_for
from acc_gym.campaigns.plan import chunks, plan_length
from acc_gym.suites import get_suite

from campaign_settings import CHUNK, CONTROLLER, HOURS, SUITE


def test_seed_is_the_first_draw_of_default_rng_index_root():
    for i, root in [(0, 0), (5, 123), (10_000, 2 ** 32 - 1)]:
        assert seed_for(i, root) == int(np.random.default_rng([i, root]).integers(0, 2 ** 31 - 1))
    assert seed_for(3, 1) != seed_for(3, 2) and seed_for(3, 1) != seed_for(4, 1)


def test_rows_hold_the_suites_scenarios_and_seeds(reference):
    _, summary, campaign = reference
    suite = get_suite(SUITE)
    root = suite.root_seed("test")
    assert summary["root_seed"] == root
    for row in campaign.rows():
        sc = suite.scenario(row["index"], "test")  # the default root: the suite's own test scenarios
        assert (row["scenario_id"], row["scenario_seed"], row["duration"]) == (sc.id, sc.seed, sc.duration)
        assert row["seed"] == seed_for(row["index"], root)


def test_scenario_at_is_order_independent_and_follows_the_root():
    suite = get_suite("singlelane-v3")
    root = suite.root_seed("dev")
    forward = [scenario_at(suite, i, "dev", 99) for i in range(6)]
    backward = [scenario_at(suite, i, "dev", 99) for i in reversed(range(6))][::-1]
    assert forward == backward
    # another root: the suite's law with default_rng([i, R]); the split's own root: the suite's scenario
    assert forward[3] == suite.generator(3, np.random.default_rng([3, 99]))
    assert scenario_at(suite, 3, "dev", root) == suite.scenario(3, "dev")
    assert [s.seed for s in forward] != [suite.scenario(i, "dev").seed for i in range(6)]


def test_length_is_the_first_scenarios_reaching_the_hours():
    suite = get_suite(SUITE)
    n, seconds = plan_length(suite, "test", suite.root_seed("test"), HOURS)
    durations = np.cumsum([suite.scenario(i, "test").duration for i in range(n)])
    assert durations[-1] == pytest.approx(seconds) and seconds >= HOURS * 3600 > durations[-2]
    n7, s7 = plan_length(suite, "test", 7, HOURS)
    d7 = np.cumsum([scenario_at(suite, i, "test", 7).duration for i in range(n7)])
    assert d7[-1] == pytest.approx(s7) and s7 >= HOURS * 3600 > d7[-2]


def test_chunks_partition_the_indices():
    cs = chunks(10, 3)
    assert [(c.number, c.start, c.stop) for c in cs] == [(0, 0, 3), (1, 3, 6), (2, 6, 9), (3, 9, 10)]
    assert [i for c in cs for i in c.indices] == list(range(10))


def test_another_root_seed_gives_other_scenarios_with_their_seeds(tmp_path):
    run_campaign(SUITE, HOURS, CONTROLLER, tmp_path, chunk_size=CHUNK, root_seed=11, max_chunks=1)
    rows = load_campaign(tmp_path).rows()
    suite = get_suite(SUITE)
    for row in rows:
        sc = scenario_at(suite, row["index"], "test", 11)
        assert (row["scenario_id"], row["scenario_seed"], row["seed"]) == (sc.id, sc.seed, seed_for(row["index"], 11))
        assert row["scenario_seed"] != suite.scenario(row["index"], "test").seed
