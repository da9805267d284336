"""The point-mass vehicle model: resistances, acceleration envelope, exact integration."""

import numpy as np
import pytest

from acc_gym.vehicle import (G, VehicleParams, VehicleState, accel_lower, accel_upper, applied_acceleration,
                             coast_acceleration, integrate, resistance_accel, step, top_speed)


def test_resistance_matches_hand_computation():
    p = VehicleParams()
    v = 30.0
    f_r = p.mass * G * (p.c_r0 + p.c_r1 * v + p.c_r2 * v * v)
    f_a = 0.5 * p.c_d * p.rho * p.area * v * v
    assert resistance_accel(v, p) == pytest.approx((f_r + f_a) / p.mass, rel=1e-12)
    assert coast_acceleration(v, p) == pytest.approx(-(f_r + f_a) / p.mass, rel=1e-12)
    # a mid-size car coasts at roughly -0.2 to -0.4 m/s^2 at highway speed
    assert -0.45 < coast_acceleration(30.0, p) < -0.15


def test_upper_bound_flat_then_falling_and_zero_at_top_speed():
    p = VehicleParams()
    v = np.linspace(0.0, 60.0, 601)
    a_u = accel_upper(v, p)
    # flat (traction limit) at low speed, minus the small resistance
    assert a_u[0] == pytest.approx(p.traction_accel - p.c_r0 * G, rel=1e-9)
    assert np.all(np.diff(a_u) <= 1e-12)  # never increases with speed
    # power limit: a_U = P / (m v) - resistance above the corner speed
    v_hi = 35.0
    assert accel_upper(v_hi, p) == pytest.approx(p.power / (p.mass * v_hi) - resistance_accel(v_hi, p), rel=1e-12)
    vt = float(top_speed(p))
    assert accel_upper(vt, p) == pytest.approx(0.0, abs=1e-5)
    assert 45.0 < vt < 70.0


def test_braking_limit_is_tyre_limit_plus_resistance():
    p = VehicleParams()
    assert accel_lower(20.0, p) == pytest.approx(-p.mu_brake * G - resistance_accel(20.0, p))
    assert -9.5 < accel_lower(0.0, p) < -8.0


def test_applied_acceleration_clips_and_never_reverses():
    p = VehicleParams()
    v = np.array([10.0, 10.0, 0.0, 0.0, 40.0])
    a_des = np.array([-20.0, 1.0, -1.0, 1.0, 5.0])
    a = applied_acceleration(a_des, v, p)
    assert a[0] == pytest.approx(accel_lower(10.0, p))
    assert a[1] == 1.0
    assert a[2] == 0.0  # a stopped car asked to brake stays put
    assert a[3] == 1.0
    assert a[4] == pytest.approx(accel_upper(40.0, p))


def test_exact_integration_and_stop_inside_step():
    x, v = integrate(np.array([0.0, 0.0]), np.array([10.0, 1.0]), np.array([2.0, -4.0]), 0.5)
    assert x[0] == pytest.approx(10.0 * 0.5 + 0.5 * 2.0 * 0.25)
    assert v[0] == pytest.approx(11.0)
    # 1 m/s at -4 m/s^2 stops after 0.25 s, having covered v^2 / (2|a|) = 0.125 m
    assert x[1] == pytest.approx(0.125)
    assert v[1] == 0.0


def test_step_over_many_steps_matches_analytic_stop():
    p = VehicleParams()
    s = VehicleState(x=[0.0], v=[20.0])
    for _ in range(100):
        s = step(s, [-3.0], p, 0.2)
    assert s.v[0] == 0.0
    assert s.x[0] == pytest.approx(20.0 ** 2 / (2 * 3.0))
    assert np.all(s.v >= 0.0)


@pytest.mark.parametrize("field,value", [("mass", -1.0), ("c_d", -0.1), ("mu_brake", np.nan), ("power", 0.0)])
def test_bad_parameters_are_named(field, value):
    with pytest.raises(ValueError, match=field):
        VehicleParams(**{field: value})


def test_bad_state_and_action():
    with pytest.raises(ValueError, match="VehicleState.v"):
        VehicleState(x=[0.0], v=[-1.0])
    with pytest.raises(ValueError, match="a_des"):
        step(VehicleState(x=[0.0], v=[1.0]), [np.nan], VehicleParams(), 0.2)


def test_batched_parameters_broadcast():
    p = VehicleParams(mass=np.array([1000.0, 2000.0]))
    a_u = accel_upper(np.array([30.0, 30.0]), p)
    assert a_u[0] > a_u[1]  # the lighter car has more power per kg
    assert p.take(1).mass == 2000.0
    assert p.broadcast(2).power.shape == (2,)
