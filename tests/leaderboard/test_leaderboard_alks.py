"""The leaderboard's UN R157 column (acc_gym.leaderboard.alks): the shipped ALKS bundle as the pinned
suite alks-v1, driven through the sandbox; the cell is the one a local run gives."""

import numpy as np
import pytest

from acc_gym.leaderboard.alks import local_cell
from acc_gym.leaderboard.run import run_leaderboard
from acc_gym.scenarios.openscenario import bundle


def test_alks_v1_is_pinned_and_covers_every_scenario():
    entries = bundle.suite_entries()
    assert bundle.suite_hash() == bundle.SUITE_HASH  # a changed selection or bundle is a new suite version
    assert [e["scenario"] for e in entries if e["index"] is None] == list(bundle.alks_scenarios())
    for number in bundle.alks_scenarios():
        idx = [e["index"] for e in entries if e["scenario"] == number and e["index"] is not None]
        assert len(idx) == len(set(idx)) <= bundle.VARIATIONS_PER_SCENARIO
    assert len(entries) == 43


def local_exchange(name):
    """A controller reached like the sandbox's round trip: one fresh copy per slot, rows in, actions out."""
    from acc_gym.evaluation.runner import load_controller

    copies = {}

    def exchange(obs, starts, slots):
        out = []
        for row, start, slot in zip(obs, starts, slots):
            if start or slot not in copies:
                copies[slot] = load_controller(name)
            action, _ = copies[slot].predict(row.astype(np.float32), deterministic=True)
            out.append(float(np.asarray(action).reshape(-1)[0]))
        return np.array(out)

    return exchange, copies


@pytest.mark.parametrize("name", ["acc", "constant"])
def test_the_remote_cell_is_the_local_cell(name):
    from acc_gym.leaderboard.alks import remote_cell

    only = ("4.2.1", "4.4.2", "4.6.1")  # a blocking target, the unavoidable cut-in, a short one
    exchange, copies = local_exchange(name)
    remote = remote_cell(exchange, first_slot=3, only=only)
    assert remote == local_cell(name, only=only)
    n = sum(e["scenario"] in only for e in bundle.suite_entries())
    assert sorted(copies) == list(range(3, 3 + n))  # one fresh copy per episode, from the first slot on
    assert remote["episodes"] == n
    assert (remote["collisions"] >= 2) == (name == "constant")  # it hits 4.2.1's blocking target and 4.4.2's


# the whole column through the sandbox, beside a local run: about 4 minutes on 2 cores
@pytest.fixture(scope="module")
def board(tmp_path_factory):
    out = tmp_path_factory.mktemp("lb") / "board"
    return run_leaderboard("ncap-v1", "test", ["constant", "acc"], episodes=1, workers=2, out=out,
                           string_stability=False, iso15622=False, waves=False, robustness=False, alks=True)


@pytest.mark.slow
def test_through_the_sandbox_the_cell_is_the_local_one(board):
    for name in ("constant", "acc"):
        entry = next(e for e in board["controllers"] if e["name"] == name)
        assert entry["alks"] == local_cell(name)
    cells = {e["name"]: e["alks"] for e in board["controllers"]}
    # the linear ACC's one collision (4.4.1 #7437: a truck cutting in 20 m ahead at 30 km/h slower) the careful
    # driver has too
    assert cells["acc"]["episodes"] == 43 and cells["acc"]["collisions"] <= 1 and cells["acc"]["preventable"] == 0
    # the never-braking ego hits the blocking targets, most of them preventable
    assert cells["constant"]["collisions"] >= 9 and cells["constant"]["preventable"] >= 7
    assert board["manifest"]["settings"]["alks"] == {"suite": "alks-v1", "sha256": bundle.SUITE_HASH,
                                                     "episodes": 43, "reference": "cc-driver"}


@pytest.mark.slow
def test_the_column_is_in_the_tables(board, tmp_path):
    from acc_gym.leaderboard.results import markdown, text_table

    md = markdown(board)
    assert "UN R157 ALKS bundle" in md and "COLLIDES" in md and "alks-v1 (43 OpenSCENARIO episodes" in md
    assert "alks-v1" in text_table(board)
