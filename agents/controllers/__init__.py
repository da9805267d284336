"""Hand-written controllers with the stable-baselines3 call shape.

Every controller offers ``predict(obs, deterministic=True) -> (action, None)`` on the
environment's observation (a single ``(7,)``/``(11,)`` vector or a batch ``(n, 7)``) and
``reset()``, so the evaluator treats them and trained policies alike. Built-in names
(:data:`BUILTINS`, factories) are what ``acc-gym evaluate NAME`` accepts.
"""

from acc_gym_agents.controllers.cc_driver import CCDriver, cc_driver
from acc_gym_agents.controllers.fsm_driver import FSMDriver, fsm_driver
from acc_gym_agents.controllers.linear import ConstantSpeed, LinearACC
from acc_gym_agents.controllers.models import ModelController, cacc, fuzzy, gipps, gm, idm, mp_cacc, mpc
from acc_gym_agents.controllers.stern import FollowerStopper, PISaturation

BUILTINS = {"acc": LinearACC, "cacc": cacc, "mp-cacc": mp_cacc, "idm": idm, "gipps": gipps, "gm": gm,
            "fuzzy": fuzzy, "mpc": mpc, "constant": ConstantSpeed, "cc-driver": cc_driver,
            "fsm-driver": fsm_driver, "follower-stopper": FollowerStopper, "pi-saturation": PISaturation}

__all__ = ["BUILTINS", "CCDriver", "ConstantSpeed", "FSMDriver", "fsm_driver", "LinearACC", "ModelController", "cacc", "fuzzy", "gipps", "gm", "idm",
           "cc_driver", "mp_cacc", "mpc", "FollowerStopper", "PISaturation"]
