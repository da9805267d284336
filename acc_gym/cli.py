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
    acc-gym controllers                       list the controllers registered by name

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

    acc-gym risk --controller C [--family cut-in] [--event collision] [--method is|crude] [--budget N] [--json]

estimates a controller's rare collision probability per encounter by importance sampling
(see :mod:`acc_gym.risk`).

    acc-gym ring [CONTROLLER] [--vehicles 22] [--length 230] [--penetration P] [--duration 600] [--json]

simulates a ring road of human-like drivers (Sugiyama's circuit), optionally with the
controller in one or more positions, and measures its stop-and-go waves (see
:mod:`acc_gym.simulation.ring`).

    acc-gym conformance CONTROLLER [--standard iso15622|r157|ncap|all] [--seeds 0 1 2] [--json] [--out DIR]

checks a controller against published standards (default all): ISO 15622's ACC envelope on
the iso15622-v1 battery, UN R157's preventability and Euro NCAP 2026's ACC score (see
:mod:`acc_gym.standards`).

    acc-gym campaign --suite S --hours H --controller C --out DIR [--split test] [--root-seed R]
                     [--workers N | --scheduler ADDRESS|local] [--chunk-size K] [--max-chunks M] [--json]

runs (or resumes) a Monte Carlo campaign: H hours of suite S's traffic with controller C,
on N local processes or a Dask cluster, one Parquet file per chunk in DIR, and prints paper
004's metrics with confidence intervals (see :mod:`acc_gym.campaigns`).

Each built-in subcommand is a module of :mod:`acc_gym.commands` with ``add_parser(sub)`` and
``run(args, parser) -> int``; :data:`COMMANDS` lists them in the order ``acc-gym --help``
shows. Other packages add theirs after them through the ``acc_gym.cli`` entry points
(``acc-gym train`` comes from the agents package).
"""

from __future__ import annotations

import argparse
import importlib
import sys

from acc_gym.controllers import cli_plugins

# Every built-in subcommand in the order ``acc-gym --help`` lists them: its name and the module
# (one per command, each with add_parser(sub) and run(args, parser) -> int) that holds it.
COMMANDS = (
    ("scenarios", "acc_gym.commands.scenarios"),
    ("score", "acc_gym.commands.score"),
    ("demo", "acc_gym.commands.demo"),
    ("evaluate", "acc_gym.commands.evaluate"),
    ("driver-demo", "acc_gym.commands.driver_demo"),
    ("controllers", "acc_gym.commands.controllers"),
    ("campaign", "acc_gym.commands.campaign"),
    ("leaderboard", "acc_gym.commands.leaderboard"),
    ("risk", "acc_gym.commands.risk"),
    ("string-stability", "acc_gym.commands.string_stability"),
    ("robustness", "acc_gym.commands.robustness"),
    ("conformance", "acc_gym.commands.conformance"),
    ("ring", "acc_gym.commands.ring"),
    ("run", "acc_gym.commands.run"),
    ("validate", "acc_gym.commands.validate"),
    ("export", "acc_gym.commands.export"),
)


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
    commands = [(name, importlib.import_module(module)) for name, module in COMMANDS]
    commands += cli_plugins().items()  # e.g. acc-gym train, from the acc_gym.cli entry points
    for _, command in commands:
        command.add_parser(sub)
    args = parser.parse_args(argv)
    parser = sub.choices[args.command]  # errors from here on print the subcommand's usage, as parsing errors do
    return dict(commands)[args.command].run(args, parser)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
