"""The leaderboard's wave column: what each controller does to a stop-and-go wave on a ring of
human-like drivers (Stern et al. 2018's experiment), measured through its sandbox.

**The ring** (:data:`RING`): 22 vehicles on 260 m (Stern et al.'s ring: about 260 m, 20-22 cars),
the naturalistic population at Sugiyama's 30 km/h, driver model 6
(:data:`acc_gym.drivers.mpc.DRIVER_MODELS`: the model that jams on a ring; the suites keep
model 5), a uniform standing start, :data:`SEEDS` (five rings, not used by the tests or
``benchmarks/ring.py``). The controller drives the last position (21, 0-based) from the start
and sees the environments' ``-v0`` observation with the set speed at the drivers' desired
speed and the time gap it declared (else 1.5 s), as ``acc-gym ring CONTROLLER --length 260``
gives it. The all-human ring of the comparison is the same ring with a human stand-in at that
position (drawn from the ring's seed as :class:`~acc_gym.simulation.ring.RingWorld`'s
``standins`` are): the other 21 drivers are the same in both.

**The measure**: each ring's speed standard deviation over all vehicles after the 120 s warm-up
(:func:`acc_gym.evaluation.waves.speed_sd`, Stern et al.'s measure) over a run of
:data:`DURATION`; the cell's ``ratio`` is the mean over the seeds of the controlled ring's speed
sd divided by the mean of the all-human ring's (below 1: the controller damps the wave). A
360 s run, decided: the human rings jam within 30-70 s of the start (on the seeds here) and the
speed sd measured over 120-360 s is within 8 % of the 120-600 s one (measured on seeds
3100-3105); it keeps the column at about 5 s of simulation per controller.

The all-human rings do not depend on the controller: :func:`human_baseline` runs them once per
leaderboard run, in the runner (trusted code), and every controller's cell is divided by the
same numbers. The controller's rings run in its simulation process with the actions of its
sandboxed copies (:func:`acc_gym.evaluation.string_stability.remote_actors`, fresh slots).

The column changes no points and no rank. A controller that fails in the column (raises, answers
NaN, overruns a budget) has the cell ``{"failed_to_run": reason}``; its episodes stand.
"""

from __future__ import annotations

import copy
import functools

import numpy as np

SEEDS = (3100, 3101, 3102, 3103, 3104)
DURATION = 360.0  # [s]
WARMUP = 120.0  # [s] measures start after this
RING = {"length": 260.0, "vehicles": 22, "drivers": "naturalistic", "driver_model": 6, "position": 21}
HEADER = "waves (sd ratio)"


def _ring(actors=None, declared: float | None = None):
    from acc_gym.evaluation.waves import ring_waves
    from acc_gym.simulation.ring import ring_layout, simulate_ring

    n = RING["vehicles"]
    trace = simulate_ring(RING["length"], n, layout=ring_layout(n, (RING["position"],)), drivers=RING["drivers"],
                          seeds=list(SEEDS), duration=DURATION, driver_model=RING["driver_model"], actors=actors,
                          standins=True, time_gap=1.5 if declared is None else float(declared))
    return ring_waves(trace, warmup=WARMUP)


def _summary(reports) -> dict:
    return {"speed_sd": [round(r.speed_sd, 6) for r in reports],
            "mean_speed": [round(r.mean_speed, 6) for r in reports],
            "braking_events": [r.braking_events for r in reports],
            "collisions": int(sum(r.collisions for r in reports))}


def human_baseline() -> dict:
    """The all-human rings (a stand-in at the controller's position): per seed speed sd [m/s],
    mean speed [m/s], braking events, and the collisions summed. Run once per process (they
    depend on nothing but this module and the drivers); a fresh copy each call."""
    return copy.deepcopy(_human_baseline())


@functools.lru_cache(maxsize=1)
def _human_baseline() -> dict:
    return _summary(_ring())


def cell(reports, baseline: dict) -> dict:
    """The JSON-safe cell of the controlled rings ``reports`` against ``baseline``
    (:func:`human_baseline`): ``ratio`` (mean speed sd / the all-human mean), ``speed_ratio``
    (mean speed likewise), per-seed lists, ``collisions`` (every vehicle's, summed over rings)."""
    out = _summary(reports)
    sd, base_sd = np.mean(out["speed_sd"]), np.mean(baseline["speed_sd"])
    out["ratio"] = round(float(sd / base_sd), 6) if base_sd > 0 else None
    out["speed_ratio"] = round(float(np.mean(out["mean_speed"]) / np.mean(baseline["mean_speed"])), 6)
    return out


def remote_cell(exchange, declared: float | None, baseline: dict) -> dict:
    """The cell with the controller reached through ``exchange`` (the sandbox's round trip;
    what goes wrong there is raised by it and ends the column)."""
    from acc_gym.evaluation.string_stability import remote_actors

    return cell(_ring(remote_actors(exchange), declared), baseline)


def failed_cell(reason: str) -> dict:
    """The cell of a controller that failed inside the column."""
    return {"failed_to_run": str(reason)}


def format_cell(value: dict | None) -> str:
    """A table cell: ``damps (0.42)`` below 0.95, ``amplifies (1.08)`` above 1.05, ``neutral (0.99)``
    between; ``COLLIDES (N, 0.00)`` when N vehicles collided on the controller's rings (a ring with a
    collision says nothing of damping); ``failed``; ``-`` (not measured)."""
    if not value:
        return "-"
    if "failed_to_run" in value:
        return "failed"
    r = value.get("ratio")
    if r is None:
        return "no verdict"
    if value.get("collisions"):
        return f"COLLIDES ({value['collisions']}, {r:.2f})"
    return f"damps ({r:.2f})" if r < 0.95 else f"amplifies ({r:.2f})" if r > 1.05 else f"neutral ({r:.2f})"


def settings(baseline: dict | None = None) -> dict:
    """What the manifest records of the column (``settings.waves``), with the all-human rings."""
    return {**RING, "seeds": list(SEEDS), "duration_s": DURATION, "warmup_s": WARMUP,
            "start": "uniform, standing", "human": baseline,
            "rule": "ratio = the rings' mean speed sd with the controller in position 21 / with a human there "
                    "(the same other 21 drivers); below 1 damps the wave; information only: no effect on points "
                    "or rank"}


def note(results: dict) -> str:
    """The tables' line on the column (from the manifest)."""
    st = results["manifest"]["settings"]["waves"]
    return (f"{HEADER}: one vehicle of {st['vehicles']} on a {st['length']:g} m ring of {st['drivers']} human-like "
            f"drivers (driver model {st['driver_model']}), {st['duration_s']:g} s from a standing start on seeds "
            f"{', '.join(map(str, st['seeds']))}; the speed sd after {st['warmup_s']:g} s over the all-human ring's "
            f"(below 1 damps the wave; acc-gym ring CONTROLLER --length 260 --duration 360 --seed S); not part of the points or the rank")
