"""estimate_risk on simulated cut-ins: certain failures, workers, resume, bad input."""

import json

import numpy as np
import pytest

from acc_gym.risk import estimate_risk
from acc_gym.risk import run as risk_run
from acc_gym.risk.episodes import RiskChunk, run_chunk
from acc_gym.risk.proposal import Proposal
from acc_gym.scenarios.registry import scenario_type
from hold import Hold  # noqa: E402  (tests/risk/hold.py)


class Ram:
    """Holds its speed until a vehicle is in its lane ahead, then full throttle into it."""

    vectorised = True

    def predict(self, obs, deterministic=True):
        o = np.atleast_2d(np.asarray(obs, dtype=float))
        act = np.where(o[:, 4] > 0.5, 1.0, 0.0).astype(np.float32)[:, None]
        return (act[0] if np.ndim(obs) == 1 else act), None


class RamOneByOne(Ram):
    """The same law, without ``vectorised``: run as one copy per episode."""

    vectorised = False


@pytest.mark.parametrize("controller", [Hold(), Ram()], ids=["constant", "ram"])
def test_a_controller_that_collides_on_every_cut_in_gives_one_exactly(controller):
    # 10 m at entry, the cut-in vehicle 4 m/s slower: holding speed (or ramming it) always collides
    r = estimate_risk(controller, "cut-in", params={"gap": 10.0, "v_rel": -4.0}, budget=256, round_size=128)
    assert r.estimate.failures == r.estimate.episodes
    assert (r.estimate.p, r.estimate.ci_low, r.estimate.ci_high) == (1.0, 1.0, 1.0)
    assert r.other.p == 1.0  # a collision is also a time-to-collision under 1 s
    assert r.rounds[0]["kind"] == "adaptive" and r.rounds[0]["level"] == 0.0  # the level was reached at once


def test_a_controller_one_copy_per_episode_gives_the_same_episodes():
    st = scenario_type("singlelane/2/cut-in")
    prop = Proposal.nominal_only(st.parameters).to_dict()
    a = run_chunk(RiskChunk(st.id, prop, Ram(), 3, 0, 0, 16, "acc_gym/SingleLane-v0"))
    b = run_chunk(RiskChunk(st.id, prop, RamOneByOne(), 3, 0, 0, 16, "acc_gym/SingleLane-v0"))
    assert a == b
    assert any(r["collision"] for r in a) and not all(r["collision"] for r in a)


def test_gm_collides_on_cut_ins_and_the_estimate_agrees_with_its_own_rounds(tmp_path):
    """GM (paper 003's unsafe model) collides in about 0.4 % of cut-ins: the importance-sampling
    run finds the failure region, its interval holds a crude count made on the same budget
    ``bench_risk.py`` compares at scale) and the adaptive rounds' levels fall to 0."""
    r = estimate_risk("gm", "cut-in", budget=3072, round_size=512, target_rhw=0.3, root_seed=1)
    levels = [x["level"] for x in r.rounds if x["kind"] == "adaptive"]
    assert levels[-1] == 0.0 and levels == sorted(levels, reverse=True)
    assert 1e-3 < r.estimate.p < 2e-2 and r.estimate.failures >= 10
    crude = estimate_risk("gm", "cut-in", method="crude", budget=3072, round_size=1024, target_rhw=0.01, root_seed=1)
    assert crude.estimate.failures > 0
    lo = min(r.estimate.ci_low, crude.estimate.ci_low)
    hi = max(r.estimate.ci_high, crude.estimate.ci_high)
    assert r.estimate.ci_low <= crude.estimate.ci_high and crude.estimate.ci_low <= r.estimate.ci_high, (lo, hi)
    # the proposal moved to short gaps and a slow cut-in vehicle
    tilted = {tuple(t["names"]): t["law"] for t in r.proposal["tilted"]}
    assert tilted[("v_rel",)]["mu"] < -3.0 and tilted[("gap",)]["M"] < np.log(18.0)


def test_a_controller_that_never_collides_gets_an_exact_upper_bound():
    """The linear ACC brakes at up to 8 m/s^2 and every generated cut-in is survivable at 6:
    the rounds tilt towards the closest calls, stall above a time-to-collision of 1 s, and
    the rest of the budget is spent on nominal draws, which give the tightest exact bound."""
    r = estimate_risk("acc", "cut-in", budget=2048, round_size=256, target_rhw=0.2)
    adaptive = [x for x in r.rounds if x["kind"] == "adaptive"]
    estimation = [x for x in r.rounds if x["kind"] == "estimation"]
    assert r.estimate.failures == 0 and r.estimate.p == 0.0 and r.stop == "budget spent"
    assert all(x["beta"] == 0.1 for x in adaptive) and all(x["beta"] == 1.0 for x in estimation)
    exposure = 0.1 * sum(x["episodes"] for x in adaptive) + sum(x["episodes"] for x in estimation)
    assert r.estimate.upper_bound == pytest.approx(-np.log(0.05) / exposure)
    assert r.min_ttc > 1.0 and adaptive[-1]["level"] > 1.0
    assert len(adaptive) < 10  # stalled, not run to max_rounds


SMALL = dict(budget=256, round_size=128, max_rounds=1, target_rhw=0.01, root_seed=5)


def _without_time(result) -> dict:
    d = result.to_dict()
    d.pop("wall_time_s")
    return d


def test_results_do_not_depend_on_the_number_of_workers():
    one = estimate_risk("fuzzy", "cut-in", workers=1, **SMALL)
    assert _without_time(one) == _without_time(estimate_risk("fuzzy", "cut-in", workers=2, **SMALL))


def test_results_on_a_dask_cluster_are_those_of_one_worker():
    # the test extras install Dask; a user's install without ".[dist]" has no Dask backend to test
    pytest.importorskip("distributed", reason="Dask distributed is not installed (pip install '.[dist]' or '.[test]')")
    one = estimate_risk("fuzzy", "cut-in", workers=1, **SMALL)
    assert _without_time(one) == _without_time(estimate_risk("fuzzy", "cut-in", workers=2, scheduler="local",
                                                             **SMALL))


def test_a_crashed_run_resumes_from_its_chunks(tmp_path, monkeypatch):
    kw = dict(budget=384, round_size=128, max_rounds=1, target_rhw=0.01, root_seed=2, out=tmp_path)
    full = estimate_risk("idm", "cut-in", **kw).to_dict()
    files = sorted(p.name for p in tmp_path.glob("r*-c*.json"))
    assert len(files) == 6 and (tmp_path / "risk.json").exists()
    (tmp_path / files[-1]).unlink()  # the last chunk was lost in the crash
    (tmp_path / files[1]).unlink()
    ran = []
    monkeypatch.setattr(risk_run, "run_chunk", lambda c: ran.append((c.round, c.number)) or run_chunk(c))
    again = estimate_risk("idm", "cut-in", **kw).to_dict()
    assert len(ran) == 2  # only the lost chunks ran again
    for d in (full, again):
        d.pop("wall_time_s")
    assert again == full
    with pytest.raises(ValueError, match="other settings.*budget"):
        estimate_risk("idm", "cut-in", **{**kw, "budget": 512})
    bad = tmp_path / files[0]
    bad.write_text(bad.read_text()[:-20])
    with pytest.raises(ValueError, match=files[0]):
        estimate_risk("idm", "cut-in", **kw)
    data = json.loads((tmp_path / files[2]).read_text())
    data["proposal"]["beta"] = 0.5
    (tmp_path / files[2]).write_text(json.dumps(data))
    bad.unlink()
    with pytest.raises(ValueError, match=f"{files[2]}.*another proposal"):
        estimate_risk("idm", "cut-in", **kw)


@pytest.mark.parametrize("kwargs, match", [
    (dict(family="merge"), "unknown family 'merge'"),
    (dict(event="near-miss"), "unknown event 'near-miss'"),
    (dict(method="mcmc"), "unknown method 'mcmc'"),
    (dict(target_rhw=0.0), "target_rhw must be a positive number"),
    (dict(budget=-5), "budget must be a positive integer"),
    (dict(params={"gap": 10.0, "color": 3}), "unknown parameter"),
    (dict(root_seed=-1), "root_seed"),
    (dict(drivers="reckless"), "unknown drivers 'reckless'"),
])
def test_bad_settings_are_named(kwargs, match):
    with pytest.raises(ValueError, match=match):
        estimate_risk("acc", **{"family": "cut-in", **kwargs})


def test_an_unknown_controller_is_named_before_any_episode():
    with pytest.raises(ValueError, match="no_such_controller"):
        estimate_risk("no_such_controller", "cut-in")


def test_an_object_controller_cannot_go_to_workers():
    with pytest.raises(ValueError, match="runs in this process only"):
        estimate_risk(Ram(), "cut-in", workers=2)


def test_a_nan_action_is_named():
    class NaNs:
        vectorised = True

        def predict(self, obs, deterministic=True):
            return np.full((np.shape(obs)[0], 1), np.nan), None

    with pytest.raises(ValueError, match="not finite: nan"):
        estimate_risk(NaNs(), "cut-in", budget=64, round_size=64)


def test_the_cli_prints_the_estimate_and_json(capsys):
    from acc_gym.cli import main

    assert main(["risk", "--controller", "acc", "--family", "cut-in", "--budget", "256", "--round-size", "128",
                 "--workers", "1", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["estimate"]["failures"] == 0 and out["estimate"]["upper_bound"] > 0 and out["stop"] == "budget spent"
    assert out["per_hour"]["upper_bound"] == pytest.approx(20.0 * out["estimate"]["upper_bound"])
    assert main(["risk", "--controller", "acc", "--budget", "256", "--round-size", "128", "--workers", "1",
                 "--param", "v_sv=20"]) == 0
    text = capsys.readouterr().out
    assert "P(collision) per encounter < " in text and "95 % upper bound" in text
    with pytest.raises(SystemExit):
        main(["risk", "--controller", "acc", "--param", "v_sv"])
    assert "expected NAME=VALUE" in capsys.readouterr().err


def test_with_an_out_directory_the_first_collisions_are_written_as_openscenario(tmp_path):
    pytest.importorskip("scenariogeneration", reason="scenariogeneration is not installed (pip install '.[osc]' or '.[test]'): nothing writes OpenSCENARIO")
    from acc_gym.evaluation.runner import load_controller
    from acc_gym.risk.run import MAX_FAILURES_WRITTEN
    from acc_gym.scenarios.openscenario import run_file

    out = tmp_path / "risk"
    r = estimate_risk("gm", "cut-in", budget=1024, round_size=512, target_rhw=0.3, root_seed=1, out=out)
    hits = r.estimate.failures
    assert hits > 0 and len(r.failures) == min(hits, MAX_FAILURES_WRITTEN)
    assert r.to_dict()["failures"] == r.failures
    for f in r.failures:
        assert f["collided"]  # built again from its draw and driven again: the same collision
        assert (out / f["xosc"]).is_file() and (out / f["xodr"]).is_file()
    result, _ = run_file(out / r.failures[0]["xosc"], load_controller("gm"))
    assert result["collided"]
    again = estimate_risk("gm", "cut-in", budget=1024, round_size=512, target_rhw=0.3, root_seed=1, out=out)
    assert again.failures == r.failures  # a resumed run writes the same files
