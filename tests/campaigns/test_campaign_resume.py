"""A campaign stopped part-way (max_chunks, an error, a killed process, a stray temp file) and run
again finishes exactly the missing chunks: the same rows and summary as an uninterrupted run,
each episode stored once."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from acc_gym.campaigns import load_campaign, run_campaign

from campaign_settings import CHUNK, CONTROLLER, HOURS, SUITE

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def _check_same(reference, out, summary):
    _, ref_summary, ref_campaign = reference
    campaign = load_campaign(out)
    rows = campaign.rows()
    assert [r["index"] for r in rows] == list(range(10))  # each episode exactly once
    assert rows == ref_campaign.rows()
    for key in ("episodes", "collisions", "preventable_collisions", "non_preventable_collisions", "mean_score",
                "share_qualified", "share_comfortable",
                "share_safe_spacing", "speed_overshoot", "damping_ratio", "min_ttc", "max_jerk", "complete"):
        assert summary[key] == ref_summary[key], key


def test_max_chunks_then_resume(reference, tmp_path):
    ran = []
    partial = run_campaign(SUITE, HOURS, CONTROLLER, tmp_path, chunk_size=CHUNK, max_chunks=1,
                           on_chunk=lambda n, done, total: ran.append((n, done, total)))
    assert ran == [(0, 1, 4)]
    assert not partial["complete"] and partial["episodes"] == 3 and partial["chunks_done"] == 1
    assert load_campaign(tmp_path).missing_chunks()[0].number == 1
    ran.clear()
    summary = run_campaign(SUITE, HOURS, CONTROLLER, tmp_path, chunk_size=CHUNK,
                           on_chunk=lambda n, done, total: ran.append(n))
    assert sorted(ran) == [1, 2, 3]  # chunk 0 was not run again
    _check_same(reference, tmp_path, summary)
    ran.clear()
    again = run_campaign(SUITE, HOURS, CONTROLLER, tmp_path, chunk_size=CHUNK, on_chunk=lambda *a: ran.append(a))
    assert ran == [] and again == summary  # a finished campaign runs nothing


class Crash(Exception):
    pass


def test_crash_in_a_pool_and_a_stray_temp_file_then_resume(reference, tmp_path):
    def crash_after_two(number, done, total):
        if done == 2:
            raise Crash
    with pytest.raises(Crash):
        run_campaign(SUITE, HOURS, CONTROLLER, tmp_path, chunk_size=CHUNK, workers=2, on_chunk=crash_after_two)
    chunk_dir = tmp_path / "chunks"
    assert len(list(chunk_dir.glob("chunk-*.parquet"))) == 2
    assert not (tmp_path / "summary.json").exists()
    stray = chunk_dir / ".chunk-000003.parquet.999.dead.tmp"  # what a write killed mid-way leaves
    stray.write_bytes(b"PAR1 half a file")
    summary = run_campaign(SUITE, HOURS, CONTROLLER, tmp_path, chunk_size=CHUNK, workers=1)
    assert not stray.exists()
    _check_same(reference, tmp_path, summary)


def test_killed_process_resumes(reference, tmp_path):
    """SIGKILL a real ``acc-gym campaign`` process once its first chunk file exists, then resume."""
    out = tmp_path / "killed"
    controller = "campaign_slow_controller:SlowACC"  # the linear ACC, slowed down by ACC_GYM_TEST_SLOW
    env = {**os.environ, "ACC_GYM_TEST_SLOW": "0.004",
           "PYTHONPATH": os.pathsep.join([str(HERE), str(ROOT), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen([sys.executable, "-m", "acc_gym.cli", "campaign", "--suite", SUITE, "--hours", str(HOURS),
                             "--controller", controller, "--out", str(out), "--chunk-size", str(CHUNK),
                             "--workers", "1"], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 60
    first = out / "chunks" / "chunk-000000.parquet"
    while not first.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert proc.returncode == -signal.SIGKILL, proc.stderr.read().decode()
    done = sorted(p.name for p in (out / "chunks").glob("chunk-*.parquet"))
    assert 1 <= len(done) < 4, done
    summary = run_campaign(SUITE, HOURS, controller, out, chunk_size=CHUNK, workers=1)  # not slowed here
    _check_same(reference, out, summary)
    assert summary["controller"] == controller


def test_a_controller_whose_code_changed_is_refused_on_resume(tmp_path, monkeypatch):
    """Editing ``mymod.py`` between an interrupted run and its resume would mix two controllers
    in one "complete" campaign: the manifest pins the code's digest and the resume names it."""
    import re

    from acc_gym.campaigns import CampaignError, load_campaign, run_campaign
    from campaign_settings import CHUNK, HOURS, SUITE

    code = tmp_path / "code"
    code.mkdir()
    module = code / "pinned_ctrl_issue20.py"
    law = ("import numpy as np\n\nclass Ctrl:\n    def predict(self, obs, deterministic=True):\n"
           "        return np.array([{}], dtype=np.float32), None\n")
    module.write_text(law.format("0.1"))
    monkeypatch.syspath_prepend(str(code))
    out = tmp_path / "run"
    run_campaign(SUITE, HOURS, "pinned_ctrl_issue20:Ctrl", out, chunk_size=CHUNK, workers=1, max_chunks=1)
    manifest = load_campaign(out).manifest
    assert len(manifest["controller_code"]) == 64
    module.write_text(law.format("0.9"))  # another controller under the same name
    with pytest.raises(CampaignError, match=re.escape("the code of controller 'pinned_ctrl_issue20:Ctrl' changed")):
        run_campaign(SUITE, HOURS, "pinned_ctrl_issue20:Ctrl", out, chunk_size=CHUNK, workers=1)
    module.write_text(law.format("0.1"))  # the same code again: resumes
    summary = run_campaign(SUITE, HOURS, "pinned_ctrl_issue20:Ctrl", out, chunk_size=CHUNK, workers=1)
    assert summary["episodes"] == load_campaign(out).episodes


def test_more_hours_extend_a_campaign_and_reuse_its_chunks(tmp_path, reference):
    """A shorter campaign is a prefix of a longer one: asking the same directory for more
    hours keeps every full chunk (byte for byte), reruns only a partial last chunk and the
    new ones, and ends where a campaign run for the longer time from scratch ends."""
    from acc_gym.campaigns import CampaignError, load_campaign, run_campaign
    from campaign_settings import CHUNK, CONTROLLER, SUITE

    short, longer = 0.025, 0.04  # 7 scenarios (chunks 3, 3, 1); 0.04 h: the reference (10: 3, 3, 3, 1)
    out = tmp_path / "grow"
    run_campaign(SUITE, short, CONTROLLER, out, chunk_size=CHUNK, workers=1)
    before = {p.name: p.read_bytes() for p in (out / "chunks").glob("chunk-*.parquet")}
    n_short = load_campaign(out).manifest["n_scenarios"]
    assert n_short % CHUNK != 0  # a partial last chunk, to be rerun
    written = []
    summary = run_campaign(SUITE, longer, CONTROLLER, out, chunk_size=CHUNK, workers=1,
                           on_chunk=lambda number, done, total: written.append(number))
    full = n_short // CHUNK
    assert written == list(range(full, load_campaign(out).manifest["n_chunks"]))  # only the partial and new chunks ran
    for name, data in before.items():
        if int(name[6:12]) < full:
            assert (out / "chunks" / name).read_bytes() == data
    assert summary == reference[1]
    kept = sorted(p.name for p in (out / "chunks").iterdir())
    with pytest.raises(CampaignError, match="holds a campaign of 0.04 h; asking for 0.025 h would drop episodes"):
        run_campaign(SUITE, short, CONTROLLER, out, chunk_size=CHUNK, workers=1)
    assert sorted(p.name for p in (out / "chunks").iterdir()) == kept
