"""``acc-gym train``: a subcommand this package adds to the core CLI (entry point group
``acc_gym.cli``), so the core imports nothing from here; training itself needs the ``rl``
extra (stable-baselines3, torch), imported only when the command runs."""

from __future__ import annotations

import json


class _Train:
    name = "train"

    @staticmethod
    def add_parser(sub) -> None:
        from acc_gym_agents.rl.policy import ALGOS  # numpy only: the parser stays cheap

        p_tr = sub.add_parser("train", help="train an ACC policy with stable-baselines3 (needs the rl extra)")
        p_tr.add_argument("algo", choices=list(ALGOS),
                          help="the algorithm (tqc and crossq: sb3-contrib's)")
        p_tr.add_argument("--env", default="acc_gym/CarFollowing-v0",
                          help="an environment id, plain (acc_gym/CarFollowing-v0) or module-qualified "
                               "(acc_gym:acc_gym/CarFollowing-v0, the form subprocess workers need)")
        p_tr.add_argument("--timesteps", type=int, default=None,
                          help="training steps (default: the tuned n_timesteps, else 100000)")
        p_tr.add_argument("--seed", type=int, default=0,
                          help="seed of the training environments and the model (default 0); the evaluations use "
                               "held-out seeds from seed + 1000003")
        p_tr.add_argument("--out", required=True, help="run directory (model, checkpoints, evaluations, manifest)")
        p_tr.add_argument("--num-envs", type=int, default=None,
                          help="parallel environments (default: the tuned n_envs, else 8)")
        p_tr.add_argument("--eval-freq", type=int, default=None, help="timesteps between evaluations (default T/5)")
        p_tr.add_argument("--eval-episodes", type=int, default=5,
                          help="episodes of each evaluation (at every --eval-freq and at the end), on held-out "
                               "seeds, scored by the 100-point score (default 5)")
        p_tr.add_argument("--no-progress", action="store_true",
                          help="no progress bar (it is drawn on stderr, and only when stderr is a terminal)")
        p_tr.add_argument("--residual", default=None, choices=["acc", "constant"],
                          help="learn a residual on this base controller: clip(base + scale * policy, -1, 1)")
        p_tr.add_argument("--residual-scale", type=float, default=0.3, help="scale of the residual action")
        p_tr.add_argument("--residual-kwargs", default=None,
                          help='JSON settings of the base controller, e.g. \'{"k1": 0.8, "s0": 0.5}\'')
        p_tr.add_argument("--max-overspeed", type=float, default=None,
                          help="with --residual: cap the speed at the set speed plus this [m/s]")
        p_tr.add_argument("--shield", nargs="?", const="proper-response", default=None,
                          choices=("proper-response", "base"),
                          help="with --residual: brake >= 2.5 m/s^2 whenever the observed Q = gap - Gapsafe < 0 "
                               "('base': and at least as hard as the base controller)")
        p_tr.add_argument("--score-bonus", type=float, default=0.0,
                          help="add BONUS * score / 100 to each episode's last reward")
        p_tr.add_argument("--scenarios", nargs="+", default=None, help="scenario ids or families to train on")
        p_tr.add_argument("--weights", nargs="+", type=float, default=None, help="their sampling weights")
        p_tr.add_argument("--mix", nargs="+", default=None, metavar="NAME=SHARE",
                          help="train on families (or ids) with these shares, e.g. singlelane=0.75 carfollowing=0.25")
        p_tr.add_argument("--train-scoring", default=None,
                          help='JSON scoring settings for the training environments only (reward, termination, score '
                               'bonus), e.g. \'{"lead_margin": 1.0}\'; evaluations use the default scoring')
        p_tr.add_argument("--torch-threads", type=int, default=1,
                          help="torch's threads for this run (default 1: faster for these small networks, and "
                               "the count the shipped results were trained with; 0: torch's default)")
        p_tr.add_argument("--algo-kwargs", default=None,
                          help='JSON keyword arguments of the algorithm, e.g. \'{"policy_kwargs": {"log_std_init": -2}}\' '
                               '(without it, a plain run takes the tuned hyperparameters of the algorithm and env id '
                               'from acc_gym_agents/rl/hyperparams/<algo>.yml where there are any; \'{}\': '
                               'stable-baselines3\'s own defaults)')

    @staticmethod
    def run(args, parser) -> int:
        from acc_gym.envs.registration import resolve_env_id

        try:
            resolve_env_id(args.env)  # named at once, before torch loads
        except ValueError as exc:
            parser.error(f"--env: {exc}")
        try:
            from acc_gym_agents.rl.train import train
        except ImportError as exc:
            parser.error(f"training needs stable-baselines3 and torch: pip install 'acc-gym[rl]' ({exc})")
        try:
            env_settings = {k: tuple(v) for k, v in (("scenarios", args.scenarios), ("weights", args.weights))
                            if v is not None}
            algo_kwargs = json.loads(args.algo_kwargs) if args.algo_kwargs else None
            mix = None
            if args.mix:
                if not all("=" in m for m in args.mix):
                    raise ValueError(f"--mix takes NAME=SHARE items, got {args.mix}")
                mix = {m.split("=", 1)[0]: float(m.split("=", 1)[1]) for m in args.mix}
            run = train(args.algo, args.env, args.timesteps, args.seed, args.out, args.num_envs, args.eval_freq,
                        args.eval_episodes, progress=not args.no_progress, algo_kwargs=algo_kwargs,
                        residual=args.residual, residual_scale=args.residual_scale, shield=args.shield,
                        residual_kwargs=json.loads(args.residual_kwargs) if args.residual_kwargs else None,
                        max_overspeed=args.max_overspeed,
                        score_bonus=args.score_bonus,
                        train_scoring=json.loads(args.train_scoring) if args.train_scoring else None,
                        mix=mix, torch_threads=args.torch_threads or None, **env_settings)
        except (ValueError, TypeError) as exc:
            parser.error(str(exc))
        final = json.loads((run / "manifest.json").read_text())["final_evaluation"]
        print(f"{args.algo} on {args.env}: {final['timesteps']} timesteps; held-out evaluation: mean score "
              f"{final['mean_score']:.1f}, qualified {final['share_qualified']:.0%}, collisions {final['collisions']}")
        print(f"run directory: {run}  (score it: acc-gym evaluate {run} --env {args.env})")
        return 0


TRAIN = _Train()
