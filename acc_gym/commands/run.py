"""``acc-gym run``: run an ASAM OpenSCENARIO file (or a scenario of the shipped UN R157 bundle)
with a controller under test as the ego (:mod:`acc_gym.scenarios.openscenario`)."""

from __future__ import annotations

import io
import json

import numpy as np

JSON_KEYS = ("file", "controller", "ego", "collided", "preventable", "collision_with", "collision_t", "score",
             "qualified", "min_gap", "min_ttc", "iso15622", "activated_at", "ended", "duration", "unsupported", "ignored", "notes")


def add_parser(sub) -> None:
    p = sub.add_parser("run", help="run an ASAM OpenSCENARIO file (1.0-1.3) with a controller as the ego: "
                                   "its score, collision and R157 preventability")
    p.add_argument("file", help="an OpenSCENARIO file (.xosc), or alks:N for a scenario of the shipped UN R157 "
                                "bundle (alks:4.4.2 is the cut-in with an unavoidable collision)")
    p.add_argument("--controller", required=True,
                   help="a registered name, module:attribute or a saved model (acc-gym controllers lists the names)")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="a value for one of the file's declared parameters (repeatable), e.g. "
                        "--param Ego_InitSpeed_Ve0_kph=40")
    p.add_argument("--ego", default=None, help="the entity under test (default: the one named Ego, else the first)")
    p.add_argument("--duration", type=float, default=600.0,
                   help="stop after this [s] if the file's stop trigger has not fired (default 600)")
    p.add_argument("--set-speed", type=float, default=None,
                   help="the ego's set speed [m/s] (default: the ego controller's setSpeed property, else its "
                        "speed when its controller is activated)")
    p.add_argument("--time-gap", type=float, default=None,
                   help="the nominal time gap [s] (default: the ego controller's timeGap property, else 1.5)")
    p.add_argument("--drivers", default=None, metavar="KIND",
                   help="human-like drivers of this population (typical, atypical, malicious, naturalistic) take "
                        "over the other moving vehicles' longitudinal control")
    p.add_argument("--seed", type=int, default=0, help="with --drivers: the drivers' draw (default 0)")
    p.add_argument("--no-preventability", action="store_true",
                   help="do not run R157's cc-driver on the file when the controller collides")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--trace", default=None, metavar="PATH.csv",
                   help="write every step as CSV: t, entity, s, y, v, a, controlled")
    p.add_argument("--plot", default=None, metavar="PATH", help="save the positions, speeds and gap over time")


def run(args, parser) -> int:
    from acc_gym.evaluation.runner import load_controller
    from acc_gym.scenarios.openscenario import OpenScenarioError, read, run_file
    from acc_gym.scenarios.openscenario.bundle import resolve
    from acc_gym.standards.r157 import REFERENCE

    params = {}
    for item in args.param:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            parser.error(f"--param {item!r}: expected NAME=VALUE")
        params[name.strip()] = value.strip()
    try:
        path = resolve(args.file)
        sc = read(path, parameters=params, ego=args.ego)
        ctl = load_controller(args.controller)
        kw = dict(duration=args.duration, set_speed=args.set_speed, time_gap=args.time_gap, scenario=sc,
                  drivers=args.drivers, seed=args.seed)
        result, trace = run_file(path, ctl, **kw)
        preventable = None
        if result["collided"] and not args.no_preventability:
            ref, _ = run_file(path, load_controller(REFERENCE), **kw)
            preventable = not ref["collided"]
    except (OpenScenarioError, ValueError, TypeError) as exc:
        parser.error(str(exc))
    out = {**result, "controller": args.controller, "preventable": preventable}
    out = {k: out[k] for k in JSON_KEYS}
    if args.trace:
        write_trace(trace, args.trace)
    if args.plot:
        plot_run(trace, out, path=args.plot)
    if args.json:
        print(json.dumps(out))
    else:
        print(summary(out))
        for what, p in (("trace", args.trace), ("plot", args.plot)):
            if p:
                print(f"{what}: {p}")
    return 0


def summary(out: dict) -> str:
    col = "no collision"
    if out["collided"]:
        prev = {True: "preventable: R157's cc-driver does not collide", False: "not preventable: the cc-driver "
                "collides too", None: "preventability not checked"}[out["preventable"]]
        col = f"COLLISION with {out['collision_with']} at {out['collision_t']:.1f} s ({prev})"
    fmt = lambda x, u="": "-" if x is None else f"{x:.2f}{' ' + u if u else ''}"  # noqa: E731
    lines = [f"{out['file']}", f"  {out['controller']} drives {out['ego']} from "
             f"{out['activated_at']:.1f} s; ended by {out['ended']} at {out['duration']:.1f} s",
             f"  {col}; min gap {fmt(out['min_gap'], 'm')}, min TTC {fmt(out['min_ttc'], 's')}",
             f"  score {fmt(out['score'])} ({'qualified' if out['qualified'] else 'not qualified'})"]
    iso = out.get("iso15622")
    if iso is not None:
        bad = [r["name"] for r in iso["requirements"] if r["passed"] is False]
        verdict = {True: "inside", False: "outside", None: "not exercised"}[iso["passed"]]
        lines.append(f"  ISO 15622 envelope: {verdict}" + (f" ({', '.join(bad)})" if bad else ""))
    for k in ("unsupported", "ignored", "notes"):
        for item in out[k]:
            lines.append(f"  {k}: {item}")
    return "\n".join(lines)


def write_trace(trace, path) -> None:
    """The run as CSV (``t, entity, s, y, v, a, controlled``), written atomically."""
    from acc_gym._io import atomic_write

    n = trace.s.shape[0]
    buf = io.StringIO()
    buf.write("t,entity,s,y,v,a,controlled\n")
    for k in range(n):
        for j, name in enumerate(trace.names):
            c = int(trace.controlled[k]) if j == trace.ego_index else 0
            buf.write(f"{trace.t[k]:.3f},{name},{trace.s[k, j]:.6f},{trace.y[k, j]:.6f},{trace.v[k, j]:.6f},"
                      f"{trace.a[k, j]:.6f},{c}\n")
    atomic_write(path, buf.getvalue())


def plot_run(trace, out: dict, *, path=None):
    """Three panels: every entity's position along the road, the speeds, and the ego's gap to its
    radar target, over time; the controlled time shaded. ``path``: also save it (atomically)."""
    from matplotlib.figure import Figure

    from acc_gym.plotting import save_figure

    fig = Figure(figsize=(11.0, 7.0), layout="constrained")
    ax_s, ax_v, ax_g = fig.subplots(3, 1, sharex=True)
    for j, name in enumerate(trace.names):
        kw = dict(color="black", lw=1.6) if j == trace.ego_index else dict(lw=1.0)
        ax_s.plot(trace.t, trace.s[:, j], label=name, **kw)
        ax_v.plot(trace.t, trace.v[:, j], label=name, **kw)
    ax_g.plot(trace.t, np.where(np.isfinite(trace.gap), trace.gap, np.nan), color="black")
    on = np.flatnonzero(trace.controlled)
    for ax in (ax_s, ax_v, ax_g):
        if len(on):
            ax.axvspan(trace.t[on[0]], trace.t[on[-1]], color="tab:green", alpha=0.08)
        if out.get("collision_t") is not None:
            ax.axvline(out["collision_t"], color="tab:red", ls="--")
    ax_s.set_ylabel("s [m]")
    ax_v.set_ylabel("speed [m/s]")
    ax_g.set_ylabel("gap to target [m]")
    ax_g.set_xlabel("t [s]")
    ax_s.legend(fontsize=8, loc="upper left")
    ax_s.set_title(f"{out['controller']} on {out['file'].rsplit('/', 1)[-1]}")
    if path is not None:
        save_figure(fig, path)
    return fig
