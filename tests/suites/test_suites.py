"""Versioned suites: the contract API, reproducible streams, splits, hashes, shipped data."""

import itertools
import json

import numpy as np
import pytest

import acc_gym.suites as suites
from acc_gym.scenarios import scenario_type
from acc_gym.suites import (
    Suite,
    data_path,
    file_text,
    get_suite,
    list_suites,
    read_definition,
    template,
)
from acc_gym.suites.generators import MALICIOUS_NCAP, MALICIOUS_SINGLELANE
from acc_gym.suites.suite import canonical_scenario, definition_hash

NAMES = ["carfollowing-v1", "malicious-v3", "ncap-v1", "ncap-v2", "singlelane-v3"]
ENV_IDS = {"carfollowing-v1": "acc_gym/CarFollowing-v0", "malicious-v3": "acc_gym/SingleLane-v0",
           "ncap-v1": "acc_gym/NCAP-v0", "ncap-v2": "acc_gym/SingleLane-v0", "singlelane-v3": "acc_gym/SingleLane-v0"}


def test_list_and_attributes():
    assert list_suites() == NAMES
    for name in NAMES:
        s = get_suite(name)
        assert isinstance(s, Suite)
        assert s.name == name and s.version == int(name.rsplit("-v", 1)[1]) and isinstance(s.family, str)
        assert s.env_id == ENV_IDS[name]
        for split in ("dev", "test"):
            assert isinstance(s.root_seed(split), int) and s.root_seed(split) >= 0
        assert s.root_seed("dev") != s.root_seed("test")


@pytest.mark.parametrize("old, new", [("singlelane-v2", "singlelane-v3"), ("malicious-v2", "malicious-v3"),
                                      ("singlelane-v1", "singlelane-v3")])
def test_a_retired_suite_names_its_successor(old, new):
    from acc_gym.suites import RETIRED, list_suites

    assert old in RETIRED and old not in list_suites() and new in list_suites()
    with pytest.raises(ValueError, match=rf"'{old}' was retired in acc-gym .*use '{new}'"):
        get_suite(old)


def test_unknown_suite_and_split_are_named():
    with pytest.raises(ValueError, match=r"'nope-v9'.*carfollowing-v1.*singlelane-v3"):
        get_suite("nope-v9")
    s = get_suite("ncap-v1")
    for call in (lambda: s.root_seed("train"), lambda: s.scenario(0, "train"), lambda: s.episodes("train"),
                 lambda: list(s.stream("train")), lambda: s.hash("train")):
        with pytest.raises(ValueError, match="'train'"):
            call()
    with pytest.raises(ValueError, match="-1"):
        s.scenario(-1)


@pytest.mark.parametrize("name", NAMES)
def test_scenario_is_a_pure_function_of_index_and_split(name):
    s = get_suite(name)
    forward = [s.scenario(i, "test").to_json() for i in range(6)]
    backward = [s.scenario(i, "test").to_json() for i in reversed(range(6))][::-1]
    assert forward == backward
    s.scenario(100, "dev")  # something else in between changes nothing
    assert s.scenario(3, "test").to_json() == forward[3]
    # the stream agrees with scenario(i) and starts where asked
    assert [(i, sc.to_json()) for i, sc in itertools.islice(s.stream("test"), 6)] == list(enumerate(forward))
    assert [i for i, _ in itertools.islice(s.stream("test", start=4), 2)] == [4, 5]
    assert next(s.stream("test", start=4))[1].to_json() == forward[4]


def test_scenario_randomness_comes_from_index_and_root_seed():
    s = get_suite("singlelane-v3")
    rng = np.random.default_rng([7, s.root_seed("dev")])
    assert canonical_scenario(s.generator(7, rng)).to_json() == s.scenario(7, "dev").to_json()


@pytest.mark.parametrize("name", NAMES)
def test_dev_and_test_differ(name):
    s = get_suite(name)
    dev, test = s.to_dict()["episodes"]["dev"], s.to_dict()["episodes"]["test"]
    assert dev != test
    assert [e["params"] for e in dev] != [e["params"] for e in test]  # not only the seeds
    assert s.hash("dev") != s.hash("test")


def test_stream_hours_counts_durations_from_index_zero():
    s = get_suite("carfollowing-v1")
    items = list(s.stream("dev", hours=0.1))
    durations = [sc.duration for _, sc in items]
    assert sum(durations) >= 360 and sum(durations[:-1]) < 360
    late = list(s.stream("dev", hours=0.1, start=2))
    assert [i for i, _ in late] == [i for i, _ in items][2:]


def test_singlelane_is_an_hour_of_paper_configurations():
    s = get_suite("singlelane-v3")
    episodes = s.episodes("test")
    assert sum(e.duration for e in episodes) >= 3600.0
    assert sum(e.duration for e in episodes[:-1]) < 3600.0  # and not more than needed
    assert all(scenario_type(e.id).in_paper and e.id.startswith("singlelane/") for e in episodes)
    assert len({e.id for e in episodes}) >= 15  # rates spread it over many configurations
    assert all(e.drivers == "typical" for e in episodes)


def test_carfollowing_and_ncap_contents():
    cf = get_suite("carfollowing-v1").episodes("test")
    assert sorted({e.id for e in cf}) == ["carfollowing/120", "carfollowing/60", "carfollowing/90"]
    assert len({e.seed for e in cf}) == len(cf)  # every episode another lead driver
    nc = get_suite("ncap-v1").episodes("dev")
    assert len({e.id for e in nc}) == 24 and all(e.id.startswith("ncap/") for e in nc)
    for e in nc:  # test-track deviations stay small
        nominal = scenario_type(e.id).build(seed=0).params
        assert 0.0 <= e.params["v_ego"] - nominal["v_ego"] <= 1.0


def test_malicious_uses_malicious_drivers():
    episodes = get_suite("malicious-v3").episodes("test")
    ids = {e.id for e in episodes}
    assert ids == set(MALICIOUS_SINGLELANE) | set(MALICIOUS_NCAP)
    for e in episodes:
        if e.id.startswith("singlelane/"):
            assert e.drivers == "malicious"
            mpc = [v.driver for v in e.vehicles[1:] if v.driver.model == "mpc"]
            assert mpc and all(d.params["c_tg"] <= 0.8 for d in mpc)  # malicious: short time gaps
        else:
            assert e.id in MALICIOUS_NCAP


def test_episodes_rebuild_the_recorded_entries():
    s = get_suite("malicious-v3")
    for e, sc in zip(s.to_dict()["episodes"]["dev"], s.episodes("dev")):
        assert (sc.id, sc.params, sc.seed, sc.drivers) == (e["id"], e["params"], e["seed"], e["drivers"])


def test_hash_changes_with_any_parameter_and_ignores_key_order():
    s = get_suite("ncap-v1")
    d = s.to_dict()
    assert definition_hash(d) == s.hash()
    reordered = json.loads(json.dumps(d, sort_keys=True))
    reordered = {k: reordered[k] for k in reversed(list(reordered))}
    reordered["episodes"]["test"] = [dict(reversed(list(e.items()))) for e in reordered["episodes"]["test"]]
    assert definition_hash(reordered) == s.hash() and definition_hash(reordered, "test") == s.hash("test")
    for split in ("dev", "test"):
        edited = s.to_dict()
        edited["episodes"][split][5]["params"]["gap"] += 1e-9
        assert definition_hash(edited) != s.hash()
        assert definition_hash(edited, split) != s.hash(split)
        other = "test" if split == "dev" else "dev"
        assert definition_hash(edited, other) == s.hash(other)  # the other split's hash is its own
        changed = Suite.from_dict(edited, s)
        assert changed.hash() != s.hash()
        assert changed.episodes(split)[5].params["gap"] == pytest.approx(s.episodes(split)[5].params["gap"] + 1e-9)
    for key, value in (("seed", 1), ("drivers", "atypical"), ("id", "ncap/ccrs/15")):
        edited = s.to_dict()
        edited["episodes"]["test"][0][key] = value
        assert definition_hash(edited) != s.hash()
    assert s.to_dict() == d  # to_dict hands out copies


def test_shipped_data_is_what_the_code_generates():
    for name in NAMES:
        shipped = read_definition(data_path(name))
        generated = template(name).materialise()
        assert shipped == generated
        assert file_text(generated) == data_path(name).read_text(encoding="utf-8")  # byte for byte
        assert definition_hash(shipped) == get_suite(name).hash() == template(name).hash()
        get_suite(name).verify()  # and the episodes still build to the recorded content


def test_verify_and_file_check_catch_edits(tmp_path):
    s = get_suite("carfollowing-v1")
    edited = s.to_dict()
    edited["episodes"]["test"][2]["params"]["brake_decel"] = 5.5
    with pytest.raises(ValueError, match="episode 2"):
        Suite.from_dict(edited, s).verify("test")
    doc = json.loads(data_path("carfollowing-v1").read_text())
    doc["definition"]["episodes"]["dev"][0]["seed"] += 1
    bad = tmp_path / "carfollowing-v1.json"
    bad.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="does not match its sha256"):
        read_definition(bad)
    bad.write_text(data_path("carfollowing-v1").read_text()[:500])
    with pytest.raises(ValueError, match="not valid JSON"):
        read_definition(bad)


def test_every_suite_is_pinned_to_its_shipped_definition():
    assert set(suites.PINNED) == set(NAMES)
    for name in NAMES:
        assert suites.PINNED[name] == definition_hash(read_definition(data_path(name))) == get_suite(name).hash()


def test_an_edited_data_file_with_a_recomputed_sha256_is_refused_by_name(tmp_path, monkeypatch):
    """Recomputing the file's own sha256 after an edit is not enough: the package pins the
    released hash, and get_suite (hence the leaderboard) names the file it refuses."""
    for f in suites.DATA_DIR.glob("*.json"):
        (tmp_path / f.name).write_bytes(f.read_bytes())
    d = read_definition(data_path("ncap-v1"))
    d["episodes"]["test"][0]["params"]["v_ego"] = round(d["episodes"]["test"][0]["params"]["v_ego"] + 0.5, 6)
    (tmp_path / "ncap-v1.json").write_text(suites.file_text(d), encoding="utf-8")
    read_definition(tmp_path / "ncap-v1.json")  # consistent with its own sha256 ...
    monkeypatch.setattr(suites, "DATA_DIR", tmp_path)
    suites._load.cache_clear()
    try:
        with pytest.raises(ValueError, match=r"ncap-v1\.json.*not the released ncap-v1.*pins 4c807fa89388"):
            get_suite("ncap-v1")
        from acc_gym.leaderboard import run_leaderboard

        with pytest.raises(ValueError, match=r"ncap-v1\.json.*not the released"):
            run_leaderboard(["ncap-v1"], "test", ["constant"], episodes=1)
        get_suite("carfollowing-v1")  # the untouched ones still load
    finally:
        suites._load.cache_clear()


def test_to_dict_is_json_safe_and_complete():
    d = get_suite("singlelane-v3").to_dict()
    assert set(d) >= {"name", "version", "family", "env_id", "root_seeds", "episodes"}
    assert json.loads(json.dumps(d, allow_nan=False)) == d
    e = d["episodes"]["test"][0]
    assert set(e) == {"id", "params", "seed", "drivers"}
