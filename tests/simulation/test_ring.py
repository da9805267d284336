"""The ring road (acc_gym.simulation.ring): wrap-around, ordering, batching, and IDM's linear
stability on the ring.

IDM's ring criterion (derived in :func:`acc_gym.evaluation.waves.idm_linear_stability`): with
``a = f(s, v, dv)``, ``dv = v_lead - v``, linearised at the uniform flow, a perturbation
``exp(lambda t + i n theta)`` obeys ``lambda^2 - (f_v + f_dv q) lambda - f_s q = 0``,
``q = exp(-i theta) - 1``; the long-wave expansion ``lambda = c1 theta + c2 theta^2`` gives
``c1 = i f_s / f_v`` and ``Re lambda ~ c2 theta^2`` with ``f_v c2 = f_s/2 - f_s^2/f_v^2 - f_dv
f_s/f_v``: string unstable iff ``f_v^2/2 - f_dv f_v - f_s < 0`` (Treiber and Kesting write it
with ``dv = v - v_lead``, whose ``f_dv`` has the other sign). On a ring of N vehicles only
``theta = 2 pi k / N`` exist; the test takes rings where every mode agrees with the long-wave
verdict. The IDM has no noise, so the test (only it) seeds a 0.3 m displacement of one vehicle.
"""

import numpy as np
import pytest

from acc_gym.drivers.baselines import IDMParams, idm_accel
from acc_gym.evaluation.waves import idm_linear_stability, ring_waves
from acc_gym.simulation.ring import (CONTROLLER, controlled_positions, ring_gaps, ring_layout, ring_rng,
                                     simulate_ring)
from acc_gym.vehicle import VehicleParams, accel_lower, accel_upper


def test_first_vehicles_leader_is_the_last():
    # three IDM vehicles; the last one stands just ahead of the first across the ring's seam
    L, p = 100.0, IDMParams(v_desired=15.0)
    x0 = np.array([90.0, 50.0, 2.0])  # vehicle 2 (the last) at 2 m: 2 + 100 - 90 - 4.7 = 7.3 m ahead of vehicle 0
    v0 = np.array([10.0, 10.0, 0.0])
    tr = simulate_ring(L, 3, layout=ring_layout(3, default="idm"), models={"idm": p}, x0=x0, v0=v0, duration=0.4)
    assert tr.gap[0, 0, 0] == pytest.approx(2.0 + L - 90.0 - 4.7)
    assert tr.gap[0, 0, 1] == pytest.approx(90.0 - 50.0 - 4.7)
    want = idm_accel(10.0, 7.3, 0.0 - 10.0, p.a, p.b, p.time_gap, p.s0, p.v_desired)  # hand: the wrapped gap
    veh = VehicleParams()
    assert want < -5.0  # it brakes hard for the stopped car ahead of it across the seam
    assert tr.a[1, 0, 0] == pytest.approx(np.clip(want, accel_lower(10.0, veh), accel_upper(10.0, veh)))
    assert tr.a[1, 0, 1] > 0  # vehicle 1 has 35 m to vehicle 0, which drives as fast: it accelerates


def test_positions_stay_on_the_ring_and_nobody_passes():
    tr = simulate_ring(230.0, 22, seeds=[11], duration=240.0, v0=0.0)
    x = tr.x
    assert np.all((x >= 0.0) & (x < 230.0))
    assert np.all(tr.s[-1] - tr.s[0] > 230.0)  # everyone went round more than a lap: the wrap was exercised
    assert np.all(np.diff(tr.s, axis=2) < 0)  # unwrapped order kept: each vehicle behind the one before it
    assert np.all(tr.gap > 0.0)  # and the first behind the last, one lap later
    assert not tr.collided.any()
    # x is s wrapped: the gaps from the wrapped positions (modulo L) are the same
    wrapped = np.mod(np.roll(x, 1, axis=2) - x, 230.0) - 4.7
    assert np.allclose(wrapped, tr.gap, atol=1e-9)


def test_same_seed_same_ring_whatever_the_batch():
    from acc_gym_agents.controllers import LinearACC

    layout = list(ring_layout(12, controlled_positions(12, None)))
    layout[3] = "idm"
    kw = dict(layout=layout, controller=LinearACC(), duration=40.0, v0=2.0, drivers="typical")
    alone = simulate_ring(150.0, 12, seeds=[7], **kw)
    batch = simulate_ring(150.0, 12, seeds=[3, 7, 9], **kw)
    assert np.array_equal(alone.v[:, 0], batch.v[:, 1])
    assert np.array_equal(alone.s[:, 0], batch.s[:, 1])
    assert not np.array_equal(batch.v[:, 0], batch.v[:, 1])  # another seed, other drivers
    assert alone.controlled.sum() == 1 and alone.layout[11] == CONTROLLER
    # the drivers come from the ring's own seed sequence
    assert np.array_equal(ring_rng(7).random(3), ring_rng(7).random(3))


def test_controlled_positions_spread_evenly():
    assert controlled_positions(22, None) == (21,)
    assert controlled_positions(22, 0.5) == tuple(range(1, 22, 2))
    assert controlled_positions(10, 0.2) == (4, 9)
    with pytest.raises(ValueError, match="penetration"):
        controlled_positions(10, 1.5)


@pytest.mark.parametrize("a, length, unstable", [(0.5, 230.0, True), (2.0, 230.0, False), (1.5, 700.0, False),
                                                 (0.3, 400.0, True)])
def test_idm_ring_waves_where_the_linear_criterion_says_unstable(a, length, unstable):
    p = IDMParams(a=a, b=1.5, time_gap=1.0, s0=2.0, v_desired=30.0)
    st = idm_linear_stability(p, length, 22)
    assert st["string_stable"] is (not unstable) and st["ring_stable"] is (not unstable)
    N = 22
    x0 = (N - 1 - np.arange(N)) * length / N
    x0[5] += 0.3  # the only perturbation: 0.3 m of one vehicle
    tr = simulate_ring(length, N, layout=ring_layout(N, default="idm"), models={"idm": p}, v0=st["v_e"], x0=x0,
                       duration=1500.0)
    w = ring_waves(tr, warmup=1200.0)[0]
    assert w.collisions == 0
    if unstable:
        assert w.speed_sd > 1.0  # grown from 0.3 m to a stop-and-go wave
        assert w.wave_speed_kmh < 0  # travelling against the traffic
    else:
        assert w.speed_sd < 1e-3  # the perturbation died out


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="do not fit"):
        simulate_ring(50.0, 22, duration=1.0)
    with pytest.raises(ValueError, match="unknown driver 'robot'"):
        simulate_ring(230.0, 2, layout=["human", "robot"], duration=1.0)
    with pytest.raises(ValueError, match="no controller"):
        simulate_ring(230.0, 2, layout=["human", "controller"], duration=1.0)
    with pytest.raises(ValueError, match="driving order"):
        simulate_ring(230.0, 2, x0=[10.0, 100.0], duration=1.0)


def test_ring_gaps_by_hand():
    s = np.array([[30.0, 20.0, 5.0]])
    assert np.allclose(ring_gaps(s, np.array([4.0, 4.0, 4.0]), 50.0), [[5.0 + 50 - 30 - 4, 30 - 20 - 4, 20 - 5 - 4]])


def test_cli_json_has_the_issue_keys_and_trace_columns(tmp_path, capsys):
    import json

    from acc_gym.cli import main
    from acc_gym.commands.ring import JSON_KEYS

    path = tmp_path / "ring.csv"
    assert main(["ring", "acc", "--vehicles", "6", "--length", "80", "--duration", "20", "--warmup", "5",
                 "--seed", "4", "--json", "--trace", str(path)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert tuple(out) == JSON_KEYS
    assert out["controller"] == "acc" and out["penetration"] == pytest.approx(1 / 6) and out["collisions"] == 0
    rows = np.loadtxt(path, delimiter=",", skiprows=1)
    assert path.read_text().splitlines()[0] == "t,vehicle,x,v,a,controlled"
    assert rows.shape == (101 * 6, 6)
    assert np.all((rows[:, 2] >= 0) & (rows[:, 2] < 80.0))
    assert rows[rows[:, 5] == 1, 1].tolist() == [5.0] * 101  # one vehicle controlled: the last
    with pytest.raises(SystemExit) as exc:
        main(["ring", "--penetration", "0.5", "--duration", "5"])
    assert exc.value.code == 2


def test_a_controller_answering_nan_is_named():
    class Bad:
        vectorised = True

        def predict(self, obs, deterministic=True):
            return np.full((len(obs), 1), np.nan, dtype=np.float32), None

    with pytest.raises(ValueError, match=r"vehicle 4, t = 0 s: returned an action that is NaN"):
        simulate_ring(60.0, 5, layout=ring_layout(5, (4,)), controller=Bad(), duration=2.0)
