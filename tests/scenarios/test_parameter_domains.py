"""Parameters given out of their domain (negative speeds, distances, time gaps) are refused by name."""

import re

import pytest

from acc_gym.scenarios import build


@pytest.mark.parametrize("sid, params, message", [
    ("singlelane/1/free-flow", {"v_sv": -3.0}, "'v_sv' of 'singlelane/1/free-flow' must be >= 0, got -3.0"),
    ("singlelane/2/cut-in", {"gap": -5.0}, "'gap' of 'singlelane/2/cut-in' must be > 0, got -5.0"),
    ("singlelane/2/approach", {"time_gap": -1.5}, "'time_gap' of 'singlelane/2/approach' must be > 0, got -1.5"),
    ("singlelane/3/approach+cut-in", {"gap2": 0.0}, "'gap2' of 'singlelane/3/approach+cut-in' must be > 0"),
    ("singlelane/2/cut-out", {"lc_duration": -4.0}, "'lc_duration' of 'singlelane/2/cut-out' must be > 0"),
    ("carfollowing/60", {"time_gap": -1.0}, "'time_gap' of 'carfollowing/60' must be > 0, got -1.0"),
    ("carfollowing/60", {"speed_limit": -60.0}, "'speed_limit' of 'carfollowing/60' must be > 0"),
    ("ncap/ccrs/20", {"v_ego": -20.0}, "'v_ego' of 'ncap/ccrs/20' must be > 0, got -20.0"),
    ("ncap/ccrm/40", {"v_target": -1.0}, "'v_target' of 'ncap/ccrm/40' must be >= 0, got -1.0"),
    ("ncap/ccrb/2-12", {"gap": -12.0}, "'gap' of 'ncap/ccrb/2-12' must be > 0, got -12.0"),
    ("stopandgo", {"queue_gap": 0.0}, "'queue_gap' of 'stopandgo' must be > 0, got 0.0"),
])
def test_out_of_domain_parameters_name_the_value(sid, params, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        build(sid, params, seed=0, drivers="idm")
