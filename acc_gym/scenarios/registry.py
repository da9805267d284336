"""Every scenario by id: list, describe, build.

A :class:`ScenarioType` has an id (``"singlelane/2/cut-in"``, ``"carfollowing/90"``,
``"ncap/ccrs/30"``, ``"stopandgo"``...), its parameters' default laws (a name, or a pair
of names for a correlated bivariate law), and a builder that turns parameter values,
a random generator and a driver choice into a :class:`~acc_gym.scenarios.spec.Scenario`.

Reproducibility: ``build(id, params, seed)`` draws every missing parameter from one
generator and the surrounding drivers and speed profiles from another, both spawned from
``SeedSequence([crc32(id), seed])`` -- private to that scenario -- so the same (id,
parameters, seed) give the same scenario whatever else is built before, after or in
between, and ``build(s.id, s.params, s.seed, s.drivers) == s`` (giving parameters never
shifts the builder's draws). Parameters given explicitly are validated and used as they
are (for a correlated pair, give both or neither).

Surrounding drivers (``drivers=``): ``"typical"`` (default), ``"atypical"`` or
``"malicious"`` human-like MPC drivers sampled from paper 001's statistics
(:func:`acc_gym.drivers.population.sample_drivers`), or the name of any baseline model
(``"idm"``, ``"gipps"``, ...) with its default parameters and the vehicle's speed as
desired speed. Scripted vehicles (paper 003's lead, the NCAP targets) follow their
speed profile whatever ``drivers`` says.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, field, fields, replace
from typing import Callable

import numpy as np

from acc_gym.drivers.baselines import MODELS
from acc_gym.drivers.population import KINDS, sample_driver_values
from acc_gym.scenarios._seeding import spawned_generators
from acc_gym.scenarios.spec import DriverSpec, Scenario, _finite

DRIVER_CHOICES = (*KINDS, *sorted(MODELS))


@dataclass(frozen=True)
class ScenarioType:
    """A scenario id with its default parameter laws and its builder."""

    id: str
    family: str
    description: str
    parameters: dict  # name or (name, name) -> law with .sample(rng)
    builder: Callable  # (stype, params: dict, rng, drivers: str, seed: int) -> Scenario
    occurrence_rate: object | None = None  # law of occurrences per hour (single-lane traffic)
    in_paper: bool = True  # one of the paper's configurations (else an addition of ours)
    units: dict = field(default_factory=dict)  # parameter name -> unit and meaning
    positive: frozenset = frozenset()  # parameters that must be > 0 (gaps, durations, time gaps, ...)
    nonnegative: frozenset = frozenset()  # parameters that must be >= 0 (speeds, start times)

    def build(self, params: dict | None = None, seed: int = 0, drivers: str = "typical") -> Scenario:
        """This type's scenario with ``params`` (missing ones drawn) and ``seed``."""
        seed = check_seed(seed)
        params = check_params(self.id, params)
        if not isinstance(drivers, str) or drivers not in DRIVER_CHOICES:
            raise ValueError(f"unknown drivers {drivers!r}; use one of {list(DRIVER_CHOICES)}")
        param_rng, build_rng = scenario_rngs(self.id, seed)
        values = self.sample_params(param_rng, params)
        return self.builder(self, values, build_rng, drivers, seed)

    @property
    def parameter_names(self) -> list[str]:
        names: list[str] = []
        for key in self.parameters:
            names.extend(key if isinstance(key, tuple) else (key,))
        return names

    def sample_params(self, rng: np.random.Generator, given: dict | None = None) -> dict:
        """Draw the parameters not in ``given`` (in declaration order) and merge."""
        given = check_params(self.id, given)
        unknown = set(given) - set(self.parameter_names) if given else ()
        if unknown:
            raise ValueError(f"unknown parameter(s) {sorted(unknown)} for scenario {self.id!r}; "
                             f"known: {self.parameter_names}")
        out: dict[str, float] = {}
        for key, law in self.parameters.items():
            if not given and type(key) is str:  # one law of one parameter, drawn (a reset's case)
                value = law.sample(rng)
                out[key] = value if type(value) is float else float(np.atleast_1d(value)[0])
                continue
            names = key if isinstance(key, tuple) else (key,)
            have = [n in given for n in names]
            if all(have):
                for n in names:
                    out[n] = _number(self.id, n, given[n])
                continue
            if any(have):
                raise ValueError(f"parameters {names} of {self.id!r} are drawn jointly: give all or none of them")
            value = law.sample(rng)
            for n, v in zip(names, np.atleast_1d(value)):
                out[n] = float(v)
        for name, value in out.items():
            if name in self.positive and value <= 0:
                raise ValueError(f"parameter {name!r} of {self.id!r} must be > 0, got {value!r}")
            if name in self.nonnegative and value < 0:
                raise ValueError(f"parameter {name!r} of {self.id!r} must be >= 0, got {value!r}")
        return out


def _number(sid: str, name: str, value) -> float:
    return _finite(f"parameter {name!r} of {sid!r}", value)


def check_seed(seed) -> int:
    """``seed`` as an int: a non-negative integer (Python's or numpy's; not a bool, a float or text)."""
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r} ({type(seed).__name__})")
    return int(seed)


def check_params(scenario_id: str, params) -> dict:
    """``params`` as a new dict: None (draw them all) or a mapping of parameter names (strings) to values."""
    if params is None:
        return {}
    if not isinstance(params, dict):
        raise ValueError(f"params of scenario {scenario_id!r} must be a dict of parameter name -> value (or None), "
                         f"got {params!r} ({type(params).__name__})")
    for name in params:
        if not isinstance(name, str):
            raise ValueError(f"params of scenario {scenario_id!r}: parameter names must be strings, got {name!r} "
                             f"({type(name).__name__})")
    return dict(params)


REGISTRY: dict[str, ScenarioType] = {}


def register(stype: ScenarioType) -> ScenarioType:
    if stype.id in REGISTRY:
        raise ValueError(f"scenario id {stype.id!r} registered twice")
    REGISTRY[stype.id] = stype
    return stype


def scenario_type(scenario_id: str) -> ScenarioType:
    _load()
    if not isinstance(scenario_id, str):
        raise ValueError(f"a scenario id must be a string, got {scenario_id!r} ({type(scenario_id).__name__})")
    try:
        return REGISTRY[scenario_id]
    except KeyError:
        close = [k for k in REGISTRY if scenario_id.split("/")[0] in k][:8]
        raise ValueError(f"unknown scenario id {scenario_id!r}"
                         + (f"; similar: {close}" if close else f"; families: {families()}")) from None


def families() -> list[str]:
    _load()
    return sorted({t.family for t in REGISTRY.values()})


def list_scenarios(family: str | None = None) -> list[str]:
    """All scenario ids (of one family)."""
    _load()
    if family is not None and family not in families():
        raise ValueError(f"unknown scenario family {family!r}; known: {families()}")
    return [k for k, t in REGISTRY.items() if family is None or t.family == family]


def describe(scenario_id: str) -> str:
    """A human-readable description: what happens and every parameter's default law."""
    t = scenario_type(scenario_id)
    lines = [f"{t.id} ({t.family}{'' if t.in_paper else ', not in the paper: an addition'})", t.description]
    if t.occurrence_rate is not None:
        lines.append(f"occurrence rate [1/h]: {t.occurrence_rate}")
    for key, law in t.parameters.items():
        names = key if isinstance(key, tuple) else (key,)
        label = ", ".join(f"{n} {t.units.get(n, '')}".strip() for n in names)
        lines.append(f"  {label}: {law}")
    return "\n".join(lines)


def scenario_rngs(scenario_id: str, seed: int) -> tuple[np.random.Generator, np.random.Generator]:
    """The two generators private to (id, seed): one for the parameters, one for the builder
    (surrounding drivers, speed profiles), spawned from ``SeedSequence([crc32(id), seed])`` so
    that giving some parameters explicitly never shifts the builder's draws."""
    entropy = [zlib.crc32(scenario_id.encode()), check_seed(seed)]
    # the two children SeedSequence(entropy).spawn(2) makes (spawn keys (0,) and (1,)), their seed words
    # computed together in one compiled call (resets draw a scenario each): numpy's generators in numpy's states
    param_rng, build_rng = spawned_generators(entropy, 2)
    return param_rng, build_rng


def build(scenario_id: str, params: dict | None = None, seed: int = 0, drivers: str = "typical") -> Scenario:
    """The scenario ``scenario_id`` with ``params`` (missing ones drawn) and ``seed``."""
    return scenario_type(scenario_id).build(params, seed, drivers)


def calibrate(scenario_id: str, data: dict) -> ScenarioType:
    """A copy of a scenario type whose parameter laws are fitted to ``data`` (paper 004, IV.A).

    ``data`` maps parameter names to observed values (1-D arrays). Independent
    parameters get the family among normal, log-normal and Laplace with the lowest AIC,
    fitted by maximum likelihood; a jointly drawn pair gets a bivariate normal fitted by
    expectation maximisation, which also uses rows where one of the two is missing
    (NaN) -- give both arrays with equal length. The defaults' truncation bounds are
    kept; parameters absent from ``data`` keep their default laws. The copy is not
    registered: build from it with ``ScenarioType.build``.
    """
    from acc_gym.scenarios.calibration import fit_best, fit_bivariate_em
    from acc_gym.scenarios.distributions import BivariateNormal

    t = scenario_type(scenario_id)
    unknown = set(data) - set(t.parameter_names)
    if unknown:
        raise ValueError(f"unknown parameter(s) {sorted(unknown)} for scenario {scenario_id!r}")
    laws = dict(t.parameters)
    for key, law in t.parameters.items():
        if isinstance(key, tuple):
            if not any(k in data for k in key):
                continue
            if not all(k in data for k in key):
                raise ValueError(f"parameters {key} are correlated: give data for both")
            x = np.column_stack([np.asarray(data[k], dtype=float) for k in key])
            fit = fit_bivariate_em(x).law
            laws[key] = BivariateNormal(fit.mean, fit.cov, low=getattr(law, "low", None),
                                        high=getattr(law, "high", None))
        elif key in data:
            best, _ = fit_best(np.asarray(data[key], dtype=float))
            fitted = best.law
            bounds = {b: getattr(law, b) for b in ("low", "high") if hasattr(law, b)}
            laws[key] = type(fitted)(*[getattr(fitted, f) for f in _law_fields(fitted)], **bounds)
    return replace(t, parameters=laws)


def _law_fields(law) -> list[str]:
    return [f.name for f in fields(law) if f.name not in ("low", "high")]


def driver_for(rng: np.random.Generator, drivers: str, speed: float) -> DriverSpec:
    """A surrounding driver cruising at ``speed`` [m/s] of the chosen kind or model."""
    speed = max(float(speed), 0.5)
    if drivers in KINDS:  # one driver's draws as plain numbers: sample_drivers(rng, 1, ...)'s values, faster
        return DriverSpec("mpc", sample_driver_values(rng, speed, drivers))
    key = "v_set" if drivers == "acc" else "v_desired"
    return DriverSpec(drivers, {key: speed})


_LOADED = False


def _load() -> None:
    """Import the family modules (they register their types on import)."""
    global _LOADED
    if not _LOADED:
        _LOADED = True
        from acc_gym.scenarios import carfollowing, ncap, ncap2026, singlelane, stopandgo  # noqa: F401
