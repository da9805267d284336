"""Damaged, foreign or mismatched files and bad inputs raise clear errors naming the file or the value."""

import json
import re
import shutil

import pytest

from acc_gym.campaigns import CampaignError, load_campaign, load_summary, run_campaign

from campaign_settings import CHUNK, CONTROLLER, HOURS, SUITE


@pytest.fixture
def copy(reference, tmp_path):
    """A copy of the finished reference campaign, free to damage."""
    out = tmp_path / "copy"
    shutil.copytree(reference[0], out)
    return out


def _run(out, **kw):
    args = {"chunk_size": CHUNK, "workers": 1, **kw}
    return run_campaign(args.pop("suite", SUITE), args.pop("hours", HOURS), args.pop("controller", CONTROLLER), out,
                        **args)


@pytest.mark.parametrize("damage", ["truncate", "empty", "garbage"])
def test_corrupted_chunk_is_refused_by_name(copy, damage):
    path = copy / "chunks" / "chunk-000001.parquet"
    data = path.read_bytes()
    path.write_bytes({"truncate": data[: len(data) // 2], "empty": b"", "garbage": b"x" * 500}[damage])
    for call in (lambda: load_campaign(copy), lambda: _run(copy)):
        with pytest.raises(CampaignError, match=re.escape(str(path)) + ".*damaged.*delete it"):
            call()


def test_a_single_flipped_bit_is_refused_by_name(copy, reference):
    """Parquet may read a flipped bit in a data page as another number; the checksum does not."""
    path = copy / "chunks" / "chunk-000001.parquet"
    data = bytearray(path.read_bytes())
    data[len(data) // 3] ^= 0x04
    path.write_bytes(bytes(data))
    for call in (lambda: load_campaign(copy), lambda: _run(copy)):
        with pytest.raises(CampaignError, match=re.escape(str(path)) + r" is damaged: its sha256 .* not the one "
                                                                        r"recorded.*delete it"):
            call()
    path.unlink()  # the advice: delete it, run again
    assert _run(copy) == reference[1]


def test_a_chunk_without_its_checksum_is_refused(copy):
    (copy / "chunks" / "chunk-000001.sha256").unlink()
    with pytest.raises(CampaignError, match=r"chunk-000001.parquet has no checksum"):
        load_campaign(copy)


def _rechecksum(path):
    import hashlib

    path.with_suffix(".sha256").write_text(hashlib.sha256(path.read_bytes()).hexdigest() + "\n")


def test_chunk_with_missing_rows_is_refused(copy, tmp_path):
    import pyarrow.parquet as pq

    path = copy / "chunks" / "chunk-000002.parquet"
    table = pq.read_table(path)
    pq.write_table(table.slice(0, 2), path)  # metadata kept, one row lost
    _rechecksum(path)  # (a consistent checksum: the deeper checks still hold)
    with pytest.raises(CampaignError, match=re.escape(str(path)) + ".*2 rows, not one for each of scenarios 6..8"):
        load_campaign(copy)


def test_chunk_from_another_campaign_is_refused(reference, tmp_path, copy):
    other = tmp_path / "other"
    _run(other, root_seed=7, max_chunks=1)  # same suite and chunking, another root seed
    shutil.copy(other / "chunks" / "chunk-000000.parquet", copy / "chunks" / "chunk-000000.parquet")
    shutil.copy(other / "chunks" / "chunk-000000.sha256", copy / "chunks" / "chunk-000000.sha256")
    with pytest.raises(CampaignError, match="chunk-000000.parquet belongs to another campaign"):
        load_campaign(copy)
    (copy / "chunks" / "chunk-000000.parquet").unlink()  # the advice: delete it, run again
    assert _run(copy) == reference[1]


def test_stray_file_in_chunks_is_refused(copy):
    (copy / "chunks" / "chunk-000009.parquet").write_bytes(b"")
    with pytest.raises(CampaignError, match="chunk-000009.parquet is not a chunk file of this campaign"):
        load_campaign(copy)


def test_corrupted_summary_is_refused_by_name(copy):
    path = copy / "summary.json"
    path.write_text(path.read_text()[:40])
    with pytest.raises(CampaignError, match=re.escape(str(path)) + " is corrupted or truncated"):
        load_summary(copy)
    path.write_text(json.dumps({"format": "acc_gym.campaign.summary/1", "mean_score": 1, "fingerprint": "x"}))
    with pytest.raises(CampaignError, match="belongs to another campaign"):
        load_summary(copy)


def test_corrupted_or_edited_manifest_is_refused(copy):
    path = copy / "campaign.json"
    text = path.read_text()
    path.write_text(text[: len(text) // 2])
    with pytest.raises(CampaignError, match=re.escape(str(path)) + " is corrupted or truncated"):
        load_campaign(copy)
    path.write_text(text.replace('"chunk_size": 3', '"chunk_size": 5'))
    with pytest.raises(CampaignError, match="was edited"):
        _run(copy)


@pytest.mark.parametrize("change, field", [
    ({"chunk_size": 2}, "chunk_size: 3 there, 2 now"),
    ({"root_seed": 1}, "root_seed: .* there, 1 now"),
    ({"controller": "idm"}, "controller: 'acc' there, 'idm' now"),
    ({"split": "dev"}, "split: 'test' there, 'dev' now"),
])
def test_restart_with_other_settings_is_refused(copy, change, field):
    before = sorted(p.name for p in (copy / "chunks").iterdir())
    with pytest.raises(CampaignError, match=f"campaign.json belongs to a campaign with other settings .*{field}"):
        _run(copy, **change)
    assert sorted(p.name for p in (copy / "chunks").iterdir()) == before  # nothing mixed in


@pytest.mark.parametrize("kwargs, message", [
    ({"hours": -1.0}, "hours must be a positive finite number, got -1.0"),
    ({"hours": float("nan")}, "hours must be a positive finite number, got nan"),
    ({"hours": 0}, "hours must be a positive finite number, got 0"),
    ({"suite": "no-such-suite"}, "unknown suite 'no-such-suite'"),
    ({"workers": 0}, "workers must be a positive integer, got 0"),
    ({"chunk_size": 0}, "chunk size must be a positive integer, got 0"),
    ({"chunk_size": 2.5}, "chunk size must be a positive integer, got 2.5"),
    ({"split": "train"}, "unknown split 'train'"),
    ({"root_seed": -3}, "root seed must be a non-negative integer, got -3"),
    ({"controller": "no-such-controller"}, "unknown controller 'no-such-controller'"),
    ({"max_chunks": 0}, "max_chunks must be a positive integer, got 0"),
    ({"confidence": 1.5}, "confidence must be in \\(0, 1\\), got 1.5"),
])
def test_bad_inputs_name_the_value(tmp_path, kwargs, message):
    with pytest.raises(CampaignError, match=message):
        _run(tmp_path / "bad", **kwargs)
    assert not (tmp_path / "bad").exists()  # refused before anything is written


def test_load_campaign_of_an_empty_directory(tmp_path):
    with pytest.raises(CampaignError, match="holds no campaign"):
        load_campaign(tmp_path)


def test_a_finished_campaign_summarises_where_nothing_can_be_written(copy, reference, monkeypatch):
    """Read-only (simulated: every write raises, since the tests may run as root): a finished
    campaign's summary.json already says it all, so nothing needs writing."""
    from acc_gym.campaigns import store

    def refuse(path, write):
        raise PermissionError(13, "Permission denied", str(path))

    monkeypatch.setattr(store, "atomic_write", refuse)
    assert _run(copy) == reference[1]
    assert load_summary(copy) == reference[1]


def test_a_full_disk_names_the_file_and_keeps_what_was_written(tmp_path, monkeypatch, reference):
    from acc_gym.campaigns import store

    real = store.atomic_write
    calls = {"n": 0}

    def full_after_two_chunks(path, write):
        if str(path).endswith(".parquet"):
            calls["n"] += 1
            if calls["n"] > 2:
                raise OSError(28, "No space left on device", str(path))
        return real(path, write)

    monkeypatch.setattr(store, "atomic_write", full_after_two_chunks)
    out = tmp_path / "full"
    with pytest.raises(CampaignError, match=r"could not write chunk file .*chunk-000002.parquet: No space left on "
                                            r"device \(errno 28\).*kept"):
        _run(out)
    monkeypatch.setattr(store, "atomic_write", real)
    assert load_campaign(out).chunks_done == (0, 1)  # what was written is kept
    assert _run(out) == reference[1]  # and the campaign finishes


def test_a_damaged_manifest_gives_advice_that_works(copy, tmp_path, reference):
    path = copy / "campaign.json"
    text = path.read_text()
    path.write_text(text[:50])
    with pytest.raises(CampaignError, match="run the campaign again with the settings it was started with: the "
                                            "manifest is rebuilt from them, every chunk file whose checksum and "
                                            "fingerprint verify is kept") as err:
        load_campaign(copy)
    assert "rewritten from the chunk files" not in str(err.value)
    chunk_files = {p.name: p.read_bytes() for p in (copy / "chunks").iterdir()}
    ran = []
    assert _run(copy, on_chunk=lambda *a: ran.append(a)) == reference[1]  # the advice: run again, same settings
    assert ran == []  # every chunk verified and was kept, byte for byte
    assert {p.name: p.read_bytes() for p in (copy / "chunks").iterdir()} == chunk_files
    assert json.loads(path.read_text()) == json.loads(text)  # the manifest as it was
    assert (copy / "campaign.json.damaged").read_text() == text[:50]  # the damaged one kept, not lost
    assert _run(tmp_path / "fresh") == reference[1]  # an empty directory still works too
