"""Integrity of a leaderboard's results: signed results.json, controllers' code digests,
the private split as the leaderboard runs it."""

import json
import os
import sys

import pytest

from acc_gym.cli import main
from acc_gym.leaderboard import load_results, run_leaderboard
from acc_gym.leaderboard.provenance import code_digest, files_digest
from acc_gym.leaderboard.results import KEY_ENV, KEY_FILE_ENV, checksum, results_text, signature
from acc_gym.suites import get_suite
from acc_gym.suites import private
from acc_gym.suites.suite import entry

KEY = "host results key 0123456789abcdef"
SECRET = "a host's private-split secret 42"


@pytest.fixture(scope="module")
def signed_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("signed") / "board"
    key_file = out.parent / "key"
    key_file.write_text(KEY)
    key_file.chmod(0o600)  # the host's only: a key others may read is refused
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv(KEY_FILE_ENV, str(key_file))
        r = run_leaderboard(["ncap-v1"], "test", ["constant", "idm"], episodes=2, out=out, report=False,
                            string_stability=False, iso15622=False, waves=False, robustness=False)  # the columns: not what is signed here
    return r, out


def test_results_are_signed_when_the_host_sets_a_key(signed_run, monkeypatch, tmp_path):
    r, out = signed_run
    doc = json.loads((out / "results.json").read_text())
    assert doc["hmac"]["alg"] == "hmac-sha256" and KEY not in (out / "results.json").read_text()
    assert doc["hmac"] == signature(doc["results"], KEY.encode())
    assert r["manifest"]["results_key_id"] == doc["hmac"]["key_id"]
    monkeypatch.setenv(KEY_ENV, KEY)
    results = load_results(out)
    assert results["ranking"] == r["ranking"]
    # a rewritten file with a recomputed, valid checksum: detected once a key is set
    forged = json.loads(json.dumps(results))
    worst = forged["ranking"][-1]
    c = next(c for c in forged["controllers"] if c["name"] == worst)
    c["summary"]["overall"]["mean_points"] = 100.0
    forged["ranking"] = [worst] + [n for n in forged["ranking"] if n != worst]
    path = tmp_path / "results.json"
    kept = {**doc, "results": forged, "sha256": checksum(forged)}  # the old signature, a new checksum
    path.write_text(json.dumps(kept))
    with pytest.raises(ValueError, match=r"results\.json.*fail verification: their HMAC does not match"):
        load_results(path)
    path.write_text(results_text(forged, key=None))  # unsigned, checksum valid
    with pytest.raises(ValueError, match=r"results\.json.*not signed"):
        load_results(path)
    path.write_text(results_text(forged, key=b"the forger's own key, 32 bytes.."))
    with pytest.raises(ValueError, match="fail verification.*another key"):
        load_results(path)
    monkeypatch.delenv(KEY_ENV)
    assert load_results(path) == forged  # without the key only the checksum can be checked
    key_file = tmp_path / "key"
    key_file.write_text(KEY + "\n")
    key_file.chmod(0o600)
    monkeypatch.setenv(KEY_FILE_ENV, str(key_file))
    assert load_results(out) == results
    with pytest.raises(ValueError, match="fail verification"):
        load_results(path)


def test_a_bad_results_key_is_refused_before_anything_runs(tmp_path, monkeypatch):
    short = tmp_path / "short"
    short.write_text("short")
    short.chmod(0o600)
    monkeypatch.setenv(KEY_FILE_ENV, str(short))
    with pytest.raises(ValueError, match="results key .*ACC_GYM_RESULTS_KEY_FILE.* 5 bytes"):
        run_leaderboard(["ncap-v1"], "test", ["constant"], episodes=1, out=tmp_path / "b")
    monkeypatch.setenv(KEY_FILE_ENV, str(tmp_path / "nope"))
    with pytest.raises(ValueError, match=r"cannot read the results key file .*nope"):
        run_leaderboard(["ncap-v1"], "test", ["constant"], episodes=1, out=tmp_path / "b")
    assert not (tmp_path / "b").exists()


def test_results_record_each_controllers_code(signed_run):
    r, _ = signed_run
    import acc_gym_agents

    package = os.path.dirname(acc_gym_agents.__file__)
    for c in r["controllers"]:
        assert c["code"]["sha256"] == files_digest(package)[0] and c["code"]["module"] == "acc_gym_agents"


def test_code_digest_reads_files_without_running_them(tmp_path):
    marker = tmp_path / "ran"
    pkg = tmp_path / "mylaws"
    pkg.mkdir()
    (pkg / "__init__.py").write_text(f"open({str(marker)!r}, 'w').close()\nclass Law: pass\n")
    (pkg / "gains.json").write_text('{"k": 0.3}')
    search = [str(tmp_path)] + sys.path
    first = code_digest("mylaws.sub:Law", search)
    assert not marker.exists()  # located, never imported
    assert first["kind"] == "module" and first["files"] == 2 and first["path"] == str(pkg)
    (pkg / "__pycache__").mkdir()
    (pkg / "__pycache__" / "x.cpython-311.pyc").write_bytes(b"\0")
    assert code_digest("mylaws:Law", search)["sha256"] == first["sha256"]  # caches do not count
    (pkg / "gains.json").write_text('{"k": 0.4}')  # a data file is part of the code
    assert code_digest("mylaws:Law", search)["sha256"] != first["sha256"]
    assert code_digest("nowhere_to_be_found:X", search)["sha256"] is None
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    (run_dir / "model.zip").write_bytes(b"weights")
    d = code_digest(str(run_dir), search)
    assert d["kind"] == "files" and d["files"] == 1 and d["sha256"] == files_digest(run_dir)[0]


def test_the_private_split_runs_unshipped_episodes_and_records_only_a_commitment(tmp_path, capsys):
    secret_file = tmp_path / "secret"
    secret_file.write_text(SECRET)
    secret_file.chmod(0o600)
    out = tmp_path / "board"
    code = main(["leaderboard", "--suite", "carfollowing-v1", "--split", "private", "--secret", str(secret_file),
                 "--controllers", "constant", "--episodes", "3", "--out", str(out), "--no-report",
                 "--no-string-stability", "--no-iso15622", "--no-waves", "--no-robustness"])
    assert code == 0
    text = (out / "results.json").read_text()
    r = load_results(out)
    m = r["manifest"]
    assert m["split"] == "private" and m["secret_commitment"] == private.commitment(SECRET.encode())
    assert SECRET not in text and SECRET.encode().hex() not in text
    assert m["suites"][0]["root_seed"] is None
    expected = private.private_episodes(get_suite("carfollowing-v1"), SECRET.encode())[:3]
    ran = [(e["scenario"], e["scenario_seed"]) for e in r["controllers"][0]["episodes"]]
    assert ran == [(sc.id, sc.seed) for sc in expected]
    test_split = {repr(entry(sc)) for sc in get_suite("carfollowing-v1").episodes("test")}
    assert not {repr(entry(sc)) for sc in expected} & test_split
    with pytest.raises(ValueError, match="private split only"):
        run_leaderboard(["ncap-v1"], "test", ["constant"], episodes=1, secret=SECRET)
    with pytest.raises(ValueError, match="needs a secret"):
        run_leaderboard(["ncap-v1"], "private", ["constant"], episodes=1)


# -- a controller is ok only when exactly the scheduled records arrived ----------------------------------
def _jobs():
    from acc_gym.leaderboard.isolation import Job

    suite = get_suite("ncap-v1")
    return [Job(suite.name, "test", k, suite.env_id, sc) for k, sc in enumerate(suite.episodes("test")[:3])]


def _record(job, **changes):
    """What the simulation sends for ``job`` (the identity fields; the rest is not checked here)."""
    return {"suite": job.suite, "split": job.split, "episode": job.episode, "scenario": job.scenario.id,
            "scenario_seed": job.scenario.seed, "score": 50.0, **changes}


def _receive(jobs, messages):
    """Feed ``messages`` to the runner's receive path, as a simulation process would send them."""
    import multiprocessing
    from types import SimpleNamespace

    from acc_gym.leaderboard.isolation import Ledger, Outcome, _Running

    r = object.__new__(_Running)  # the receiving half only: no simulation process behind it
    r.reference, r.jobs, r.outcome, r.ledger = "x", jobs, Outcome("x", episodes=[]), Ledger(jobs)
    r.conn, sender = multiprocessing.Pipe(duplex=False)
    r.process = SimpleNamespace(exitcode=0)
    for m in [*messages, ("closed", None)]:
        sender.send(m)
    assert r.receive() is True
    return r.outcome, r.ledger


def test_exactly_the_scheduled_records_make_a_controller_ok():
    jobs = _jobs()
    outcome, ledger = _receive(jobs, [("episode", j, _record(jobs[j])) for j in (2, 0, 1)] + [("done", None)])
    assert outcome.status == "ok" and outcome.reason is None and sorted(ledger.received) == [0, 1, 2]


@pytest.mark.parametrize("case", ["missing", "duplicated", "other episode", "other seed", "other suite",
                                  "other split", "unscheduled job", "record for another job"])
def test_a_record_off_the_schedule_makes_a_controller_failed(case):
    jobs = _jobs()
    records = {j: _record(jobs[j]) for j in range(3)}
    extra = []
    if case == "missing":
        del records[1]
        words = f"2 of 3 scheduled episodes arrived; missing: 1 (ncap-v1 test episode 1, {jobs[1].scenario.id}, " \
                f"seed {jobs[1].scenario.seed})"
    elif case == "duplicated":
        extra = [("episode", 0, _record(jobs[0]))]
        words = f"job 0 (ncap-v1 test episode 0, {jobs[0].scenario.id}, seed {jobs[0].scenario.seed}) reported twice"
    elif case == "other episode":
        records[1]["episode"] = 7
        words = "the record for job 1 is for ('ncap-v1', 'test', 7,"
    elif case == "other seed":
        records[2]["scenario_seed"] = jobs[2].scenario.seed + 1
        words = f"{jobs[2].scenario.seed + 1}), but the schedule says ('ncap-v1', 'test', 2, " \
                f"'{jobs[2].scenario.id}', {jobs[2].scenario.seed})"
    elif case == "other suite":
        records[0]["suite"] = "carfollowing-v1"
        words = "the record for job 0 is for ('carfollowing-v1',"
    elif case == "other split":
        records[0]["split"] = "dev"
        words = "the record for job 0 is for ('ncap-v1', 'dev',"
    elif case == "unscheduled job":
        extra = [("episode", 3, _record(jobs[0], episode=3))]
        words = "a record for job 3, which is not scheduled (jobs 0..2)"
    else:  # the record of job 0 arrives as job 1's: each is a real episode, but not the one scheduled there
        records[1] = _record(jobs[0])
        words = f"the record for job 1 is for ('ncap-v1', 'test', 0, '{jobs[0].scenario.id}'"
    messages = [("episode", j, rec) for j, rec in records.items()] + extra + [("done", None)]
    outcome, _ = _receive(jobs, messages)
    assert outcome.status == "failed" and words in outcome.reason, outcome.reason


# -- the private split defeats a controller that knows the shipped episodes by their first observation ---
def test_first_observations_identify_test_episodes_but_no_private_one():
    """A controller can compute, offline, every shipped test episode's first observation
    (cheats.first_observation_table) and so know on its first step which test episode it is
    in -- and tune to it. On the private split it finds no episode: no private first
    observation identifies a test episode."""
    sys.path.insert(0, os.path.dirname(__file__))
    try:
        from cheats import first_observation, first_observation_table
    finally:
        sys.path.pop(0)
    identified_on_test = 0
    for name in ("ncap-v1", "malicious-v3", "carfollowing-v1"):
        suite = get_suite(name)
        table = first_observation_table(suite)
        test = suite.episodes("test")
        for k, sc in enumerate(test):  # on test, the lookup never names a wrong episode ...
            found = table.get(first_observation(suite, sc), [])
            assert k in found, (name, k)
            identified_on_test += len(found) == 1
        for sc in private.private_episodes(suite, SECRET.encode()):  # ... on private it names none
            found = table.get(first_observation(suite, sc), [])
            assert len(found) != 1, (name, sc.id, found)  # several: car following's speed, shared by 5
    assert identified_on_test > 0  # the cheat is real on the shipped split
