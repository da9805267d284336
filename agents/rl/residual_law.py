"""The residual law of :mod:`acc_gym_agents.rl.residual`, in plain numpy (no torch, no stable-baselines3).

The executed action of a residual policy is ``clip(a_base(obs) + scale * clip(a_rl, -1, 1),
-1, 1)``, then the optional set-speed cap and proper-response shield. Training
(:class:`acc_gym_agents.rl.residual.ResidualVecEnv`) and inference
(:class:`acc_gym_agents.rl.policy.SB3Policy`) both call :func:`controller_action`, so a saved
residual policy acts exactly as it did in training, and a policy exported to numpy
(:mod:`acc_gym_agents.rl.mlp`) runs without torch.
"""

from __future__ import annotations

import numpy as np


def _bases() -> dict:
    from acc_gym_agents.controllers.linear import ConstantSpeed, LinearACC

    # stateless laws only: the wrapper evaluates them on a batch of observations at every step
    return {"acc": LinearACC, "constant": ConstantSpeed}


BASES = ("acc", "constant")


def make_base(name: str, kwargs: dict | None = None):
    """The base controller called ``name`` (one of :data:`BASES`), with its settings ``kwargs``
    (e.g. ``{"k1": 0.8, "s0": 0.5}`` for the linear ACC)."""
    bases = _bases()
    if name not in bases:
        raise ValueError(f"unknown residual base {name!r}; use one of {list(bases)}")
    try:
        return bases[name](**(kwargs or {}))
    except TypeError as exc:
        raise ValueError(f"residual base {name!r}: bad settings {kwargs!r} ({exc})") from None


def check_scale(scale) -> float:
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not np.isfinite(scale) or scale <= 0:
        raise ValueError(f"residual_scale must be a number > 0, got {scale!r}")
    return float(scale)


def residual_action(base_action, rl_action, scale: float) -> np.ndarray:
    """``clip(base + scale * clip(rl, -1, 1), -1, 1)`` as float32."""
    rl = np.clip(np.asarray(rl_action, dtype=np.float64), -1.0, 1.0)
    out = np.asarray(base_action, dtype=np.float64) + float(scale) * rl
    return np.clip(out, -1.0, 1.0).astype(np.float32)


SHIELD_DECEL = 2.5  # [m/s^2] the shield's braking: above the score's proper response (2 m/s^2)
SHIELD_B = 8.0  # [m/s^2] b0 = b1 of Gapsafe (the scoring default)


SHIELDS = ("proper-response", "base")


def check_shield(shield) -> str | None:
    """``None``/``False``: no shield; ``True`` or ``"proper-response"``; ``"base"``
    (:func:`proper_response_shield`)."""
    if shield is None or shield is False:
        return None
    if shield is True:
        return "proper-response"
    if isinstance(shield, str) and shield in SHIELDS:
        return shield
    raise ValueError(f"shield must be one of {SHIELDS} (or True / False), got {shield!r}")


def proper_response_shield(obs, action, decel_max: float = 8.0, decel: float = SHIELD_DECEL,
                           floor=None) -> np.ndarray:
    """Brake at least ``decel`` while the observed Q = gap - Gapsafe is negative (a vehicle ahead in range,
    moving ego): the proper response of the score's safety item, so the learnt part cannot make it fail.

    ``floor`` (the ``"base"`` shield: the base controller's action): while Q < 0, at any speed,
    also brake at least as hard as it. The learnt part may then brake harder than the
    hand-written law when inside Gapsafe, never softer: where the law stops short of a car
    (a stationary target, a hard-braking lead, scenarios the policy never saw in training),
    the policy does not creep on into it.
    """
    o = np.atleast_2d(np.asarray(obs, dtype=np.float64))
    a = np.asarray(action, dtype=np.float32)
    v, gap, dv, seen, h = o[:, 0], o[:, 2], o[:, 3], o[:, 4] > 0.5, o[:, 6]
    v_lead = v + dv
    gap_safe = v * h + (v ** 2 - v_lead ** 2) / (2.0 * SHIELD_B)
    inside = (seen & (gap < gap_safe)).reshape((-1,) + (1,) * (a.ndim - 1))
    moving = (v > 0.5).reshape(inside.shape)  # the score's standing ego needs no brake
    out = np.where(inside & moving, np.minimum(a, np.float32(-decel / decel_max)), a)
    if floor is not None:  # at any speed: creeping up to a stopped car is how a residual collides
        out = np.where(inside, np.minimum(out, np.asarray(floor, dtype=np.float32).reshape(a.shape)), out)
    return out.astype(np.float32)


SPEED_GAIN = 1.0  # [1/s] of the set-speed cap


def speed_cap(obs, action, max_overspeed: float, accel_max: float = 3.0, decel_max: float = 8.0) -> np.ndarray:
    """Cap the desired acceleration at ``SPEED_GAIN (v_set + max_overspeed - v)``: the ego does not
    drive (much) faster than its set speed plus ``max_overspeed``, whatever the learnt part wants."""
    o = np.atleast_2d(np.asarray(obs, dtype=np.float64))
    a = np.asarray(action, dtype=np.float32)
    a_cap = SPEED_GAIN * (o[:, 5] + float(max_overspeed) - o[:, 0])  # [m/s^2]
    cap = np.where(a_cap >= 0, a_cap / accel_max, a_cap / decel_max).reshape((-1,) + (1,) * (a.ndim - 1))
    return np.minimum(a, np.clip(cap, -1.0, 1.0)).astype(np.float32)


def check_overspeed(max_overspeed):
    if max_overspeed is None:
        return None
    if isinstance(max_overspeed, bool) or not isinstance(max_overspeed, (int, float)) or not (
            np.isfinite(max_overspeed) and max_overspeed >= 0):
        raise ValueError(f"max_overspeed must be a number >= 0 or None, got {max_overspeed!r}")
    return float(max_overspeed)


def controller_action(obs, rl_action, base, scale: float, shield: str | bool | None = None,
                      max_overspeed: float | None = None) -> np.ndarray:
    """The executed action of a residual policy on raw ``obs`` (a batch or one observation): the base plus
    the scaled residual, then the set-speed cap (``max_overspeed`` not None), then the shield
    (:func:`check_shield`: ``"proper-response"`` or ``"base"``)."""
    shield = check_shield(shield)
    base_action, _ = base.predict(obs)
    action = residual_action(base_action, np.asarray(rl_action).reshape(np.shape(base_action)), scale)
    if max_overspeed is not None:
        action = speed_cap(obs, action, max_overspeed)
    if shield is None:
        return action
    return proper_response_shield(obs, action, floor=base_action if shield == "base" else None)
