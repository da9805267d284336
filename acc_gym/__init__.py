"""acc_gym: a Gymnasium environment package for testing adaptive cruise control.

This release holds the simulation core: the longitudinal vehicle model
(:mod:`acc_gym.vehicle`), the MPC human-like driver of Cho, Park and Lee (2023) with its
naturalistic-driving population sampler and weight calibration (:mod:`acc_gym.drivers`),
classical car-following models and ACC laws (:mod:`acc_gym.drivers.baselines`), column
rollouts and the single-lane world (:mod:`acc_gym.simulation`); the scenarios
(:mod:`acc_gym.scenarios`: paper 004's single-lane taxonomy, paper 003's car-following
test, NCAP-style tests, stop-and-go, Monte Carlo traffic); and the evaluation
(:mod:`acc_gym.evaluation`: paper 003's criteria and 100-point score).
"""

__version__ = "0.38.0"

from acc_gym.envs.registration import make_vec_env, qualified_id  # noqa: E402,F401  (cheap: SB3 imported on use)
from acc_gym.envs.registration import register_envs as _register_envs  # noqa: E402  (cheap: ids only)

_register_envs()
