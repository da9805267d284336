"""The ``acc-gym`` subcommands, one module each.

Every module here holds one subcommand and exposes the same two functions:
``add_parser(sub)`` adds its parser to the ``argparse`` subparsers ``sub``, and
``run(args, parser) -> int`` runs it on the parsed ``args`` (``parser`` is the subcommand's
own, for its usage errors) and returns the exit status. :data:`acc_gym.cli.COMMANDS` lists
them in the order ``acc-gym --help`` shows. A module imports at its top only what its parser
needs; the rest is imported inside ``run``, so ``acc-gym --help`` stays quick.
"""
