"""The disk a controller's working directory holds, as the trusted side measures it
(acc_gym.leaderboard.sandbox.disk_usage). The attacks on it -- many small files past the disk
limit, under either sandbox -- are in test_attacks_sandbox.py and test_cheats.py (FillsDisk).
"""

import os

from acc_gym.leaderboard.sandbox import ENTRY_BYTES, disk_usage


def test_disk_usage_counts_blocks_and_entries_and_follows_no_link(tmp_path):
    (tmp_path / "d" / "e").mkdir(parents=True)
    for k in range(10):
        (tmp_path / "d" / f"empty{k}").touch()  # no blocks, an inode each: ENTRY_BYTES each
    (tmp_path / "d" / "e" / "data").write_bytes(b"x" * (1 << 20))
    with open(tmp_path / "sparse", "wb") as f:  # 1 GiB long, nothing written: no blocks
        f.truncate(1 << 30)
    (tmp_path / "link").symlink_to("/usr")
    blocks = os.stat(tmp_path / "d" / "e" / "data").st_blocks * 512
    assert blocks >= 1 << 20
    # d, e, link, sparse and 10 empty files at the least each; data its blocks
    assert disk_usage(str(tmp_path)) == 14 * ENTRY_BYTES + blocks
    assert disk_usage(str(tmp_path), stop_above=ENTRY_BYTES) > ENTRY_BYTES  # stops early, past the mark
    assert disk_usage(str(tmp_path / "gone")) == 0
