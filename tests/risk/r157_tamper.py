"""A controller that tries to rig UN R157's verdict from its own process (loaded as
``r157_tamper:PatchesCarefulDriver`` by the isolation tests, in its sandbox only).

It never brakes (action 0, as the built-in ``constant``), after patching, in the process it
is loaded in, the careful driver to floor the throttle and :func:`acc_gym.standards.r157.collides`
to answer True: were the re-drive done where the controller runs, every collision of its
would come out non-preventable."""

import importlib

import numpy as np


class PatchesCarefulDriver:
    def __init__(self):
        cc = importlib.import_module("acc_gym_agents.controllers.cc_driver")
        r157 = importlib.import_module("acc_gym.standards.r157")

        def floor_it(self, obs, deterministic=True):
            rows = np.atleast_2d(np.asarray(obs, dtype=float)).shape[0]
            act = np.ones((rows, 1), dtype=np.float32)
            return (act[0] if np.ndim(obs) == 1 else act), None

        cc.CCDriver.predict = floor_it
        r157.collides = lambda *args, **kwargs: True
        print("TAMPER patched cc-driver and r157.collides", flush=True)

    def predict(self, obs, deterministic=True):
        return np.zeros(1, dtype=np.float32), None
