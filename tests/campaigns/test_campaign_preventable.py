"""UN R157 in campaigns: each collision's row says whether the careful driver (cc-driver) avoids
the same scenario; the summary counts preventable and non-preventable collisions; a resumed
campaign gives the same verdicts; campaigns of format /1 (no verdicts) are refused by name."""

import json
import re

import numpy as np
import pytest

from acc_gym.campaigns import CampaignError, format_summary, load_campaign, run_campaign
from acc_gym.campaigns.manifest import FORMAT


class R157Suite:
    """Scenario ``i`` cycles through three cases (each a pure function of ``i``):

    0. ``ncap/ccrs/30``, a stationary target: cc-driver stops in time, a controller that never
       brakes hits it -- a preventable collision;
    1. :func:`acc_gym.standards.r157.staged_cut_in`: a cut-in 2 m ahead closing at 10 m/s,
       which everybody hits -- non-preventable;
    2. a far, slow cut-in (40 m, 1 m/s slower) nobody hits."""

    name, version, env_id = "r157-cases", "1", "acc_gym/SingleLane-v0"

    def root_seed(self, split):
        return 0

    def hash(self, split):
        return "r157-cases-1"

    def scenario(self, i, split="test"):
        from acc_gym.scenarios.registry import scenario_type
        from acc_gym.standards.r157 import staged_cut_in

        kind = i % 3
        if kind == 1:
            return staged_cut_in()
        sid, fixed = ("ncap/ccrs/30", {}) if kind == 0 else ("singlelane/2/cut-in", {"gap": 40.0, "v_rel": -1.0})
        st = scenario_type(sid)
        return st.build(st.sample_params(np.random.default_rng([i, 36]), fixed), i, "typical")


SUITE = R157Suite()
N = 6
HOURS = (sum(float(SUITE.scenario(i).duration) for i in range(N)) - 1.0) / 3600  # [h] exactly N scenarios


def _run(out, controller="constant", **kw):
    return run_campaign(SUITE, HOURS, controller, out, chunk_size=2, **kw)


@pytest.fixture(scope="module")
def never_brakes(tmp_path_factory):
    out = tmp_path_factory.mktemp("constant")
    return out, _run(out)


def test_collisions_carry_the_careful_drivers_verdict(never_brakes):
    out, summary = never_brakes
    rows = load_campaign(out).rows()
    assert [r["index"] for r in rows] == list(range(N))
    assert [(r["collision"], r["preventable"]) for r in rows] == [(True, True), (True, False), (False, None)] * 2
    assert summary["collisions"]["count"] == 4
    assert (summary["preventable_collisions"], summary["non_preventable_collisions"]) == (2, 2)
    assert "2 preventable, 2 not" in format_summary(summary)
    assert json.loads((out / "summary.json").read_text())["preventable_collisions"] == 2


def test_the_verdicts_are_those_of_r157_preventability(never_brakes):
    """The campaign's re-drive agrees with acc_gym.standards.r157 on every scenario."""
    from acc_gym.standards.r157 import preventability

    out, _ = never_brakes
    for row in load_campaign(out).rows()[:3]:
        assert row["preventable"] == preventability("constant", SUITE.scenario(row["index"]))["preventable"]


def test_a_controller_that_brakes_has_only_the_unavoidable_collision(tmp_path):
    summary = _run(tmp_path, "acc", max_chunks=1)  # scenarios 0 and 1: the stationary target, the staged cut-in
    rows = load_campaign(tmp_path).rows()
    assert [(r["collision"], r["preventable"]) for r in rows] == [(False, None), (True, False)]
    assert (summary["preventable_collisions"], summary["non_preventable_collisions"]) == (0, 1)


def test_a_resumed_campaign_has_the_same_verdicts(never_brakes, tmp_path):
    out, summary = never_brakes
    partial = _run(tmp_path, max_chunks=1)
    assert not partial["complete"] and (partial["preventable_collisions"], partial["non_preventable_collisions"]) \
        == (1, 1)
    again = _run(tmp_path)
    assert load_campaign(tmp_path).rows() == load_campaign(out).rows()
    for key in ("collisions", "preventable_collisions", "non_preventable_collisions", "mean_score", "complete"):
        assert again[key] == summary[key], key


def test_a_campaign_of_format_1_is_refused_as_an_older_version(never_brakes, tmp_path):
    import shutil

    out, _ = never_brakes
    copy = tmp_path / "old"
    shutil.copytree(out, copy)
    path = copy / "campaign.json"
    manifest = json.loads(path.read_text())
    assert manifest["format"] == FORMAT == "acc_gym.campaign/2"
    manifest["format"] = "acc_gym.campaign/1"
    path.write_text(json.dumps(manifest))
    with pytest.raises(CampaignError, match=re.escape(str(path)) + r" was written by an older version of acc-gym.*"
                                            r"no UN R157 'preventable' column"):
        load_campaign(copy)
