"""Each controller's failing episode as ASAM OpenSCENARIO, beside the leaderboard's results.

The simulation re-runs every controller's worst episode for the report (its whole scene, recorded
on the trusted side: :func:`acc_gym.leaderboard.isolation.simulate`); when that episode failed
(a collision, or not qualified by paper 003's score), :func:`write_failing_episodes` writes it
as ``failures/<controller>.xosc`` and ``.xodr`` in the results directory
(:func:`acc_gym.scenarios.openscenario.writer.write_episode`: the trajectories driven, the
controller's too, so an engineer can replay it in another tool or run it again with
``acc-gym run``). Written only with the ``osc`` extra (scenariogeneration); without it the
results say why in ``failing_episode``.
"""

from __future__ import annotations

from pathlib import Path

from acc_gym.scenarios.openscenario.writer import file_stem

FOLDER = "failures"


def write_failing_episodes(trace_map: dict, episodes: dict, out_dir: Path) -> dict:
    """``{controller: {"xosc", "xodr", "suite", "episode"} or {"not_written": reason}}`` for
    every controller whose traced worst episode (``trace_map[name]``: ``position``, ``trace``,
    ``scenario``, ``time_gap``) failed; paths relative to ``out_dir``. ``episodes[name]``: the
    controller's episode records."""
    out: dict = {}
    stems: set = set()
    for name, t in trace_map.items():
        ep = episodes[name][t["position"]]
        if ep["qualified"] and not ep["metrics"].get("collision"):
            continue
        if t.get("scenario") is None:
            continue
        stem = file_stem(name)
        while stem in stems:
            stem += "_"
        stems.add(stem)
        try:
            from acc_gym.scenarios.openscenario.writer import write_episode

            ex = write_episode(t["scenario"], t["trace"], Path(out_dir) / FOLDER, name=stem, controller=name,
                               time_gap=t.get("time_gap"))
        except (ImportError, RuntimeError) as exc:
            out[name] = {"not_written": str(exc)}
            continue
        out[name] = {"xosc": f"{FOLDER}/{ex.xosc.name}", "xodr": f"{FOLDER}/{ex.xodr.name}", "suite": ep["suite"],
                     "episode": ep["episode"], "collision": bool(ep["metrics"].get("collision"))}
    return out
