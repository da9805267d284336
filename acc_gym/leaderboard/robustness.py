"""The leaderboard's robustness column: each controller in a car with the ``typical`` radar and
actuators (:mod:`acc_gym.onboard`), measured through its sandbox.

After its other columns the simulation process drives :data:`SUITE`'s :data:`SPLIT` episodes
(cut-ins, cut-outs, stopped and braking targets: where a late acquisition and a slow powertrain
matter) in envs with ``sensors=PRESET, actuators=PRESET``, all at once in lockstep, with the
answers of the controller's fresh copies in the sandbox (one slot per episode). The controller
only ever sees observation rows, as in its episodes; each episode's env is seeded with its
scenario's seed (the radar's draws come from it), so the cell is the one ``acc-gym robustness``-style local run gives for the
same episodes (:func:`local_cell`, tested against this). A collision is preventable when UN
R157's careful driver (``cc-driver``, trusted code run here, without the car's radar and
actuators) avoids the same scenario.

The cell: ``{"score", "qualified", "collisions", "preventable", "episodes"}`` (mean score, share
qualified, collisions, preventable ones). The column changes no points and no rank. A controller
that fails in it (raises, answers NaN, overruns a budget) has ``{"failed_to_run": reason}``; its
episodes stand.
"""

from __future__ import annotations

from dataclasses import asdict

import numpy as np

SUITE = "ncap-v2"
SPLIT = "test"
PRESET = "typical"
HEADER = f"robustness ({PRESET} car)"


def _episodes():
    from acc_gym.suites import get_suite

    suite = get_suite(SUITE)
    return suite.env_id, suite.episodes(SPLIT)


def _env(env_id: str):
    import gymnasium as gym

    import acc_gym  # noqa: F401  (registers the ids)

    return gym.make(env_id, sensors=PRESET, actuators=PRESET)


def _cell(env_id: str, scenarios: list, infos: list) -> dict:
    from acc_gym.evaluation.runner import preventability

    collided = [sc for sc, info in zip(scenarios, infos) if info["report"]["metrics"]["collision"]]
    split = preventability(collided, env_id)
    return {"episodes": len(infos), "score": round(float(np.mean([i["score"] for i in infos])), 6),
            "qualified": round(float(np.mean([i["qualified"] for i in infos])), 6), "collisions": len(collided),
            "preventable": split["preventable_collisions"]}


def local_cell(controller, declared: float | None = None, episodes: int | None = None) -> dict:
    """The cell of a controller run here (``run_episode`` on each episode in turn)."""
    from acc_gym.evaluation.runner import run_episode

    env_id, scenarios = _episodes()
    scenarios = scenarios[:episodes]
    env = _env(env_id)
    try:
        infos = [run_episode(env, controller, seed=sc.seed, scenario=sc, record=False)[0] for sc in scenarios]
    finally:
        env.close()
    return _cell(env_id, scenarios, infos)


def remote_cell(exchange, declared: float | None = None, first_slot: int = 0, episodes: int | None = None) -> dict:
    """The cell with the controller reached through ``exchange(obs, starts, slots) -> actions``
    (the sandbox's round trip, as :func:`acc_gym.standards.battery.remote_iso15622_report` uses
    it): every episode at once, one round trip per step for the episodes still running, episode
    ``k`` in slot ``first_slot + k`` (:class:`acc_gym.leaderboard.batch.Lockstep`, which checks
    the answers)."""
    from acc_gym.leaderboard.batch import Episode, Lockstep

    env_id, scenarios = _episodes()
    scenarios = scenarios[:episodes]
    runs = [Episode(sc, lambda: _env(env_id), env_id, sc.id) for sc in scenarios]
    done = Lockstep(runs, time_gap=declared, first_slot=first_slot).run(exchange)
    return _cell(env_id, scenarios, [done[k].info for k in range(len(scenarios))])


def slots() -> int:
    """How many of the controller's copies the column uses."""
    return len(_episodes()[1])


def failed_cell(reason: str) -> dict:
    """The cell of a controller that failed inside the column."""
    return {"failed_to_run": str(reason)}


def format_cell(value: dict | None) -> str:
    """A table cell: ``71% (2 preventable)``: the share qualified and the preventable collisions
    (``COLLIDES`` first when there are any); ``failed``; ``-`` (not measured)."""
    if not value:
        return "-"
    if "failed_to_run" in value:
        return "failed"
    text = f"{value['qualified']:.0%}"
    if value.get("collisions"):
        return f"COLLIDES {value['collisions']} ({value['preventable']} preventable), {text}"
    return text


def settings() -> dict:
    """What the manifest records of the column (``settings.robustness``)."""
    from acc_gym.onboard import ACTUATOR_PRESETS, SENSOR_PRESETS

    return {"suite": SUITE, "split": SPLIT, "episodes": slots(), "preset": PRESET,
            "sensors": asdict(SENSOR_PRESETS[PRESET]), "actuators": asdict(ACTUATOR_PRESETS[PRESET]),
            "rule": "share qualified and collisions (preventable: UN R157's careful driver avoids the same scenario) "
                    "on the suite's episodes in a car with these sensors and actuators; information only: no effect "
                    "on points or rank"}


def note(results: dict) -> str:
    """The tables' line on the column (from the manifest)."""
    st = results["manifest"]["settings"]["robustness"]
    return (f"{HEADER}: the {st['suite']} {st['split']} episodes ({st['episodes']}) with the {st['preset']} radar "
            f"and actuators (docs/sensors-actuators.md), driven by each controller in its sandbox: share qualified, "
            f"and collisions with how many the careful driver prevents (acc-gym robustness); not part of the points "
            f"or the rank")
