"""Monte Carlo traffic: hours of single-lane scenarios drawn by occurrence rates."""

import collections

import numpy as np
import pytest

from acc_gym.scenarios import list_scenarios, scenario_type, traffic, traffic_hour
from acc_gym.scenarios.montecarlo import HOUR

PAPER = {i for i in list_scenarios("singlelane") if scenario_type(i).in_paper}
RATES = {i: scenario_type(i).occurrence_rate.mean for i in PAPER}
N_HOURS = 5


@pytest.fixture(scope="module")
def hours():
    return [traffic_hour(h, drivers="idm") for h in range(N_HOURS)]


def test_an_hour_is_filled_and_the_last_scenario_crosses_it(hours):
    for h in hours:
        durations = np.array([s.duration for s in h])
        assert durations.sum() >= HOUR == 3600.0
        assert durations[:-1].sum() < HOUR  # stops as soon as the hour is full


def test_about_280_scenarios_per_hour(hours):
    for h in hours:
        assert 230 <= len(h) <= 330
    assert 250 <= np.mean([len(h) for h in hours]) <= 310


def test_only_paper_configurations_with_fresh_seeds(hours):
    for h in hours:
        assert {s.id for s in h} <= PAPER
        assert all(s.drivers == "idm" for s in h)
    seeds = [s.seed for h in hours for s in h]
    assert len(set(seeds)) > 0.99 * len(seeds)  # each scenario its own seed


def test_include_extra_adds_the_separate_configuration():
    ids = [s.id for h in range(3) for s in traffic_hour(h, drivers="idm", include_extra=True)]
    assert "singlelane/2/separate" in ids
    assert set(ids) <= PAPER | {"singlelane/2/separate"}


def test_same_hour_and_root_seed_give_identical_scenarios(hours):
    assert traffic_hour(1, drivers="idm") == hours[1]
    assert hours[0] != hours[1]
    other_root = traffic_hour(1, root_seed=1, drivers="idm")
    assert [s.seed for s in other_root] != [s.seed for s in hours[1]]


def test_hours_are_independent_of_what_came_before(hours):
    flat = list(traffic(3, drivers="idm"))
    n0, n1 = len(hours[0]), len(hours[1])
    assert len(flat) == n0 + n1 + len(hours[2])
    assert flat[:n0] == hours[0]
    assert flat[n0 + n1:] == hours[2]
    # building other scenarios in between changes nothing
    traffic_hour(4, root_seed=9, drivers="idm")
    assert traffic_hour(2, drivers="idm") == hours[2]


def test_drivers_choice_does_not_change_the_traffic_mix(hours):
    typical = traffic_hour(0)
    assert [(s.id, s.seed, s.params) for s in typical] == [(s.id, s.seed, s.params) for s in hours[0]]
    assert {v.driver.model for s in typical for v in s.vehicles[1:]} == {"mpc"}


def test_configuration_frequencies_follow_occurrence_rates(hours):
    counts = collections.Counter(s.id for h in hours for s in h)
    n = sum(counts.values())
    total = sum(RATES.values())
    assert total == pytest.approx(280.0)
    expected = {i: n * r / total for i, r in RATES.items()}
    # e.g. car-following 70/280 = 25 % (about 350 of ~1400), lane-change+cut-out 2/280 (about 10)
    assert min(expected.values()) >= 5  # chi-square is valid
    chi2 = sum((counts[i] - e) ** 2 / e for i, e in expected.items())
    # 21 degrees of freedom: P(chi2 > 46.8) = 0.001
    assert chi2 < 46.8, (chi2, counts)
    # and the most frequent configuration is the most frequent one drawn
    assert counts.most_common(1)[0][0] == "singlelane/2/car-following"
    assert abs(counts["singlelane/2/car-following"] / n - 0.25) < 0.04


def test_mean_duration_matches_the_hour(hours):
    # ~280 scenarios per hour means a mean scenario length near 3600 / 280 = 12.9 s
    durations = [s.duration for h in hours for s in h]
    assert 11.0 < np.mean(durations) < 15.0


@pytest.mark.parametrize("hour", [-1, 1.5])
def test_bad_hour(hour):
    with pytest.raises(ValueError, match=f"hour must be a non-negative integer, got {hour}"):
        traffic_hour(hour)


@pytest.mark.parametrize("root_seed", [-1, 0.5])
def test_bad_root_seed(root_seed):
    with pytest.raises(ValueError, match="root_seed must be a non-negative integer"):
        traffic_hour(0, root_seed=root_seed)


def test_bad_traffic_arguments():
    with pytest.raises(ValueError, match="hours must be a non-negative integer"):
        list(traffic(-1))
    with pytest.raises(ValueError, match="'ncap' has no occurrence rates"):
        traffic_hour(0, family="ncap")
    with pytest.raises(ValueError, match="unknown scenario family"):
        traffic_hour(0, family="rural")
    with pytest.raises(ValueError, match="unknown drivers"):
        traffic_hour(0, drivers="robots")
    assert list(traffic(0)) == []
