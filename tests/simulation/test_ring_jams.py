"""Driver model 6's human-like drivers jam on Sugiyama's ring from a uniform start, as people do, and
do not at low density; driver model 5's do not jam at all (the extension is what makes the wave).
Seeds 1-3 (benchmarks/ring.py uses 1000-1009)."""

import numpy as np
import pytest

from acc_gym.evaluation.waves import ring_waves
from acc_gym.simulation.ring import simulate_ring

SEEDS = [1, 2, 3]


@pytest.fixture(scope="module")
def sugiyama():
    return simulate_ring(230.0, 22, seeds=SEEDS, duration=200.0)


def test_model_6_jams_on_sugiyamas_ring_with_a_backward_wave_at_the_fields_speed(sugiyama):
    reports = ring_waves(sugiyama)
    assert not sugiyama.collided.any()  # no contact in any ring
    for r in reports:
        assert r.jam and r.jam_onset_s < 140.0
        # Sugiyama et al.: about 20 km/h against the traffic; the band 12-25 km/h
        assert -25.0 <= r.wave_speed_kmh <= -12.0
        assert r.speed_sd >= 1.0 and r.stops > 0
    # the start is uniform: every vehicle evenly spaced and standing, nothing scripted
    np.testing.assert_allclose(np.diff(sugiyama.x[0], axis=1), -230.0 / 22, atol=1e-9)
    assert np.all(sugiyama.v[0] == 0.0)


def test_model_6_flows_freely_on_a_long_ring():
    tr = simulate_ring(1500.0, 22, seeds=SEEDS[:2], duration=200.0)
    for r in ring_waves(tr):
        assert not r.jam and r.speed_sd < 0.5
        assert r.mean_speed == pytest.approx(30 / 3.6, abs=0.1)  # at the desired speed


def test_model_5_settles_into_uniform_flow_on_the_same_ring():
    tr = simulate_ring(230.0, 22, seeds=SEEDS[:1], duration=200.0, driver_model=5)
    (r,) = ring_waves(tr)
    assert not r.jam and r.speed_sd < 0.3


def test_the_same_seed_gives_the_same_ring_with_perception_whatever_the_batch(sugiyama):
    alone = simulate_ring(230.0, 22, seeds=[SEEDS[1]], duration=60.0)
    np.testing.assert_array_equal(alone.s[:, 0], sugiyama.s[:alone.s.shape[0], 1])
    np.testing.assert_array_equal(alone.a[:, 0], sugiyama.a[:alone.a.shape[0], 1])


def test_an_unknown_driver_model_is_named():
    with pytest.raises(ValueError, match="unknown driver model 4"):
        simulate_ring(230.0, 22, seeds=[0], duration=1.0, driver_model=4)
