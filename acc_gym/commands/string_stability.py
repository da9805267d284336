"""``acc-gym string-stability``: is a controller string stable? (:mod:`acc_gym.evaluation.string_stability`)."""

from __future__ import annotations

import json

from acc_gym.commands._args import add_onboard_args, number_params, onboard_kwargs
from acc_gym.drivers.mpc import DRIVER_MODELS, ENV_DRIVER_MODEL
from acc_gym.evaluation import string_stability as ss


def add_parser(sub) -> None:
    p = sub.add_parser("string-stability",
                       help="does a speed disturbance grow down a column of copies of a controller? (frequency "
                            "response, a Gunter-like disturbance, verdict: largest gain <= 1 + %g)" % ss.TOLERANCE)
    p.add_argument("controller", help="a registered name, module:attribute, a saved model, or 'human' (the human-like "
                                      "drivers of --drivers alone)")
    p.add_argument("--vehicles", type=int, default=8, help="copies behind the lead (1-100, default 8)")
    p.add_argument("--speed", type=float, default=20.0, help="operating speed [m/s] (default 20)")
    p.add_argument("--set-speed", type=float, default=None, help="set speed in the observation [m/s] (default: "
                                                                  "speed + 5)")
    p.add_argument("--time-gap", type=float, default=None, help="time gap in the observation [s] (default: the "
                                                                 "controller's declared one, else 1.5)")
    p.add_argument("--v2v", action="store_true", help="observe the vehicle ahead's acceleration and the second "
                                                       "vehicle ahead (CACC)")
    p.add_argument("--penetration", type=float, default=1.0,
                   help="share of the positions the controller drives; human-like MPC drivers the others "
                        "(default 1)")
    p.add_argument("--drivers", default="typical", help="the human drivers' population (typical, atypical, "
                                                        "naturalistic, malicious)")
    p.add_argument("--driver-model", type=int, default=ENV_DRIVER_MODEL, choices=sorted(DRIVER_MODELS),
                   help="the human drivers' model version (default %d, the environments'; 6 adds a 1.0 s reaction "
                        "time with anticipation, a reflex and a following rule)" % ENV_DRIVER_MODEL)
    p.add_argument("--seed", type=int, default=0, help="the human drivers' draw (and the stop-and-go trace's)")
    p.add_argument("--frequencies", type=float, nargs="+", default=None, metavar="HZ",
                   help="the sweep's frequencies [Hz] (default: 25 from 0.005 to 1, log-spaced)")
    p.add_argument("--no-disturbance", action="store_true", help="skip the Gunter-like disturbance")
    p.add_argument("--lead-trace", default=None, metavar="stopandgo|FILE.csv",
                   help="also drive the lead on a trace: 'stopandgo' (human-like wave) or a CSV with columns t, v")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="a parameter of a built-in controller (repeatable), e.g. --param k1=0.4 for acc")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    # the controller's actuators (the radar is not modelled here: the sweep measures the loop's gains)
    add_onboard_args(p, sensors=False)
    p.add_argument("--plot", default=None, metavar="PATH", help="save |Gamma| against frequency and the "
                                                                 "disturbance's space-time diagram")


def run(args, parser) -> int:
    from acc_gym.controllers import make_controller

    from acc_gym._progress import progress_bar

    params = number_params(args.param, parser)
    controller = args.controller
    # one batched simulation: no count to show, but the time it has taken from the start
    bar = progress_bar(f"string-stability: {args.vehicles} copies of {args.controller}", enabled=not args.json)
    try:
        bar.start()
        if params:
            controller = make_controller(args.controller, **params)
            if controller is None:
                parser.error(f"--param needs a registered controller name; {args.controller!r} is not one")
        config = ss.PlatoonConfig(vehicles=args.vehicles, speed=args.speed, set_speed=args.set_speed,
                                  time_gap=args.time_gap, penetration=args.penetration, drivers=args.drivers,
                                  seed=args.seed, v2v=args.v2v, driver_model=args.driver_model,
                                  **onboard_kwargs(args, parser))
        trace = None if args.lead_trace is None else ss.lead_trace(args.lead_trace, args.seed)
        report = ss.string_stability(controller, config, frequencies=args.frequencies,
                                     disturbance=not args.no_disturbance, trace=trace, name=args.controller)
    except (ValueError, TypeError) as exc:
        bar.close()
        parser.error(str(exc))
    finally:
        bar.close()
    if args.plot:
        from acc_gym.plotting import plot_string_stability

        plot_string_stability(report, path=args.plot)
    if args.json:
        out = report.to_dict()
        if params:
            out["params"] = params
        if args.plot:
            out["plot"] = args.plot
        print(json.dumps(out))
    else:
        print(report.summary())
        if args.plot:
            print(f"plot: {args.plot}")
    return 0
