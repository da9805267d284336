"""acc_gym: a Gymnasium environment package for testing adaptive cruise control.

This release holds the simulation core: the longitudinal vehicle model
(:mod:`acc_gym.vehicle`), the MPC human-like driver of Cho, Park and Lee (2023) with its
naturalistic-driving population sampler and weight calibration (:mod:`acc_gym.drivers`),
classical car-following models and ACC laws (:mod:`acc_gym.drivers.baselines`), and
column rollouts (:mod:`acc_gym.simulation`).
"""

__version__ = "0.1.0"
