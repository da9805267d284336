"""``acc-gym demo``: one episode of a built-in scenario with a controller; prints the episode
report and saves the episode plot."""

from __future__ import annotations


def add_parser(sub) -> None:
    p = sub.add_parser("demo", help="run one episode of a built-in scenario, print its score, save its plot")
    p.add_argument("--scenario", default="carfollowing/90", help="a scenario id (see: acc-gym scenarios)")
    p.add_argument("--controller", default="acc", help="a built-in controller or module:attribute")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--plot", default="acc_gym_demo.png", help="where to save the episode plot ('' for none)")
    p.add_argument("--json", action="store_true", help="print one JSON object")


def run(args, parser) -> int:
    import json

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
    return 0


def demo(scenario: str = "carfollowing/90", controller: str = "acc", seed: int = 0, plot: str | None = None) -> dict:
    """One episode of ``scenario`` with ``controller``; returns the final info (report included)."""
    import time

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


def _print_report(r: dict) -> None:
    from acc_gym.evaluation.scoring import report_text

    print(report_text(r, header=False))
