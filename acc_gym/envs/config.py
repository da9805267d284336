"""The environment's configuration and its default scenario generator."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields

import numpy as np

from acc_gym._validation import from_mapping
from acc_gym.evaluation.scoring import ScoringConfig
from acc_gym.onboard import (ActuatorConfig, Randomisation, SensorConfig, V2VConfig, actuator_config, randomisation,
                             sensor_config, v2v_config)
from acc_gym.scenarios.registry import DRIVER_CHOICES, build, list_scenarios, scenario_type
from acc_gym.scenarios.spec import Scenario

CARFOLLOWING = tuple(i for i in list_scenarios("carfollowing") if scenario_type(i).in_paper)  # paper 003's test
SINGLELANE = tuple(i for i in list_scenarios("singlelane") if scenario_type(i).in_paper)
NCAP = tuple(list_scenarios("ncap"))
STOPANDGO = ("stopandgo",)
VERSIONS = (0, 1)  # environment versions (see EnvConfig.version)
FAMILIES = {"carfollowing": CARFOLLOWING, "singlelane": SINGLELANE, "ncap": NCAP, "stopandgo": STOPANDGO}


@dataclass(frozen=True)
class EnvConfig:
    """Everything that defines an environment; validated on construction.

    ``scenarios`` are the ids (or family names: ``"carfollowing"``, ``"singlelane"`` -- its
    22 paper configurations --, ``"ncap"``, ``"stopandgo"``) an episode is drawn from, with
    probabilities proportional to
    ``weights`` (default: the single-lane configurations' occurrence rates where they have
    them, else uniform). ``drivers`` picks the surrounding drivers (see
    :func:`acc_gym.scenarios.build`). The action ``[-1, 1]`` maps to a desired acceleration
    ``action * accel_max`` for ``action >= 0`` and ``action * decel_max`` below (0 is
    "no acceleration"), which the vehicle model then limits. ``sensors`` and ``actuators``
    model the radar and the powertrain between the controller and the world
    (:mod:`acc_gym.onboard`): a preset's name (``"ideal"``, the default, models neither;
    ``"typical"``, ``"degraded"``), a mapping of the config's fields (rl-zoo3's
    ``env_kwargs``) or a :class:`~acc_gym.onboard.SensorConfig` /
    :class:`~acc_gym.onboard.ActuatorConfig`; ``v2v_link`` likewise the V2V link of ``v2v=True``
    (:mod:`acc_gym.onboard.v2v`). ``randomise`` draws each episode's actuators and
    radar error scale (:mod:`acc_gym.onboard.randomisation`; a mapping ``{"lag": [lo, hi],
    "dead_time": [lo, hi], "noise": [lo, hi]}``, for training under domain randomisation).
    """

    scenarios: tuple = CARFOLLOWING
    weights: tuple | None = None
    drivers: str = "typical"
    accel_max: float = 3.0  # [m/s^2] desired acceleration at action +1
    decel_max: float = 8.0  # [m/s^2] desired deceleration at action -1 (about the tyre limit)
    sensor_range: float = 200.0  # [m] radar range: beyond it the observation shows no vehicle
    v2v: bool = False  # observe the vehicle ahead's acceleration and the second vehicle ahead (CACC)
    terminate_on_violation: bool = False  # also end the episode at a safety violation (proper response)
    scoring: ScoringConfig = field(default_factory=ScoringConfig)
    # the environment's version (the ids' -vN): 1 appends the safety-margin features to the
    # observation (acc_gym.envs.observation) and makes MarginReward the default reward
    version: int = 0
    # the radar and the actuators between the controller and the world (acc_gym.onboard): a preset's name
    # ("ideal", "typical", "degraded"), a mapping of the config's fields or the config; ideal: none modelled
    sensors: SensorConfig = field(default_factory=SensorConfig)
    actuators: ActuatorConfig = field(default_factory=ActuatorConfig)
    v2v_link: V2VConfig = field(default_factory=V2VConfig)  # the V2V link with v2v=True (acc_gym.onboard.v2v)
    # per-episode draws of the actuators' lag and dead time and the sensors' error multiple (None: none)
    randomise: Randomisation | None = None

    def __post_init__(self) -> None:
        names = (self.scenarios,) if isinstance(self.scenarios, str) else tuple(self.scenarios)
        if not names:
            raise ValueError("EnvConfig.scenarios must name at least one scenario id or family")
        ids: list[str] = []
        for name in names:
            if name in FAMILIES:
                ids.extend(FAMILIES[name])
            else:
                scenario_type(name)  # raises naming an unknown id
                ids.append(name)
        ids = tuple(ids)
        object.__setattr__(self, "scenarios", ids)
        if self.weights is not None:
            w = tuple(float(x) for x in self.weights)
            if len(w) != len(ids) or not all(math.isfinite(x) and x >= 0 for x in w) or sum(w) <= 0:
                raise ValueError(f"EnvConfig.weights must be {len(ids)} non-negative numbers with a positive sum, "
                                 f"got {self.weights!r}")
            object.__setattr__(self, "weights", w)
        if self.drivers not in DRIVER_CHOICES:
            raise ValueError(f"EnvConfig.drivers must be one of {list(DRIVER_CHOICES)}, got {self.drivers!r}")
        for name in ("accel_max", "decel_max", "sensor_range"):
            value = getattr(self, name)
            number = isinstance(value, (int, float)) and not isinstance(value, bool)
            if not number or not (math.isfinite(value) and value > 0):
                raise ValueError(f"EnvConfig.{name} must be a number > 0, got {value!r}")
        if isinstance(self.version, bool) or self.version not in VERSIONS:
            raise ValueError(f"EnvConfig.version must be one of {list(VERSIONS)}, got {self.version!r}")
        for name in ("v2v", "terminate_on_violation"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"EnvConfig.{name} must be True or False, got {getattr(self, name)!r}")
        if isinstance(self.scoring, dict):
            object.__setattr__(self, "scoring", ScoringConfig.from_dict(self.scoring))
        if not isinstance(self.scoring, ScoringConfig):
            raise ValueError(f"EnvConfig.scoring must be a ScoringConfig, got {type(self.scoring).__name__}")
        object.__setattr__(self, "sensors", sensor_config(self.sensors))
        object.__setattr__(self, "actuators", actuator_config(self.actuators))
        object.__setattr__(self, "randomise", randomisation(self.randomise))
        object.__setattr__(self, "v2v_link", v2v_config(self.v2v_link))

    @property
    def probabilities(self) -> np.ndarray:
        if self.weights is not None:
            w = np.array(self.weights)
        else:
            rates = [scenario_type(i).occurrence_rate for i in self.scenarios]
            w = np.array([r.value if r is not None and hasattr(r, "value") else 1.0 for r in rates])
        return w / w.sum()

    def replace(self, **changes) -> "EnvConfig":
        return EnvConfig.from_dict({**self.to_dict(), **changes})

    def to_dict(self) -> dict:
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        d["scoring"] = asdict(self.scoring)
        d["sensors"] = asdict(self.sensors)
        d["actuators"] = asdict(self.actuators)
        d["v2v_link"] = asdict(self.v2v_link)
        d["randomise"] = None if self.randomise is None else asdict(self.randomise)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "EnvConfig":
        return from_mapping(cls, d, "environment")


def mixture(shares: dict) -> dict:
    """EnvConfig settings (``scenarios``, ``weights``) drawing each of ``shares``' families or
    ids with its share, and within a family by its default probabilities:
    ``{"singlelane": 0.75, "carfollowing": 0.25}``."""
    if not shares:
        raise ValueError("a mixture must name at least one scenario family or id")
    total = sum(float(w) for w in shares.values())
    if not all(float(w) >= 0 for w in shares.values()) or total <= 0:
        raise ValueError(f"mixture shares must be >= 0 with a positive sum, got {shares!r}")
    ids, weights = [], []
    for name, share in shares.items():
        cfg = EnvConfig(scenarios=(name,))
        ids += list(cfg.scenarios)
        weights += [float(share) / total * float(p) for p in cfg.probabilities]
    return {"scenarios": tuple(ids), "weights": tuple(weights)}


class ScenarioSampler:
    """The default scenario generator: an id drawn by the config's probabilities, a fresh seed,
    and :func:`acc_gym.scenarios.build` -- all from the generator it is called with."""

    def __init__(self, config: EnvConfig):
        self.ids = config.scenarios
        self.p = config.probabilities
        self.drivers = config.drivers
        # rng.choice(len(ids), p=p) draws one rng.random() and looks it up in p's normalised
        # cumulative sums; kept here so that each call skips choice's checks of p (a tenth
        # of a reset's cost), with the same draw and the same index
        cdf = np.cumsum(np.asarray(self.p, dtype=float))
        cdf /= cdf[-1]
        self._cdf = cdf

    def __call__(self, rng: np.random.Generator) -> Scenario:
        sid = self.ids[int(self._cdf.searchsorted(rng.random(), side="right"))] if len(self.ids) > 1 else self.ids[0]
        return build(sid, seed=int(rng.integers(0, 2 ** 31 - 1)), drivers=self.drivers)



class CounterScenarioSampler(ScenarioSampler):
    """A scenario generator on the counter-based generator (opt-in:
    ``gymnasium.make(id, scenario_generator="counter")``, likewise ``make_vec``): an id and
    a seed drawn from the environment's generator exactly as :class:`ScenarioSampler`
    draws them, then the scenario of that ``(id, seed)`` from
    :func:`acc_gym.scenarios.batched.build`, its parameters drawn by a compiled Philox
    keyed by ``(id, seed)``, in one call for a batch of scenes (:meth:`draw_many`, which a
    vector env's resets use).

    Decided: each scenario is a pure function of ``(id, seed)`` -- whatever the batch it is
    drawn in, the number of environments or workers and the order of resets -- and the
    sequence of ``(id, seed)`` is :class:`ScenarioSampler`'s; the parameters differ from
    its (another generator), their laws do not. Every such scenario is rebuilt by
    ``acc_gym.scenarios.build(s.id, s.params, s.seed, s.drivers)``, like any other.

    Not any id's default: the ``-v1`` ids' stored results (the shipped PPO's held-out
    scores, the tests that drive a ``-v1`` id and its ``-v0`` twin on one seed) are of
    :class:`ScenarioSampler`'s streams; making it ``-v1``'s default is :func:`make_sampler`'s
    one line once those are re-recorded."""

    def _choose(self, rng: np.random.Generator) -> tuple[str, int]:
        sid = self.ids[int(self._cdf.searchsorted(rng.random(), side="right"))] if len(self.ids) > 1 else self.ids[0]
        return sid, int(rng.integers(0, 2 ** 31 - 1))

    def __call__(self, rng: np.random.Generator) -> Scenario:
        return self.draw_many([rng])[0]

    def draw_many(self, rngs) -> list[Scenario]:
        """The next scenario of each generator in ``rngs`` (each used as :meth:`__call__` uses it)."""
        from acc_gym.scenarios.batched import build_many

        chosen = [self._choose(rng) for rng in rngs]
        return build_many([c[0] for c in chosen], [c[1] for c in chosen], self.drivers)

    def build(self, scenario_id: str, seed: int) -> Scenario:
        """The scenario ``(scenario_id, seed)`` as this sampler draws it (a reset's named scenario)."""
        from acc_gym.scenarios.batched import build

        return build(scenario_id, seed, self.drivers)


SAMPLERS = {"numpy": ScenarioSampler, "counter": CounterScenarioSampler}  # scenario_generator= by name


def make_sampler(config: EnvConfig, generator=None):
    """An environment's scenario generator: ``generator`` itself when it is a callable, the
    sampler it names (``"numpy"``: :class:`ScenarioSampler`, the default of every id;
    ``"counter"``: :class:`CounterScenarioSampler`), and :class:`ScenarioSampler` for None."""
    if generator is None:
        return ScenarioSampler(config)
    if isinstance(generator, str):
        if generator not in SAMPLERS:
            raise ValueError(f"scenario_generator must be a callable or one of {sorted(SAMPLERS)}, got {generator!r}")
        return SAMPLERS[generator](config)
    if not callable(generator):
        raise TypeError(f"scenario_generator must be a callable or one of {sorted(SAMPLERS)}, "
                        f"got {type(generator).__name__}")
    return generator
