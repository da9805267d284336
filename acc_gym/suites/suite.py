"""A versioned suite: a scenario stream per split (code) and a fixed episode list (data).

A :class:`Suite` has two faces:

* **the stream** -- :meth:`Suite.scenario` ``(index, split)``: a pure function of the index
  and the split's root seed (all randomness from
  ``numpy.random.default_rng([index, root_seed(split)])``, see
  :mod:`acc_gym.suites.generators`), unbounded, for campaigns that want more traffic;
* **the definition** -- :meth:`Suite.episodes`: the fixed list of scenarios the suite
  *is*, per split, each recorded as ``(id, params, seed, drivers)`` -- exactly what
  :func:`acc_gym.scenarios.build` needs to rebuild it. It is the stream's first
  ``count`` scenarios, or the first scenarios whose durations reach ``hours``.

Splits: ``dev`` is for tuning, ``test`` for ranking. Their root seeds are public and
secret-free: the first four bytes of ``sha256("acc_gym.suites:<name>:<split>")``, so
the test split is not hidden, only separate -- a controller tuned on dev meets other
scenarios on test, and a new version (a new name) gets new seeds.

Machine independence: the same definition on every machine. The sampled parameters
come from transcendental functions (``exp``, ``log``, ...) whose last bits differ between
CPU instruction sets (numpy's AVX-512 ``exp`` is not its AVX2 ``exp``), so a parameter
drawn on one machine can differ from the same draw on another in its last bit or two.
:meth:`Suite.scenario` therefore **rounds every parameter to** ``PARAM_DECIMALS`` **(6)
decimals** -- a micrometre, a microsecond, a micrometre per second: far below anything
physical, far above a last-bit difference (about 1e-14 for values below 100) -- and
*builds the scenario from the rounded values*; the definition stores exactly those
values and :meth:`Suite.episodes` builds from them, never re-deriving them. Decimal
rounding of a double is exact and platform-independent in Python (``round`` is correctly
rounded), so regenerating a suite on any machine gives byte-identical data, unless a
drawn value lies within a last-bit difference of a rounding boundary (a chance of about
1e-8 per value, ~1e-5 per suite). What is *not* exactly the same on every machine: what the
episode's build derives from the seed (the surrounding drivers' sampled parameters, a
lead's speed profile) and the simulation itself (compiled code may fuse multiply-adds
differently), so trajectories and scores are reproducible to a tolerance (measured in
``tests/suites/test_reproducibility.py``), not to the bit.

Hashes: :meth:`Suite.hash` is the sha256 of the canonical JSON (sorted keys, no
whitespace, no NaN) of the definition, so it changes when any id, parameter, seed,
driver choice, root seed or the environment id changes, and never with dict key order.
The definition also holds, per split, ``content_sha256``: a digest of the *built*
scenarios (every vehicle, driver parameter and speed profile, floats rounded to 6
decimals so that last-bit differences between platforms do not count). It is part of
the hash, and :meth:`Suite.verify` rebuilds the episodes to check it -- so a change to
a scenario builder that would silently change a published suite is caught by the tests
(and shows in a leaderboard's manifest) instead of going unnoticed.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Callable, Iterator

import numpy as np

from acc_gym.scenarios import build
from acc_gym.scenarios.spec import Scenario

SPLITS = ("dev", "test")
PRIVATE_ORDER_STREAM = 0x5EC2E7  # the shuffle's generator: default_rng([root_seed, this])
HOUR = 3600.0  # [s]
ROUND_DECIMALS = 6  # of the content digest
PARAM_DECIMALS = 6  # a suite episode's parameters are stored and built at this many decimals


def canonical_json(obj) -> str:
    """Sorted keys, no whitespace, no NaN or infinity: the same value gives the same text."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False)


def sha256_of(obj) -> str:
    return hashlib.sha256(canonical_json(obj).encode("ascii")).hexdigest()


def derive_root_seed(name: str, split: str) -> int:
    """The public root seed of ``split`` of suite ``name`` (see the module docstring)."""
    return int.from_bytes(hashlib.sha256(f"acc_gym.suites:{name}:{split}".encode()).digest()[:4], "big")


def check_split(split) -> str:
    if split not in SPLITS:
        raise ValueError(f"unknown split {split!r}; use one of {list(SPLITS)}")
    return split


def _rounded(x):
    if isinstance(x, dict):
        return {k: _rounded(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_rounded(v) for v in x]
    if isinstance(x, float):
        if not math.isfinite(x):
            return str(x)
        return round(x, ROUND_DECIMALS) + 0.0  # + 0.0: no "-0.0"
    return x


def canonical_params(params: dict) -> dict:
    """``params`` with every value rounded to ``PARAM_DECIMALS`` decimals (``-0.0`` as ``0.0``):
    the canonical form a suite stores and builds from (see the module docstring)."""
    return {str(k): round(float(v), PARAM_DECIMALS) + 0.0 for k, v in params.items()}


def canonical_scenario(sc: Scenario) -> Scenario:
    """``sc`` built again from its canonical parameters (itself when they are canonical already)."""
    params = canonical_params(sc.params)
    if params == sc.params:
        return sc
    return build(sc.id, params, sc.seed, sc.drivers)


def content_digest(scenarios: list[Scenario]) -> str:
    """sha256 of the built scenarios (full ``to_dict``, floats rounded to 6 decimals)."""
    return sha256_of([_rounded(s.to_dict()) for s in scenarios])


def entry(s: Scenario) -> dict:
    """How the definition records one episode: enough for :func:`acc_gym.scenarios.build`."""
    return {"id": s.id, "params": dict(s.params), "seed": int(s.seed), "drivers": s.drivers}


def definition_hash(definition: dict, split: str | None = None) -> str:
    """The hash of a definition (:meth:`Suite.to_dict` form), of one split or of all."""
    if split is None:
        return sha256_of(definition)
    check_split(split)
    part = {k: definition[k] for k in ("name", "version", "family", "env_id")}
    part.update(split=split, root_seed=definition["root_seeds"][split], episodes=definition["episodes"][split],
                content_sha256=definition["content_sha256"][split])
    return sha256_of(part)


class Suite:
    """A versioned suite (see the module docstring).

    ``generator(index, rng) -> Scenario`` is the stream's code; exactly one of ``count``
    (episodes per split) and ``hours`` (simulated hours per split) sizes the definition.
    ``definition`` is the materialised definition (:meth:`to_dict` form, as shipped in
    ``acc_gym/suites/data``); without it the definition is generated from the code.
    """

    def __init__(self, name: str, version: int, family: str, env_id: str, generator: Callable, *,
                 count: int | None = None, hours: float | None = None, description: str = "",
                 definition: dict | None = None):
        if (count is None) == (hours is None):
            raise ValueError(f"suite {name!r}: give exactly one of count and hours")
        if count is not None and (int(count) != count or count < 1):
            raise ValueError(f"suite {name!r}: count must be a positive integer, got {count!r}")
        if hours is not None and not (math.isfinite(hours) and hours > 0):
            raise ValueError(f"suite {name!r}: hours must be > 0, got {hours!r}")
        self.name, self.version, self.family, self.env_id = name, int(version), family, env_id
        self.generator, self.count, self.hours, self.description = generator, count, hours, description
        self._definition = None
        if definition is not None:
            self._definition = self._checked(definition)

    def __repr__(self) -> str:
        return f"Suite({self.name!r}, version={self.version}, env_id={self.env_id!r})"

    # -- the stream (code) ---------------------------------------------------------------
    def root_seed(self, split: str) -> int:
        check_split(split)
        if self._definition is not None:
            return int(self._definition["root_seeds"][split])
        return derive_root_seed(self.name, split)

    def scenario(self, index: int, split: str = "test") -> Scenario:
        """Scenario ``index`` of the split's stream (a pure function of ``(index, split)``),
        built from its canonical (rounded) parameters."""
        if isinstance(index, bool) or int(index) != index or index < 0:
            raise ValueError(f"index must be a non-negative integer, got {index!r}")
        return self._drawn(int(index), self.root_seed(split))

    def _drawn(self, index: int, root_seed: int) -> Scenario:
        rng = np.random.default_rng([index, root_seed])
        return canonical_scenario(self.generator(index, rng))

    def private_episodes(self, root_seed: int) -> list[Scenario]:
        """A private split's episode list: as many as the test split holds (``count``, or
        the first scenarios reaching ``hours``), drawn by the suite's own generator from
        ``root_seed`` (see :mod:`acc_gym.suites.private`: derived from a host's secret),
        then shuffled by a generator seeded from the same root, so that neither the
        episodes nor their order come from anything shipped."""
        if isinstance(root_seed, bool) or not isinstance(root_seed, int) or root_seed < 0:
            raise ValueError(f"root_seed must be a non-negative integer, got {root_seed!r}")
        if self.count is not None:
            drawn = [self._drawn(i, root_seed) for i in range(int(self.count))]
        else:
            drawn, elapsed, i = [], 0.0, 0
            while elapsed < self.hours * HOUR:
                drawn.append(self._drawn(i, root_seed))
                elapsed += drawn[-1].duration
                i += 1
        order = np.random.default_rng([root_seed, PRIVATE_ORDER_STREAM]).permutation(len(drawn))
        return [drawn[k] for k in order]

    def stream(self, split: str = "test", hours: float | None = None, start: int = 0) \
            -> Iterator[tuple[int, Scenario]]:
        """``(index, scenario)`` from ``start`` on; with ``hours``, stops once the durations
        from index 0 add up to ``hours * 3600`` s (the scenarios before ``start`` count)."""
        check_split(split)
        if int(start) != start or start < 0:
            raise ValueError(f"start must be a non-negative integer, got {start!r}")
        if hours is not None and not (math.isfinite(hours) and hours >= 0):
            raise ValueError(f"hours must be a finite number >= 0, got {hours!r}")
        elapsed, index = 0.0, 0
        while hours is None or elapsed < hours * HOUR:
            if hours is None and index < start:
                index = int(start)
            sc = self.scenario(index, split)
            if index >= start:
                yield index, sc
            elapsed += sc.duration
            index += 1

    def generate(self, split: str) -> list[Scenario]:
        """The split's episode list from the code (what the definition must hold)."""
        if self.count is not None:
            return [self.scenario(i, split) for i in range(int(self.count))]
        return [sc for _, sc in self.stream(split, hours=self.hours)]

    # -- the definition (data) -----------------------------------------------------------
    def materialise(self) -> dict:
        """The definition generated from the code (what ``acc_gym/suites/data`` ships)."""
        episodes = {sp: [] for sp in SPLITS}
        digests = {}
        for sp in SPLITS:
            scenarios = [sc for sc in self._generate_from_code(sp)]
            episodes[sp] = [entry(s) for s in scenarios]
            digests[sp] = content_digest(scenarios)
        return {"name": self.name, "version": self.version, "family": self.family, "env_id": self.env_id,
                "root_seeds": {sp: derive_root_seed(self.name, sp) for sp in SPLITS},
                "episodes": episodes, "content_sha256": digests}

    def _generate_from_code(self, split: str) -> list[Scenario]:
        saved, self._definition = self._definition, None  # the code's root seeds, not the data's
        try:
            return self.generate(split)
        finally:
            self._definition = saved

    def to_dict(self) -> dict:
        """The JSON-safe definition: name, version, family, env_id, root seeds, and per split
        the episodes as ``{"id", "params", "seed", "drivers"}`` and the content digest."""
        if self._definition is None:
            self._definition = self._checked(self.materialise())
        return json.loads(json.dumps(self._definition))  # a deep copy: callers may edit it

    def episodes(self, split: str = "test") -> list[Scenario]:
        """The split's fixed episode list (the suite's definition), built."""
        check_split(split)
        out = []
        for k, e in enumerate(self.to_dict()["episodes"][split]):
            try:
                out.append(build(e["id"], e["params"], e["seed"], e["drivers"]))
            except (KeyError, TypeError, ValueError) as exc:
                raise ValueError(f"suite {self.name!r}, split {split!r}: episode {k} ({e!r}) does not build: "
                                 f"{exc}") from None
        return out

    def hash(self, split: str | None = None) -> str:
        """sha256 hex of the canonical JSON of the definition (all splits if ``split`` is None)."""
        return definition_hash(self.to_dict(), split)

    def verify(self, split: str | None = None) -> None:
        """Check that the definition is what the code generates and builds to its content
        digest; ``ValueError`` naming the first difference otherwise."""
        splits = SPLITS if split is None else (check_split(split),)
        d = self.to_dict()
        for sp in splits:
            if d["root_seeds"][sp] != derive_root_seed(self.name, sp):
                raise ValueError(f"suite {self.name!r}: the {sp} root seed {d['root_seeds'][sp]} is not the derived "
                                 f"{derive_root_seed(self.name, sp)}")
            code = [entry(s) for s in self._generate_from_code(sp)]
            data = d["episodes"][sp]
            if canonical_json(code) != canonical_json(data):
                n = next((k for k, (a, b) in enumerate(zip(code, data)) if a != b), min(len(code), len(data)))
                raise ValueError(f"suite {self.name!r}, split {sp!r}: the definition differs from the code at "
                                 f"episode {n} (code {len(code)} episodes, definition {len(data)})")
            digest = content_digest(self.episodes(sp))
            if digest != d["content_sha256"][sp]:
                raise ValueError(f"suite {self.name!r}, split {sp!r}: the episodes build to content {digest[:12]}..., "
                                 f"not the definition's {d['content_sha256'][sp][:12]}...: a scenario builder "
                                 f"changed what this suite's scenarios are")

    @classmethod
    def from_dict(cls, definition: dict, template: Suite) -> Suite:
        """A suite with ``template``'s code and this definition (e.g. an edited copy)."""
        return cls(template.name, template.version, template.family, template.env_id, template.generator,
                   count=template.count, hours=template.hours, description=template.description,
                   definition=definition)

    def _checked(self, d: dict) -> dict:
        if not isinstance(d, dict):
            raise ValueError(f"suite {self.name!r}: a definition must be a JSON object, got {type(d).__name__}")
        keys = {"name", "version", "family", "env_id", "root_seeds", "episodes", "content_sha256"}
        if set(d) != keys:
            raise ValueError(f"suite {self.name!r}: a definition needs exactly the keys {sorted(keys)}, "
                             f"got {sorted(d)}")
        for key in ("name", "version", "family", "env_id"):
            if d[key] != getattr(self, key):
                raise ValueError(f"suite {self.name!r}: the definition's {key} is {d[key]!r}, "
                                 f"expected {getattr(self, key)!r}")
        for key in ("root_seeds", "episodes", "content_sha256"):
            if not isinstance(d[key], dict) or set(d[key]) != set(SPLITS):
                raise ValueError(f"suite {self.name!r}: the definition's {key} must map each of {list(SPLITS)}")
        for sp in SPLITS:
            for k, e in enumerate(d["episodes"][sp]):
                if not isinstance(e, dict) or set(e) != {"id", "params", "seed", "drivers"}:
                    raise ValueError(f"suite {self.name!r}, split {sp!r}: episode {k} must be "
                                     f"{{id, params, seed, drivers}}, got {e!r}")
        canonical_json(d)  # JSON-safe (raises on NaN / infinity / odd types)
        return json.loads(json.dumps(d))
