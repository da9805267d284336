"""Hours of single-lane traffic for Monte Carlo campaigns (paper 004, Section III.E).

Paper 004 builds its traffic model as a sequence of single-lane scenarios: from the
desired simulated time, scenarios are drawn by their configurations' occurrence rates
until their durations fill it (1 hour was 280 scenarios there). Here each simulated hour
``h`` has its own generator ``default_rng([root_seed, h])``: it draws each
configuration's occurrence rate from its law (constants by default), then picks
configurations with probability proportional to their rates, each with a fresh seed,
building them until the durations add up to 3600 s. So hour ``h`` is the same whatever
hours come before it or how a campaign splits the hours among workers.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from acc_gym.scenarios.registry import build, list_scenarios, scenario_type
from acc_gym.scenarios.spec import Scenario

HOUR = 3600.0  # [s]


def traffic_hour(hour: int, root_seed: int = 0, *, family: str = "singlelane", drivers: str = "typical",
                 include_extra: bool = False) -> list[Scenario]:
    """The scenarios of simulated hour ``hour`` (a non-negative integer)."""
    if int(hour) != hour or hour < 0:
        raise ValueError(f"hour must be a non-negative integer, got {hour!r}")
    if int(root_seed) != root_seed or root_seed < 0:
        raise ValueError(f"root_seed must be a non-negative integer, got {root_seed!r}")
    types = [scenario_type(i) for i in list_scenarios(family)]
    types = [t for t in types if t.occurrence_rate is not None and (include_extra or t.in_paper)]
    if not types:
        raise ValueError(f"scenario family {family!r} has no occurrence rates; use 'singlelane'")
    rng = np.random.default_rng([int(root_seed), int(hour)])
    rates = np.array([max(float(t.occurrence_rate.sample(rng)), 0.0) for t in types])
    if rates.sum() <= 0:
        raise ValueError("every occurrence rate is zero")
    p = rates / rates.sum()
    out: list[Scenario] = []
    elapsed = 0.0
    while elapsed < HOUR:
        t = types[int(rng.choice(len(types), p=p))]
        sc = build(t.id, seed=int(rng.integers(0, 2 ** 31 - 1)), drivers=drivers)
        out.append(sc)
        elapsed += sc.duration
    return out


def traffic(hours: int, root_seed: int = 0, **kwargs) -> Iterator[Scenario]:
    """Scenarios for ``hours`` simulated hours, hour after hour (lazily)."""
    if int(hours) != hours or hours < 0:
        raise ValueError(f"hours must be a non-negative integer, got {hours!r}")
    for h in range(int(hours)):
        yield from traffic_hour(h, root_seed, **kwargs)
