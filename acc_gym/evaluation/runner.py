"""Score a controller over episodes of an environment (what ``acc-gym evaluate`` runs).

A controller is any object with ``predict(obs, deterministic=True)`` returning the action
(or ``(action, state)``, as stable-baselines3 models do): a registered name
(:mod:`acc_gym.controllers`: the built-ins ``acc``, ``idm``, ..., the shipped policy
``ppo-acc``, any installed package's entry points), ``"module:attribute"`` naming such an
object, a class or a factory that makes one, or a saved model (a run directory of
``acc-gym train`` or its ``model.zip``, opened by an installed loader).
"""

from __future__ import annotations

import importlib
import os
import sys
import math
from pathlib import Path

import numpy as np


def import_from_cwd(name: str):
    """Import ``name`` with the working directory first on the path, as ``python -m`` has it
    (a console script such as ``acc-gym`` does not), so that ``mymod:ctrl`` finds the
    ``mymod.py`` in the directory the command runs in."""
    cwd = os.getcwd()
    added = sys.path[:1] not in ([""], [cwd])
    if added:
        sys.path.insert(0, cwd)
    try:
        return importlib.import_module(name)
    finally:
        if added and cwd in sys.path:
            sys.path.remove(cwd)


def load_controller(ref):
    """A controller from a registered name, ``"module:attribute"``, a saved model's path, or
    an object with ``predict`` (returned as it is)."""
    from acc_gym import controllers

    if hasattr(ref, "predict"):
        return ref
    if not isinstance(ref, str):
        raise TypeError(f"a controller reference must be a name, 'module:attribute' or an object with predict(), "
                        f"got {type(ref).__name__}")
    made = controllers.make_controller(ref)
    if made is not None:
        return made
    if ref.endswith(".zip") or Path(ref).is_dir():  # a saved model (acc-gym train)
        if not Path(ref).exists():
            raise ValueError(f"controller {ref!r}: no such file or directory")
        saved = controllers.load_saved(ref)
        if saved is None:
            raise ValueError(f"controller {ref!r}: not a run directory written by `acc-gym train` (no manifest.json), "
                             f"a stable-baselines3 model file or an rl-zoo3 run folder, and no installed loader "
                             f"({controllers.LOADER_GROUP}) opens it")
        return saved
    if ":" not in ref:
        raise ValueError(f"unknown controller {ref!r}: use a registered name {sorted(controllers.registered_controllers())}"
                         f" (acc-gym controllers lists them), 'module:attribute' or a saved model's path")
    module_name, attr = ref.split(":", 1)
    try:
        module = import_from_cwd(module_name)
    except ImportError as exc:
        raise ValueError(f"controller {ref!r}: cannot import module {module_name!r} ({exc})") from None
    except SyntaxError as exc:  # the file and line, not the import machinery's traceback
        where = f"{exc.filename}, line {exc.lineno}" if exc.filename else f"line {exc.lineno}"
        raise ValueError(f"controller {ref!r}: {where}: {type(exc).__name__}: {exc.msg}") from None
    except Exception as exc:  # noqa: BLE001  (the module's own code raised while it was imported)
        raise ValueError(f"controller {ref!r}: importing module {module_name!r} raised "
                         f"{_raised_where(exc)}") from None
    obj = module
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise ValueError(f"controller {ref!r}: module {module_name!r} has no attribute {attr!r}")
        obj = getattr(obj, part)
    if isinstance(obj, type) or (not hasattr(obj, "predict") and callable(obj)):
        obj = obj()  # a class or a factory
    if not hasattr(obj, "predict"):
        raise ValueError(f"controller {ref!r} has no predict(obs, deterministic=True) method")
    return obj


def _raised_where(exc: BaseException) -> str:
    """``Type: message (file, line N)``: the exception and the deepest frame it came from."""
    import traceback

    frames = traceback.extract_tb(exc.__traceback__)
    text = str(exc).splitlines()[0] if str(exc) else ""
    where = f" ({frames[-1].filename}, line {frames[-1].lineno})" if frames else ""
    return f"{type(exc).__name__}: {text}{where}"


def declared_time_gap(controller) -> float | None:
    """The time gap [s] a controller declares (its ``time_gap`` attribute) and is judged at
    (:func:`acc_gym.evaluation.scoring.judged_tau1`), or None; ``ValueError`` naming a bad one."""
    from acc_gym.envs.acc_env import check_time_gap

    value = getattr(controller, "time_gap", None)
    return check_time_gap(value, f"controller {controller!r}: its time_gap")


def _action(controller, obs):
    out = controller.predict(obs, deterministic=True)
    return out[0] if isinstance(out, tuple) else out


def as_action(out, controller=None) -> np.ndarray:
    """A controller's answer (``predict``'s action) as the env's ``(1,)`` float32 action;
    ``ValueError`` naming the value otherwise: no action (None), not a real number (text,
    a boolean, a complex number), a wrong shape, NaN or infinite. A finite action beyond
    [-1, 1] is clipped first, as the env clips it (so ``1e300`` is +1, not float32's
    overflow to infinity)."""
    if out is None:
        raise ValueError(f"controller {controller!r} returned no action (None); expected shape (1,)")
    raw = np.asarray(out)
    if raw.dtype.kind not in "fiu":
        raise ValueError(f"controller {controller!r} returned {out!r} ({raw.dtype}); an action is a real number")
    if raw.shape not in ((1,), ()):
        raise ValueError(f"controller {controller!r} returned an action of shape {raw.shape}; expected (1,)")
    value = raw.astype(np.float64).reshape(1)
    if not np.isfinite(value[0]):
        what = "NaN" if np.isnan(value[0]) else "infinite"
        raise ValueError(f"controller {controller!r} returned an action that is {what}: {out!r}")
    return np.clip(value, -1.0, 1.0).astype(np.float32)


class EpisodeRun:
    """One episode of a (single) ACC environment stepped from outside: whoever holds it
    owns the environment, the scoring and the recording, and only feeds actions in.

    :func:`run_episode` drives it with a controller in the same process. (The leaderboard's
    trusted process steps its episodes as rows of one batch instead,
    :class:`acc_gym.leaderboard.batch.Lockstep`: the same values for the same actions.)"""

    def __init__(self, env, *, seed: int | None = None, scenario=None, record: bool = True,
                 time_gap: float | None = None):
        from acc_gym.simulation.single_lane import SceneRecord

        self.env, self.record, self.done, self.info = env, record, False, None
        options = {"scenario": scenario} if scenario is not None else {}
        if time_gap is not None:
            options["time_gap"] = time_gap
        options = options or None
        self.obs, _ = env.reset(seed=seed, options=options)
        self._scene = SceneRecord(env.unwrapped.core.world) if record else None

    def step(self, action: np.ndarray) -> bool:
        """Apply one ``(1,)`` float32 action; True once the episode has ended."""
        self.obs, _, term, trunc, self.info = self.env.step(action)
        if self._scene is not None:
            self._scene.snap(self.info["modes"])
        self.done = bool(term or trunc)
        return self.done

    def trace(self):
        """The whole scene as a :class:`~acc_gym.simulation.single_lane.WorldTrace` (needs ``record``)."""
        return self._scene.trace(self.env.unwrapped.scenario.road)


def run_episode(env, controller, *, seed: int | None = None, scenario=None, record: bool = True):
    """One episode of a (single) ACC environment driven by ``controller``.

    Returns ``(final_info, trace)``: the last step's info (score, report, ...) and, with
    ``record``, the whole scene as a :class:`~acc_gym.simulation.single_lane.WorldTrace`
    (for :func:`acc_gym.plotting.plot_episode`)."""
    policy = load_controller(controller)
    run = EpisodeRun(env, seed=seed, scenario=scenario, record=record, time_gap=declared_time_gap(policy))
    if hasattr(policy, "reset"):
        policy.reset()
    while not run.step(as_action(_action(policy, run.obs), controller)):
        pass
    return run.info, (run.trace() if record else None)


def evaluate(controller, env_id: str = "acc_gym/CarFollowing-v0", episodes: int = 10, seed: int = 0,
             **env_kwargs) -> dict:
    """Run ``episodes`` episodes (seeded once with ``seed``) and summarise their reports.

    ``env_id`` plain (``"acc_gym/CarFollowing-v0"``) or module-qualified
    (``"acc_gym:acc_gym/CarFollowing-v0"``); an unknown id is a ``ValueError`` naming it and
    listing acc_gym's ids (:func:`acc_gym.envs.registration.resolve_env_id`)."""
    import gymnasium as gym

    import acc_gym  # noqa: F401  (registers the ids)
    from acc_gym.envs.registration import resolve_env_id

    if int(episodes) != episodes or episodes < 1:
        raise ValueError(f"episodes must be a positive integer, got {episodes!r}")
    env_id = resolve_env_id(env_id)  # before loading the controller: a misspelt --env fails at once
    policy = load_controller(controller)
    env = gym.make(env_id, **env_kwargs)
    declared = declared_time_gap(policy)
    options = None if declared is None else {"time_gap": declared}
    reports, scenarios, collided = [], [], []
    try:
        obs, info = env.reset(seed=int(seed), options=options)
        for ep in range(int(episodes)):
            if ep:
                obs, info = env.reset(options=options)
            if hasattr(policy, "reset"):
                policy.reset()
            while True:
                action = np.asarray(_action(policy, obs), dtype=np.float32)
                if action.shape not in ((1,), ()):
                    raise ValueError(f"controller {controller!r} returned an action of shape {action.shape}; "
                                     f"expected (1,)")
                obs, _, term, trunc, info = env.step(action.reshape(1))
                if term or trunc:
                    break
            reports.append(info["report"])
            scenarios.append(info["scenario"])
            if info["report"]["metrics"]["collision"]:
                collided.append(env.unwrapped.scenario)
    finally:
        env.close()
    out = summarise(reports, scenarios)
    out.update(preventability(collided, env_id, env_kwargs))
    out["by_scenario"] = by_scenario(reports, scenarios)
    return out


def by_scenario(reports: list[dict], scenarios: list[str]) -> dict:
    """Per scenario id (paper 003's speed bands are ids of their own: ``carfollowing/60`` ...):
    ``episodes``, ``mean_score``, ``share_qualified``, ``collisions`` and ``failed`` -- for each
    score item (``safety``, ``car_following``, ``road_edge``, ``boundary_line``), the number of
    episodes in which it was applicable and unqualified (a collision fails ``safety``). What a
    user looks at first when a policy does not qualify: which scenarios, and which requirement
    (``acc-gym evaluate`` prints it). Reports in
    :meth:`~acc_gym.evaluation.scoring.ScoreReport.to_dict` form, in episode order; ids in
    their order of first appearance."""
    if len(reports) != len(scenarios):
        raise ValueError(f"{len(reports)} reports for {len(scenarios)} scenario ids")
    groups: dict[str, list[dict]] = {}
    for report, sid in zip(reports, scenarios):
        groups.setdefault(sid, []).append(report)
    out = {}
    for sid, group in groups.items():
        failed: dict[str, int] = {}
        for r in group:
            for name, item in r["items"].items():
                failed.setdefault(name, 0)
                if item["applicable"] and not item["qualified"]:
                    failed[name] += 1
        out[sid] = {"episodes": len(group),
                    "mean_score": float(np.mean([r["score"] for r in group])),
                    "share_qualified": float(np.mean([r["qualified"] for r in group])),
                    "collisions": int(sum(bool(r["metrics"]["collision"]) for r in group)),
                    "failed": failed}
    return out


def preventability(scenarios: list, env_id: str, env_kwargs: dict | None = None) -> dict:
    """UN R157's split of the collisions of ``scenarios`` (the built scenarios of collision
    episodes): ``preventable_collisions`` (the careful and competent driver, the built-in
    ``cc-driver``, avoids the same scenario) and ``non_preventable_collisions`` (it collides
    too); see :mod:`acc_gym.standards.r157`. The careful driver perceives and acts as its
    model says: ``env_kwargs``' ``sensors`` and ``actuators`` (the car's radar and powertrain,
    :mod:`acc_gym.onboard`) are not its, and it drives without them."""
    if not scenarios:
        return {"preventable_collisions": 0, "non_preventable_collisions": 0}
    import gymnasium as gym

    from acc_gym.standards.r157 import REFERENCE, collides

    kwargs = {k: v for k, v in (env_kwargs or {}).items() if k not in ("sensors", "actuators")}
    env = gym.make(env_id, **kwargs)
    cc = load_controller(REFERENCE)
    try:
        avoided = [not collides(env, cc, sc) for sc in scenarios]
    finally:
        env.close()
    return {"preventable_collisions": sum(avoided), "non_preventable_collisions": len(avoided) - sum(avoided)}


def summarise(reports: list[dict], scenarios: list[str]) -> dict:
    """Mean score, share qualified, collisions and the extra metrics over episode reports (``to_dict()`` form)."""
    def metric(name):
        vals = [r["metrics"][name] for r in reports]
        return [float(v) if not isinstance(v, str) else math.inf for v in vals if v is not None]

    scores = np.array([r["score"] for r in reports])
    ttc = metric("min_ttc")
    overshoot = metric("speed_overshoot")
    return {
        "episodes": len(reports),
        "mean_score": float(scores.mean()),
        "share_qualified": float(np.mean([r["qualified"] for r in reports])),
        "collisions": int(sum(bool(r["metrics"]["collision"]) for r in reports)),
        "share_comfortable": float(np.mean(metric("share_comfortable"))),
        "share_safe_spacing": float(np.mean(metric("share_safe_spacing"))) if metric("share_safe_spacing") else None,
        "min_ttc": float(min(ttc)) if ttc and math.isfinite(min(ttc)) else None,
        "max_jerk": float(max(metric("max_jerk"))),
        "mean_speed_overshoot": float(np.mean(overshoot)) if overshoot else None,
        "scores": [float(s) for s in scores],
        "scenarios": scenarios,
    }
