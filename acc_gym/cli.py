"""Command line.

    acc-gym demo [--scenario carfollowing/90] [--controller acc] [--seed 0] [--plot demo.png] [--json]

runs one episode of a built-in scenario with a simple controller (the linear ACC), prints
the episode report (paper 003's score and the extra metrics) and saves the episode plot.

    acc-gym evaluate CONTROLLER [--env acc_gym/CarFollowing-v0] [--episodes 10] [--seed 0] [--json]

scores a controller (a built-in name, or ``module:attribute`` naming an object with
``predict(obs, deterministic=True)``) and prints the mean score, the share qualified,
collisions and the extra metrics.

    acc-gym train {ppo,sac,td3} --env ID --timesteps T --seed S --out DIR [--num-envs 8]
                  [--residual acc --residual-scale 0.3 [--shield [base]]] [--score-bonus B] [--scenarios ...] [--weights ...]
                  [--mix singlelane=0.75 carfollowing=0.25] [--algo-kwargs JSON]

trains a policy with stable-baselines3 on the native vector env (progress bar, periodic
evaluation on held-out seeds with the 100-point score, checkpoints, a manifest).

    acc-gym driver-demo [--driver #57] [--speed 25] [--json]

simulates an MPC human-like driver behind a lead that accelerates, cruises, brakes to a
stop and pulls away, then prints what the driver did: its modes over time, the gaps it
kept, its accelerations and jerk, and how its QPs were solved.

    acc-gym scenarios [--family F]            list scenario ids
    acc-gym scenarios ID [--seed S] [--json]  describe one (or print it as JSON)

    acc-gym score TRACE.csv [--time-gap 1.5] [--set-speed V] [--literal] [--json]

scores a recorded drive (columns ``t, v, a, gap, v_lead``; see
:mod:`acc_gym.evaluation.trace`) by paper 003's criteria and prints the episode report.

    acc-gym leaderboard [--suite S] [--split test] [--controllers C ...] [--out leaderboard] [--workers 2]
                        [--step-budget 1] [--budget 600] [--episodes N] [--no-report] [--json]

scores controllers (default: every built-in and the shipped ppo-acc and ppo), each in its own process with time budgets, on
versioned suites (default: all five), prints the ranking and writes results.json,
results.csv, leaderboard.md and report.html (see :mod:`acc_gym.leaderboard`).

    acc-gym string-stability CONTROLLER [--vehicles 8] [--speed 20] [--time-gap H] [--v2v]
                             [--penetration P --drivers KIND] [--param k=v] [--lead-trace T] [--json] [--plot PATH]

runs N copies of a controller in a column: its frequency response vehicle to vehicle, a
Gunter-like disturbance, and the verdict (see :mod:`acc_gym.evaluation.string_stability`).

    acc-gym conformance CONTROLLER [--standard iso15622|r157|ncap|all] [--seeds 0 1 2] [--json] [--out DIR]

checks a controller against ISO 15622's ACC envelope on the iso15622-v1 battery (see
:mod:`acc_gym.standards`).

    acc-gym campaign --suite S --hours H --controller C --out DIR [--split test] [--root-seed R]
                     [--workers N | --scheduler ADDRESS|local] [--chunk-size K] [--max-chunks M] [--json]

runs (or resumes) a Monte Carlo campaign: H hours of suite S's traffic with controller C,
on N local processes or a Dask cluster, one Parquet file per chunk in DIR, and prints paper
004's metrics with confidence intervals (see :mod:`acc_gym.campaigns`).
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from acc_gym.controllers import cli_plugins, registered_controllers


def _segments(mode: np.ndarray, t: np.ndarray) -> list[tuple[str, float, float]]:
    from acc_gym.drivers.mpc import Mode

    out = []
    start = 0
    for k in range(1, len(mode) + 1):
        if k == len(mode) or mode[k] != mode[start]:
            out.append((Mode(int(mode[start])).name, float(t[start]), float(t[k - 1])))
            start = k
    return out


def driver_demo(driver: str = "#57", speed: float = 25.0) -> dict:
    """Run the MPC driver demo and return its summary (what ``acc-gym driver-demo --json`` prints)."""
    from acc_gym.drivers.mpc import MPCDriver, SolvePath, preset
    from acc_gym.simulation.profiles import SpeedProfile
    from acc_gym.simulation.rollout import simulate_column

    if not (np.isfinite(speed) and 5.0 <= speed <= 40.0):
        raise ValueError(f"--speed must be within [5, 40] m/s, got {speed!r}")
    params = preset(driver, v_desired=speed + 3.0)
    lead = SpeedProfile.from_segments(0.0, [(0.0, 3.0), (1.5, speed / 1.5), (0.0, 25.0), (-2.0, speed / 2.0),
                                            (0.0, 10.0), (1.0, 10.0), (0.0, 15.0)])
    from acc_gym.drivers.base import Observation

    mpc = MPCDriver(params)
    t0 = time.perf_counter()
    mpc.act(Observation.build(v=10.0, a=0.0, gap=30.0, v_lead=10.0))  # loads (first run: compiles) the kernel
    ready = time.perf_counter() - t0
    gap0 = float(params.x_min)
    t0 = time.perf_counter()
    tr = simulate_column(lead, [mpc], [gap0 + 4.7, 0.0], [0.0, 0.0])
    wall = time.perf_counter() - t0
    mode = tr.mode[1:, 1]
    t = tr.t[1:]
    jerk = np.diff(tr.a[:, 1]) / (tr.t[1] - tr.t[0])
    stats = {k: int(v[0]) for k, v in mpc.stats.items()}
    return {
        "driver": driver if driver.startswith("#") else f"#{driver}",
        "duration_s": float(tr.t[-1]),
        "modes": [{"mode": m, "from_s": a, "to_s": b} for m, a, b in _segments(mode, t)],
        "min_gap_m": float(tr.gap[:, 1].min()),
        "x_min_m": float(params.x_min),
        "final_gap_m": float(tr.gap[-1, 1]),
        "max_speed_mps": float(tr.v[:, 1].max()),
        "max_accel_mps2": float(tr.a[:, 1].max()),
        "min_accel_mps2": float(tr.a[:, 1].min()),
        "max_abs_jerk_mps3": float(np.abs(jerk).max()),
        "collided": bool(tr.collided[1]),
        "solver": stats,
        "solve_paths": {p.name.lower(): int(np.sum(tr.path[1:, 1] == p)) for p in SolvePath},
        "wall_time_s": wall,
        "kernel_ready_s": ready,
    }


def demo(scenario: str = "carfollowing/90", controller: str = "acc", seed: int = 0, plot: str | None = None) -> dict:
    """One episode of ``scenario`` with ``controller``; returns the final info (report included)."""
    import gymnasium as gym

    import acc_gym  # noqa: F401  (registers the ids)
    from acc_gym.evaluation.runner import run_episode
    from acc_gym.scenarios import scenario_type

    family = scenario_type(scenario).family
    env = gym.make("acc_gym/CarFollowing-v0", scenarios=(scenario,), drivers="typical")
    t0 = time.perf_counter()
    info, trace = run_episode(env, controller, seed=seed, scenario=scenario)
    wall = time.perf_counter() - t0
    out = {"scenario": info["scenario"], "family": family, "controller": controller, "score": info["score"],
           "qualified": info["qualified"], "report": info["report"], "wall_time_s": wall, "plot": None}
    if plot:
        from acc_gym.plotting import plot_episode

        plot_episode(trace, 0, title=f"{info['scenario']} - {controller}: score {info['score']:.1f}", path=plot)
        out["plot"] = str(plot)
    env.close()
    return out


def _print_driver_demo(s: dict) -> None:
    print(f"MPC human-like driver {s['driver']} behind a lead that accelerates, cruises, brakes to a stop "
          f"and pulls away ({s['duration_s']:.0f} s at 5 Hz)")
    print("modes:")
    for seg in s["modes"]:
        print(f"  {seg['from_s']:6.1f} - {seg['to_s']:6.1f} s  {seg['mode']}")
    print(f"gap: min {s['min_gap_m']:.2f} m (x_min {s['x_min_m']:.2f} m), final {s['final_gap_m']:.2f} m; "
          f"collision: {'yes' if s['collided'] else 'no'}")
    print(f"speed max {s['max_speed_mps']:.1f} m/s; acceleration {s['min_accel_mps2']:.2f} .. "
          f"{s['max_accel_mps2']:.2f} m/s^2; max |jerk| {s['max_abs_jerk_mps3']:.2f} m/s^3")
    paths = ", ".join(f"{k} {v}" for k, v in s["solve_paths"].items())
    print(f"QP steps: {paths}; fallbacks {s['solver']['fallback']}; simulated in {s['wall_time_s'] * 1e3:.0f} ms")
    if s["kernel_ready_s"] > 1.0:
        print(f"(the driver kernel took {s['kernel_ready_s']:.1f} s to compile; numba caches it for later runs)")


def _scenarios(args) -> str:
    from acc_gym import scenarios

    if args.id is None:
        return "\n".join(scenarios.list_scenarios(args.family))
    if args.json:
        return scenarios.build(args.id, seed=args.seed, drivers=args.drivers).to_json(indent=1)
    return scenarios.describe(args.id)


def _score(args) -> str:
    from acc_gym.evaluation import EgoTrace, ScoringConfig, score_episode

    trace = EgoTrace.from_csv(args.trace, set_speed=args.set_speed, time_gap=args.time_gap)
    report = score_episode(trace, ScoringConfig.literal() if args.literal else ScoringConfig())
    return json.dumps(report.to_dict()) if args.json else report.summary()


def main(argv=None) -> int:
    import warnings

    # The suites, batteries and the paper's tests pin -v0 ids on purpose (a result names the
    # version it ran); gymnasium's advice to move to -v1 is noise in this command's output.
    # (gym.make on a -v0 id in a user's own code still shows it.)
    warnings.filterwarnings("ignore", message=".*is out of date. You should consider upgrading",
                            category=DeprecationWarning)
    try:
        return _main(argv)
    except KeyboardInterrupt:
        print("acc-gym: interrupted", file=sys.stderr)
        return 130


def _main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="acc-gym", description="acc_gym: test ACC controllers in simulation")
    sub = parser.add_subparsers(dest="command", required=True)
    p_sc = sub.add_parser("scenarios", help="list scenario ids, or describe one")
    p_sc.add_argument("id", nargs="?", help="a scenario id (omit to list them)")
    p_sc.add_argument("--family", help="list only this family (singlelane, carfollowing, ncap, ncap2026, stopandgo)")
    p_sc.add_argument("--seed", type=int, default=0, help="seed for --json")
    p_sc.add_argument("--drivers", default="typical", help="surrounding drivers for --json")
    p_sc.add_argument("--json", action="store_true", help="print the built scenario as JSON")
    p_score = sub.add_parser("score", help="score a recorded drive (CSV) by paper 003's criteria")
    p_score.add_argument("trace", help="CSV with columns t, v, a, gap, v_lead (optional a_lead, lead_id, a_y, d2, d3)")
    p_score.add_argument("--time-gap", type=float, default=None, help="nominal time gap [s] (the reaction time tau1)")
    p_score.add_argument("--set-speed", type=float, default=None, help="the ego's set speed [m/s]")
    p_score.add_argument("--literal", action="store_true", help="paper 003's rules read literally")
    p_score.add_argument("--json", action="store_true", help="print one JSON object")
    p_demo = sub.add_parser("demo", help="run one episode of a built-in scenario, print its score, save its plot")
    p_demo.add_argument("--scenario", default="carfollowing/90", help="a scenario id (see: acc-gym scenarios)")
    p_demo.add_argument("--controller", default="acc", help="a built-in controller or module:attribute")
    p_demo.add_argument("--seed", type=int, default=0)
    p_demo.add_argument("--plot", default="acc_gym_demo.png", help="where to save the episode plot ('' for none)")
    p_demo.add_argument("--json", action="store_true", help="print one JSON object")
    p_eval = sub.add_parser("evaluate", help="score a controller over episodes of an environment")
    p_eval.add_argument("controller", help="a built-in name (acc, cacc, mp-cacc, idm, gipps, gm, fuzzy, mpc, "
                                           "constant), the shipped policies ppo-acc and ppo, module:attribute, a "
                                           "run directory of acc-gym train, a stable-baselines3 model file "
                                           "or an rl-zoo3 run folder")
    p_eval.add_argument("--algo", default=None, help="the algorithm of a stable-baselines3 model file or rl-zoo3 "
                                                     "folder (ppo, a2c, sac, td3, ddpg; default: read from the file)")
    p_eval.add_argument("--env", default="acc_gym/CarFollowing-v0",
                        help="an environment id, plain (acc_gym/CarFollowing-v0) or module-qualified "
                             "(acc_gym:acc_gym/CarFollowing-v0, the form subprocess workers need)")
    p_eval.add_argument("--episodes", type=int, default=10)
    p_eval.add_argument("--seed", type=int, default=0)
    p_eval.add_argument("--drivers", default=None, help="surrounding drivers (typical, atypical, malicious, idm, ...)")
    p_eval.add_argument("--json", action="store_true", help="print one JSON object")
    p_dd = sub.add_parser("driver-demo", help="simulate an MPC human-like driver and print what it did")
    p_dd.add_argument("--driver", default="#57", help="paper 001 Table 4 preset: #23, #57, #61 or #13")
    p_dd.add_argument("--speed", type=float, default=25.0, help="the lead's cruise speed [m/s]")
    p_dd.add_argument("--json", action="store_true", help="print one JSON object")
    sub.add_parser("controllers", help="list the controllers registered by name: what each is, and where it comes from")
    _add_campaign_parser(sub)
    _add_leaderboard_parser(sub)
    from acc_gym.risk import cli as risk_cli

    risk_cli.add_parser(sub)
    from acc_gym.evaluation import string_stability_cli
    from acc_gym.standards import conformance as conformance_cli

    string_stability_cli.add_parser(sub)
    conformance_cli.add_parser(sub)
    from acc_gym.simulation import ring_cli

    ring_cli.add_parser(sub)
    plugins = cli_plugins()  # e.g. acc-gym train, from the acc_gym.cli entry points
    for plugin in plugins.values():
        plugin.add_parser(sub)
    args = parser.parse_args(argv)
    parser = sub.choices[args.command]  # errors from here on print the subcommand's usage, as parsing errors do
    if args.command in plugins:
        return plugins[args.command].run(args, parser)
    if args.command == "controllers":
        _print_controllers()
        return 0
    if args.command == "campaign":
        return _campaign(args, parser)
    if args.command == "leaderboard":
        return _leaderboard(args, parser)
    if args.command == "risk":
        return risk_cli.run(args, parser)
    if args.command == "string-stability":
        return string_stability_cli.run(args, parser)
    if args.command == "conformance":
        return conformance_cli.run(args, parser)
    if args.command == "ring":
        return ring_cli.run(args, parser)
    if args.command in ("scenarios", "score"):
        try:
            print(_scenarios(args) if args.command == "scenarios" else _score(args))
        except (ValueError, OSError) as exc:
            parser.error(str(exc))
        return 0
    if args.command == "driver-demo":
        try:
            summary = driver_demo(args.driver, args.speed)
        except ValueError as exc:
            parser.error(str(exc))
        if args.json:
            print(json.dumps(summary))
        else:
            _print_driver_demo(summary)
    elif args.command == "demo":
        try:
            out = demo(args.scenario, args.controller, args.seed, args.plot or None)
        except (ValueError, TypeError) as exc:
            parser.error(str(exc))
        if args.json:
            print(json.dumps(out))
        else:
            print(f"{out['scenario']} with controller {out['controller']!r}: score {out['score']:.1f} / 100 "
                  f"({'qualified' if out['qualified'] else 'NOT qualified'}), simulated in {out['wall_time_s']:.2f} s")
            _print_report(out["report"])
            if out["plot"]:
                print(f"plot: {out['plot']}")
    elif args.command == "evaluate":
        from acc_gym.envs.registration import resolve_env_id
        from acc_gym.evaluation.runner import evaluate

        kwargs = {} if args.drivers is None else {"drivers": args.drivers}
        try:
            resolve_env_id(args.env)  # before the controller loads: an unknown id is named at once
        except ValueError as exc:
            parser.error(f"--env: {exc}")
        try:
            controller = args.controller
            if args.algo is not None:  # a model file or folder of the user's own tooling, algorithm given
                from acc_gym.controllers import load_saved

                controller = load_saved(args.controller, algo=args.algo)
                if controller is None:
                    parser.error(f"--algo: {args.controller!r} is not a stable-baselines3 model file or an rl-zoo3 "
                                 f"run folder")
            summary = evaluate(controller, args.env, args.episodes, args.seed, **kwargs)
        except (ValueError, TypeError) as exc:
            parser.error(str(exc))
        if args.json:
            print(json.dumps(summary))
        else:
            _print_summary(args.controller, args.env, summary)
    return 0


def _print_controllers() -> None:
    """One line per registered name: the name, what it is
    (:func:`acc_gym.controllers.describe_controller`) and, in brackets, where it comes from; a
    plugin that does not load says why, and the list goes on."""
    from acc_gym.controllers import describe_controller

    found = registered_controllers()
    width = max((len(n) for n in found), default=0)
    for name, origin in found.items():
        try:
            what = describe_controller(name) or "(no description: its factory has no docstring)"
        except ValueError as exc:
            what = f"(does not load: {exc})"
        print(f"{name:<{width}}  {what}  [{origin}]")


def _add_campaign_parser(sub) -> None:
    p = sub.add_parser("campaign", help="run or resume a Monte Carlo campaign of a suite's traffic "
                                        "(needs pyarrow; Dask for --scheduler)")
    p.add_argument("--suite", required=True, help="a suite name (singlelane-v3, carfollowing-v1, ncap-v1, ncap-v2, "
                                                   "malicious-v3)")
    p.add_argument("--hours", type=float, required=True, help="hours of traffic to simulate")
    p.add_argument("--controller", required=True, help="a built-in controller, module:attribute or a saved model")
    p.add_argument("--out", required=True, help="output directory (resumed if it holds this campaign)")
    p.add_argument("--split", default="test", help="the suite's split: dev or test (default test)")
    p.add_argument("--root-seed", type=int, default=None, help="root seed (default: the split's own)")
    p.add_argument("--workers", type=int, default=None,
                   help="local worker processes (default: the CPU count); with --scheduler local, the "
                        "LocalCluster's size (default 2)")
    p.add_argument("--scheduler", default=None, help="a Dask scheduler address, or 'local' for a LocalCluster")
    p.add_argument("--chunk-size", type=int, default=20, help="scenarios per task and per result file")
    p.add_argument("--max-chunks", type=int, default=None, help="run at most this many missing chunks now")
    p.add_argument("--confidence", type=float, default=0.95, help="confidence level of the intervals")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")


def _campaign(args, parser) -> int:
    import os

    from acc_gym.campaigns import CampaignError, MissingDependencyError, format_summary, run_campaign

    if args.workers is not None and args.scheduler not in (None, "local"):
        parser.error(f"--workers {args.workers} sets the size of --scheduler local only; a running cluster "
                     f"({args.scheduler}) has its own workers")
    workers = args.workers if args.workers is not None else (2 if args.scheduler else (os.cpu_count() or 1))
    from acc_gym._progress import progress_bar

    bar = progress_bar(f"campaign {args.suite}", unit="chunks", enabled=not args.json)

    def progress(number, n_done, total):
        bar.update(completed=n_done, total=total)

    try:
        with bar:  # from the start: the plan, the workers' start-up and the chunks that are already there
            summary = run_campaign(args.suite, args.hours, args.controller, args.out, split=args.split,
                                   root_seed=args.root_seed, workers=workers, scheduler=args.scheduler,
                                   chunk_size=args.chunk_size, max_chunks=args.max_chunks,
                                   confidence=args.confidence, on_chunk=progress,
                                   on_start=lambda n_done, total: bar.update(completed=n_done, total=total))
    except MissingDependencyError as exc:
        parser.error(str(exc))
    except (CampaignError, ValueError, TypeError, OSError) as exc:
        parser.error(str(exc))
    if args.json:
        print(json.dumps(summary))
    else:
        print(format_summary(summary))
        print(f"results: {args.out} (summary.json, chunks/*.parquet)")
    return 0


def _print_report(r: dict) -> None:
    from acc_gym.evaluation.scoring import report_text

    print(report_text(r, header=False))


def _print_summary(controller: str, env_id: str, s: dict) -> None:
    print(f"{controller} on {env_id}, {s['episodes']} episodes:")
    split = (f" ({s['preventable_collisions']} preventable by UN R157's careful driver, "
             f"{s['non_preventable_collisions']} not)" if s.get("collisions") else "")
    print(f"  mean score {s['mean_score']:.1f}, qualified {s['share_qualified']:.0%}, collisions {s['collisions']}"
          + split)
    safe = "n/a" if s["share_safe_spacing"] is None else f"{s['share_safe_spacing']:.1%}"
    ttc = "none" if s["min_ttc"] is None else f"{s['min_ttc']:.2f} s"
    os_ = "n/a" if s["mean_speed_overshoot"] is None else f"{s['mean_speed_overshoot']:.2f}"
    print(f"  comfortable {s['share_comfortable']:.1%}, safe spacing {safe}, min TTC {ttc}, "
          f"max jerk {s['max_jerk']:.2f} m/s^3, mean speed overshoot {os_}")
    groups = s.get("by_scenario") or {}
    if groups:
        width = max(len(sid) for sid in groups)
        print(f"  {'by scenario':<{width}}  episodes  score  qualified  collisions  unqualified items")
        for sid, g in sorted(groups.items(), key=lambda kv: (-kv[1]["episodes"], kv[0])):
            failed = ", ".join(f"{name} {n}" for name, n in g["failed"].items() if n) or "-"
            print(f"  {sid:<{width}}  {g['episodes']:>8}  {g['mean_score']:>5.1f}  {g['share_qualified']:>9.0%}  "
                  f"{g['collisions']:>10}  {failed}")


def _add_leaderboard_parser(sub) -> None:
    from acc_gym.leaderboard.run import DEFAULT_BUDGET, DEFAULT_STEP_BUDGET, DEFAULT_WORKERS

    from acc_gym.leaderboard.results import RANKING_RULE

    p = sub.add_parser("leaderboard", help="score controllers on versioned suites and rank them",
                       description=f"Score controllers on versioned suites and rank them. Ranking: {RANKING_RULE}. "
                                   f"Paths (run directories, model files) and module:attribute modules are looked "
                                   f"up from the directory the command runs in.",
                       epilog="exit status: 0 every controller finished; 3 at least one controller failed (the "
                              "ranking is printed and the results are written all the same, so a CI job can gate "
                              "on it); 1 the results could not be written or the sandbox cannot run here; 2 bad "
                              "arguments.")
    p.add_argument("--suite", action="append", default=None,
                   help="a suite (carfollowing-v1, malicious-v3, ncap-v1, ncap-v2, singlelane-v3); repeat or "
                        "comma-separate for several (default: all of them)")
    p.add_argument("--split", default="test",
                   help="dev, test or private (default test): develop on dev, publish on test, rank officially "
                        "on private")
    p.add_argument("--secret", default=None, metavar="FILE",
                   help="the host's secret for --split private: a file only its owner can read (mode 0600; "
                        "never the environment); only its commitment is recorded")
    p.add_argument("--controllers", nargs="+", default=None,
                   help="built-in names, module:attribute or saved model paths (default: every built-in "
                        "and the shipped policies ppo-acc and ppo)")
    p.add_argument("--out", default="leaderboard", help="output directory (default leaderboard/)")
    p.add_argument("--workers", type=int, default=DEFAULT_WORKERS, help="controllers run in parallel")
    p.add_argument("--step-budget", type=float, default=DEFAULT_STEP_BUDGET,
                   help="seconds per observation row of a round trip: the simulation sends up to 16 episodes' "
                        "rows at a time and a round trip of n rows may take n times this, so one slow call "
                        "among fast ones can pass (default %(default)g; the first round trip is exempt)")
    p.add_argument("--budget", type=float, default=DEFAULT_BUDGET, help="seconds per controller in all")
    p.add_argument("--episodes", type=int, default=None, help="run at most N episodes of each suite")
    p.add_argument("--no-report", action="store_true", help="skip report.html (and its episode re-runs)")
    p.add_argument("--sandbox", choices=("process", "bwrap"), default="process",
                   help="how controllers are contained: process (own process, session, limits and, as root, "
                        "user id) or bwrap (bubblewrap: read-only root, no network, own PID namespace)")
    from acc_gym.leaderboard.sandbox import Limits

    p.add_argument("--allow-root", action="store_true",
                   help="run strangers' controllers (module:attribute, model files, other packages' entry points) "
                        "as root even where they cannot get a user id of their own; the reports then say so "
                        "(refused otherwise; the built-ins always run)")
    p.add_argument("--log-limit", type=float, default=Limits.log_bytes / 2**20, metavar="MiB",
                   help="of a controller's output kept in its log; the rest is dropped with a note (default "
                        "%(default)g)")
    p.add_argument("--memory", type=float, default=Limits.memory_bytes / 2**30, metavar="GiB",
                   help="per controller: its whole process tree's where a cgroup can be made (root), else each "
                        "process's address space (default %(default)g)")
    p.add_argument("--processes", type=int, default=Limits.processes,
                   help="processes and threads per controller (a pids cgroup as root, else RLIMIT_NPROC with its "
                        "own user id; default %(default)s)")
    p.add_argument("--tmp-size", type=float, default=Limits.tmp_bytes / 2**20, metavar="MiB",
                   help="of a controller's private /tmp and /dev/shm (in RAM; default %(default)g)")
    p.add_argument("--disk-limit", type=float, default=Limits.disk_bytes / 2**20, metavar="MiB",
                   help="what a controller's working directory may hold; past it the controller is killed and "
                        "fails (default %(default)g)")
    p.add_argument("--risk", action="store_true",
                   help="add each controller's collision probability per encounter, estimated by importance "
                        "sampling in the same sandbox (acc-gym risk; slower)")
    p.add_argument("--risk-family", default="cut-in", help="the family of --risk (default cut-in)")
    p.add_argument("--risk-budget", type=int, default=4096, help="episodes per controller for --risk (default 4096)")
    p.add_argument("--no-string-stability", action="store_true",
                   help="skip the string-stability column (8 copies of each controller in a column, measured in "
                        "the same sandbox after its episodes: a few seconds each)")
    p.add_argument("--no-iso15622", action="store_true",
                   help="skip the ISO 15622 column (the iso15622-v1 battery, 30 episodes per controller in its "
                        "sandbox: a few seconds each; it does not change points or rank)")
    p.add_argument("--json", action="store_true", help="print the ranking as one JSON object")


def _limits(args):
    from acc_gym.leaderboard.sandbox import Limits

    return Limits(log_bytes=int(args.log_limit * 2**20), memory_bytes=int(args.memory * 2**30),
                  processes=args.processes, tmp_bytes=int(args.tmp_size * 2**20),
                  disk_bytes=int(args.disk_limit * 2**20))


def _leaderboard(args, parser) -> int:
    import contextlib

    from acc_gym.leaderboard import run_leaderboard
    from acc_gym.leaderboard.progress import LeaderboardProgress
    from acc_gym.leaderboard.results import text_table
    from acc_gym.leaderboard.run import OutputError, default_controllers
    from acc_gym.suites import list_suites

    suites = None if args.suite is None else [s.strip() for arg in args.suite for s in arg.split(",") if s.strip()]
    bar = None if args.json else LeaderboardProgress(args.controllers or default_controllers(),
                                                     len(suites or list_suites()), max(1, args.workers))

    def show(results):  # the ranking, printed before anything is written
        if args.json:
            by_name = {c["name"]: c for c in results["controllers"]}
            print(json.dumps({"ranking": [{"controller": n, "rank": by_name[n]["rank"], "status": by_name[n]["status"],
                                           "reason": by_name[n]["reason"],
                                           "summary": by_name[n]["summary"] and by_name[n]["summary"]["overall"],
                                           **({"risk": by_name[n].get("risk")} if args.risk else {}),
                                           **({} if args.no_string_stability else
                                              {"string_stability": by_name[n].get("string_stability")}),
                                           **({} if args.no_iso15622 else {"iso15622": by_name[n].get("iso15622")})}
                                          for n in results["ranking"]], "out": str(args.out)}), flush=True)
        else:
            bar.__exit__(None, None, None)  # the bar's last line stays, the table comes below it
            m = results["manifest"]
            print(f"leaderboard, split {m['split']}: " + ", ".join(
                f"{s['name']} ({s['episodes_run']} episodes, sha256 {s['hash'][:12]})" for s in m["suites"]))
            print(text_table(results), flush=True)

    try:
        secret = None
        if args.secret is not None:
            from acc_gym.suites.private import read_secret

            secret = read_secret(args.secret)
        with bar if bar is not None else contextlib.nullcontext():
            results = run_leaderboard(suites, args.split, args.controllers, out=args.out, workers=args.workers,
                                      step_budget=args.step_budget, budget=args.budget, episodes=args.episodes,
                                      report=not args.no_report, progress=bar and bar.finished, sandbox=args.sandbox,
                                      episode_progress=bar and bar.episode,
                                      show=show, phase=bar and bar.phase,
                                      secret=secret, risk={"family": args.risk_family, "budget": args.risk_budget}
                                      if args.risk else None, string_stability=not args.no_string_stability,
                                      iso15622=not args.no_iso15622, allow_root=args.allow_root,
                                      limits=_limits(args))
    except (OutputError, RuntimeError) as exc:  # a failed write, or a sandbox this machine cannot give
        print(f"acc-gym leaderboard: error: {exc}", file=sys.stderr)
        return 1
    except (ValueError, TypeError) as exc:
        parser.error(str(exc))
    if not args.json:
        print(f"files: {args.out}/ ({', '.join(sorted(results['files']))}, logs/) "
              f"({results['manifest']['timings']['total_wall_s']:.0f} s)")
    failed = [c["name"] for c in results["controllers"] if c["status"] != "ok"]
    if failed:  # the exit status of the epilog: a CI job fails on it
        print(f"acc-gym leaderboard: {len(failed)} controller(s) failed: {', '.join(failed)} (exit status 3)",
              file=sys.stderr)
        return 3
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
