"""Trained policies shipped with the package, by name (``acc-gym evaluate ppo-acc``).

Each is a run directory of ``acc-gym train`` (model, observation normalisation,
manifest with the exact settings, evaluations) plus its actor exported to numpy
(``policy.npz``, :mod:`acc_gym_agents.rl.mlp`). They load with the numpy actor, so they run on the
core install without torch or stable-baselines3 and sit on the leaderboard beside the
hand-written controllers; ``load_shipped(name, backend="sb3")`` loads the
stable-baselines3 model instead (to fine-tune it, or to sample actions).

* ``ppo-acc``: PPO residual on the linear ACC (k1 0.8, s0 0.5), trained on paper 004's
  single-lane generator and paper 003's car-following test; how it was trained and how
  it scores on held-out seeds: ``agents/policies/ppo_acc/README.md``.
* ``ppo``: plain PPO from scratch (no residual, no shield, no bonus) on the ``-v1``
  observation and reward with the shipped hyperparameters; given the ``-v0`` fields (a
  ``-v0`` id, a suite, the leaderboard) it computes the margin features itself. How it was
  chosen and how it scores on held-out seeds: ``agents/policies/ppo/README.md``.
"""

from __future__ import annotations

from pathlib import Path

SHIPPED = {"ppo-acc": "ppo_acc", "ppo": "ppo"}  # name -> folder next to this file


def shipped_path(name: str) -> Path:
    """The run directory of the shipped policy ``name``."""
    if name not in SHIPPED:
        raise ValueError(f"unknown shipped policy {name!r}; use one of {sorted(SHIPPED)}")
    return Path(__file__).resolve().parent / SHIPPED[name]


def load_shipped(name: str, backend: str = "numpy"):
    """The shipped policy ``name`` as a controller (``predict(obs, deterministic=True)``)."""
    from acc_gym_agents.rl.policy import load_policy

    return load_policy(shipped_path(name), backend=backend)


def ppo_acc():
    """The shipped ``ppo-acc`` (the ``acc_gym.controllers`` entry point of that name)."""
    return load_shipped("ppo-acc")


def ppo():
    """The shipped ``ppo`` (the ``acc_gym.controllers`` entry point of that name)."""
    return load_shipped("ppo")
