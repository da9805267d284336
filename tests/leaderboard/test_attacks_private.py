"""Round two: the private split, the results key and root.

* the secret and the results key come only from files their owner alone can read, never from
  the environment; a private run's results are the host's only (0600 files in a 0700
  directory), so an earlier private run's results are no help to a later controller;
* a stranger's code never runs as root without a user id of its own unless the host passes
  ``--allow-root``, and then every report says so; the built-ins always run.
"""

import json
import re
import os
import stat
import sys
from pathlib import Path

import pytest

from acc_gym.cli import main
from acc_gym.leaderboard import run_leaderboard
from acc_gym.leaderboard import sandbox as sandbox_mod
from acc_gym.leaderboard.results import KEY_ENV, KEY_FILE_ENV, load_results
from acc_gym.suites import private

HERE = Path(__file__).resolve().parent
SECRET = "a host's private-split secret 42"
KEY = "host results key 0123456789abcdef"
ROOT = os.geteuid() == 0
WHY = "not readable by other users: /root/venv/bin/python (/root is mode 0700)"


def _file(path: Path, text: str, mode: int) -> Path:
    path.write_text(text)
    path.chmod(mode)
    return path


@pytest.mark.parametrize("mode", [0o644, 0o640, 0o604, 0o660])
def test_a_secret_others_may_read_is_refused_naming_its_mode(tmp_path, mode):
    f = _file(tmp_path / "secret.txt", SECRET, mode)
    with pytest.raises(ValueError, match=f"secret file .*secret.txt' is mode {mode:04o}: group or others may read"):
        private.read_secret(f)
    with pytest.raises(SystemExit):  # the CLI: a usage error naming the mode
        main(["leaderboard", "--suite", "ncap-v1", "--split", "private", "--secret", str(f), "--controllers",
              "constant", "--episodes", "1", "--out", str(tmp_path / "b")])
    assert not (tmp_path / "b").exists()
    f.chmod(0o600)
    assert private.read_secret(f) == SECRET.encode()


def test_the_secret_never_comes_from_the_environment(tmp_path, monkeypatch):
    monkeypatch.setenv(private.SECRET_ENV, SECRET)
    with pytest.raises(ValueError, match="ACC_GYM_LEADERBOARD_SECRET is set: the secret is read from a file only"):
        private.read_secret(_file(tmp_path / "s", SECRET, 0o600))
    monkeypatch.delenv(private.SECRET_ENV)
    with pytest.raises(ValueError, match="needs a secret: --secret FILE"):
        private.read_secret()


def test_the_results_key_comes_from_a_private_file_for_a_run(tmp_path, monkeypatch):
    monkeypatch.setenv(KEY_FILE_ENV, str(_file(tmp_path / "key", KEY, 0o644)))
    with pytest.raises(ValueError, match=r"results key .* is mode 0644: group or others may read"):
        run_leaderboard(["ncap-v1"], "test", ["constant"], episodes=1, out=tmp_path / "b", waves=False, robustness=False)
    monkeypatch.delenv(KEY_FILE_ENV)
    monkeypatch.setenv(KEY_ENV, KEY)
    with pytest.raises(ValueError, match="results key is in the environment .*ACC_GYM_RESULTS_KEY_FILE"):
        run_leaderboard(["ncap-v1"], "test", ["constant"], episodes=1, out=tmp_path / "b", waves=False, robustness=False)
    assert not (tmp_path / "b").exists()


@pytest.fixture(scope="module")
def private_run(tmp_path_factory):
    base = tmp_path_factory.mktemp("private")
    os.chmod(base, 0o755)  # others may enter: only the run's own modes keep them out
    secret = _file(base / "secret.txt", SECRET, 0o600)
    out = base / "board"
    assert main(["leaderboard", "--suite", "ncap-v1", "--split", "private", "--secret", str(secret),
                 "--controllers", "constant", "--episodes", "2", "--out", str(out), "--no-string-stability",
                 "--no-iso15622", "--no-waves", "--no-robustness"]) == 0
    return out


def test_a_private_runs_files_are_the_hosts_only(private_run):
    out = private_run
    assert stat.S_IMODE(out.stat().st_mode) == 0o700
    files = [p for p in out.rglob("*")]
    assert any(p.name == "results.json" for p in files) and any(p.suffix == ".log" for p in files)
    for p in files:
        assert stat.S_IMODE(p.stat().st_mode) == (0o700 if p.is_dir() else 0o600), p
    assert load_results(out)["manifest"]["split"] == "private"


@pytest.mark.skipif(not ROOT, reason="reading as another user id needs root to become one")
def test_an_earlier_private_runs_results_are_unreadable_by_another_user(private_run):
    """What a controller under its own user id gets when it reads them: nothing."""
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # a process as a controller's user id would be
        os.close(read)
        try:
            os.setgroups([])
            os.setgid(sandbox_mod.UID_BASE + 77)
            os.setuid(sandbox_mod.UID_BASE + 77)
            try:
                (private_run / "results.json").read_bytes()
                os.write(write, b"read")
            except PermissionError:
                os.write(write, b"refused")
        finally:
            os._exit(0)
    os.close(write)
    os.waitpid(pid, 0)
    assert os.read(read, 100) == b"refused"


def test_a_stranger_on_the_private_split_needs_its_own_user_id(tmp_path, monkeypatch):
    monkeypatch.setattr(sandbox_mod, "own_uid_possible", lambda extra=(): (False, WHY))
    monkeypatch.syspath_prepend(str(HERE))
    with pytest.raises(RuntimeError, match=r"'cheats:ReadsResults' on the private split without a user id .*"
                                           r"/root is mode 0700.*could read the secret"):
        run_leaderboard(["ncap-v1"], "private", ["acc", "cheats:ReadsResults"], episodes=1, secret=SECRET,
                        allow_root=True, out=tmp_path / "b", waves=False, robustness=False)


@pytest.mark.skipif(not sandbox_mod.own_uid_possible()[0], reason=f"no own user id here: "
                                                                  f"{sandbox_mod.own_uid_possible()[1]}")
def test_a_controller_reading_an_earlier_private_run_gains_nothing(private_run, tmp_path, monkeypatch):
    (HERE / "cheats_private_target.txt").write_text(str(private_run))
    try:
        monkeypatch.syspath_prepend(str(HERE))
        r = run_leaderboard(["ncap-v1"], "private", ["cheats:ReadsResults"], episodes=1, secret=SECRET,
                            out=tmp_path / "b", string_stability=False, iso15622=False, waves=False, robustness=False)
    finally:
        (HERE / "cheats_private_target.txt").unlink()
    text = (tmp_path / "b" / r["controllers"][0]["log"]).read_text()
    # refused either by the results' modes (0600 in 0700) or, as root, because the jail's private /tmp
    # does not hold the host's files at all
    assert re.search(r"CHEAT refused (PermissionError|FileNotFoundError)", text) and "CHEAT read" not in text


# -- root --------------------------------------------------------------------------------------------
needs_root = pytest.mark.skipif(not ROOT, reason="the refusal is for a runner that is root")


@needs_root
def test_a_stranger_is_refused_as_root_without_its_own_user_id(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(sandbox_mod, "own_uid_possible", lambda extra=(): (False, WHY))
    monkeypatch.syspath_prepend(str(HERE))
    with pytest.raises(RuntimeError, match=r"refusing to run 'cheats:FullThrottle' as root without a user id of its "
                                           r"own \(not readable .*/root is mode 0700\).*a system Python.*--allow-root"):
        run_leaderboard(["ncap-v1"], "test", ["acc", "cheats:FullThrottle"], episodes=1, out=tmp_path / "b", waves=False, robustness=False)
    assert not (tmp_path / "b").exists()
    code = main(["leaderboard", "--suite", "ncap-v1", "--controllers", "cheats:FullThrottle", "--episodes", "1",
                 "--out", str(tmp_path / "b")])
    assert code == 1 and "refusing to run 'cheats:FullThrottle' as root" in capsys.readouterr().err


@needs_root
def test_with_allow_root_every_report_says_so_and_builtins_need_no_flag(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(sandbox_mod, "own_uid_possible", lambda extra=(): (False, WHY))
    monkeypatch.syspath_prepend(str(HERE))
    out = tmp_path / "b"
    code = main(["leaderboard", "--suite", "ncap-v1", "--controllers", "constant", "cheats:FullThrottle",
                 "--episodes", "1", "--out", str(out), "--allow-root", "--no-string-stability", "--no-iso15622", "--no-waves", "--no-robustness"])
    assert code == 0
    terminal = capsys.readouterr().out
    words = "WARNING: controllers ran as root without a user id of their own"
    assert words in terminal and "/root is mode 0700" in terminal
    doc = json.loads((out / "results.json").read_text())
    assert doc["results"]["manifest"]["sandbox"]["warning"].startswith(words)
    assert words in (out / "leaderboard.md").read_text() and words in (out / "report.html").read_text()
    alone = run_leaderboard(["ncap-v1"], "test", ["constant", "idm"], episodes=1, string_stability=False,
                            iso15622=False, waves=False, robustness=False)  # the package's own code: no flag, no warning
    assert alone["manifest"]["sandbox"]["warning"] is None
    assert [c["status"] for c in alone["controllers"]] == ["ok", "ok"]
    assert sys.path  # untouched
