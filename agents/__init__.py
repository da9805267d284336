"""Controllers under test (hand-written ACC laws and trained policies), installed as
``acc_gym_agents`` (the repository folder is ``agents/``; the installed name is one this
project owns, since other packages install a top-level ``agents``).

They reach the core only through its registry (:mod:`acc_gym.controllers`): the
built-ins and the shipped policy are entry points of the ``acc_gym.controllers`` group,
saved runs open through ``acc_gym.controller_loaders``, and ``acc-gym train`` is a
subcommand of the ``acc_gym.cli`` group. The core imports nothing from here.
"""
