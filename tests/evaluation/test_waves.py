"""Wave measures (acc_gym.evaluation.waves) on hand-made series with known answers."""

import numpy as np
import pytest

from acc_gym.evaluation import waves as W
from acc_gym.vehicle import VehicleParams, resistance_accel


def _synthetic(c_kmh: float, m: int, L: float = 230.0, N: int = 22, T: float = 400.0, dt: float = 0.2, seed=0):
    """Vehicles driving round the ring at 5 m/s from uneven positions; their speeds sampled from the
    travelling field v(x, t) = 4 - 2 cos(2 pi m (x - c t) / L)."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(T / dt) + 1) * dt
    start = np.sort(rng.uniform(0, L, N))[::-1]  # driving order: front first
    x = np.mod(start[None, :] + 5.0 * t[:, None], L)[:, None, :]  # (T+1, 1, N)
    c = c_kmh / 3.6
    v = 4.0 - 2.0 * np.cos(2 * np.pi * m * (x - c * t[:, None, None]) / L)
    return t, x, v, L


@pytest.mark.parametrize("c_kmh, m", [(-18.0, 1), (-12.0, 2), (15.0, 1), (-25.0, 1)])
def test_wave_speed_of_a_synthetic_travelling_wave(c_kmh, m):
    t, x, v, L = _synthetic(c_kmh, m, seed=int(abs(c_kmh)))
    got = W.wave_speed(x, v, t, L, warmup=50.0)[0]
    assert got == pytest.approx(c_kmh, rel=0.05)


def test_no_wave_no_speed():
    t = np.arange(1001) * 0.2
    x = np.mod(np.linspace(200, 0, 10)[None, None, :] + 3.0 * t[:, None, None], 230.0)
    v = np.full_like(x, 3.0)
    assert np.isnan(W.wave_speed(x, v, t, 230.0, warmup=10.0)[0])


def test_speed_sd_pools_vehicles_and_time_after_the_warmup():
    t = np.arange(11) * 1.0
    v = np.zeros((11, 1, 2))
    v[:, 0, 0] = 100.0  # the warm-up rows differ, and are left out
    v[5:, 0, 0], v[5:, 0, 1] = 2.0, 4.0
    assert W.speed_sd(v, t, warmup=5.0)[0] == pytest.approx(1.0)
    assert W.mean_speed(v, t, warmup=5.0)[0] == pytest.approx(3.0)


def test_jam_needs_60_s_without_a_break():
    dt = 0.2
    t = np.arange(int(400 / dt) + 1) * dt
    v = np.full((t.size, 2, 3), 5.0)
    # ring 0: one vehicle stands from 100 s to 170 s while the others drive (sd >= 1): a jam from 100 s
    on = (t >= 100.0) & (t < 170.0)
    v[on, 0, 0] = 0.0
    # ring 1: the same but only 59 s, then a break, then 59 s: no jam
    for a, b in ((100.0, 159.0), (160.0, 219.0)):
        v[(t >= a) & (t < b), 1, 0] = 0.0
    onset = W.jam_onset(v, t)
    assert onset[0] == pytest.approx(100.0)
    assert np.isnan(onset[1])


def test_stops_and_braking_events_count_with_hysteresis():
    t = np.arange(9) * 1.0
    v = np.array([3.0, 0.4, 0.6, 0.4, 2.0, 0.1, 0.0, 1.5, 0.2])[:, None, None]  # stops at 1, 5, 8 (not 3)
    assert W.stops(v, t, warmup=0.0)[0] == 3
    a = np.array([0.0, -1.5, -0.8, -1.5, 0.0, -2.0, -0.2, 0.0, 0.0])[:, None, None]  # 1, 5 (3 is the same event)
    assert W.braking_events(a, t, warmup=0.0)[0] == 2


def test_energy_at_constant_speed_is_the_resistance_work():
    veh = VehicleParams()
    t = np.arange(501) * 0.2
    v = np.full((501, 1, 4), 10.0)
    a = np.zeros_like(v)
    force = veh.mass * resistance_accel(10.0, veh)  # [N] rolling resistance and drag at 10 m/s
    want = force * 100e3 / 3.6e6  # [kWh per 100 km]
    assert W.energy_per_100km(v, a, t, veh, warmup=0.0)[0] == pytest.approx(want, rel=1e-12)
    # braking is not credited: a decelerating stretch adds no negative work
    a2 = a.copy()
    a2[1:, 0, 0] = -2.0
    e, _ = W.tractive_energy(v, a2, t, veh, warmup=0.0)
    e0, _ = W.tractive_energy(v, a, t, veh, warmup=0.0)
    assert e[0] == pytest.approx(e0[0] * 3 / 4)
