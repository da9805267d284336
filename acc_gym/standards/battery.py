"""Test batteries for the standards' verdicts, and running a controller through one.

``iso15622-v1`` exercises ISO 15622's requirements with the package's scenarios, each at
three seeds: following at 60 / 90 / 120 km/h (paper 003's test), a lead braking at 2 and
6 m/s^2 (Euro NCAP CCRb, 40 m), stop-and-go (the lead stops and starts again), an approach
to a slower target (CCRm at 50 km/h, and in traffic), a cut-in and a cut-out (paper 004's
single-lane configurations). A battery is versioned: changing its cases makes a new
version, so a report names what it ran.
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


def run_battery(controller, battery: str = ISO15622_V1, seeds=SEEDS, progress=None):
    """Drive ``controller`` (a name, ``module:attribute``, a saved model or an object) through
    ``battery``: returns ``(drives, errors, traces)`` -- an :class:`~acc_gym.standards.iso15622.Drive`
    per episode, ``(label, reason)`` for each episode the controller failed (the rest still
    run), and the recorded world traces by label (for plots)."""
    import gymnasium as gym
    import numpy as np

    import acc_gym  # noqa: F401  (registers the ids)
    from acc_gym.evaluation.runner import load_controller, run_episode
    from acc_gym.evaluation.trace import EgoTrace
    from acc_gym.scenarios.registry import scenario_type

    if battery not in BATTERIES:
        raise ValueError(f"unknown battery {battery!r}; the batteries are {sorted(BATTERIES)}")
    policy = load_controller(controller)
    env = gym.make(ENV_ID)
    drives, errors, traces = [], [], {}
    for label, sid, fixed in BATTERIES[battery]:
        stype = scenario_type(sid)
        for seed in seeds:
            name = f"{label} (seed {seed})"
            try:
                sc = stype.build(stype.sample_params(np.random.default_rng([seed, 15622]), fixed), seed, "typical")
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


def iso15622_report(controller, battery: str = ISO15622_V1, seeds=SEEDS, limits=None) -> iso15622.Report:
    """ISO 15622's requirements over ``battery`` (:func:`run_battery`, then
    :func:`~acc_gym.standards.iso15622.check_drives`)."""
    drives, errors, _ = run_battery(controller, battery, seeds)
    report = iso15622.check_drives(drives, limits)
    report.errors = errors
    return report
