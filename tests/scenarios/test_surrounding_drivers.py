"""Surrounding drivers: MPC kinds by default, baselines on request, recorded profiles accepted."""

import numpy as np
import pytest

from acc_gym import scenarios
from acc_gym.drivers import IDM, IDMParams, preset
from acc_gym.simulation import SpeedProfile


def ego(sc):
    return IDM(IDMParams(v_desired=sc.set_speed), n=1, dt=sc.dt)


def test_default_surrounding_drivers_are_typical_mpc_drivers_cruising_at_their_speed():
    sc = scenarios.build("singlelane/3/car-following+approach", seed=5)
    for role in ("POV", "POV2"):
        v = sc.vehicle(role)
        assert v.driver.model == "mpc"
        assert v.driver.params["v_desired"] == pytest.approx(v.v0)
        assert 0.8 <= v.driver.params["c_tg"] <= 3.0  # typical time gaps
    malicious = scenarios.build("singlelane/3/car-following+approach", seed=5, drivers="malicious")
    assert malicious.vehicle("POV").driver.params["c_tg"] < 0.8  # malicious drivers tailgate
    idm = scenarios.build("singlelane/3/car-following+approach", seed=5, drivers="idm")
    assert idm.vehicle("POV").driver.model == "idm"
    assert idm.vehicle("POV").driver.params == {"v_desired": pytest.approx(idm.vehicle("POV").v0)}


def test_a_recorded_lead_profile_replaces_a_driver():
    sc = scenarios.build("singlelane/2/car-following", {"v_sv": 25.0, "gap": 40.0, "v_rel": 0.0}, seed=0,
                         drivers="idm")
    t = np.arange(0.0, sc.duration + 1.0, 0.1)
    v = 25.0 - 5.0 * np.sin(np.pi * np.clip(t / 6.0, 0, 1))  # a recorded dip to 20 m/s and back
    rec = sc.with_driver("POV", SpeedProfile.recorded(t, v))
    assert rec.vehicle("POV").driver.model == "profile" and rec.drivers == "custom"
    assert scenarios.Scenario.from_json(rec.to_json()) == rec
    tr = scenarios.simulate(rec, ego(rec))
    np.testing.assert_allclose(tr.v[:, 0, 1], np.interp(tr.t, t, v), atol=1e-9)
    mpc = sc.with_driver("POV", preset("#23", v_desired=25.0))
    assert mpc.vehicle("POV").driver.params["a_min"] == -2.1
    with pytest.raises(ValueError, match="ego"):
        sc.with_driver("SV", preset("#23"))
    with pytest.raises(TypeError, match="DriverSpec"):
        sc.with_driver("POV", "idm")
