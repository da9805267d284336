"""campaign.json records each finished chunk's sha256 and is checked against it; a lost or
damaged manifest is rebuilt from the chunk files that verify (never losing them, never
adopting one that does not); campaigns of older acc-gym versions are named as such."""

import hashlib
import json
import re
import shutil

import pytest

from acc_gym.campaigns import CampaignError, load_campaign, run_campaign

from campaign_settings import CHUNK, CONTROLLER, HOURS, SUITE

NAMES = [f"chunk-{k:06d}.parquet" for k in range(4)]


def _run(out, **kw):
    args = {"chunk_size": CHUNK, "workers": 1, **kw}
    return run_campaign(SUITE, HOURS, args.pop("controller", CONTROLLER), out, **args)


def _files(out) -> dict:
    return {p.name: p.read_bytes() for p in out.rglob("*") if p.is_file()}


def _sha(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture
def copy(reference, tmp_path):
    """A copy of the finished reference campaign, free to damage."""
    out = tmp_path / "copy"
    shutil.copytree(reference[0], out)
    return out


@pytest.fixture
def half(tmp_path):
    """A campaign stopped after 2 of its 4 chunks."""
    out = tmp_path / "half"
    _run(out, max_chunks=2)
    return out


# ----------------------------------------------------------------------------- checksums in the manifest
def test_the_manifest_records_each_chunks_sha256(reference):
    out = reference[0]
    manifest = json.loads((out / "campaign.json").read_text())
    assert manifest["chunk_sha256"] == {name: _sha(out / "chunks" / name) for name in NAMES}
    for name in NAMES:  # the same as the .sha256 file beside it
        assert (out / "chunks" / name).with_suffix(".sha256").read_text().strip() == manifest["chunk_sha256"][name]


def test_a_half_done_campaign_records_exactly_its_chunks(half):
    manifest = json.loads((half / "campaign.json").read_text())
    assert manifest["chunk_sha256"] == {name: _sha(half / "chunks" / name) for name in NAMES[:2]}


def test_a_chunk_rewritten_with_a_matching_sha256_file_is_refused_by_the_manifest(copy):
    """A chunk and its .sha256 file replaced together, every other check passing (same campaign,
    same rows, one score changed): only the manifest's record tells."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = copy / "chunks" / NAMES[1]
    table = pq.read_table(path)
    scores = table.column("score").to_pylist()
    table = table.set_column(table.schema.get_field_index("score"), table.schema.field("score"),
                             pa.array([s + 1.0 for s in scores]))
    pq.write_table(table, path)  # the schema's metadata (fingerprint, chunk number) is kept
    path.with_suffix(".sha256").write_text(_sha(path) + "\n")
    before = _files(copy)
    for call in (lambda: load_campaign(copy), lambda: _run(copy)):
        with pytest.raises(CampaignError, match=re.escape(str(path)) + r" and its chunk-000001.sha256 agree .* but "
                                                                        r"campaign.json records .* for it.*delete it"):
            call()
    assert _files(copy) == before  # nothing deleted or rewritten


def test_a_sha256_file_that_disagrees_with_the_chunk_and_the_manifest_is_refused(copy):
    path = copy / "chunks" / NAMES[2]
    path.with_suffix(".sha256").write_text("0" * 64 + "\n")
    with pytest.raises(CampaignError, match=re.escape(str(path)) + " is damaged"):
        load_campaign(copy)


@pytest.mark.parametrize("edit", ["drop one record", "no record at all"])
def test_chunks_the_manifest_does_not_record_yet_are_verified_and_recorded(half, reference, edit):
    """A kill between a chunk's file and the manifest's rewrite leaves a chunk unrecorded; a manifest
    written before the record existed has none. Such chunks verify by their .sha256 file and
    fingerprint, are recorded on the next run and not run again."""
    path = half / "campaign.json"
    manifest = json.loads(path.read_text())
    if edit == "drop one record":
        del manifest["chunk_sha256"][NAMES[1]]
    else:
        del manifest["chunk_sha256"]
    path.write_text(json.dumps(manifest))
    assert load_campaign(half).chunks_done == (0, 1)  # readable as it is (nothing written)
    assert json.loads(path.read_text()) == manifest
    ran = []
    assert _run(half, on_chunk=lambda number, done, total: ran.append(number)) == reference[1]
    assert ran == [2, 3]
    assert json.loads(path.read_text()) == json.loads((reference[0] / "campaign.json").read_text())


@pytest.mark.parametrize("value, words", [
    ({"chunk-000009.parquet": "0" * 64}, r"chunk_sha256 names 'chunk-000009.parquet', not a chunk file of this "
                                         r"campaign \(4 chunks\)"),
    ({"chunk-000000.parquet": "abc"}, r"chunk_sha256\['chunk-000000.parquet'\] is not a sha256 digest: 'abc'"),
    (["x"], "chunk_sha256 must map chunk file names to sha256 digests, got list"),
])
def test_a_malformed_checksum_record_is_named(copy, value, words):
    path = copy / "campaign.json"
    manifest = json.loads(path.read_text())
    manifest["chunk_sha256"] = value
    path.write_text(json.dumps(manifest))
    with pytest.raises(CampaignError, match=re.escape(str(path)) + ": " + words):
        load_campaign(copy)


# ----------------------------------------------------------------------------- a lost or damaged manifest
@pytest.mark.parametrize("damage", ["deleted", "truncated", "not an object", "not UTF-8"])
def test_a_lost_manifest_is_rebuilt_from_the_chunks_that_verify(half, reference, damage):
    path = half / "campaign.json"
    text = path.read_text()
    chunk_files = {name: data for name, data in _files(half / "chunks").items()}
    if damage == "deleted":
        path.unlink()
        with pytest.raises(CampaignError, match=r"holds chunk files but no campaign.json; to rebuild it, run the "
                                                r"campaign again with the settings it was started with"):
            load_campaign(half)
    else:
        path.write_bytes({"truncated": text[:60].encode(), "not an object": b"[1, 2]",
                          "not UTF-8": b"\xff\xfe{"}[damage])
        with pytest.raises(CampaignError, match=re.escape(str(path)) + " is corrupted.*run the campaign again"):
            load_campaign(half)
    ran = []
    summary = _run(half, on_chunk=lambda number, done, total: ran.append(number))
    assert summary == reference[1]  # as an uninterrupted run
    assert ran == [2, 3]  # the two verified chunks were adopted, not run again
    assert {n: d for n, d in _files(half / "chunks").items() if n in chunk_files} == chunk_files  # kept byte for byte
    assert load_campaign(half).rows() == reference[2].rows()
    assert json.loads(path.read_text()) == json.loads((reference[0] / "campaign.json").read_text())
    assert (half / "campaign.json.damaged").exists() == (damage != "deleted")


def test_chunks_of_other_settings_are_refused_by_name_and_kept(tmp_path, reference):
    out = tmp_path / "other"
    _run(out, root_seed=7, max_chunks=2)  # same suite and chunking, another root seed
    (out / "campaign.json").unlink()
    before = _files(out)
    with pytest.raises(CampaignError, match=re.escape(str(out / "campaign.json")) + r" is missing, and it cannot be "
                                            r"rebuilt from the chunk files with the settings asked for: chunk file "
                                            + re.escape(str(out / "chunks" / NAMES[0])) + r" belongs to another "
                                            r"campaign \(fingerprint '\w+', expected '\w+'\)\. If the chunk files "
                                            r"were written with other settings .* run again with those.*Nothing was "
                                            r"written or deleted"):
        _run(out)
    assert _files(out) == before  # no manifest written, no chunk deleted
    ran = []
    _run(out, root_seed=7, on_chunk=lambda number, done, total: ran.append(number))  # its own settings: rebuilt
    assert ran == [2, 3]


def test_a_damaged_manifest_and_a_damaged_chunk_refuse_naming_the_chunk(half):
    path = half / "campaign.json"
    path.write_text(path.read_text()[:60])
    chunk = half / "chunks" / NAMES[1]
    data = bytearray(chunk.read_bytes())
    data[len(data) // 3] ^= 0x04
    chunk.write_bytes(bytes(data))
    before = _files(half)
    with pytest.raises(CampaignError, match=re.escape(str(path)) + r" is damaged, and it cannot be rebuilt .*"
                                            + re.escape(str(chunk)) + r" is damaged: its sha256"):
        _run(half)
    assert _files(half) == before and not (half / "campaign.json.damaged").exists()


# ----------------------------------------------------------------------------- older acc-gym versions
def _legacy_fingerprint(manifest):  # before the fingerprint left hours out
    pinned = ("format", "suite", "suite_version", "suite_hash", "env_id", "split", "root_seed", "controller",
              "controller_code", "hours", "chunk_size", "acc_gym_version")
    blob = json.dumps({k: manifest[k] for k in pinned}, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:20]


@pytest.mark.parametrize("era", ["no controller_code", "fingerprint with hours"])
def test_a_campaign_of_an_older_version_says_so_and_what_to_do(copy, era):
    path = copy / "campaign.json"
    manifest = json.loads(path.read_text())
    del manifest["chunk_sha256"]
    if era == "no controller_code":  # the first campaign format: no code digest, no checksums
        del manifest["controller_code"]
        for p in (copy / "chunks").glob("*.sha256"):
            p.unlink()
    else:
        manifest["fingerprint"] = _legacy_fingerprint(manifest)
    path.write_text(json.dumps(manifest))
    before = _files(copy)
    for call in (lambda: load_campaign(copy), lambda: _run(copy)):
        with pytest.raises(CampaignError, match=re.escape(str(path)) + r" was written by an older version of acc-gym "
                                                r"\(acc_gym_version '.*' in it\).*Run the campaign again with this "
                                                r"version in a new, empty output directory") as err:
            call()
        assert "delete it" not in str(err.value) and "missing [" not in str(err.value)
    assert _files(copy) == before
