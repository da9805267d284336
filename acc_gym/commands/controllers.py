"""``acc-gym controllers``: the controllers registered by name (:mod:`acc_gym.controllers`)."""

from __future__ import annotations


def add_parser(sub) -> None:
    sub.add_parser("controllers", help="list the controllers registered by name: what each is, and where it comes from")


def run(args, parser) -> int:
    _print_controllers()
    return 0


def _print_controllers() -> None:
    """One line per registered name: the name, what it is
    (:func:`acc_gym.controllers.describe_controller`) and, in brackets, where it comes from; a
    plugin that does not load says why, and the list goes on."""
    from acc_gym.controllers import describe_controller, registered_controllers

    found = registered_controllers()
    width = max((len(n) for n in found), default=0)
    for name, origin in found.items():
        try:
            what = describe_controller(name) or "(no description: its factory has no docstring)"
        except ValueError as exc:
            what = f"(does not load: {exc})"
        print(f"{name:<{width}}  {what}  [{origin}]")
