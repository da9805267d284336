"""Eq. (12) of paper 001: fit a driver's weights (q1, r1) to a recorded speed trace.

    q1*, r1* = argmin sqrt( (1/T) sum_k (v_data(k) - v_model(k))^2 )

The model driver is simulated in closed loop behind the recorded vehicle ahead (a
:class:`~acc_gym.simulation.profiles.SpeedProfile`), or towards a stop position, from the
recorded initial speed and gap; every other parameter comes from ``base``. The search is
a log-spaced grid (all grid points simulated together as one batch), then Nelder-Mead
(scipy) in log space from the best grid point, within the bounds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acc_gym._validation import check_finite, check_positive
from acc_gym.drivers.mpc import MPCDriver, MPCDriverParams, MPCSettings
from acc_gym.simulation.profiles import SpeedProfile
from acc_gym.vehicle import VehicleParams


@dataclass(frozen=True)
class CalibrationResult:
    q1: float
    r1: float
    rmse: float  # [m/s]
    evaluations: int
    v_model: np.ndarray  # the fitted driver's speed at the data's samples [m/s]


def _simulate(q1, r1, base: MPCDriverParams, lead: SpeedProfile, v0: float, gap0: float, duration: float,
              dt: float, vehicle: VehicleParams, settings: MPCSettings | None, stop_position) -> np.ndarray:
    """Speeds ``(B, T+1)`` of drivers with weights ``q1``, ``r1`` (arrays ``(B,)``)."""
    q1 = np.atleast_1d(np.asarray(q1, float))
    r1 = np.atleast_1d(np.asarray(r1, float))
    B = q1.size
    params = MPCDriverParams.stack([base] * B).replace(q1=q1, r1=r1)
    driver = MPCDriver(params, vehicle=vehicle, settings=settings)
    length = float(np.asarray(vehicle.length).ravel()[0])
    x0 = np.tile([gap0 + length, 0.0], (B, 1))
    v_lead0 = float(lead.speed(0.0))
    prof = SpeedProfile(lead.times, np.tile(lead.speeds, (B, 1)))
    from acc_gym.simulation.rollout import simulate_column  # here: simulation imports drivers

    tr = simulate_column(prof, [driver], x0, np.tile([v_lead0, v0], (B, 1)), duration=duration, dt=dt,
                         vehicle=vehicle, stop_position=stop_position, batch=B)
    return tr.v[:, :, 1].T


def calibrate_weights(t, v_data, lead: SpeedProfile, gap0: float, base: MPCDriverParams | None = None, *,
                      q1_bounds=(1e-3, 50.0), r1_bounds=(1.0, 500.0), grid: int = 6,
                      vehicle: VehicleParams | None = None, settings: MPCSettings | None = None,
                      stop_position: float | None = None, max_evaluations: int = 200) -> CalibrationResult:
    """Fit ``(q1, r1)`` of an MPC driver to the speed trace ``v_data`` sampled at ``t``.

    ``t`` must start at 0 and be evenly spaced; its spacing is the simulation step.
    ``lead`` is the recorded vehicle ahead (its position starts ``gap0`` [m] ahead of the
    driver's front bumper, bumper to bumper); use a stopped profile and
    ``stop_position`` for a stop. Returns the weights, the RMSE [m/s] and the fitted trace.
    """
    from scipy.optimize import minimize

    t = np.asarray(t, dtype=float)
    v_data = np.asarray(v_data, dtype=float)
    check_finite("t", t)
    check_finite("v_data", v_data)
    if t.ndim != 1 or t.shape != v_data.shape or t.size < 3:
        raise ValueError(f"t and v_data must be 1-D of equal length >= 3, got {t.shape} and {v_data.shape}")
    dt = float(t[1] - t[0])
    if t[0] != 0.0 or not np.allclose(np.diff(t), dt, rtol=1e-6, atol=1e-9) or dt <= 0:
        raise ValueError("t must start at 0 and be evenly spaced")
    check_positive("gap0", gap0)
    for name, (lo, hi) in (("q1_bounds", q1_bounds), ("r1_bounds", r1_bounds)):
        if not (0 < lo < hi and np.isfinite(hi)):
            raise ValueError(f"{name} must satisfy 0 < low < high, got {(lo, hi)!r}")
    base = base if base is not None else MPCDriverParams()
    vehicle = vehicle if vehicle is not None else VehicleParams()
    duration = float(t[-1])
    lo = np.log([q1_bounds[0], r1_bounds[0]])
    hi = np.log([q1_bounds[1], r1_bounds[1]])
    evaluations = 0

    def rmse(v_model):
        return np.sqrt(np.mean((v_model - v_data) ** 2, axis=-1))

    # 1) grid, simulated as one batch
    gq, gr = np.meshgrid(np.linspace(lo[0], hi[0], grid), np.linspace(lo[1], hi[1], grid))
    v_grid = _simulate(np.exp(gq.ravel()), np.exp(gr.ravel()), base, lead, float(v_data[0]), gap0, duration, dt,
                       vehicle, settings, stop_position)
    errors = rmse(v_grid)
    evaluations += errors.size
    best = int(np.argmin(errors))
    x_best = np.array([gq.ravel()[best], gr.ravel()[best]])

    # 2) Nelder-Mead in log space, clipped to the bounds
    def objective(x):
        nonlocal evaluations
        evaluations += 1
        x = np.clip(x, lo, hi)
        return float(rmse(_simulate(np.exp(x[0]), np.exp(x[1]), base, lead, float(v_data[0]), gap0, duration, dt,
                                    vehicle, settings, stop_position)[0]))

    res = minimize(objective, x_best, method="Nelder-Mead",
                   options={"maxfev": max(max_evaluations - evaluations, 1), "xatol": 1e-3, "fatol": 1e-6,
                            "initial_simplex": np.array([x_best, x_best + [0.3, 0.0], x_best + [0.0, 0.3]])})
    x = np.clip(res.x, lo, hi)
    v_fit = _simulate(np.exp(x[0]), np.exp(x[1]), base, lead, float(v_data[0]), gap0, duration, dt, vehicle,
                      settings, stop_position)[0]
    err = float(rmse(v_fit))
    if errors[best] < err:  # the grid point was better (Nelder-Mead never makes it worse, but be exact)
        x, v_fit, err = x_best, v_grid[best], float(errors[best])
    return CalibrationResult(q1=float(np.exp(x[0])), r1=float(np.exp(x[1])), rmse=err, evaluations=evaluations,
                             v_model=v_fit)
