"""``acc-gym evaluate``: score a controller over episodes of an environment
(:func:`acc_gym.evaluation.runner.evaluate`) and print the summary."""

from __future__ import annotations

from acc_gym.commands._args import add_onboard_args, onboard_kwargs


def add_parser(sub) -> None:
    p = sub.add_parser("evaluate", help="score a controller over episodes of an environment")
    p.add_argument("controller", help="a built-in name (acc, cacc, mp-cacc, idm, gipps, gm, fuzzy, mpc, "
                                      "constant), the shipped policies ppo-acc and ppo, module:attribute, a "
                                      "run directory of acc-gym train, a stable-baselines3 model file "
                                      "or an rl-zoo3 run folder")
    p.add_argument("--algo", default=None, help="the algorithm of a stable-baselines3 model file or rl-zoo3 "
                                                "folder (ppo, a2c, sac, td3, ddpg; default: read from the file)")
    p.add_argument("--env", default="acc_gym/CarFollowing-v0",
                   help="an environment id, plain (acc_gym/CarFollowing-v0) or module-qualified "
                        "(acc_gym:acc_gym/CarFollowing-v0, the form subprocess workers need)")
    p.add_argument("--episodes", type=int, default=10)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--drivers", default=None, help="surrounding drivers (typical, atypical, malicious, idm, ...)")
    p.add_argument("--v2v", action="store_true", help="observe the vehicle ahead's acceleration and the second "
                                                      "vehicle ahead over V2V (cacc, mp-cacc)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    add_onboard_args(p)


def run(args, parser) -> int:
    import json

    from acc_gym.envs.registration import resolve_env_id
    from acc_gym.evaluation.runner import evaluate

    kwargs = {} if args.drivers is None else {"drivers": args.drivers}
    kwargs.update(onboard_kwargs(args, parser))
    if args.v2v:
        kwargs["v2v"] = True
    elif "v2v_link" in kwargs:
        parser.error("--v2v-link needs --v2v (the link carries the V2V fields)")
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
