"""Train an ACC policy with stable-baselines3 on the native vector environment.

    acc-gym train ppo --env acc_gym/CarFollowing-v0 --timesteps 200000 --seed 0 --out runs/ppo

writes into ``--out``: ``model.zip`` (the final model), for PPO ``policy.npz`` (its actor in
plain numpy, :mod:`acc_gym_agents.rl.mlp`; the final evaluation scores it), ``obs_rms.npz`` (observation
normalisation), ``checkpoints/`` (a model, its normalisation and a short manifest at every evaluation),
``evaluations.json`` (the 100-point score on held-out seeds at every evaluation) and
``manifest.json`` (package versions, algorithm, env id, config, seeds, budget, timings),
all written atomically. Evaluation seeds come from ``seed + 1_000_003`` -- never a
training seed.

``residual="acc"`` trains a residual policy on top of the linear ACC (executed action
``clip(a_acc(obs) + residual_scale * a_rl, -1, 1)``, :mod:`acc_gym_agents.rl.residual`);
``score_bonus`` adds ``score_bonus * score / 100`` at each episode's end. Both are
recorded in the manifest, and :func:`acc_gym_agents.rl.policy.load_policy` applies the residual.
"""

from __future__ import annotations

import json
import os
import platform
import time
from contextlib import contextmanager
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as np

from acc_gym._io import atomic_write
from acc_gym_agents.rl.policy import ALGOS, MANIFEST_FILE, algorithm_class, MODEL_FILE, RMS_FILE, SB3Policy, sensor_range_of

EVAL_SEED_OFFSET = 1_000_003


def _atomic_write(path: Path, data: bytes) -> None:
    atomic_write(path, data)


def _save_rms(path: Path, vecnorm) -> None:
    rms = vecnorm.obs_rms
    atomic_write(path, lambda fh: np.savez(fh, mean=rms.mean, var=rms.var, clip=vecnorm.clip_obs))


def _save_model(model, path: Path) -> None:
    """The model's zip written atomically, with the mode of every other output
    (:func:`acc_gym._io.atomic_write`)."""
    atomic_write(path, model.save)  # stable-baselines3 writes into the open binary file


def _versions() -> dict:
    out = {"python": platform.python_version()}
    for pkg in ("acc-gym", "stable-baselines3", "sb3-contrib", "torch", "gymnasium", "numpy"):
        try:
            out[pkg] = version(pkg)
        except PackageNotFoundError:
            out[pkg] = None
    return out


def mix_settings(mix: dict) -> dict:
    """Env settings (``scenarios``, ``weights``) drawing each of ``mix``'s families or ids with its share,
    and within a family by its default probabilities: ``{"singlelane": 0.75, "carfollowing": 0.25}``
    (:func:`acc_gym.envs.config.mixture`)."""
    from acc_gym.envs.config import mixture

    if not mix:
        raise ValueError("mix must name at least one scenario family or id")
    return mixture(mix)


@contextmanager
def _torch_threads(n: int | None):
    """torch's intra-op threads set to ``n`` inside the block and restored after it (None:
    left as they are)."""
    if n is None:
        yield
        return
    if isinstance(n, bool) or int(n) != n or n < 1:
        raise ValueError(f"torch_threads must be a positive integer or None, got {n!r}")
    import torch

    previous = torch.get_num_threads()
    torch.set_num_threads(int(n))
    try:
        yield
    finally:
        torch.set_num_threads(previous)


def _current_torch_threads() -> int:
    import torch

    return int(torch.get_num_threads())


DEFAULT_TIMESTEPS = 100_000  # without tuned hyperparameters (acc_gym_agents.rl.hyperparams)
DEFAULT_NUM_ENVS = 8


def tuned_defaults(algo: str, env_id: str, algo_kwargs: dict | None, residual: str | None) -> dict | None:
    """The tuned rl-zoo3 hyperparameters (:func:`acc_gym_agents.rl.hyperparams.defaults`) that
    :func:`train` uses for a plain run (no ``algo_kwargs``, no residual) of ``algo`` on
    ``env_id``, or None."""
    if algo_kwargs is not None or residual is not None:
        return None
    from acc_gym_agents.rl.hyperparams import defaults

    return defaults(algo, env_id)


def train(algo: str, env_id: str = "acc_gym/CarFollowing-v0", timesteps: int | None = None, seed: int = 0,
          out: str | os.PathLike = "runs/acc", num_envs: int | None = None, eval_freq: int | None = None,
          eval_episodes: int = 5, progress: bool = False, algo_kwargs: dict | None = None,
          residual: str | None = None, residual_scale: float = 0.3, shield: str | bool | None = None,
          residual_kwargs: dict | None = None, max_overspeed: float | None = None, score_bonus: float = 0.0,
          mix: dict | None = None, train_scoring: dict | None = None, torch_threads: int | None = 1,
          **env_settings) -> Path:
    """Train ``algo`` (``ppo``, ``sac``, ``td3``, or sb3-contrib's ``tqc`` and ``crossq``) and write the run directory; returns its path.

    Tuned defaults: a plain run (``algo_kwargs`` None and no ``residual``) of an algorithm and
    environment id with an entry in ``acc_gym_agents/rl/hyperparams/<algo>.yml`` (rl-zoo3's
    format, :mod:`acc_gym_agents.rl.hyperparams`) takes the algorithm's keyword arguments
    from it, and ``timesteps`` / ``num_envs`` from its ``n_timesteps`` / ``n_envs`` when they
    are None (given, they win). The manifest's ``hyperparams`` records the entry used (or
    None); ``algo_kwargs={}`` asks for stable-baselines3's own defaults. Without an entry,
    ``timesteps`` defaults to 100,000 and ``num_envs`` to 8. ``algo_kwargs`` may use rl-zoo3's
    strings (``"learning_rate": "lin_3e-4"``, ``"policy_kwargs": "dict(log_std_init=-1)"``).
    rl-zoo3's ``env_kwargs`` (in the entry or ``algo_kwargs``) are settings of the *training*
    environments only, e.g. the scenario mixture trained on; the checkpoint evaluations
    score on the id's own scenarios (``scenarios`` / ``weights`` / ``mix`` given here apply
    to both and win over them).

    ``residual``: a base controller name (:data:`acc_gym_agents.rl.residual.BASES`, its settings
    ``residual_kwargs``) to learn a correction of, scaled by ``residual_scale``; ``shield``:
    cap the action at a firm brake while the observed Q < 0, ``"base"``: and at the base
    controller's action (:func:`acc_gym_agents.rl.residual.proper_response_shield`); ``max_overspeed``: cap the speed at the
    set speed plus this (:func:`acc_gym_agents.rl.residual.speed_cap`); ``score_bonus``: weight of the
    episode's 100-point score (/100) added to its last reward; ``mix``: scenario families (or
    ids) and their shares (:func:`mix_settings`), instead of ``scenarios`` / ``weights``;
    ``train_scoring``: :class:`~acc_gym.evaluation.ScoringConfig` settings for the *training*
    environments only (their reward, termination and the score bonus), e.g.
    ``{"lead_margin": 1.0}``; the evaluations, like every user of the run, score with the
    environment's own scoring, so they stay comparable with other controllers.

    ``torch_threads``: torch's intra-op threads for this run (``torch.set_num_threads``; None
    leaves torch's default, one per core). One is the default because the networks are small:
    measured on 2 cores, three runs with torch's default threads each ran 4-6 times slower
    than with one thread, and the thread count changes the floating-point order of the
    updates, so a run is reproducible only at the thread count recorded in its manifest.

    ``env_id`` may be module-qualified (``"acc_gym:acc_gym/CarFollowing-v0"``); the run's
    manifest records the registered (plain) id."""
    if algo not in ALGOS:
        raise ValueError(f"unknown algorithm {algo!r}; use one of {list(ALGOS)}")
    from acc_gym._progress import progress_bar

    # from the start (torch, the environments and the model take seconds to set up), on stderr, a terminal only
    with _torch_threads(torch_threads), progress_bar(f"train {algo}: setting up", unit="steps",
                                                     enabled=bool(progress)) as bar:
        return _train(algo, env_id, timesteps=timesteps, seed=seed, out=out, num_envs=num_envs, eval_freq=eval_freq,
                      eval_episodes=eval_episodes, progress=bar, algo_kwargs=algo_kwargs, residual=residual,
                      residual_scale=residual_scale, shield=shield, residual_kwargs=residual_kwargs,
                      max_overspeed=max_overspeed, score_bonus=score_bonus, mix=mix, train_scoring=train_scoring,
                      **env_settings)


def _train(algo: str, env_id: str, timesteps, seed, out, num_envs, eval_freq, eval_episodes, progress, algo_kwargs,
           residual, residual_scale, shield, residual_kwargs, max_overspeed, score_bonus, mix, train_scoring,
           **env_settings) -> Path:
    """:func:`train`'s body, on the torch threads it set; ``progress``: the
    :class:`~acc_gym._progress.ProgressBar` it advances (timesteps, and what it is doing)."""
    import gymnasium as gym
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import VecNormalize

    import acc_gym  # noqa: F401  (registers the ids)
    from acc_gym.evaluation.runner import evaluate
    from acc_gym.envs.registration import resolve_env_id
    from acc_gym_agents.rl.vec_env import SB3VecEnv

    env_id = resolve_env_id(env_id)  # plain or "acc_gym:"-qualified; ValueError naming an unknown id
    tuned = tuned_defaults(algo, env_id, algo_kwargs, residual)
    if tuned is not None:
        algo_kwargs = tuned["entry"]  # rl-zoo3 form (JSON-able, recorded as it is); to_sb3 below
    if timesteps is None:
        timesteps = tuned["timesteps"] if tuned is not None else DEFAULT_TIMESTEPS
    if num_envs is None:
        num_envs = tuned["num_envs"] if tuned is not None else DEFAULT_NUM_ENVS
    for name, value in (("timesteps", timesteps), ("num_envs", num_envs), ("eval_episodes", eval_episodes)):
        if int(value) != value or value < 1:
            raise ValueError(f"{name} must be a positive integer, got {value!r}")
    from acc_gym_agents.rl.residual_law import check_shield

    shield = check_shield(shield)  # stored normalised: None, "proper-response" or "base"
    spec = gym.spec(env_id)
    if mix:
        if "scenarios" in env_settings or "weights" in env_settings:
            raise ValueError("give either mix or scenarios / weights, not both")
        env_settings = {**env_settings, **mix_settings(mix)}
    settings = {**spec.kwargs, **env_settings}
    # rl-zoo3's env_kwargs (the tuned entry's or --algo-kwargs'; e.g. the scenario mixture trained on)
    # shape the training envs only; settings given here win over them
    from acc_gym_agents.rl.hyperparams import env_kwargs as zoo_env_kwargs

    train_settings = {**spec.kwargs, **zoo_env_kwargs(algo_kwargs or {}), **env_settings}
    if train_scoring:
        from acc_gym.evaluation.scoring import ScoringConfig

        base = settings.get("scoring", ScoringConfig())
        base = ScoringConfig.from_dict(base) if isinstance(base, dict) else base
        train_settings["scoring"] = ScoringConfig.from_dict({**base.to_dict(), **train_scoring})  # validated
    out = Path(out)
    (out / "checkpoints").mkdir(parents=True, exist_ok=True)
    raw = SB3VecEnv(int(num_envs), seed=int(seed), **train_settings)
    if residual is not None:
        from acc_gym_agents.rl.residual import ResidualVecEnv, check_scale

        residual_scale = check_scale(residual_scale)
        raw = ResidualVecEnv(raw, residual, residual_scale, shield, residual_kwargs,  # below VecNormalize: raw obs
                             max_overspeed)
    elif shield:
        raise ValueError(f"shield={shield!r} needs a residual base controller (residual='acc')")
    if (residual_kwargs or max_overspeed is not None) and residual is None:
        raise ValueError("residual_kwargs and max_overspeed need a residual base controller (residual='acc')")
    if score_bonus:
        from acc_gym_agents.rl.residual import ScoreBonusVecEnv

        raw = ScoreBonusVecEnv(raw, score_bonus)
    from acc_gym_agents.rl.hyperparams import normalize_settings

    norm = normalize_settings((algo_kwargs or {}).get("normalize"), (algo_kwargs or {}).get("gamma", 0.99))
    venv = VecNormalize(raw, norm_obs=True, **norm)  # clip_obs: the entry's, else 10 (normalize_settings)
    cls = algorithm_class(algo)
    from acc_gym_agents.rl.hyperparams import to_sb3

    model = cls("MlpPolicy", venv, seed=int(seed), device="cpu", verbose=0, **to_sb3(algo_kwargs or {}))
    eval_freq = int(eval_freq) if eval_freq else max(int(timesteps) // 5, 1)
    evaluations: list[dict] = []
    clock = {"start": time.time(), "evaluating": 0.0}  # [s]; reset when learning starts

    def run_eval(step: int, actor=None) -> dict:
        progress.update(description=f"train {algo}: evaluating ({eval_episodes} episodes)")
        rms = venv.obs_rms
        policy = SB3Policy(model if actor is None else actor, rms.mean.copy(), rms.var.copy(), venv.clip_obs, residual=residual,
                           residual_scale=residual_scale if residual is not None else None, shield=shield,
                           residual_kwargs=residual_kwargs, max_overspeed=max_overspeed,
                           sensor_range=sensor_range_of({"train_env_settings": train_settings}))
        trained_for = time.time() - clock["start"] - clock["evaluating"]  # [s] of training, evaluations excluded
        started = time.time()
        summary = evaluate(policy, env_id, episodes=eval_episodes, seed=int(seed) + EVAL_SEED_OFFSET, **env_settings)
        clock["evaluating"] += time.time() - started
        entry = {"timesteps": step, "mean_score": summary["mean_score"], "share_qualified": summary["share_qualified"],
                 "collisions": summary["collisions"], "wall_time_s": trained_for}
        evaluations.append(entry)
        ck = out / "checkpoints" / f"step_{step:09d}"
        ck.mkdir(exist_ok=True)
        _save_model(model, ck / MODEL_FILE)
        _save_rms(ck / RMS_FILE, venv)
        ck_manifest = {"algo": algo, "env_id": env_id, "timesteps": step, "seed": int(seed), "checkpoint": True,
                       "evaluation": entry, "residual": residual,
                       "residual_scale": float(residual_scale) if residual is not None else None,
                       "shield": shield, "residual_kwargs": residual_kwargs or None,
                       "max_overspeed": max_overspeed}
        _atomic_write(ck / MANIFEST_FILE, json.dumps(ck_manifest, indent=1).encode())  # loadable on its own
        _atomic_write(out / "evaluations.json", json.dumps(evaluations, indent=1).encode())
        progress.update(description=f"train {algo}")
        return entry

    class EvalCallback(BaseCallback):
        def __init__(self):
            super().__init__()
            self.next = eval_freq

        def _on_step(self) -> bool:
            if self.num_timesteps >= self.next:
                run_eval(self.num_timesteps)
                self.next += eval_freq
            return True

    class ProgressCallback(BaseCallback):  # the bar of acc_gym._progress (SB3's own draws on stdout)
        def _on_training_start(self) -> None:
            progress.update(total=int(timesteps), completed=0, description=f"train {algo}")

        def _on_step(self) -> bool:
            progress.update(completed=self.num_timesteps)
            return True

    t0 = time.time()
    clock["start"] = t0
    model.learn(total_timesteps=int(timesteps), callback=[EvalCallback(), ProgressCallback()])
    wall = time.time() - t0
    done_at = int(model.num_timesteps)
    if evaluations and evaluations[-1]["timesteps"] == done_at:
        # the callback ran before the last update (rollout collection comes first): score the final model
        evaluations.pop()
    # a PPO run also keeps its actor in plain numpy, which is what load_policy runs by default
    # (acc_gym_agents.rl.mlp; no torch needed): the final evaluation scores that, so it is reproducible
    actor = None
    if algo == "ppo":
        from acc_gym_agents.rl.mlp import POLICY_FILE, from_sb3

        actor = from_sb3(model)
    final = run_eval(done_at, actor)
    _save_model(model, out / MODEL_FILE)
    _save_rms(out / RMS_FILE, venv)
    if actor is not None:
        actor.save(out / POLICY_FILE)
    manifest = {"algo": algo, "env_id": env_id, "env_settings": {k: (list(v) if isinstance(v, tuple) else v)
                                                                 for k, v in settings.items()},
                "train_env_settings": {k: (list(v) if isinstance(v, tuple) else v) for k, v in train_settings.items()
                                       if k != "scoring"},
                "timesteps": int(model.num_timesteps), "seed": int(seed), "num_envs": int(num_envs),
                "eval_seed": int(seed) + EVAL_SEED_OFFSET, "eval_episodes": int(eval_episodes),
                "final_evaluation": final, "train_wall_time_s": wall, "versions": _versions(),
                "algo_kwargs": algo_kwargs or {},
                "hyperparams": None if tuned is None else {"file": Path(tuned["file"]).name, "env_id": env_id,
                                                           "entry": tuned["entry"]},
                "residual": residual,
                "residual_scale": float(residual_scale) if residual is not None else None,
                "shield": shield, "residual_kwargs": residual_kwargs or None, "max_overspeed": max_overspeed,
                "score_bonus": float(score_bonus), "mix": dict(mix) if mix else None,
                "torch_threads": _current_torch_threads(),
                "train_scoring": dict(train_scoring) if train_scoring else None}
    _atomic_write(out / MANIFEST_FILE, json.dumps(manifest, indent=1, default=str).encode())
    venv.close()
    return out
