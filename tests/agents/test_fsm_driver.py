"""The JRC's Fuzzy Safety Model driver: its metrics by hand, its phases step by step, and its
use as UN R157's second reference."""

import numpy as np
import pytest

from acc_gym_agents.controllers.fsm_driver import BRAKE_DECEL, JERK, FSMDriver, cfs, fsm_driver, pfs


def test_pfs_by_hand():
    # v = v_lead = 20 m/s: d_safe = 15 + 400/8 - 400/14 + 2 = 38.43 m, d_unsafe = 15 + 400/12 - 400/14 = 19.76 m
    d_safe, d_unsafe = 15 + 50 - 400 / 14 + 2, 15 + 400 / 12 - 400 / 14
    assert pfs(2 + d_safe + 0.01, 20, 20) == 0.0
    assert pfs(2 + (d_safe + d_unsafe) / 2, 20, 20) == pytest.approx(0.5)
    assert pfs(2 + d_unsafe - 0.01, 20, 20) == 1.0


def test_cfs_by_hand():
    # closing 10 m/s, no braking yet: d_safe = 7.5 + 100/8 = 20 m, d_unsafe = 7.5 + 100/12 = 15.83 m
    assert cfs(20.01, 20, 10, 0.0) == 0.0
    assert cfs(18.0, 20, 10, 0.0) == pytest.approx((18 - 20) / (7.5 + 100 / 12 - 20))
    assert cfs(15.0, 20, 10, 0.0) == 1.0
    assert cfs(1.0, 10, 12, 0.0) == 0.0  # not closing in
    # braking at 4 m/s^2 sheds a 2 m/s closing within the reaction time: only a gap under 4/8 m is critical
    assert cfs(0.4, 12, 10, -4.0) == 1.0 and cfs(0.6, 12, 10, -4.0) == 0.0


def obs(gap, v=20.0, v_lead=10.0, a=0.0, seen=1.0):
    return np.array([v, a, gap, v_lead - v, seen, 30.0, 1.5])


def test_the_phases_step_by_step():
    d = FSMDriver()
    follow = d.following(obs(80.0)[None])[0]
    assert d._accel(obs(80.0)[None])[0] == pytest.approx(follow)  # safe: the linear ACC law
    risky = obs(12.0)  # CFS = 1: target 6 m/s^2
    got = [d._accel(risky[None])[0] for _ in range(8)]
    # 0.75 s of reaction at 0.2 s steps: four steps at 0 m/s^2, then braking rising 12.65 m/s^3 to the target
    assert got[:4] == [0.0] * 4
    rise = [-min(JERK * 0.2 * k, 6.0) for k in range(1, 5)]
    assert got[4:] == pytest.approx(rise)
    assert max(-x for x in got) <= BRAKE_DECEL
    # safe again: back to following, and a new event reacts again
    assert d._accel(obs(80.0)[None])[0] == pytest.approx(follow)
    assert d._accel(risky[None])[0] == 0.0


def test_pfs_alone_brakes_comfortably():
    d = FSMDriver()
    o = obs(2 + (15 + 50 - 400 / 14 + 2 + 15 + 400 / 12 - 400 / 14) / 2, v=20.0, v_lead=20.0)  # PFS 0.5, CFS 0
    p, c = d.metrics(o[None])
    assert p[0] == pytest.approx(0.5) and c[0] == 0.0
    got = [d._accel(o[None])[0] for _ in range(7)]
    assert got[4:] == pytest.approx([-2.0] * 3)  # 0.5 x 4 m/s^2


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="reaction_tme"):
        fsm_driver(reaction_tme=1.0)
    with pytest.raises(ValueError, match="max_fuzzy_decel"):
        fsm_driver(max_fuzzy_decel=3.0)
    bad = obs(20.0)
    bad[2] = np.nan
    with pytest.raises(ValueError, match="fsm-driver: observation field 2 \\(gap\\) is NaN"):
        FSMDriver().predict(bad)


def test_it_serves_as_r157_reference():
    from acc_gym.standards.r157 import r157_cases

    itself = r157_cases("fsm-driver", reference="fsm-driver", families=("lead deceleration",))
    assert itself["reference"] == "fsm-driver" and itself["preventable_collisions"] == 0
    never = r157_cases("constant", reference="fsm-driver", families=("lead deceleration",))
    assert never["preventable_collisions"] > 0


def test_conformance_takes_the_fsm_as_reference(capsys):
    import json

    from acc_gym.cli import main

    with pytest.raises(SystemExit):
        main(["conformance", "acc", "--standard", "r157", "--r157-reference", "rss"])
    assert "rss" in capsys.readouterr().err
    assert main(["conformance", "fsm-driver", "--standard", "r157", "--r157-reference", "fsm-driver", "--json"]) == 0
    r157 = json.loads(capsys.readouterr().out)["standards"]["r157"]
    assert r157["reference"] == "fsm-driver" and r157["preventable_collisions"] == 0
    assert all(c["preventable"] is False for c in r157["cases"] if c["controller_collides"])


def test_steady_following_stays_outside_its_own_unsafe_zone():
    """Normal driving keeps at least PFS's safe distance (+1 m): at that gap behind a lead at its own
    speed both metrics are 0 and the law asks for no acceleration, and in a column behind a constant
    lead it reaches a steady state (with the plain ACC law it cycled around the PFS boundary)."""
    from acc_gym.evaluation.string_stability import PlatoonConfig, string_stability

    d = FSMDriver()
    for v in (10.0, 20.0, 30.0):
        steady = 2.0 + v * 0.75 + v ** 2 / 8 - v ** 2 / 14 + 2.0 + 1.0  # [m] the gap its law aims at
        o = obs(steady, v=v, v_lead=v)
        o[5] = v  # set speed: no cruise pull
        p, c = d.metrics(o[None])
        assert p[0] == 0.0 and c[0] == 0.0
        assert d.following(o[None])[0] == pytest.approx(0.0, abs=1e-9)
    report = string_stability("fsm-driver", PlatoonConfig(vehicles=3), frequencies=(0.02,), disturbance=False)
    assert report.max_gain > 0
