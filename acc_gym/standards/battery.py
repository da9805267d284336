"""Test batteries for the standards' verdicts, and running a controller through one.

``iso15622-v1`` exercises ISO 15622's requirements with the package's scenarios, each at
three seeds: following at 60 / 90 / 120 km/h (paper 003's test), a lead braking at 2 and
6 m/s^2 (Euro NCAP CCRb, 40 m), stop-and-go (the lead stops and starts again), an approach
to a slower target (CCRm at 50 km/h, and in traffic), a cut-in and a cut-out (paper 004's
single-lane configurations). A battery is versioned: changing its cases makes a new
version, so a report names what it ran.

:func:`iso15622_report` runs a local controller through a battery; :func:`remote_iso15622_report`
gives the same verdict for a controller reached through an ``exchange`` of observations and
actions (the leaderboard's sandbox); both build the episodes with :func:`battery_cases`.
"""

from __future__ import annotations

from acc_gym.standards import iso15622

ISO15622_V1 = "iso15622-v1"
BATTERIES = {
    ISO15622_V1: (  # (label, scenario id, parameters held fixed)
        ("follow at 60 km/h", "carfollowing/60", {}),
        ("follow at 90 km/h", "carfollowing/90", {}),
        ("follow at 120 km/h", "carfollowing/120", {}),
        # long enough for the ego to stop behind the stopped target and stand there (automatic stop)
        ("lead brakes at 2 m/s^2 to a stop", "ncap/ccrb/2-40", {"duration": 40.0}),
        ("lead brakes at 6 m/s^2 to a stop", "ncap/ccrb/6-40", {"duration": 40.0}),
        ("stop-and-go", "stopandgo", {}),
        ("approach to a slower target", "ncap/ccrm/50", {}),
        ("approach in traffic", "singlelane/2/approach", {}),
        ("cut-in", "singlelane/2/cut-in", {}),
        ("cut-out", "singlelane/2/cut-out", {}),
    ),
}
SEEDS = (0, 1, 2)
ENV_ID = "acc_gym/SingleLane-v0"  # any scenario id runs in it; the -v0 observation every controller reads


def battery_cases(battery: str = ISO15622_V1, seeds=SEEDS):
    """The episodes of ``battery`` at ``seeds``, in the battery's order: a list of ``(name, seed, scenario)``
    with the built :class:`~acc_gym.scenarios.spec.Scenario` (its parameters drawn from
    ``numpy.random.default_rng([seed, 15622])`` with the case's fixed ones, the ``"typical"``
    surroundings). Every way of running a battery (:func:`run_battery` with a local controller,
    :func:`remote_iso15622_report` through an exchange) builds its scenarios here, so both drive
    the same scenes. ``ValueError`` naming an unknown battery (before anything is built); a
    scenario that cannot be built is the battery's fault, raised, not a controller's error."""
    import numpy as np

    from acc_gym.scenarios.registry import scenario_type

    if battery not in BATTERIES:
        raise ValueError(f"unknown battery {battery!r}; the batteries are {sorted(BATTERIES)}")
    seeds = list(seeds)
    cases = []
    for label, sid, fixed in BATTERIES[battery]:
        stype = scenario_type(sid)
        for seed in seeds:
            sc = stype.build(stype.sample_params(np.random.default_rng([seed, 15622]), fixed), seed, "typical")
            cases.append((f"{label} (seed {seed})", seed, sc))
    return cases


def run_battery(controller, battery: str = ISO15622_V1, seeds=SEEDS, progress=None, car: dict | None = None):
    """Drive ``controller`` (a name, ``module:attribute``, a saved model or an object) through
    ``battery``: returns ``(drives, errors, traces)`` -- an :class:`~acc_gym.standards.iso15622.Drive`
    per episode, ``(label, reason)`` for each episode the controller failed (the rest still
    run), and the recorded world traces by label (for plots). ``car``: the ego's car, as
    ``gym.make`` settings (``sensors``, ``actuators``: :mod:`acc_gym.onboard`; None: ideal)."""
    import gymnasium as gym

    import acc_gym  # noqa: F401  (registers the ids)
    from acc_gym.evaluation.runner import load_controller, run_episode
    from acc_gym.evaluation.trace import EgoTrace

    cases = battery_cases(battery, seeds)
    policy = load_controller(controller)
    env = gym.make(ENV_ID, **(car or {}))
    drives, errors, traces = [], [], {}
    for name, seed, sc in cases:
        try:
            _, trace = run_episode(env, policy, seed=seed, scenario=sc)
        except Exception as exc:  # noqa: BLE001  (the controller's failure is a result, not a crash)
            text = str(exc).splitlines()[0] if str(exc) else ""
            errors.append((name, f"{type(exc).__name__}: {text}"))
            continue
        drives.append(iso15622.Drive.from_trace(name, EgoTrace.from_world(trace, 0, sc)))
        traces[name] = trace
        if progress is not None:
            progress(name)
    env.close()
    return drives, errors, traces


def remote_iso15622_report(exchange, time_gap: float | None = None, battery: str = ISO15622_V1, seeds=SEEDS,
                           limits=None, first_slot: int = 0) -> iso15622.Report:
    """ISO 15622's requirements over ``battery`` for a controller that lives elsewhere (the
    leaderboard's sandbox): the same verdict :func:`iso15622_report` gives for the same
    controller run locally.

    ``exchange(obs, starts, slots) -> actions`` is one round trip: ``obs`` ``(n, d)`` float64
    observation rows, ``starts`` ``(n,)`` bool (the row's episode starts: its copy of the
    controller is ``reset()``), ``slots`` ``(n,)`` int (which copy answers the row), one action per
    row back -- the shape :func:`acc_gym.evaluation.string_stability.remote_actors` and the
    leaderboard's ``_exchange`` use. ``time_gap``: the controller's declared time gap [s] (None:
    none), as :func:`~acc_gym.evaluation.runner.run_episode` passes a local controller's.

    Decisions: every episode of the battery (30 for ``iso15622-v1`` at the three seeds) runs at
    once, each in its own slot (``first_slot + its index in`` :func:`battery_cases`), in lockstep:
    one round trip per step carries a row for every episode still running, so the battery costs
    as many round trips as its longest episode has steps. The episodes are the rows of one
    :class:`~acc_gym.leaderboard.batch.Lockstep` of ``ENV_ID`` with ``record=True`` (the
    trusted process's one episode runner); a finished one is turned into a :class:`~acc_gym.standards.iso15622.Drive` here,
    and the drives (in the battery's order, as :func:`run_battery` lists them) are checked here:
    whoever calls this owns the simulation and the verdict, ``exchange`` only ever carries
    observations out and actions in. A controller's failure is whatever ``exchange`` raises: it
    ends the run (a remote controller's process does not survive its own error, so there are no
    per-episode errors as :func:`run_battery` has). Answers are checked
    (:func:`~acc_gym.leaderboard.batch.check_answers`): not one finite number per row is a
    ``ValueError`` naming the count or the value and the case; a finite action is clipped to
    [-1, 1] and rounded to float32 as :func:`~acc_gym.evaluation.runner.as_action` does."""
    import gymnasium as gym
    import numpy as np

    import acc_gym  # noqa: F401  (registers the ids)
    from acc_gym.evaluation.trace import EgoTrace
    from acc_gym.leaderboard.batch import Episode, Lockstep

    if isinstance(first_slot, bool) or not isinstance(first_slot, (int, np.integer)) or first_slot < 0:
        raise ValueError(f"first_slot must be a non-negative integer, got {first_slot!r}")
    cases = battery_cases(battery, seeds)
    episodes = [Episode(sc, lambda: gym.make(ENV_ID), ENV_ID, name) for name, _, sc in cases]
    done = Lockstep(episodes, time_gap=time_gap, first_slot=first_slot, record=True).run(exchange)
    drives = [iso15622.Drive.from_trace(name, EgoTrace.from_world(done[k].trace, 0, sc))
              for k, (name, _, sc) in enumerate(cases)]
    return iso15622.check_drives(drives, limits)


def iso15622_report(controller, battery: str = ISO15622_V1, seeds=SEEDS, limits=None) -> iso15622.Report:
    """ISO 15622's requirements over ``battery`` (:func:`run_battery`, then
    :func:`~acc_gym.standards.iso15622.check_drives`)."""
    drives, errors, _ = run_battery(controller, battery, seeds)
    report = iso15622.check_drives(drives, limits)
    report.errors = errors
    return report
