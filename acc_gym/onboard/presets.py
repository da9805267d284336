"""Named sensor and actuator settings: ``ideal``, ``typical`` and ``degraded``.

Every number's source is in ``docs/sensors-actuators.md`` (its table lists each field of
each preset with its source and confidence tag). ``ideal`` is no model at all:
every environment id's trajectories are those without this package.
"""

from __future__ import annotations

from collections.abc import Mapping

from acc_gym._validation import from_mapping
from acc_gym.onboard.actuators import ActuatorConfig
from acc_gym.onboard.sensors import SensorConfig
from acc_gym.onboard.v2v import V2VConfig

SENSOR_PRESETS: dict[str, SensorConfig] = {
    "ideal": SensorConfig(),
    # a current long-range radar (Continental ARS 408 / Bosch LRR3 class: two beams) and a production tracker
    "typical": SensorConfig(far_range=250.0, far_fov=18.0, near_range=70.0, near_fov=90.0, gap_sd=0.1,
                            rate_sd=0.12, dropout_share=0.02, dropout_burst=0.2, coast=0.2, latency=0.07),
    # an older single-beam ACC radar in bad weather: shorter reach, larger errors, dropouts in bursts
    "degraded": SensorConfig(far_range=100.0, far_fov=16.0, gap_sd=1.8, rate_sd=0.3, dropout_share=0.14,
                             dropout_burst=0.27, coast=0.24, latency=0.16),
}
ACTUATOR_PRESETS: dict[str, ActuatorConfig] = {
    "ideal": ActuatorConfig(),
    "typical": ActuatorConfig(lag=0.5, dead_time=0.1),
    "degraded": ActuatorConfig(lag=0.7, dead_time=0.25),
}
V2V_PRESETS: dict[str, V2VConfig] = {
    "ideal": V2VConfig(),
    # CAM / BSM at 10 Hz, a few tens of ms, a per cent lost independently
    "typical": V2VConfig(period=0.1, latency=0.02, loss_share=0.01, loss_burst=0.2, timeout=0.5),
    # a congested channel: CAM throttled to 1 Hz, slower, a third lost in bursts
    "degraded": V2VConfig(period=1.0, latency=0.1, loss_share=0.3, loss_burst=1.0, timeout=1.5),
}
PRESETS = tuple(SENSOR_PRESETS)


def describe(config: dict) -> str:
    """A car part's settings (a config's ``asdict`` form) where they differ from the ideal
    part's, as text (``ideal`` when none does)."""
    from dataclasses import asdict

    kinds = (SensorConfig, ActuatorConfig, V2VConfig)
    kind = next(k for k in kinds if set(config) == set(asdict(k())))
    ideal = asdict(kind())
    diff = [f"{k} {v:g}" for k, v in config.items() if ideal.get(k) != v]
    return ", ".join(diff) if diff else "ideal"


def _resolve(value, presets: dict, cls: type, what: str):
    if value is None:
        return cls()
    if isinstance(value, cls):
        return value
    if isinstance(value, str):
        if value not in presets:
            raise ValueError(f"unknown {what} preset {value!r}; known: {list(presets)}")
        return presets[value]
    if isinstance(value, Mapping):
        return from_mapping(cls, dict(value), cls.__name__)
    raise TypeError(f"{what} must be a preset name ({list(presets)}), a {cls.__name__}, a mapping of its fields or "
                    f"None, got {type(value).__name__}")


def sensor_config(value) -> SensorConfig:
    """``value`` as a :class:`SensorConfig`: a preset's name, a mapping of its fields, one
    itself, or None (ideal)."""
    return _resolve(value, SENSOR_PRESETS, SensorConfig, "sensors")


def v2v_config(value) -> V2VConfig:
    """``value`` as a :class:`V2VConfig` (as :func:`sensor_config`)."""
    return _resolve(value, V2V_PRESETS, V2VConfig, "v2v_link")


def actuator_config(value) -> ActuatorConfig:
    """``value`` as an :class:`ActuatorConfig` (as :func:`sensor_config`)."""
    return _resolve(value, ACTUATOR_PRESETS, ActuatorConfig, "actuators")
