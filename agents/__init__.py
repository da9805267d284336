"""Controllers under test (hand-written ACC laws and trained policies) live here.

The simulation core's car-following laws are in :mod:`acc_gym.drivers.baselines`; the
controller interface for the environments (``predict(obs, deterministic=True)``) comes
with the environments.
"""
