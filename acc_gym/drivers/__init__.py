"""Driver models: the MPC human-like driver, its population and calibration, and baselines.

All models control a batch of vehicles and share one call shape: ``act(obs) -> a_des``
(see :mod:`acc_gym.drivers.base`).
"""

from acc_gym.drivers.base import NO_VEHICLE, DelayBuffer, Observation
from acc_gym.drivers.baselines import (ACC, GM, IDM, MODELS, Fuzzy, Gipps, Newell, Pipes, Tyler, ACCParams,
                                       FuzzyParams, GippsParams, GMParams, IDMParams, NewellParams, PipesParams,
                                       TylerParams, cacc_params, mp_cacc_params)
from acc_gym.drivers.calibration import CalibrationResult, calibrate_weights
from acc_gym.drivers.mpc import PRESETS, Mode, MPCDriver, MPCDriverParams, MPCSettings, SolvePath, Target, preset
from acc_gym.drivers.population import sample_drivers

__all__ = [
    "ACC", "ACCParams", "CalibrationResult", "DelayBuffer", "Fuzzy", "FuzzyParams", "GM", "GMParams", "Gipps",
    "GippsParams", "IDM", "IDMParams", "MODELS", "MPCDriver", "MPCDriverParams", "MPCSettings", "Mode",
    "NO_VEHICLE", "Newell", "NewellParams", "Observation", "PRESETS", "Pipes", "PipesParams", "SolvePath",
    "Target", "Tyler", "TylerParams", "cacc_params", "calibrate_weights", "mp_cacc_params", "preset",
    "sample_drivers",
]
