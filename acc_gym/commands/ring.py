"""``acc-gym ring``: a ring road of human-like drivers, optionally with a controller under test
(:mod:`acc_gym.simulation.ring`), and its wave measures (:mod:`acc_gym.evaluation.waves`)."""

from __future__ import annotations

import io
import json

import numpy as np

from acc_gym.commands._args import add_onboard_args, number_params, onboard_kwargs
from acc_gym.drivers.mpc import DRIVER_MODELS, MODEL_VERSION
from acc_gym.evaluation import waves as W
from acc_gym.simulation import ring as R

JSON_KEYS = ("controller", "vehicles", "length", "drivers", "driver_model", "penetration", "seed", "duration", "mean_speed",
             "speed_sd", "stops", "jam", "jam_onset_s", "wave_speed_kmh", "braking_events", "energy_kwh_per_100km",
             "collisions")


def add_parser(sub) -> None:
    p = sub.add_parser("ring", help="a ring road of human-like drivers (Sugiyama's circuit), optionally with a "
                                    "controller in one or more positions: does a stop-and-go wave form?")
    p.add_argument("controller", nargs="?", default=None,
                   help="a registered name, module:attribute or a saved model (default: human drivers only)")
    p.add_argument("--vehicles", type=int, default=22, help="vehicles on the ring (default 22, Sugiyama's)")
    p.add_argument("--length", type=float, default=230.0, help="the ring's length [m] (default 230, Sugiyama's)")
    p.add_argument("--drivers", default="naturalistic", help="the human drivers' population (typical, atypical, "
                                                             "naturalistic, malicious; default naturalistic)")
    p.add_argument("--penetration", type=float, default=None,
                   help="share of the vehicles the controller drives, spread evenly (default: one vehicle)")
    p.add_argument("--seed", type=int, default=0, help="the ring's seed (its human drivers' draw)")
    p.add_argument("--duration", type=float, default=600.0, help="simulated time [s] (default 600)")
    p.add_argument("--warmup", type=float, default=W.WARMUP,
                   help=f"measures start after this [s] (default {W.WARMUP:g}; the jam onset counts from 0)")
    p.add_argument("--v-desired", type=float, default=R.SUGIYAMA_SPEED,
                   help="the human drivers' desired speed [m/s] (default 30 km/h, Sugiyama's instruction)")
    p.add_argument("--set-speed", type=float, default=None,
                   help="the set speed in the controller's observation [m/s] (default: --v-desired)")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="a parameter of a built-in controller (repeatable), e.g. --param v_des=3 for follower-stopper")
    p.add_argument("--driver-model", type=int, default=MODEL_VERSION, choices=sorted(DRIVER_MODELS),
                   help=f"the human drivers' model version (default {MODEL_VERSION}: with a reaction time, they jam; "
                        "5: paper 001's MPC as the other ids drive it, which does not jam)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    add_onboard_args(p, sensors=False)  # the controller's actuators (the ring's observation has no radar model)
    p.add_argument("--trace", default=None, metavar="PATH.csv",
                   help="write every step as CSV: t, vehicle, x, v, a, controlled (x along the ring in [0, L))")
    p.add_argument("--plot", default=None, metavar="PATH", help="save the space-time diagram and the speeds")


def run(args, parser) -> int:
    from acc_gym.controllers import make_controller
    from acc_gym.evaluation.runner import load_controller

    params = number_params(args.param, parser)
    ctl = None
    try:
        if args.controller is not None:
            ctl = make_controller(args.controller, **params) if params else load_controller(args.controller)
            if ctl is None:
                parser.error(f"--param needs a registered controller name; {args.controller!r} is not one")
        elif args.penetration is not None or params:
            parser.error("--penetration and --param need a controller")
        positions = R.controlled_positions(args.vehicles, args.penetration) if ctl is not None else ()
        if ctl is not None and not positions:
            parser.error(f"--penetration {args.penetration:g} of {args.vehicles} vehicles leaves the controller none")
        trace = R.simulate_ring(args.length, args.vehicles, layout=R.ring_layout(args.vehicles, positions),
                                drivers=args.drivers, seeds=[args.seed], duration=args.duration,
                                v_desired=args.v_desired, controller=ctl, set_speed=args.set_speed,
                                driver_model=args.driver_model, **onboard_kwargs(args, parser))
        report = W.ring_waves(trace, warmup=args.warmup)[0]
    except (ValueError, TypeError) as exc:
        parser.error(str(exc))
    out = {"controller": args.controller, "vehicles": args.vehicles, "length": args.length,
           "drivers": args.drivers, "driver_model": args.driver_model,
           "penetration": (len(positions) / args.vehicles) if ctl is not None else 0.0, "seed": args.seed,
           "duration": args.duration, **{k: v for k, v in report.to_dict().items() if k in JSON_KEYS}}
    out = {k: out[k] for k in JSON_KEYS}
    if args.trace:
        write_trace(trace, args.trace)
    if args.plot:
        plot_ring(trace, path=args.plot)
    if args.json:
        print(json.dumps(out))
    else:
        print(summary(out, report))
        for what, path in (("trace", args.trace), ("plot", args.plot)):
            if path:
                print(f"{what}: {path}")
    return 0


def summary(out: dict, report: W.WaveReport) -> str:
    who = out["controller"] or "human drivers only"
    jam = f"yes, from {out['jam_onset_s']:.0f} s" if out["jam"] else "no"
    c = "-" if out["wave_speed_kmh"] is None else f"{out['wave_speed_kmh']:+.1f} km/h"
    e = "-" if out["energy_kwh_per_100km"] is None else f"{out['energy_kwh_per_100km']:.2f} kWh/100 km"
    return "\n".join([
        f"ring {out['length']:g} m, {out['vehicles']} vehicles ({out['drivers']}), {who}, seed {out['seed']}, "
        f"{out['duration']:g} s (measures after {report.warmup_s:g} s)",
        f"  mean speed {out['mean_speed']:.2f} m/s, speed sd {out['speed_sd']:.2f} m/s",
        f"  jam: {jam}; wave speed {c}; stops {out['stops']}, braking events {out['braking_events']}",
        f"  tractive energy {e}; collisions {out['collisions']}"])


def write_trace(trace: R.RingTrace, path) -> None:
    """The first ring of ``trace`` as CSV (``t, vehicle, x, v, a, controlled``), written atomically."""
    from acc_gym._io import atomic_write

    T1, _, N = trace.v.shape
    t = np.repeat(trace.t, N)
    veh = np.tile(np.arange(N), T1)
    ctl = np.tile(trace.controlled.astype(int), T1)
    cols = (t, veh, trace.x[:, 0].reshape(-1), trace.v[:, 0].reshape(-1), trace.a[:, 0].reshape(-1), ctl)
    buf = io.StringIO()
    buf.write("t,vehicle,x,v,a,controlled\n")
    np.savetxt(buf, np.column_stack(cols), fmt=["%.3f", "%d", "%.6f", "%.6f", "%.6f", "%d"], delimiter=",")
    atomic_write(path, buf.getvalue())


def plot_ring(trace: R.RingTrace, *, path=None, ring: int = 0):
    """Two panels of one ring: the space-time diagram (each vehicle's position along the ring over
    time, coloured by its speed: the figure of Sugiyama's and Stern's papers) and every vehicle's
    speed over time (the controlled ones in black). ``path``: also save it (atomically)."""
    import matplotlib
    from matplotlib.collections import LineCollection
    from matplotlib.figure import Figure

    from acc_gym.plotting import save_figure

    fig = Figure(figsize=(11.0, 4.5), layout="constrained")
    ax_st, ax_v = fig.subplots(1, 2)
    t, x, v = trace.t, trace.x[:, ring], trace.v[:, ring]
    norm = matplotlib.colors.Normalize(0.0, max(float(v.max()), 1e-6))
    for j in range(x.shape[1]):
        pts = np.column_stack([t, x[:, j]])
        seg = np.stack([pts[:-1], pts[1:]], axis=1)
        keep = np.diff(x[:, j]) >= 0  # no line across the seam of the ring
        lc = LineCollection(seg[keep], cmap="viridis", norm=norm, linewidths=0.8)
        lc.set_array(v[:-1, j][keep])
        ax_st.add_collection(lc)
    ax_st.set_xlim(t[0], t[-1])
    ax_st.set_ylim(0.0, trace.length)
    ax_st.set_xlabel("time [s]")
    ax_st.set_ylabel("position along the ring [m]")
    ax_st.set_title(f"ring of {trace.length:g} m, {x.shape[1]} vehicles (seed {trace.seeds[ring]})", fontsize=10)
    fig.colorbar(matplotlib.cm.ScalarMappable(norm=norm, cmap="viridis"), ax=ax_st, label="speed [m/s]")
    ctl = trace.controlled
    for j in range(v.shape[1]):
        ax_v.plot(t, v[:, j], lw=1.4 if ctl[j] else 0.6, color="k" if ctl[j] else "tab:blue",
                  alpha=1.0 if ctl[j] else 0.4, label="controlled" if ctl[j] and j == np.argmax(ctl) else None)
    ax_v.set_xlabel("time [s]")
    ax_v.set_ylabel("speed [m/s]")
    ax_v.grid(True, alpha=0.3)
    if ctl.any():
        ax_v.legend(fontsize=8)
    if path is not None:
        save_figure(fig, path)
    return fig
