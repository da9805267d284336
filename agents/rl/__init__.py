"""Reinforcement learning with stable-baselines3: training, the vector-env adapter, saved policies."""
