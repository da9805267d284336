"""The leaderboard's progress: one tick per episode the trusted side accepted, in order, and the
bar that counts them (acc_gym.leaderboard.progress)."""

import io
from pathlib import Path

import pytest
from rich.console import Console

from acc_gym.leaderboard.isolation import Job, run_isolated
from acc_gym.leaderboard.progress import LeaderboardProgress
from acc_gym.suites import get_suite

HERE = Path(__file__).resolve().parent
EPISODES = 3


@pytest.fixture(scope="module")
def ticks():
    suite = get_suite("ncap-v1")
    jobs = [Job(suite.name, "test", k, suite.env_id, sc) for k, sc in enumerate(suite.episodes("test")[:EPISODES])]
    refs = ["constant", "bad_controllers:ExitsEarly", "idm"]
    console = Console(file=io.StringIO(), force_terminal=False, width=200)
    bar = LeaderboardProgress(refs, 1, 1, console=console)
    calls, totals = [], []

    def episode(ref, received, scheduled):
        calls.append(("episode", ref, received, scheduled))
        bar.episode(ref, received, scheduled)
        totals.append((bar.bar.tasks[0].completed, bar.bar.tasks[0].total))

    def finished(outcome):
        calls.append(("finished", outcome.reference, len(outcome.episodes), outcome.status))
        bar.finished(outcome)
        totals.append((bar.bar.tasks[0].completed, bar.bar.tasks[0].total))

    with pytest.MonkeyPatch.context() as mp:
        mp.syspath_prepend(str(HERE))
        with bar:
            bar.phase("controllers", None)
            outcomes = run_isolated(refs, jobs, workers=1, step_budget=1.0, budget=120.0, progress=finished,
                                    episode_progress=episode)
    return {"calls": calls, "totals": totals, "outcomes": outcomes, "console": console.file.getvalue()}


def test_every_accepted_episode_ticks_once_in_order_before_its_controller_ends(ticks):
    calls, outcomes = ticks["calls"], ticks["outcomes"]
    assert outcomes["constant"].status == "ok" and outcomes["idm"].status == "ok"
    assert outcomes["bad_controllers:ExitsEarly"].status == "failed"
    for ref, outcome in outcomes.items():
        mine = [c for c in calls if c[1] == ref]
        n = len(outcome.episodes)
        assert mine == [("episode", ref, k, EPISODES) for k in range(1, n + 1)] + \
            [("finished", ref, n, outcome.status)], mine
    assert len(outcomes["constant"].episodes) == EPISODES


def test_the_bar_counts_episodes_and_a_failed_controllers_whole_share(ticks):
    completed = [c for c, _ in ticks["totals"]]
    assert completed == sorted(completed)  # it only moves forward
    assert {t for _, t in ticks["totals"]} == {3 * EPISODES}  # controllers x scheduled episodes
    # the failed controller ends with fewer episodes than scheduled: the bar still counts it done
    assert ticks["totals"][-1] == (3 * EPISODES, 3 * EPISODES)
    assert "bad_controllers:ExitsEarly" in ticks["console"] and "FAILED" in ticks["console"]


def test_before_any_episode_the_total_is_not_known():
    bar = LeaderboardProgress(["a", "b"], 2, 2, console=Console(file=io.StringIO()))
    assert bar.bar.tasks[0].total is None
    bar.episode("b", 1, 4)
    assert (bar.bar.tasks[0].completed, bar.bar.tasks[0].total) == (1, 8)
