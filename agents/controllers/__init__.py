"""Hand-written controllers with the stable-baselines3 call shape.

Every controller offers ``predict(obs, deterministic=True) -> (action, None)`` on the
environment's observation (a single ``(7,)``/``(11,)`` vector or a batch ``(n, 7)``) and
``reset()``, so the evaluator treats them and trained policies alike. Built-in names
(:data:`BUILTINS`) are what ``acc-gym evaluate NAME`` accepts.
"""

from agents.controllers.linear import ConstantSpeed, LinearACC

BUILTINS = {"acc": LinearACC, "constant": ConstantSpeed}

__all__ = ["BUILTINS", "ConstantSpeed", "LinearACC"]
