"""Learning curves of the tuned plain PPO and SAC (acc_gym_agents/rl/hyperparams/*.yml).

    python benchmarks/rl_curves.py --algos ppo sac --envs acc_gym/CarFollowing-v0 acc_gym/SingleLane-v0 \\
        --seeds 0 1 2 --runs /tmp/rl_curves

trains each (algorithm, env id, seed) with ``acc-gym train``'s tuned defaults (no
``--algo-kwargs``: the rl-zoo3 files), each run on one torch thread (``--jobs N`` runs N at
once, each in its own process; results do not depend on N), and writes

* ``--json`` (default ``agents/rl/curves.json``): per run the steps and, at each
  checkpoint, the deterministic evaluation's mean score, share qualified and collisions
  (``--eval-episodes`` episodes on the run's evaluation seed, ``seed + 1_000_003``, as
  ``acc-gym train`` does), plus the last and best mean score, the wall time and -- with
  ``--heldout SEED`` -- the final policy's deterministic evaluation on that seed
  (``--heldout-episodes`` episodes per env id, e.g. ``CarFollowing-v1=100 SingleLane-v1=300``),
  and on each of ``--heldout-envs``'s other ids under ``heldout_other_envs``;
* ``--png`` (default ``agents/rl/curves.png``): mean score and share qualified against steps,
  one panel per env id, a line per run.

``--twins ID ...`` adds, for each trained run, the curve of each id whose tuned entry is the
run's own (the ``-v1`` ids): the run's checkpoints scored on that id's own scenarios
(:func:`twin_curve`), so the same policy is not trained twice.

A ring id (``--envs acc_gym/Ring-v1``, :data:`acc_gym.envs.registration.RING_IDS`; not in the default
set: 300,000 steps a seed) trains with its shipped settings (``agents/rl/hyperparams/ppo_ring.yml``,
:func:`ring_curve`) and, with ``--heldout SEED``, compares each final policy with the all-human ring
and Stern's follower-stopper on ``--heldout-episodes Ring-v1=N`` seeds from SEED (speed sd, its
ratio to the all-human ring's, mean speed, collisions; under ``"ring"`` in the JSON; ``--table``
prints them):

    python benchmarks/rl_curves.py --algos ppo --envs acc_gym/Ring-v1 --seeds 0 1 2 --timesteps 150000 \\
        --heldout 5000 --heldout-episodes Ring-v1=5 --runs /tmp/ring_runs --json ring_curves.json

``--plot-only`` redraws the PNG from the JSON; ``--table`` prints its runs as Markdown (every
seed's held-out results, then the median and min-max over seeds); ``--candidates`` prints the
search's candidates that were validated seed by seed (:func:`candidates`). Runs whose directory already holds a
finished ``manifest.json`` are read, not retrained (``--retrain`` forces it).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_JSON = ROOT / "agents" / "rl" / "curves.json"
DEFAULT_PNG = ROOT / "agents" / "rl" / "curves.png"
RING_JSON = ROOT / "agents" / "rl" / "ring_curves.json"  # a ring-only run's default --json


def run_name(algo: str, env_id: str, seed: int) -> str:
    return f"{algo}_{env_id.split('/')[-1]}_s{seed}"


def _episodes(heldout_episodes: dict, env_id: str) -> int:
    return int(heldout_episodes.get(env_id.split("/")[-1], heldout_episodes.get(env_id, 100)))


def curve(algo: str, env_id: str, seed: int, runs: Path, eval_freq: int | None, eval_episodes: int,
          heldout: int | None, heldout_episodes: dict, retrain: bool = False, timesteps: int | None = None,
          heldout_envs: tuple = ()) -> dict:
    """Train (or read) one run and return its curve entry (``train`` runs torch on one thread)."""
    from acc_gym.evaluation.runner import evaluate
    from acc_gym_agents.rl.hyperparams import defaults
    from acc_gym_agents.rl.train import train

    tuned = defaults(algo, env_id)
    if tuned is None:
        raise SystemExit(f"no tuned hyperparameters for {algo} on {env_id}")
    out = runs / run_name(algo, env_id, seed)
    steps = int(timesteps or tuned["timesteps"])
    freq = int(eval_freq or max(steps // 10, 1))
    if retrain or not (out / "manifest.json").is_file():
        train(algo, env_id, timesteps=steps, seed=seed, out=out, eval_freq=freq, eval_episodes=eval_episodes)
    manifest = json.loads((out / "manifest.json").read_text())
    evals = json.loads((out / "evaluations.json").read_text())
    scores = [e["mean_score"] for e in evals]
    used = manifest.get("hyperparams")
    if used is None:  # a search run with the same settings given as --algo-kwargs (the rest SB3's defaults)
        used = {"adopted_search_run": out.name, "algo_kwargs": manifest["algo_kwargs"]}
    entry = {"algo": algo, "env_id": env_id, "seed": seed, "hyperparams": used,
             "eval_seed": manifest["eval_seed"], "eval_episodes": manifest["eval_episodes"],
             "steps": [e["timesteps"] for e in evals], "mean_score": scores,
             "share_qualified": [e["share_qualified"] for e in evals], "collisions": [e["collisions"] for e in evals],
             "wall_time_s": [e.get("wall_time_s") for e in evals],  # [s] of training at each checkpoint
             "last_mean_score": scores[-1], "best_mean_score": max(scores),
             "last_within_5_of_best": max(scores) - scores[-1] <= 5.0,
             "train_wall_time_s": manifest["train_wall_time_s"]}
    if heldout is not None:
        def score(on: str) -> dict:
            n = _episodes(heldout_episodes, on)
            s = evaluate(str(out), on, episodes=n, seed=int(heldout))
            return {"seed": int(heldout), "episodes": n, "mean_score": s["mean_score"],
                    "share_qualified": s["share_qualified"], "collisions": s["collisions"]}

        entry["heldout"] = score(env_id)
        others = [e for e in heldout_envs if e != env_id]
        if others:  # the same final policy on the other ids (a -v1 policy runs on any: it derives its features)
            entry["heldout_other_envs"] = {e: score(e) for e in others}
    return entry


def twin_curve(entry: dict, twin_env: str, runs: Path) -> dict:
    """The curve of ``twin_env`` for the run behind ``entry``, without training it again: when the
    two ids' tuned entries are the same (the ``-v1`` ids train on the same mixture, drivers and
    reward from rl-zoo3's ``env_kwargs``; ``acc-gym train`` gives the same policy for both), only
    the checkpoint evaluations differ, each on its id's own scenarios. So each saved checkpoint
    of the run is scored on ``twin_env``'s scenarios with the run's evaluation seed and episodes
    (its numpy actor; ``acc-gym train`` scores its torch model, which can differ in the last bits
    of an action), and the held-out results are the run's own on the twin id. ``trained_as``
    names the run."""
    from acc_gym.evaluation.runner import evaluate
    from acc_gym_agents.rl import hyperparams as hp

    algo, env_id = entry["algo"], entry["env_id"]
    entries = hp.load(algo)
    if entries.get(twin_env) != entries.get(env_id):
        raise SystemExit(f"{twin_env} and {env_id} have different {algo} entries: train {twin_env} itself")
    out = runs / run_name(algo, env_id, entry["seed"])
    steps, scores, quals, colls = list(entry["steps"]), [], [], []
    for step in steps:
        s = evaluate(str(out / "checkpoints" / f"step_{step:09d}"), twin_env, episodes=entry["eval_episodes"],
                     seed=entry["eval_seed"])
        scores.append(s["mean_score"])
        quals.append(s["share_qualified"])
        colls.append(s["collisions"])
    twin = {**entry, "env_id": twin_env, "trained_as": out.name, "steps": steps, "mean_score": scores,
            "share_qualified": quals, "collisions": colls, "last_mean_score": scores[-1],
            "best_mean_score": max(scores), "last_within_5_of_best": max(scores) - scores[-1] <= 5.0}
    held = {entry["env_id"]: entry.get("heldout"), **entry.get("heldout_other_envs", {})}
    twin.pop("heldout", None)
    twin.pop("heldout_other_envs", None)
    if held.get(twin_env) is not None:
        twin["heldout"] = held[twin_env]
        twin["heldout_other_envs"] = {e: h for e, h in held.items() if e != twin_env and h is not None}
    return twin


BOOTSTRAP_RESAMPLES = 2000
BOOTSTRAP_SEED = 20261202  # the intervals' own generator (numpy SeedSequence), fixed: the table is reproducible


def iqm(values) -> float:
    """The interquartile mean: the mean after dropping the lowest and highest quarter of the
    values (``floor(n / 4)`` from each end, as ``scipy.stats.trim_mean(x, 0.25)`` and
    rliable's IQM; with 3 seeds nothing is dropped and it is their mean)."""
    import numpy as np

    x = np.sort(np.asarray(values, dtype=float))
    cut = len(x) // 4
    return float(x[cut:len(x) - cut].mean())


def iqm_interval(values, level: float = 0.95, resamples: int = BOOTSTRAP_RESAMPLES) -> tuple[float, float]:
    """The percentile bootstrap interval of :func:`iqm` over seeds (rliable's, one task): the
    seeds resampled with replacement ``resamples`` times, a generator seeded with
    :data:`BOOTSTRAP_SEED`. With a handful of seeds it is wide, which is the point."""
    import numpy as np

    x = np.asarray(values, dtype=float)
    rng = np.random.default_rng(np.random.SeedSequence(BOOTSTRAP_SEED))
    draws = np.sort(x[rng.integers(0, len(x), size=(resamples, len(x)))], axis=1)
    cut = len(x) // 4
    stats = draws[:, cut:len(x) - cut].mean(axis=1)
    lo, hi = np.quantile(stats, [(1 - level) / 2, (1 + level) / 2])
    return float(lo), float(hi)


def wall_times(c: dict) -> list[float]:
    """A curve's training wall time [s] at each checkpoint: recorded by ``acc-gym train``
    (evaluations excluded) since acc-gym 0.27.0; for older runs, which kept only the total,
    that total spread linearly over the steps."""
    recorded = c.get("wall_time_s") or []
    if recorded and all(t is not None for t in recorded):
        return [float(t) for t in recorded]
    return [c["train_wall_time_s"] * s / c["steps"][-1] for s in c["steps"]]


def table(data: dict) -> str:
    """Markdown: every run's last / best checkpoint and its held-out results on each scored id,
    then per algorithm and id over seeds the median and min-max (what the README shows) and the
    interquartile mean with its 95 % bootstrap interval (:func:`iqm`, :func:`iqm_interval`)."""
    import statistics

    rows = ["| algo | trained for | seed | last / best checkpoint | held-out on | qualified | mean score | collisions |",
            "|---|---|---:|---|---|---:|---:|---:|"]
    spread: dict = {}
    for c in sorted(data["curves"], key=lambda c: (c["algo"], c["env_id"], c["seed"])):
        held = {c["env_id"]: c.get("heldout"), **c.get("heldout_other_envs", {})}
        for on, h in held.items():
            if h is None:
                continue
            rows.append(f"| {c['algo']} | {c['env_id'].split('/')[-1]} | {c['seed']} | {c['last_mean_score']:.1f} / "
                        f"{c['best_mean_score']:.1f} | {on.split('/')[-1]} ({h['episodes']} ep.) | "
                        f"{100 * h['share_qualified']:.0f} % | {h['mean_score']:.1f} | {h['collisions']} |")
            spread.setdefault((c["algo"], c["env_id"], on), []).append(h["share_qualified"])
    rows += ["", "| algo | trained for | held-out on | seeds | qualified: median (min-max) | IQM [95 % bootstrap] |",
             "|---|---|---|---:|---|---|"]
    for (algo, env_id, on), q in sorted(spread.items()):
        lo, hi = iqm_interval(q)
        rows.append(f"| {algo} | {env_id.split('/')[-1]} | {on.split('/')[-1]} | {len(q)} | "
                    f"{100 * statistics.median(q):.0f} % ({100 * min(q):.0f}-{100 * max(q):.0f} %) | "
                    f"{100 * iqm(q):.0f} % [{100 * lo:.0f}, {100 * hi:.0f}] |")
    return "\n".join(rows)


def _seed_result(r: dict) -> tuple[float, float, int, bool]:
    """(CarFollowing-v1 share, SingleLane-v1 share, collisions on both, meets) of one seed's
    validation in a ``selection_*`` entry, whichever of the three forms the search recorded it in."""
    if "carfollowing_v1" in r:  # 0.20.0 on
        return (r["carfollowing_v1"], r["singlelane_v1"],
                r["collisions_carfollowing_v1"] + r["collisions_singlelane_v1"], bool(r["meets"]))
    if "CarFollowing-v1" in r:  # [share, score, collisions]
        cf, sl = r["CarFollowing-v1"], r["SingleLane-v1"]
        return cf[0], sl[0], cf[2] + sl[2], bool(r["meets"])
    cf, sl = r["acc_gym/CarFollowing-v1"], r["acc_gym/SingleLane-v1"]
    return cf["share_qualified"], sl["share_qualified"], cf["collisions"] + sl["collisions"], bool(r["meets"])


def candidates(data: dict) -> str:
    """Markdown: every candidate of the search validated seed by seed (each ``selection_*``
    entry with a ``per_seed`` record, in the JSON's order): its fresh validation seed, the seeds
    that meet issue 33's per-seed test, the median and the lowest seed's share qualified on each
    id, and the collisions in all its validation episodes. Rules and traces: the entries
    themselves and docs/rl-training.md."""
    import statistics

    rows = ["| selection entry | validation seed | seeds meeting | CarFollowing-v1: median (lowest) | "
            "SingleLane-v1: median (lowest) | collisions |", "|---|---:|---|---|---|---:|"]
    for key, entry in data.items():
        per_seed = entry.get("per_seed") if key.startswith("selection_") and isinstance(entry, dict) else None
        if not isinstance(per_seed, dict) or not per_seed:
            continue
        results = {seed: _seed_result(r) for seed, r in per_seed.items()}
        cf = [r[0] for r in results.values()]
        sl = [r[1] for r in results.values()]
        meeting = [seed for seed, r in results.items() if r[3]]
        rows.append(f"| `{key}` | {entry.get('validation_seed', '')} | {len(meeting)} of {len(results)}"
                    f"{' (' + ', '.join(meeting) + ')' if meeting else ''} | "
                    f"{100 * statistics.median(cf):.0f} % ({100 * min(cf):.0f} %) | "
                    f"{100 * statistics.median(sl):.0f} % ({100 * min(sl):.0f} %) | "
                    f"{sum(r[2] for r in results.values())} |")
    return "\n".join(rows)


RING_FILE = ROOT / "agents" / "rl" / "hyperparams" / "ppo_ring.yml"  # the ring's shipped PPO settings


def ring_defaults(algo: str, env_id: str) -> dict:
    """The shipped settings of ``algo`` on a ring id (``RING_FILE``, rl-zoo3's format) in the form of
    :func:`acc_gym_agents.rl.hyperparams.defaults`."""
    import yaml

    from acc_gym_agents.rl import hyperparams as hp

    entry = (yaml.safe_load(RING_FILE.read_text()) or {}).get(env_id) if algo == "ppo" else None
    if entry is None:
        raise SystemExit(f"no shipped {algo} settings for {env_id} (ring ids: ppo, {RING_FILE})")
    hp.normalize_settings(entry.get("normalize"))
    return {"entry": dict(entry), "algo_kwargs": hp.to_sb3(entry), "num_envs": int(entry["n_envs"]),
            "timesteps": int(entry["n_timesteps"]), "file": str(RING_FILE), "env_kwargs": hp.env_kwargs(entry)}


def ring_episode(env_id: str, seed: int, act=None, **env_kwargs) -> dict:
    """One episode of a ring id on ``seed``: the ego driven by ``act(obs) -> action`` (None: its
    human-like stand-in, the all-human ring on the same seed); the ring's wave measures over the
    control time (the env's ``info["ring"]``) and the ego's score."""
    import gymnasium as gym

    import acc_gym  # noqa: F401  (registers the ids)

    env = gym.make(env_id, **env_kwargs)
    obs, _ = env.reset(seed=int(seed), options={"ego": "human"} if act is None else None)
    zero = env.action_space.sample() * 0.0
    while True:
        obs, _, term, trunc, info = env.step(zero if act is None else act(obs))
        if term or trunc:
            break
    env.close()
    ring = info["ring"]
    return {"seed": int(seed), "length": info["length"], "speed_sd": ring["speed_sd"],
            "mean_speed": ring["mean_speed"], "collisions": ring["collisions"], "terminated": bool(term),
            "ego_score": info["score"]}


def ring_compare(env_id: str, seeds, policies: dict, **env_kwargs) -> dict:
    """Per held-out seed: the all-human ring and each of ``policies`` (name -> ``act``), each
    policy's speed sd as a ratio to the all-human ring's on the same seed (below 1 damps)."""
    out = {"human": [ring_episode(env_id, s, None, **env_kwargs) for s in seeds]}
    for name, act in policies.items():
        rows = [ring_episode(env_id, s, act, **env_kwargs) for s in seeds]
        for row, h in zip(rows, out["human"]):
            row["speed_sd_ratio"] = row["speed_sd"] / h["speed_sd"] if h["speed_sd"] > 0 else float("nan")
            row["mean_speed_gain"] = row["mean_speed"] - h["mean_speed"]
        out[name] = rows
    return out


def ring_curve(algo: str, env_id: str, seed: int, runs: Path, heldout: int | None, heldout_episodes: dict,
               retrain: bool = False, timesteps: int | None = None) -> dict:
    """Train plain ``algo`` on a ring id with its shipped settings (:func:`ring_defaults`; SB3's
    DummyVecEnv of the id, observations and rewards normalised as the entry says, one torch
    thread), save the model and its normalisation in the run directory, and with ``heldout``
    compare the final deterministic policy with the all-human ring and Stern's follower-stopper
    on ``heldout_episodes`` seeds from ``heldout`` (:func:`ring_compare`)."""
    import numpy as np
    import stable_baselines3 as sb3
    import torch
    import gymnasium as gym
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    from acc_gym._io import atomic_write
    from acc_gym.envs.registration import qualified_id
    from acc_gym_agents.controllers import FollowerStopper
    from acc_gym_agents.rl.hyperparams import normalize_settings

    tuned = ring_defaults(algo, env_id)
    out = runs / run_name(algo, env_id, seed)
    steps = int(timesteps or tuned["timesteps"])
    model_path, norm_path, manifest_path = out / "model.zip", out / "obs_rms.npz", out / "manifest.json"
    torch.set_num_threads(1)
    if retrain or not manifest_path.is_file():
        out.mkdir(parents=True, exist_ok=True)
        def make():  # SB3's make_vec_env asks for render_mode="rgb_array", which the ring does not draw
            return Monitor(gym.make(qualified_id(env_id), **tuned["env_kwargs"]))

        raw = DummyVecEnv([make] * tuned["num_envs"])
        raw.seed(int(seed))  # sub-env i resets first with seed + i
        norm = normalize_settings(tuned["entry"].get("normalize"), tuned["entry"].get("gamma", 0.99))
        venv = VecNormalize(raw, norm_obs=True, **norm)
        model = {"ppo": sb3.PPO}[algo]("MlpPolicy", venv, seed=int(seed), device="cpu", verbose=0,
                                       **tuned["algo_kwargs"])
        t0 = time.time()
        model.learn(total_timesteps=steps)
        wall = time.time() - t0
        atomic_write(model_path, model.save)
        rms = venv.obs_rms
        atomic_write(norm_path, lambda fh: np.savez(fh, mean=rms.mean, var=rms.var, clip=venv.clip_obs,
                                                    epsilon=venv.epsilon))
        atomic_write(manifest_path, json.dumps({"algo": algo, "env_id": env_id, "seed": int(seed),
                                                "timesteps": int(model.num_timesteps), "train_wall_time_s": wall,
                                                "hyperparams": {"file": RING_FILE.name, "entry": tuned["entry"]}},
                                               indent=1))
        venv.close()
    manifest = json.loads(manifest_path.read_text())
    entry = {"algo": algo, "env_id": env_id, "seed": int(seed), "timesteps": manifest["timesteps"],
             "train_wall_time_s": manifest["train_wall_time_s"], "hyperparams": manifest["hyperparams"]}
    if heldout is not None:
        model = {"ppo": sb3.PPO}[algo].load(model_path, device="cpu")
        with np.load(norm_path) as z:
            mean, scale, clip = z["mean"], np.sqrt(z["var"] + z["epsilon"]), float(z["clip"])

        def act(obs):  # VecNormalize's observation normalisation
            o = np.clip((obs - mean) / scale, -clip, clip).astype(np.float32)
            return model.predict(o, deterministic=True)[0]

        fs = FollowerStopper()
        seeds = range(int(heldout), int(heldout) + _episodes(heldout_episodes, env_id))
        # the policies are compared on the env they were trained on (its env_kwargs: connected=True's observation)
        entry["heldout"] = ring_compare(env_id, seeds, {algo: act, "follower-stopper": lambda o: fs.predict(o)[0]},
                                        **tuned["env_kwargs"])
    return entry


def ring_table(data: dict) -> str:
    """Markdown: every ring run's held-out seeds, the all-human ring, the policy and the
    follower-stopper (speed sd [m/s], its ratio to the all-human ring's, mean speed [m/s], collisions)."""
    rows = ["| run | held-out seed | L [m] | human: sd / mean | policy: sd (ratio) / mean / coll. | "
            "follower-stopper: sd (ratio) / mean / coll. |", "|---|---:|---:|---|---|---|"]
    for c in data.get("ring", []):
        h = c.get("heldout")
        if not h:
            continue
        for hu, rl, fs in zip(h["human"], h[c["algo"]], h["follower-stopper"]):
            rows.append(f"| {c['algo']} s{c['seed']} ({c['timesteps']} steps) | {hu['seed']} | {hu['length']:.0f} | "
                        f"{hu['speed_sd']:.2f} / {hu['mean_speed']:.2f} | {rl['speed_sd']:.2f} "
                        f"({rl['speed_sd_ratio']:.2f}) / {rl['mean_speed']:.2f} / {rl['collisions']} | "
                        f"{fs['speed_sd']:.2f} ({fs['speed_sd_ratio']:.2f}) / {fs['mean_speed']:.2f} / "
                        f"{fs['collisions']} |")
    return "\n".join(rows)


def _curve_job(kwargs: dict) -> dict:
    return curve(**kwargs)


def plot(data: dict, png: Path) -> None:
    """Per env id (columns): the mean score and the share qualified against training steps,
    and the share qualified against training wall time (:func:`wall_times`); every seed thin,
    and where the seeds share their checkpoints the IQM over seeds with its 95 % bootstrap band
    (:func:`iqm`, :func:`iqm_interval`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import numpy as np

    envs = sorted({c["env_id"] for c in data["curves"]})
    fig, axes = plt.subplots(3, len(envs), figsize=(5.5 * len(envs), 9.5), squeeze=False)
    colours = {"ppo": "tab:blue", "sac": "tab:red", "td3": "tab:green", "tqc": "tab:purple", "crossq": "tab:orange"}
    panels = ((0, "mean_score", 1.0, "steps"), (1, "share_qualified", 100.0, "steps"),
              (2, "share_qualified", 100.0, "wall"))
    for j, env_id in enumerate(envs):
        for algo in sorted({c["algo"] for c in data["curves"] if c["env_id"] == env_id}):
            runs = [c for c in data["curves"] if c["env_id"] == env_id and c["algo"] == algo]
            colour = colours.get(algo, "k")
            for row, key, scale, axis in panels:
                ax = axes[row, j]
                xs = [c["steps"] if axis == "steps" else wall_times(c) for c in runs]
                for c, x in zip(runs, xs):  # every seed, thin
                    ax.plot(x, [scale * y for y in c[key]], color=colour, lw=0.6, alpha=0.45)
                if len({tuple(c["steps"]) for c in runs}) == 1:  # the IQM and its bootstrap band over seeds
                    y = scale * np.array([c[key] for c in runs])
                    x = runs[0]["steps"] if axis == "steps" else np.median(np.array(xs), 0)
                    band = np.array([iqm_interval(col) for col in y.T])
                    ax.fill_between(x, band[:, 0], band[:, 1], color=colour, alpha=0.15)
                    ax.plot(x, [iqm(col) for col in y.T], color=colour, lw=2,
                            label=f"{algo}: IQM of {len(runs)} seeds (band: 95 % bootstrap)" if row == 0 else None)
        axes[0, j].set_title(env_id)
        axes[0, j].set_ylabel("mean score (deterministic)")
        axes[1, j].set_ylabel("qualified [%]")
        axes[2, j].set_ylabel("qualified [%]")
        axes[1, j].set_xlabel("training steps")
        axes[2, j].set_xlabel("training wall time [s] (median over seeds)")
        for row in range(3):
            axes[row, j].set_xscale("log")
            axes[row, j].grid(alpha=0.3)
        axes[0, j].legend(fontsize=7)
    fig.tight_layout()
    from acc_gym.plotting import save_figure

    save_figure(fig, png, dpi=80)  # atomic, as every results file
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--algos", nargs="+", default=["ppo", "sac"], help="any of ppo, sac, td3, tqc, crossq")
    ap.add_argument("--envs", nargs="+", default=["acc_gym/CarFollowing-v0", "acc_gym/SingleLane-v0"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    ap.add_argument("--runs", default="rl_curves_runs", help="directory of the run directories")
    ap.add_argument("--timesteps", type=int, default=None, help="default: the tuned n_timesteps")
    ap.add_argument("--eval-freq", type=int, default=None, help="default: a tenth of the steps")
    ap.add_argument("--eval-episodes", type=int, default=30)
    ap.add_argument("--heldout", type=int, default=None, help="held-out evaluation seed of the final policies")
    ap.add_argument("--heldout-episodes", nargs="+", default=["CarFollowing-v0=100", "SingleLane-v0=300",
                                                              "CarFollowing-v1=100", "SingleLane-v1=300"],
                    metavar="ENV=N")
    ap.add_argument("--heldout-envs", nargs="+", default=[],
                    help="also score each final policy on these env ids (held-out seed, --heldout-episodes)")
    ap.add_argument("--twins", nargs="+", default=[],
                    help="env ids whose tuned entry equals a trained id's: their curves are that run's checkpoints "
                         "scored on their own scenarios (no second training; see twin_curve)")
    ap.add_argument("--jobs", type=int, default=1,
                    help="runs trained at once, each in its own process on one torch thread (at most the cores)")
    ap.add_argument("--json", default=str(DEFAULT_JSON))
    ap.add_argument("--png", default=str(DEFAULT_PNG))
    ap.add_argument("--plot-only", action="store_true")
    ap.add_argument("--table", action="store_true", help="print the JSON's runs as a Markdown table and exit")
    ap.add_argument("--candidates", action="store_true",
                    help="print the search's candidates validated seed by seed as a Markdown table and exit")
    ap.add_argument("--retrain", action="store_true")
    ap.add_argument("--merge", action="store_true", help="keep the JSON's other runs (replace the same ones)")
    args = ap.parse_args(argv)
    if args.plot_only:
        plot(json.loads(Path(args.json).read_text()), Path(args.png))
        return 0
    if args.table:
        data = json.loads(Path(args.json).read_text())
        print(table(data) + ("\n\n" + ring_table(data) if data.get("ring") else ""))
        return 0
    if args.candidates:
        print(candidates(json.loads(Path(args.json).read_text())))
        return 0
    os.environ.setdefault("OMP_NUM_THREADS", "1")  # inherited by --jobs workers
    from acc_gym._io import atomic_write

    held = {k: v for k, v in (h.split("=", 1) for h in args.heldout_episodes)}
    data = {"curves": []}
    if args.merge and Path(args.json).is_file():
        data = json.loads(Path(args.json).read_text())
    key = lambda c: (c["algo"], c["env_id"], c["seed"])  # noqa: E731
    from acc_gym.envs.registration import RING_IDS

    ring_envs = [e for e in args.envs if e in RING_IDS]  # trained and compared by ring_curve
    args.envs = [e for e in args.envs if e not in RING_IDS]
    if ring_envs and not args.envs and args.json == str(DEFAULT_JSON):  # a ring-only run keeps curves.json
        args.json = str(RING_JSON)
        if Path(args.json).is_file():
            data = json.loads(Path(args.json).read_text()) if args.merge else {"curves": []}
    jobs = [dict(algo=algo, env_id=env_id, seed=seed, runs=Path(args.runs), eval_freq=args.eval_freq,
                 eval_episodes=args.eval_episodes, heldout=args.heldout, heldout_episodes=held,
                 retrain=args.retrain, timesteps=args.timesteps, heldout_envs=tuple(args.heldout_envs))
            for algo in args.algos for env_id in args.envs for seed in args.seeds]
    if args.jobs < 1:
        ap.error(f"--jobs must be at least 1, got {args.jobs}")
    t0 = time.time()

    def record(c: dict) -> None:
        data["curves"] = [d for d in data["curves"] if key(d) != key(c)] + [c]
        print(f"{c['algo']} {c['env_id']} seed {c['seed']}: last {c['last_mean_score']:.1f} best "
              f"{c['best_mean_score']:.1f} qualified {c['share_qualified'][-1]:.0%} ({time.time() - t0:.0f} s)"
              + (f"; held-out {c['heldout']}" if "heldout" in c else ""), file=sys.stderr)
        atomic_write(args.json, json.dumps(data, indent=1))  # a killed run keeps the finished curves

    data.setdefault("curves", [])
    for env_id in ring_envs:
        for algo in args.algos:
            if algo != "ppo":  # the ring has shipped settings for PPO only (ppo_ring.yml)
                print(f"{algo} {env_id}: no shipped settings, skipped", file=sys.stderr)
                continue
            for seed in args.seeds:
                c = ring_curve(algo, env_id, seed, Path(args.runs), args.heldout, held, args.retrain, args.timesteps)
                data["ring"] = [d for d in data.get("ring", []) if key(d) != key(c)] + [c]
                print(f"{algo} {env_id} seed {seed}: {c['timesteps']} steps, {c['train_wall_time_s']:.0f} s",
                      file=sys.stderr)
                atomic_write(args.json, json.dumps(data, indent=1))
    if args.jobs == 1:
        for job in jobs:
            record(curve(**job))
    else:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor, as_completed

        with ProcessPoolExecutor(args.jobs, mp_context=multiprocessing.get_context("spawn")) as pool:
            for fut in as_completed([pool.submit(_curve_job, job) for job in jobs]):
                record(fut.result())
    trained = {(j["algo"], j["env_id"], j["seed"]) for j in jobs}
    for c in [c for c in data["curves"] if key(c) in trained]:
        for twin_env in args.twins:
            if twin_env != c["env_id"]:
                record(twin_curve(c, twin_env, Path(args.runs)))
    data["curves"].sort(key=key)
    from acc_gym_agents.rl.train import _versions

    data["versions"] = _versions()
    atomic_write(args.json, json.dumps(data, indent=1))
    if data["curves"]:
        plot(data, Path(args.png))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
