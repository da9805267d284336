"""The leaderboard's UN R157 (ALKS) column: each controller on the shipped OpenSCENARIO bundle as
the suite ``alks-v1``, measured through its sandbox.

``alks-v1`` (:func:`acc_gym.scenarios.openscenario.bundle.suite_entries`, pinned by
:data:`~acc_gym.scenarios.openscenario.bundle.SUITE_HASH`, which covers the selection and every
file's SHA-256): BMW AG's 15 concrete Annex 5 scenarios at their defaults and two concrete
scenarios of each variation file (43 episodes), run by :func:`acc_gym.scenarios.openscenario.run_file` in
the simulation process, the ego's actions from one of the controller's fresh copies in the
sandbox per episode (one round trip per step). The controller only ever sees observation
rows, as in its episodes, and is judged at the time gap it declared. A collision is
preventable when UN R157's careful driver (``cc-driver``, trusted code run here) avoids the
same concrete scenario. Off by default (``--alks``): about 25 s a controller on 2 cores, most of
it the free-driving scenarios' ten simulated minutes.

The cell: ``{"episodes", "score", "qualified", "collisions", "preventable"}`` (the mean of paper
003's score of the controlled time, the share qualified, the collisions and the preventable
ones), what :func:`local_cell` gives for the same controller run here. The column changes no
points and no rank. A controller that fails in it has ``{"failed_to_run": reason}``.
"""

from __future__ import annotations

import numpy as np

from acc_gym.leaderboard.robustness import failed_cell, format_cell  # noqa: F401  (the same cell form)

HEADER = "UN R157 ALKS bundle"


def _episodes(only=None) -> list:
    from acc_gym.scenarios.openscenario.bundle import SUITE_HASH, suite_entries, suite_hash

    if suite_hash() != SUITE_HASH:
        raise RuntimeError(f"the shipped ALKS bundle or alks-v1's selection changed (sha256 {suite_hash()}, pinned "
                           f"{SUITE_HASH}): a changed suite is a new suite version")
    return [e for e in suite_entries() if only is None or e["scenario"] in only]


def _read(entry: dict):
    from acc_gym.scenarios.openscenario import read
    from acc_gym.scenarios.openscenario.bundle import alks_scenarios

    return read(alks_scenarios()[entry["scenario"]], parameters=entry["parameters"] or None)


class _Remote:
    """A controller reached through ``exchange(obs, starts, slots) -> actions``, one slot, as an
    object with SB3's ``predict`` for :func:`~acc_gym.scenarios.openscenario.run_file`."""

    def __init__(self, exchange, slot: int):
        self.exchange, self.slot, self.start = exchange, slot, True

    def predict(self, obs, deterministic: bool = True):
        from acc_gym.evaluation.runner import as_action

        row = np.asarray(obs, dtype=float).reshape(1, -1)
        raw = np.asarray(self.exchange(row, np.array([self.start]), np.array([self.slot])))
        self.start = False
        if raw.dtype.kind not in "fiu" or raw.size != 1:
            raise ValueError(f"the controller answered one observation with {raw.size} values ({raw.dtype})")
        return as_action(raw.reshape(1), "the controller"), None


def _cell(results: list, runs: list) -> dict:
    from acc_gym.evaluation.runner import load_controller
    from acc_gym.scenarios.openscenario import run_file
    from acc_gym.standards.r157 import REFERENCE

    cc = load_controller(REFERENCE)
    collided = [sc for sc, r in zip(runs, results) if r["collided"]]
    preventable = sum(not run_file(sc.path, cc, scenario=sc)[0]["collided"] for sc in collided)
    scores = [r["score"] for r in results if r["score"] is not None]
    return {"episodes": len(results), "score": round(float(np.mean(scores)), 6) if scores else None,
            "qualified": round(float(np.mean([bool(r["qualified"]) for r in results])), 6),
            "collisions": len(collided), "preventable": int(preventable)}


def local_cell(controller, declared: float | None = None, only: tuple | None = None) -> dict:
    """The cell of a controller run here (``controller`` loaded, or a name); ``only``: the Annex
    5 numbers of the scenarios to run (default all)."""
    from acc_gym.evaluation.runner import declared_time_gap, load_controller
    from acc_gym.scenarios.openscenario import run_file

    policy = load_controller(controller)
    tg = declared if declared is not None else declared_time_gap(policy)
    runs = [_read(e) for e in _episodes(only)]
    results = [run_file(sc.path, policy, scenario=sc, time_gap=tg)[0] for sc in runs]
    return _cell(results, runs)


def remote_cell(exchange, declared: float | None = None, first_slot: int = 0, only: tuple | None = None) -> dict:
    """The cell with the controller reached through ``exchange`` (the sandbox's round trip):
    episode ``k`` driven by the copy in slot ``first_slot + k``, one episode after another."""
    from acc_gym.scenarios.openscenario import run_file

    runs = [_read(e) for e in _episodes(only)]
    results = [run_file(sc.path, _Remote(exchange, first_slot + k), scenario=sc, time_gap=declared)[0]
               for k, sc in enumerate(runs)]
    return _cell(results, runs)


def slots() -> int:
    """How many of the controller's copies the column uses."""
    return len(_episodes())


def note(results: dict) -> str:
    """The tables' line on the column (from the manifest)."""
    st = results["manifest"]["settings"]["alks"]
    return (f"{HEADER}: {st['suite']} ({st['episodes']} OpenSCENARIO episodes of BMW AG's UN R157 Annex 5 bundle, "
            f"docs/openscenario.md), driven by each controller in its sandbox: share qualified, and collisions with "
            f"how many the careful driver prevents (acc-gym run alks:N); not part of the points or the rank")


def settings() -> dict:
    """What the manifest records of the column (``settings.alks``)."""
    from acc_gym.scenarios.openscenario.bundle import SUITE, SUITE_HASH

    return {"suite": SUITE, "sha256": SUITE_HASH, "episodes": slots(), "reference": "cc-driver"}
