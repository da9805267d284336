"""Argument parsing shared by the ``acc-gym`` subcommands."""

from __future__ import annotations


def number_params(items: list[str], parser, flag: str = "--param") -> dict[str, float]:
    """``NAME=VALUE`` items (a repeatable ``flag``) as ``{name: float}``; a malformed one is the
    parser's error naming it."""
    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            parser.error(f"{flag} {item!r}: expected NAME=VALUE with a number")
        if not sep or not name.strip():
            parser.error(f"{flag} {item!r}: expected NAME=VALUE")
    return out


def add_onboard_args(p, sensors: bool = True, v2v: bool = True) -> None:
    """``--sensors`` (with ``sensors``), ``--actuators``, ``--actuator-lag`` and
    ``--actuator-delay`` (:mod:`acc_gym.onboard`), and ``--v2v-link`` with ``sensors`` and ``v2v``."""
    from acc_gym.onboard import PRESETS

    g = p.add_argument_group("sensors and actuators (acc_gym.onboard; default: ideal, none modelled)")
    if sensors:
        g.add_argument("--sensors", default=None, choices=PRESETS, help="the radar's preset")
        if v2v:
            g.add_argument("--v2v-link", default=None, choices=PRESETS, help="the V2V link's preset (with --v2v)")
    g.add_argument("--actuators", default=None, choices=PRESETS, help="the powertrain's preset")
    g.add_argument("--actuator-lag", type=float, default=None, metavar="S",
                   help="the actuators' first-order lag [s] (replaces the preset's)")
    g.add_argument("--actuator-delay", type=float, default=None, metavar="S",
                   help="the actuators' dead time [s] (replaces the preset's)")


def onboard_kwargs(args, parser) -> dict:
    """``{"sensors": ..., "actuators": ...}`` for the options given (none: ``{}``); a bad
    number is the parser's error naming it."""
    from dataclasses import replace

    from acc_gym.onboard import actuator_config

    out = {}
    if getattr(args, "sensors", None) is not None:
        out["sensors"] = args.sensors
    if getattr(args, "v2v_link", None) is not None:
        out["v2v_link"] = args.v2v_link
    if args.actuators is not None or args.actuator_lag is not None or args.actuator_delay is not None:
        changes = {k: v for k, v in (("lag", args.actuator_lag), ("dead_time", args.actuator_delay)) if v is not None}
        try:
            out["actuators"] = replace(actuator_config(args.actuators), **changes)
        except ValueError as exc:
            flag = "--actuator-lag" if "lag" in str(exc) else "--actuator-delay"
            parser.error(f"{flag}: {exc}")
    return out
