"""``--budget``: a risk run never spends more episodes than its budget (adaptive and estimation
rounds together), whatever the round size, because the estimation rounds run in whole chunks."""

import numpy as np
import pytest

from acc_gym.risk.episodes import CHUNK, draw_episodes
from acc_gym.risk.proposal import Proposal
from acc_gym.risk.run import search
from acc_gym.scenarios.distributions import Normal

LAWS = {"x": Normal(0.0, 1.0, low=-10.0, high=10.0)}


def _search(budget, round_size, margin, max_rounds=10, rhw=0.01):
    spent = []

    def simulate(rnd, prop, size):
        draws, lw = draw_episodes(prop, 0, rnd, 0, size)
        spent.append(size)
        return [{"params": d[0], "nominal": d[1], "log_w": float(lw[i]), "S": float(margin(d[0]["x"]))}
                for i, d in enumerate(draws)]

    out = search(Proposal.nominal_only(LAWS), simulate, lambda recs: np.array([r["S"] for r in recs]),
                 budget=budget, round_size=round_size, max_rounds=max_rounds, target_rhw=rhw)
    return out, spent


@pytest.mark.parametrize("budget, round_size", [(1024, 256), (1088, 256), (1000, 256), (64, 256), (300, 64),
                                                (2048, 512)])
def test_a_run_spends_at_most_its_budget(budget, round_size):
    # a failure far out in the tail (x > 6): the adaptive rounds keep lowering the level and the
    # estimation never reaches a 1 % half-width, so only the budget stops the run
    (_, _, rounds, stop), spent = _search(budget, round_size, lambda x: 6.0 - x)
    assert stop == "budget spent"
    assert sum(spent) == sum(r["episodes"] for r in rounds) <= budget
    assert sum(spent) > budget - CHUNK - round_size  # and it is not left idle: less than a round and a chunk unspent
    assert any(r["kind"] == "estimation" for r in rounds)  # the adaptive rounds left the estimation room
    assert all(n % CHUNK == 0 for n in spent)


def test_1024_episodes_were_1088_before():
    """The case a user met: --budget 1024 with 256-episode rounds ran four adaptive rounds (1024) and
    then a 64-episode pilot estimation round on top. Now the adaptive rounds stop at three, which
    leaves the estimation 256."""
    (_, _, rounds, _), spent = _search(1024, 256, lambda x: 6.0 - x)
    assert [r["kind"] for r in rounds].count("adaptive") == 3 and sum(spent) == 1024


def test_a_budget_below_one_chunk_is_an_error_naming_it():
    with pytest.raises(ValueError, match=f"budget must be at least {CHUNK} episodes .*got 10"):
        _search(10, 64, lambda x: 6.0 - x)


def test_the_cli_says_so_and_rejects_a_budget_below_a_chunk(capsys):
    from acc_gym.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["risk", "--help"])
    assert exc.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "at most this many episodes, adaptive and estimation rounds together" in text
    with pytest.raises(SystemExit) as exc:
        main(["risk", "--controller", "acc", "--budget", "10", "--workers", "1"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "usage: acc-gym risk" in err and "budget must be at least 64 episodes" in err
