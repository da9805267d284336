"""Issue 16's cheats, each as a small controller (cheats.py), gain nothing on the leaderboard.

One leaderboard run holds the honest linear ACC and every cheat; a second run holds the
ACC alone (two episodes of each suite, without the columns: the cheats act in the episodes). Under
``--sandbox bwrap`` one more run holds the ACC, the cheats bwrap must contain and the ones that fill
its working directory, /tmp and /dev/shm (:data:`LIMITS`). The cheats rank below the ACC or fail, the ACC's episodes are the same bits
with or without them, results.json is what the run returned, and nothing the run
started is alive when it returns. The cheats that need the controller's own user id to
be stopped (signals, writing files) are checked only where the runner can give it one
(root, and the interpreter readable by other users: CI makes it so).
"""

import os
import stat
import tempfile
import time
from pathlib import Path

import pytest

from acc_gym.leaderboard import load_results, run_leaderboard
from acc_gym.leaderboard import sandbox as sandbox_mod
from acc_gym.leaderboard.sandbox import UID_BASE, Limits, bwrap_problem, own_uid_possible, processes_of

HERE = Path(__file__).resolve().parent
SUITES = ["ncap-v1", "carfollowing-v1"]
UID_ISOLATED, WHY_NOT = own_uid_possible()
# KillsOthers SIGKILLs every process it can see (the test runner too): only where it cannot
CHEATS = ["cheats:FullThrottle", "cheats:PatchesScorer", "cheats:Introspects", "cheats:FreezesClock",
          "cheats:ForgesDone", "cheats:Lingers", "cheats:EditsFiles", "cheats:Floods"] + \
         (["cheats:KillsOthers"] if UID_ISOLATED else [])
BWRAP_PROBLEM = bwrap_problem(UID_BASE + 99 if UID_ISOLATED else None)  # installed, and allowed its namespaces
LIMITS = Limits(tmp_bytes=16 << 20, disk_bytes=64 << 20, file_bytes=4 << 20)  # the bwrap run's
DISK_REASON = "killed: its working directory held more than the disk limit of 64 MiB (--disk-limit)"
needs_uid = pytest.mark.skipif(not UID_ISOLATED, reason=f"the controller cannot get its own user id here ({WHY_NOT}); "
                                                        f"without it a controller can signal and write as the runner")


def episodes(results, name):
    c = next(c for c in results["controllers"] if c["name"] == name)
    return [(e["suite"], e["episode"], e["scenario"], e["score"], e["points"], e["metrics"]) for e in c["episodes"]]


def log_text(out: Path, results, name) -> str:
    c = next(c for c in results["controllers"] if c["name"] == name)
    return (out / c["log"]).read_text(errors="replace")


@pytest.fixture(scope="module")
def runs():
    with pytest.MonkeyPatch.context() as mp:
        mp.syspath_prepend(str(HERE))
        base = Path(tempfile.mkdtemp(prefix="acc-gym-cheats-"))
        os.chmod(base, 0o755)  # the lingering grandchild may look for it; it must still not write there
        out = base / "board"
        target = HERE / "cheats_target.txt"
        target.write_text(str(out))
        import acc_gym
        import acc_gym.envs.core

        watched = [Path(acc_gym.envs.core.__file__), Path(acc_gym.__file__).parent / "suites" / "data" / "ncap-v1.json"]
        before = {p: p.read_bytes() for p in watched}
        t0 = time.monotonic()
        mixed = run_leaderboard(SUITES, "test", ["acc", *CHEATS], episodes=2, workers=2, step_budget=1.0,
                                string_stability=False, iso15622=False, waves=False, robustness=False,
                                budget=300, out=out, allow_root=True)  # as root without own uids: say so
        wall = time.monotonic() - t0
        alone = run_leaderboard(SUITES, "test", ["acc"], episodes=2, workers=1, string_stability=False,
                                iso15622=False, waves=False, robustness=False)
        yield {"mixed": mixed, "alone": alone, "out": out, "before": before, "wall": wall}
        target.unlink()


def test_every_cheat_ranks_below_the_honest_acc_or_fails(runs):
    r = runs["mixed"]
    by = {c["name"]: c for c in r["controllers"]}
    acc = by["acc"]
    assert acc["status"] == "ok" and acc["rank"] == 1
    for name in CHEATS:
        c = by[name]
        if c["status"] == "ok":
            assert c["summary"]["overall"]["mean_points"] < acc["summary"]["overall"]["mean_points"] - 10, name
            assert c["rank"] > acc["rank"], name
    # the ones that collide get no points for those episodes, whatever they did to their own scorer
    for name in ("cheats:FullThrottle", "cheats:PatchesScorer", "cheats:Introspects"):
        eps = by[name]["episodes"]
        assert len(eps) == 4 and all(e["score"] < 100.0 for e in eps)
        assert all(e["points"] == 0.0 for e in eps if e["metrics"]["collision"] and e["preventable"])
        assert sum(e["metrics"]["collision"] for e in eps) >= 2


def test_the_honest_controller_is_untouched_by_the_cheaters(runs):
    assert episodes(runs["mixed"], "acc") == episodes(runs["alone"], "acc")


def test_the_controller_sees_no_simulator_and_its_clocks_are_its_own(runs):
    r, out = runs["mixed"], runs["out"]
    assert "CHEAT found 0" in log_text(out, r, "cheats:Introspects")
    by = {c["name"]: c for c in r["controllers"]}
    assert by["cheats:FreezesClock"]["status"] == "failed"
    assert "step budget of 1 s" in by["cheats:FreezesClock"]["reason"]
    assert by["cheats:ForgesDone"]["status"] == "failed" and "protocol" in by["cheats:ForgesDone"]["reason"]
    assert len(by["cheats:ForgesDone"]["episodes"]) < 4  # what it finished is kept, not ranked


def test_results_json_is_what_the_run_returned_and_stays_so(runs, tmp_path):
    r, out = runs["mixed"], runs["out"]
    time.sleep(1.0)  # a lingering grandchild would have rewritten it by now
    stored = load_results(out / "results.json")
    expected = {k: v for k, v in r.items() if k != "files"}
    assert stored == expected
    assert "rewrote results" not in log_text(out, r, "cheats:Lingers")
    from cheats import forged_results_text  # what it would have written: a file that loads (unsigned), it first

    forged = tmp_path / "results.json"
    forged.write_text(forged_results_text(out / "results.json", "cheats:Lingers"))
    assert load_results(forged, key=None)["ranking"][0] == "cheats:Lingers" != stored["ranking"][0]


def test_nothing_the_run_started_is_alive(runs):
    r, out = runs["mixed"], runs["out"]
    text = log_text(out, r, "cheats:Lingers")
    pids = [int(line.split()[-1]) for line in text.splitlines() if line.startswith("CHEAT grandchild")]
    assert pids, text[:500]
    for pid in pids:
        assert not Path(f"/proc/{pid}").exists() or Path(f"/proc/{pid}/stat").read_text().split()[2] == "Z"
    if UID_ISOLATED:
        uids = [UID_BASE + 100 * (os.getpid() % 1_000_000) + k for k in range(len(CHEATS) + 1)]
        assert not any(processes_of(u) for u in uids)


def test_children_output_goes_to_their_logs_not_the_runners(runs, capfd):
    r, out = runs["mixed"], runs["out"]
    text = log_text(out, r, "cheats:Floods")
    assert "1  cheats:Floods  ok  100.0" in text and len(text) > 3 << 20
    captured = capfd.readouterr()
    assert "cheats:Floods  ok  100.0" not in captured.out and "xxxxxxxx" not in captured.out


@needs_uid
def test_a_controller_cannot_signal_its_siblings_or_the_runner(runs):
    r, out = runs["mixed"], runs["out"]
    text = log_text(out, r, "cheats:KillsOthers")
    assert "CHEAT killed 0 refused" in text
    by = {c["name"]: c for c in r["controllers"]}
    assert all(by[n]["status"] == "ok" for n in ("acc", "cheats:FullThrottle", "cheats:Floods"))


@needs_uid
def test_a_controller_cannot_write_the_package_the_suites_or_the_output(runs):
    r, out = runs["mixed"], runs["out"]
    text = log_text(out, r, "cheats:EditsFiles")
    assert text.count("CHEAT refused") == 2 and "CHEAT writable" not in text
    for path, content in runs["before"].items():
        assert path.read_bytes() == content
    sb = r["manifest"]["sandbox"]
    assert (sb["kind"], sb["uid_isolated"], sb["why_not"], sb["warning"]) == ("process", True, None, None)
    mode = (out / "results.json").stat().st_mode
    assert not mode & stat.S_IWOTH


def test_an_unusable_bwrap_is_refused_before_anything_runs(monkeypatch, tmp_path):
    """A bwrap that cannot start a sandbox (a container refusing its namespaces: here a
    stand-in program that fails) stops the run with bwrap's reason, instead of ranking every
    controller as crashed."""
    bin_dir = Path(tempfile.mkdtemp(prefix="acc-gym-fake-bwrap-"))
    bin_dir.chmod(0o755)  # run under the controllers' user id where they get one
    fake = bin_dir / "bwrap"
    fake.write_text("#!/bin/sh\necho 'bwrap: No permissions to create new namespace' >&2\nexit 1\n")
    fake.chmod(0o755)
    monkeypatch.setattr(sandbox_mod, "bwrap_available", lambda: str(fake))
    monkeypatch.setattr(sandbox_mod, "_BWRAP_PROBES", {})
    out = tmp_path / "board"
    with pytest.raises(RuntimeError, match="bwrap.*not usable.*No permissions to create new namespace"):
        run_leaderboard(["ncap-v1"], "test", ["acc"], episodes=1, out=out, sandbox="bwrap", string_stability=False,
                        allow_root=True, waves=False, robustness=False)
    assert not out.exists()


BWRAP_CHEATS = ["cheats:KillsOthers", "cheats:EditsFiles", "cheats:Introspects"]


@pytest.fixture(scope="module")
def bwrap_run():
    if BWRAP_PROBLEM is not None:
        pytest.skip(f"--sandbox bwrap cannot run here: {BWRAP_PROBLEM}")
    with pytest.MonkeyPatch.context() as mp:
        mp.syspath_prepend(str(HERE))
        out = Path(tempfile.mkdtemp(prefix="acc-gym-bwrap-")) / "board"
        r = run_leaderboard(SUITES, "test", ["acc", *BWRAP_CHEATS, "cheats:FillsDisk", "cheats:FillsTmp"],
                            string_stability=False, iso15622=False, waves=False, robustness=False, report=False, limits=LIMITS,
                            episodes=2, workers=2, budget=300, out=out, sandbox="bwrap", allow_root=True)
    return r, out


def test_bwrap_sandbox_contains_the_cheats_too(runs, bwrap_run):
    r, out = bwrap_run
    assert r["manifest"]["sandbox"]["kind"] == "bwrap"
    assert episodes(r, "acc") == episodes(runs["alone"], "acc")  # the honest one, unaffected by the limits too
    text = log_text(out, r, "cheats:EditsFiles")
    assert text.count("CHEAT refused") == 2 and "CHEAT writable" not in text  # a read-only root, even as root
    assert "CHEAT found 0" in log_text(out, r, "cheats:Introspects")
    by = {c["name"]: c for c in r["controllers"]}
    assert all(by[n]["status"] == "ok" for n in ("acc", *BWRAP_CHEATS)), [by[n]["reason"] for n in BWRAP_CHEATS]
    for path, content in runs["before"].items():
        assert path.read_bytes() == content


def test_bwrap_a_working_directory_past_the_disk_limit_fails_naming_it(bwrap_run):
    r, out = bwrap_run
    c = next(c for c in r["controllers"] if c["name"] == "cheats:FillsDisk")
    assert c["status"] == "failed" and DISK_REASON in c["reason"], c["reason"]
    assert c["rank"] is None and c["summary"] is None  # gains nothing
    assert "CHEAT wrote" in log_text(out, r, "cheats:FillsDisk")  # in files under the 4 MiB per-file cap
    assert r["manifest"]["sandbox"]["limits"]["disk_bytes"] == 64 << 20


def test_bwrap_tmp_and_dev_shm_are_sized_and_filling_them_fails_cleanly(bwrap_run):
    r, out = bwrap_run
    c = next(c for c in r["controllers"] if c["name"] == "cheats:FillsTmp")
    assert c["status"] == "failed" and "OSError: [Errno 28] No space left on device" in c["reason"], c["reason"]
    text = log_text(out, r, "cheats:FillsTmp")
    assert "CHEAT no room in /dev/shm 28" in text and "CHEAT no room in /tmp 28" in text, text
    assert "CHEAT filled" not in text
    assert not list(Path("/tmp").glob("acc-gym-fill-*")) and not list(Path("/dev/shm").glob("acc-gym-fill-*"))
    assert r["manifest"]["sandbox"]["tmp"] == "private (bwrap tmpfs on /tmp and /dev/shm)"
