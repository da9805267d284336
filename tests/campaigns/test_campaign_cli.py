"""``acc-gym campaign``: prints the table or one JSON object, writes summary.json, and turns bad values,
mismatched settings and missing dependencies into usage errors that say what is wrong."""

import json
import sys

import pytest

from acc_gym.cli import main

from campaign_settings import CHUNK, HOURS, SUITE

ARGS = ["campaign", "--suite", SUITE, "--hours", str(HOURS), "--controller", "acc", "--chunk-size", str(CHUNK)]


def test_json_then_table_on_resume(reference, tmp_path, capsys):
    out = str(tmp_path / "c")
    assert main([*ARGS, "--out", out, "--workers", "1", "--max-chunks", "2", "--json"]) == 0
    partial = json.loads(capsys.readouterr().out)
    assert partial["episodes"] == 6 and not partial["complete"]
    assert main([*ARGS, "--out", out, "--workers", "1", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary == reference[1] == json.loads((tmp_path / "c" / "summary.json").read_text())
    assert main([*ARGS, "--out", out, "--workers", "1"]) == 0
    text = capsys.readouterr().out
    assert "10 of 10 episodes" in text and "(complete)" in text and "mean score" in text


@pytest.mark.parametrize("extra, message", [
    (["--hours", "-2"], "hours must be a positive finite number, got -2.0"),
    (["--suite", "bogus-v9"], "unknown suite 'bogus-v9'"),
    (["--workers", "0"], "workers must be a positive integer, got 0"),
    (["--split", "validation"], "unknown split 'validation'"),
    (["--scheduler", "tcp://10.0.0.1:8786", "--workers", "3"], "--workers 3 sets the size of --scheduler local only"),
])
def test_bad_values_are_usage_errors(tmp_path, capsys, extra, message):
    with pytest.raises(SystemExit) as exc:
        main([*ARGS, "--out", str(tmp_path / "c"), *extra])
    assert exc.value.code == 2
    assert message in capsys.readouterr().err


def test_settings_mismatch_is_a_usage_error(reference, capsys):
    with pytest.raises(SystemExit):
        main([*ARGS[:-1], "5", "--out", str(reference[0]), "--workers", "1"])
    assert "belongs to a campaign with other settings (chunk_size: 3 there, 5 now)" in capsys.readouterr().err


def test_missing_pyarrow_says_what_to_install(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyarrow", None)  # import pyarrow -> ImportError
    with pytest.raises(SystemExit):
        main([*ARGS, "--out", str(tmp_path / "c"), "--workers", "1"])
    assert "pip install 'acc-gym[campaign]'" in capsys.readouterr().err
    assert not (tmp_path / "c").exists()
