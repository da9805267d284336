"""``acc-gym leaderboard``: score controllers, each in its own sandbox, on versioned suites,
print the ranking and write the results (:mod:`acc_gym.leaderboard`)."""

from __future__ import annotations

import json
import sys

from acc_gym.commands._args import add_onboard_args, onboard_kwargs


def add_parser(sub) -> None:
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
    p.add_argument("--no-waves", action="store_true",
                   help="skip the wave column (each controller drives one vehicle of five rings of 22 human-like "
                        "drivers: its ring's speed sd over the all-human ring's; about 5 s each; it does not "
                        "change points or rank)")
    p.add_argument("--no-robustness", action="store_true",
                   help="skip the robustness column (each controller drives the ncap-v2 test episodes in a car with "
                        "the typical radar and actuators: share qualified and collisions; a few seconds each; it "
                        "does not change points or rank)")
    p.add_argument("--alks", action="store_true",
                   help="add the UN R157 column: each controller drives the shipped ALKS OpenSCENARIO bundle as the "
                        "suite alks-v1 (43 episodes; about 25 s each; it does not change points or rank)")
    p.add_argument("--json", action="store_true", help="print the ranking as one JSON object")
    add_onboard_args(p, v2v=False)  # the suites' episodes in that car (the ranking is then that car's)


def _limits(args):
    from acc_gym.leaderboard.sandbox import Limits

    return Limits(log_bytes=int(args.log_limit * 2**20), memory_bytes=int(args.memory * 2**30),
                  processes=args.processes, tmp_bytes=int(args.tmp_size * 2**20),
                  disk_bytes=int(args.disk_limit * 2**20))


def run(args, parser) -> int:
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
                                           **({} if args.no_iso15622 else {"iso15622": by_name[n].get("iso15622")}),
                                           **({} if args.no_waves else {"waves": by_name[n].get("waves")}),
                                           **({} if args.no_robustness else
                                              {"robustness": by_name[n].get("robustness")}),
                                           **({"alks": by_name[n].get("alks")} if args.alks else {})}
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
                                      iso15622=not args.no_iso15622, waves=not args.no_waves,
                                      robustness=not args.no_robustness, alks=args.alks,
                                      car=onboard_kwargs(args, parser) or None,
                                      allow_root=args.allow_root,
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
