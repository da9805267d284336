"""Which scenarios a campaign runs, with which seeds, in which chunks.

Scenarios come from a suite (:mod:`acc_gym.suites`): scenario ``i`` of a split is
``suite.scenario(i, split)``, a pure function of ``(i, split)`` whose randomness comes
from ``numpy.random.default_rng([i, suite.root_seed(split)])``.

**Root seed.** A campaign has a root seed ``R``. By default ``R`` is the split's own root
(``suite.root_seed(split)``) and the campaign's scenario ``i`` *is* the suite's scenario
``i`` -- a campaign on the ``test`` split runs exactly the published test scenarios. With
another ``R`` (``--root-seed``) scenario ``i`` is drawn by the same law with
``default_rng([i, R])`` in place of ``default_rng([i, suite.root_seed(split)])``: the suite's
``scenario(i, split, root_seed=R)`` when it takes that argument, else its stream's code
``suite.generator(i, default_rng([i, R]))`` (how :class:`acc_gym.suites.Suite` defines
``scenario``). So a campaign with root ``R`` is the same traffic law with other draws,
and with ``R = suite.root_seed(split)`` both ways give the suite's own scenarios. Either way scenario ``i``
and its seed depend only on ``(suite, split, R, i)``, never on the number of workers, the
chunking or the order chunks run in -- which is what makes results reproducible and
resumable.

**Episode seed.** Each episode is reset with ``seed_for(i, R)``, the first draw
``integers(0, 2**31 - 1)`` of ``default_rng([i, R])`` (seeds per scenario come from
``default_rng([scenario_id, root_seed])``); it is recorded in every result row.

**Length.** ``hours`` of traffic are the scenarios ``0 .. n-1`` with ``n`` the smallest
count whose durations sum to at least ``hours * 3600`` s (the suite's ``stream`` rule).
Finding ``n`` builds each scenario once in the calling process (a few ms each); the
manifest records ``n`` so a resumed campaign does not plan again.

**Chunks.** Chunk ``k`` holds indices ``[k * chunk_size, min((k + 1) * chunk_size, n))``;
it is the unit of work sent to a worker and of storage (one Parquet file).
"""

from __future__ import annotations

import inspect
import math
from dataclasses import dataclass

import numpy as np

from acc_gym.campaigns.errors import CampaignError

HOUR = 3600.0  # [s]
SPLITS = ("dev", "test")
SEED_HIGH = 2 ** 31 - 1
SUITE_ATTRIBUTES = ("name", "version", "env_id", "root_seed", "scenario", "hash")


def resolve_suite(suite):
    """A suite object from a registered name (``acc_gym.suites.get_suite``) or a suite object."""
    if isinstance(suite, str):
        try:
            from acc_gym.suites import get_suite
        except ImportError as exc:
            raise CampaignError(f"suite {suite!r}: the suite registry acc_gym.suites is not available ({exc})") \
                from None
        try:
            return get_suite(suite)
        except (KeyError, ValueError) as exc:
            msg = str(exc).strip("'\"")
            raise CampaignError(msg if repr(suite) in msg else f"unknown suite {suite!r}: {msg}") from None
    missing = [a for a in SUITE_ATTRIBUTES if not hasattr(suite, a)]
    if missing:
        raise CampaignError(f"suite {suite!r} is neither a suite name nor a suite object (missing {missing})")
    return suite


def check_split(split) -> str:
    if split not in SPLITS:
        raise CampaignError(f"unknown split {split!r}: use one of {list(SPLITS)}")
    return split


def check_root_seed(root_seed) -> int:
    if isinstance(root_seed, bool) or not isinstance(root_seed, (int, np.integer)) or root_seed < 0:
        raise CampaignError(f"root seed must be a non-negative integer, got {root_seed!r}")
    return int(root_seed)


def check_hours(hours) -> float:
    if isinstance(hours, bool) or not isinstance(hours, (int, float, np.integer, np.floating)) \
            or not math.isfinite(hours) or hours <= 0:
        raise CampaignError(f"hours must be a positive finite number, got {hours!r}")
    return float(hours)


def check_positive_int(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise CampaignError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def seed_for(index: int, root_seed: int) -> int:
    """The reset seed of the campaign's scenario ``index`` under ``root_seed``."""
    return int(np.random.default_rng([int(index), int(root_seed)]).integers(0, SEED_HIGH))


def _takes_root_seed(suite) -> bool:
    try:
        return "root_seed" in inspect.signature(suite.scenario).parameters
    except (TypeError, ValueError):
        return False


def scenario_at(suite, index: int, split: str, root_seed: int):
    """The campaign's scenario ``index`` (see the module docstring for how ``root_seed`` enters)."""
    if root_seed == suite.root_seed(split):
        return suite.scenario(int(index), split=split)
    if _takes_root_seed(suite):
        return suite.scenario(int(index), split=split, root_seed=int(root_seed))
    if callable(getattr(suite, "generator", None)):  # acc_gym.suites.Suite: scenario(i) = generator(i, rng)
        return suite.generator(int(index), np.random.default_rng([int(index), int(root_seed)]))
    raise CampaignError(f"suite {suite.name!r} cannot draw its scenarios from root seed {root_seed}: it has neither "
                        f"scenario(..., root_seed=) nor generator(index, rng); omit the root seed to use the "
                        f"{split!r} split's own root {suite.root_seed(split)}")


def plan_length(suite, split: str, root_seed: int, hours: float) -> tuple[int, float]:
    """``(n, seconds)``: how many scenarios make ``hours`` of traffic, and their total duration."""
    if hasattr(suite, "n_points"):  # an OpenSCENARIO variation (acc_gym.campaigns.sweep): all its scenarios
        if suite.n_points == 0:
            raise CampaignError(f"{suite.name}: the variation has no concrete scenario that satisfies the "
                                f"template's constraints")
        return int(suite.n_points), 0.0
    target = hours * HOUR
    total, n = 0.0, 0
    if root_seed == suite.root_seed(split) and hasattr(suite, "stream"):
        source = (sc for _, sc in suite.stream(split=split, hours=hours))
    else:
        source = (scenario_at(suite, i, split, root_seed) for i in range(2 ** 62))
    for sc in source:
        total += float(sc.duration)
        n += 1
        if total >= target:
            break
    if n == 0 or total < target:
        raise CampaignError(f"suite {suite.name!r} ({split}) ran out of scenarios after {n} "
                            f"({total / HOUR:.3f} h < {hours} h)")
    return n, total


@dataclass(frozen=True)
class Chunk:
    """Chunk ``number``: scenario indices ``start .. stop-1``."""

    number: int
    start: int
    stop: int

    @property
    def indices(self) -> range:
        return range(self.start, self.stop)

    def __len__(self) -> int:
        return self.stop - self.start


def chunks(n_scenarios: int, chunk_size: int) -> list[Chunk]:
    """The chunks covering scenarios ``0 .. n_scenarios-1``."""
    return [Chunk(k, s, min(s + chunk_size, n_scenarios))
            for k, s in enumerate(range(0, n_scenarios, chunk_size))]
