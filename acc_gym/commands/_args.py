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
