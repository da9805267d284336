"""Scenario parameters drawn in batches by a counter-based generator keyed by (id, seed).

The ``-v0`` environments draw each scenario with numpy generators spawned from
``SeedSequence([crc32(id), seed])`` (:func:`acc_gym.scenarios.registry.scenario_rngs`),
one scenario at a time in Python. This module draws the same laws for many scenarios in
one compiled call, with a *counter-based* generator: every random number is a pure
function of its key and its counter, so nothing is carried from one draw, one scenario
or one batch to the next.

Decisions:

* **The generator** is Philox4x32-10 (Salmon et al., "Parallel random numbers: as easy as
  1, 2, 3", SC 2011), checked against the Random123 known-answer vectors
  (``tests/scenarios/test_batched.py``). Key: ``(crc32(id), seed)`` -- the scenario's id
  and seed, as :func:`~acc_gym.scenarios.registry.scenario_rngs` keys its generators.
  Counter: ``(draw, stream, 0, VERSION)``: each parameter law, and each surrounding
  driver, has its own stream (:data:`PARAM_STREAM`, :data:`DRIVER_STREAM`), and ``draw``
  counts the blocks drawn on it. So a scenario's numbers depend on (id, seed) only --
  never on the batch it is drawn in, its place in the batch, the number of workers or
  the order of resets -- and one law's draws never shift another's.
* **Uniforms**: one per 64 bits of output (two 32-bit words, the top 53 bits), as
  ``(m + 0.5) / 2^53``: strictly inside (0, 1), so an inverse CDF never meets 0 or 1.
* **Laws**: the truncated univariate laws of :mod:`acc_gym.scenarios.distributions` are
  sampled as they define it -- the inverse CDF restricted to ``[F(low), F(high)]``, with
  the upper-tail reflection they use -- and :class:`~acc_gym.scenarios.distributions.BivariateNormal`
  by rejection in its box (Cholesky factor of the covariance, two standard normals per
  try from the inverse CDF), at most :data:`MAX_TRIES` tries (a box holding almost no
  mass is an error, as there). :class:`~acc_gym.scenarios.distributions.Constant` draws
  nothing. The normal inverse CDF is Acklam's approximation refined by one Halley step
  (:func:`_ndtri`: scipy's ``ndtri`` to about 1e-15), written here rather than called
  from scipy so that the kernels stay in numba's on-disk cache.
* **Scenarios** (:func:`build_many`): the parameters from here, the rest (surrounding
  drivers, speed profiles, geometry) by the scenario type's own builder with the
  generator :func:`acc_gym.scenarios.build` gives it for ``(id, seed)``: every scenario
  drawn here is rebuilt by the registry from what it records.
* **Drivers** (:func:`draw_drivers`, :func:`driver_values`): paper 001's population
  sampler (:func:`acc_gym.drivers.population.sample_driver_values`: the levels, the
  tables' inverse CDFs, the self-consistency rejection and clips, the time gap, the
  standstill gap, the speed-normalised distance weight) with its uniforms and normals from
  this generator, one stream per surrounding vehicle, for a batch in one call. Not used
  by :func:`build_many` yet: the builders draw their drivers themselves (taking them
  pre-drawn is a change to the builders, and then the registry would no longer rebuild
  the scenario from its record).

Who uses it: :class:`acc_gym.envs.config.CounterScenarioSampler`
(``gymnasium.make(id, scenario_generator="counter")``). What changes against numpy's
sampler: the numbers (the streams differ), not the laws -- the goodness-of-fit tests check
every law's 10,000 draws against its CDF (``tests/scenarios/test_batched.py``).
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass

import numba
import numpy as np

from acc_gym.drivers import population as _pop
from acc_gym.scenarios.distributions import BivariateNormal, Constant, Laplace, LogNormal, Normal

VERSION = 1  # counter word 3: the layout of the streams (a new layout is a new version)
MAX_TRIES = 1000  # rejection tries of a truncated bivariate normal before it is an error
PARAM_STREAM = 1  # + the law's index in its ScenarioType's declaration order
DRIVER_STREAM = 1000  # + the surrounding vehicle's index (0: the POV, 1: the POV2)

# Acklam's rational approximation of the standard normal inverse CDF (relative error below
# 1.2e-9), refined by one Halley step on erfc: what ndtri computes, to about 1e-15
_NA = (-3.969683028665376e+01, 2.209460984245205e+02, -2.759285104469687e+02, 1.383577518672690e+02,
       -3.066479806614716e+01, 2.506628277459239e+00)
_NB = (-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02, 6.680131188771972e+01,
       -1.328068155288572e+01)
_NC = (-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00, -2.549732539343734e+00,
       4.374664141464968e+00, 2.938163982698783e+00)
_ND = (7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00, 3.754408661907416e+00)
_P_LOW = 0.02425

_M0 = np.uint64(0xD2511F53)
_M1 = np.uint64(0xCD9E8D57)
_W0 = np.uint64(0x9E3779B9)
_W1 = np.uint64(0xBB67AE85)
_LO = np.uint64(0xFFFFFFFF)
_S32 = np.uint64(32)
_S11 = np.uint64(11)
_TWO53 = 9007199254740992.0  # 2^53


def key_of(scenario_id: str, seed: int) -> tuple[int, int]:
    """The Philox key of scenario ``(scenario_id, seed)``: ``(crc32(id), seed)`` (seed < 2^32)."""
    if not 0 <= int(seed) < 2 ** 32:
        raise ValueError(f"a seed of the counter-based generator must be in [0, 2^32), got {seed!r}")
    return zlib.crc32(scenario_id.encode()), int(seed)


@numba.njit(cache=True)
def philox4x32(c0, c1, c2, c3, k0, k1):  # pragma: no cover - compiled
    """Philox4x32-10 of the counter ``(c0, c1, c2, c3)`` and key ``(k0, k1)`` (32-bit words
    held in uint64): the four output words."""
    x0, x1, x2, x3 = np.uint64(c0) & _LO, np.uint64(c1) & _LO, np.uint64(c2) & _LO, np.uint64(c3) & _LO
    y0, y1 = np.uint64(k0) & _LO, np.uint64(k1) & _LO
    for _ in range(10):
        p0 = _M0 * x0  # < 2^64: exact in uint64
        p1 = _M1 * x2
        x0, x1, x2, x3 = ((p1 >> _S32) ^ x1 ^ y0), (p1 & _LO), ((p0 >> _S32) ^ x3 ^ y1), (p0 & _LO)
        y0 = (y0 + _W0) & _LO
        y1 = (y1 + _W1) & _LO
    return x0, x1, x2, x3


@numba.njit(cache=True)
def uniform2(k0, k1, stream, draw):  # pragma: no cover - compiled
    """The two uniforms in (0, 1) of block ``draw`` of ``stream`` under key ``(k0, k1)``."""
    w0, w1, w2, w3 = philox4x32(draw, stream, 0, VERSION, k0, k1)
    m0 = ((w0 << _S32) | w1) >> _S11  # the top 53 of 64 bits
    m1 = ((w2 << _S32) | w3) >> _S11
    return (float(m0) + 0.5) / _TWO53, (float(m1) + 0.5) / _TWO53


@numba.njit(cache=True)
def uniforms(k0, k1, stream, n):  # pragma: no cover - compiled
    """The first ``n`` uniforms of ``stream`` (two per block, in order)."""
    out = np.empty(n)
    for j in range((n + 1) // 2):
        a, b = uniform2(k0, k1, stream, j)
        out[2 * j] = a
        if 2 * j + 1 < n:
            out[2 * j + 1] = b
    return out


@numba.njit(cache=True)
def _ndtri(p):  # pragma: no cover - compiled
    """The standard normal law's inverse CDF at ``p`` in (0, 1) (``scipy.special.ndtri``
    to about 1e-15; ``tests/scenarios/test_batched.py`` compares them). The upper half by
    symmetry, ``-ndtri(1 - p)`` (``1 - p`` is exact there), so the refinement never
    subtracts two numbers near 1."""
    return -_ndtri_lower(1.0 - p) if p > 0.5 else _ndtri_lower(p)


@numba.njit(cache=True)
def _ndtri_lower(p):  # pragma: no cover - compiled
    """:func:`_ndtri` for ``p`` in (0, 0.5]: Acklam's approximation, then one Halley step."""
    if p < _P_LOW:
        q = math.sqrt(-2.0 * math.log(p))
        x = ((((((_NC[0] * q + _NC[1]) * q + _NC[2]) * q + _NC[3]) * q + _NC[4]) * q + _NC[5])
             / ((((_ND[0] * q + _ND[1]) * q + _ND[2]) * q + _ND[3]) * q + 1.0))
    else:
        q = p - 0.5
        r = q * q
        x = ((((((_NA[0] * r + _NA[1]) * r + _NA[2]) * r + _NA[3]) * r + _NA[4]) * r + _NA[5]) * q
             / (((((_NB[0] * r + _NB[1]) * r + _NB[2]) * r + _NB[3]) * r + _NB[4]) * r + 1.0))
    e = 0.5 * math.erfc(-x / math.sqrt(2.0)) - p  # Halley's step on Phi(x) = p
    u = e * math.sqrt(2.0 * math.pi) * math.exp(0.5 * x * x)
    return x - u / (1.0 + 0.5 * x * u)


@numba.njit(cache=True)
def _laplace_ppf(u):  # pragma: no cover - compiled
    """The standard Laplace law's inverse CDF (:func:`acc_gym.scenarios.distributions._laplace_ppf`)."""
    return math.log(2.0 * u) if u < 0.5 else -math.log(2.0 - 2.0 * u)


# law kinds of the compiled sampler
K_CONSTANT, K_NORMAL, K_LOGNORMAL, K_LAPLACE, K_BIVARIATE = range(5)
N_LAW = 11  # columns of a law row (see law_row)


def law_row(law) -> np.ndarray:
    """A law as one float row for :func:`sample_law`: ``(kind, a, b, low, high, ua, ub, flip)``
    for the univariate laws (``a, b`` location and scale, ``ua, ub`` the CDF bounds the
    inverse CDF is restricted to), ``(kind, m0, m1, l00, l10, l11, low0, low1, high0,
    high1)`` for the bivariate normal (``l`` its covariance's Cholesky factor)."""
    row = np.zeros(N_LAW)
    if isinstance(law, Constant):
        row[:2] = K_CONSTANT, law.value
    elif isinstance(law, (Normal, LogNormal, Laplace)):
        kind = {Normal: K_NORMAL, LogNormal: K_LOGNORMAL, Laplace: K_LAPLACE}[type(law)]
        loc, scale = (law.M, law.S) if isinstance(law, LogNormal) else (law.mu, law.sigma if isinstance(law, Normal)
                                                                          else law.b)
        ua, ub, flip = law._cdf_bounds
        row[:8] = kind, loc, scale, law.low, law.high, float(ua), float(ub), float(flip)
    elif isinstance(law, BivariateNormal):
        (c00, c01), (_, c11) = law.cov
        l00 = math.sqrt(c00)
        row[:10] = (K_BIVARIATE, law.mean[0], law.mean[1], l00, c01 / l00, math.sqrt(c11 - c01 * c01 / c00),
                    law.low[0], law.low[1], law.high[0], law.high[1])
    else:
        raise TypeError(f"no batched sampler for the law {law!r}")
    return row


@numba.njit(cache=True)
def sample_law(row, k0, k1, stream, out, j):  # pragma: no cover - compiled
    """Draw law ``row`` (:func:`law_row`) on ``stream`` of key ``(k0, k1)`` into ``out[j]``
    (and ``out[j + 1]`` for a pair). Returns False if a bivariate box rejected every try."""
    kind = int(row[0])
    if kind == K_CONSTANT:
        out[j] = row[1]
        return True
    if kind == K_BIVARIATE:
        for t in range(MAX_TRIES):
            u0, u1 = uniform2(k0, k1, stream, t)
            z0, z1 = _ndtri(u0), _ndtri(u1)
            x0 = row[1] + row[3] * z0
            x1 = row[2] + row[4] * z0 + row[5] * z1
            if row[6] <= x0 <= row[8] and row[7] <= x1 <= row[9]:
                out[j], out[j + 1] = x0, x1
                return True
        return False
    u, _ = uniform2(k0, k1, stream, 0)
    p = row[5] + (row[6] - row[5]) * u
    z = _laplace_ppf(p) if kind == K_LAPLACE else _ndtri(p)
    if row[7] != 0.0:  # the interval lies above the median: reflected (the survival function)
        z = -z
    x = row[1] + row[2] * z
    if kind == K_LOGNORMAL:
        x = math.exp(x)
    out[j] = min(max(x, row[3]), row[4])
    return True


@numba.njit(cache=True)
def sample_params(laws, widths, keys, out):  # pragma: no cover - compiled
    """Every law of one scenario type for every key: ``laws`` ``(L, N_LAW)`` rows, ``widths``
    ``(L,)`` the values each gives (1, or 2 for a pair), ``keys`` ``(n, 2)``; ``out`` ``(n,
    sum(widths))``. Law ``l`` draws on stream ``PARAM_STREAM + l``. Returns the first row
    whose bivariate box rejected every try, or -1."""
    for i in range(keys.shape[0]):
        j = 0
        for l in range(laws.shape[0]):
            if not sample_law(laws[l], keys[i, 0], keys[i, 1], PARAM_STREAM + l, out[i], j):
                return i
            j += widths[l]
    return -1


@dataclass(frozen=True)
class LawTable:
    """A scenario type's laws as arrays for :func:`sample_params` (declaration order)."""

    names: tuple  # the parameter names, in the order of the values
    laws: np.ndarray  # (L, N_LAW)
    widths: np.ndarray  # (L,) int64

    @classmethod
    def of(cls, stype) -> "LawTable":
        names, rows, widths = [], [], []
        for key, law in stype.parameters.items():
            group = key if isinstance(key, tuple) else (key,)
            names.extend(group)
            rows.append(law_row(law))
            widths.append(len(group))
        return cls(tuple(names), np.array(rows).reshape(-1, N_LAW), np.array(widths, dtype=np.int64))


def draw_params(stype, seeds) -> list[dict]:
    """The parameters of scenario type ``stype`` for each of ``seeds``, drawn in one compiled
    call: each a pure function of ``(stype.id, seed)``, checked against the type's
    positivity constraints as :meth:`ScenarioType.sample_params` checks them."""
    table = _table(stype)
    seeds = [int(s) for s in seeds]
    keys = np.array([key_of(stype.id, s) for s in seeds], dtype=np.int64).reshape(-1, 2)
    out = np.empty((len(seeds), len(table.names)))
    bad = sample_params(table.laws, table.widths, keys, out)
    if bad >= 0:
        raise RuntimeError(f"scenario {stype.id!r}, seed {seeds[bad]}: a truncated bivariate normal rejected "
                           f"{MAX_TRIES} tries (its box holds almost no probability)")
    params = [dict(zip(table.names, row)) for row in out.tolist()]
    for seed, p in zip(seeds, params):
        for name, value in p.items():  # the type's own constraints (the laws' bounds already keep them)
            if (name in stype.positive and value <= 0) or (name in stype.nonnegative and value < 0):
                raise ValueError(f"parameter {name!r} of {stype.id!r} (seed {seed}) must be "
                                 f"{'> 0' if name in stype.positive else '>= 0'}, got {value!r}")
    return params


_TABLES: dict = {}


def _table(stype) -> LawTable:
    """The law table of ``stype`` (cached by the type object, which is frozen)."""
    table = _TABLES.get(id(stype))
    if table is None or table[0] is not stype:
        table = _TABLES[id(stype)] = (stype, LawTable.of(stype))
    return table[1]


# ------------------------------------------------------------------ surrounding drivers
# the driver kinds the compiled sampler draws (the others take the numpy sampler)
DRIVER_KINDS = {"typical": 0, "naturalistic": 1, "atypical": 2}
# its output columns: MPCDriverParams fields (v_max left out, as sample_driver_values does)
DRIVER_FIELDS = ("a_max", "a_min", "a_req_sail", "a_sail", "q1", "r1", "q2", "c_tg", "x_min", "v_desired", "r_jerk",
                 "jerk_max", "jerk_emergency")
_A1 = _pop.TABLE_A1_MAX_ACCEL.copy()
_A2 = _pop.TABLE_A2_MAX_DECEL.copy()
_A4 = _pop.TABLE_A4_SAILING_START.copy()
_LOG_TG = float(np.log(1.5))  # [log s] the time gap's log median
_LOG_Q1N_LO, _LOG_Q1N_HI = (float(np.log(v)) for v in _pop.Q1N_RANGE)


@numba.njit(cache=True)
def _u(k0, k1, stream, j):  # pragma: no cover - compiled
    """Uniform number ``j`` of ``stream`` (two per block)."""
    a, b = uniform2(k0, k1, stream, j // 2)
    return a if j % 2 == 0 else b


@numba.njit(cache=True)
def _level(kind, k0, k1, stream, j):  # pragma: no cover - compiled
    """A quantile level of ``kind`` (0 typical: [0.1, 0.9], 1 naturalistic: [0, 1], 2 atypical:
    either tail, each with probability 1/2), from uniforms ``j, j + 1, ...``; returns the level
    and the next uniform's index."""
    if kind == 0:
        return 0.1 + 0.8 * _u(k0, k1, stream, j), j + 1
    if kind == 1:
        return _u(k0, k1, stream, j), j + 1
    tail = _u(k0, k1, stream, j) < 0.5
    low = 0.1 * _u(k0, k1, stream, j + 1)
    high = 0.9 + 0.1 * _u(k0, k1, stream, j + 2)
    return (low if tail else high), j + 3


@numba.njit(cache=True)
def _quantile(table, band, p):  # pragma: no cover - compiled
    """:func:`acc_gym.drivers.population.quantile` of one level on one row."""
    idx = min(max(int(math.floor(p * 4.0)), 0), 3)
    lo, hi = table[band, idx], table[band, idx + 1]
    return lo + (p - 0.25 * idx) / 0.25 * (hi - lo)


@numba.njit(cache=True)
def driver_values(kind, speed, k0, k1, stream, max_tries, out):  # pragma: no cover - compiled
    """One MPC driver of paper 001's population cruising at ``speed`` [m/s] > 0 into ``out``
    (:data:`DRIVER_FIELDS`): :func:`acc_gym.drivers.population.sample_driver_values`' laws
    and steps, its uniforms and normals drawn in turn on ``stream`` of key ``(k0, k1)``."""
    band = 0
    while band < 3 and speed >= (10.0, 20.0, 30.0)[band]:
        band += 1  # bisect_right on the band edges
    j = 0
    a_max = a_min = a_req_sail = a_sail = 0.0
    for _ in range(max_tries):
        p, j = _level(kind, k0, k1, stream, j)
        a_max = _quantile(_A1, band, p)
        p, j = _level(kind, k0, k1, stream, j)
        a_min = _quantile(_A2, band, p)
        p, j = _level(kind, k0, k1, stream, j)
        a_req_sail = _quantile(_A4, band, p)
        a_sail = -0.5 + 0.4 * _u(k0, k1, stream, j)  # uniform in [-0.5, -0.1] [m/s^2]
        j += 1
        if a_min <= 1.5 * a_req_sail and a_req_sail < a_sail:
            break
    a_req_sail = min(a_req_sail, a_sail - 0.05)
    a_min = min(a_min, 1.5 * a_req_sail)
    a_max = max(a_max, 0.3)
    c_tg = min(max(math.exp(_LOG_TG + 0.25 * _ndtri(_u(k0, k1, stream, j))), 0.8), 3.0)  # [s]
    x_min = 2.0 + 2.0 * _u(k0, k1, stream, j + 1)  # [m]
    q1n = math.exp(_LOG_Q1N_LO + (_LOG_Q1N_HI - _LOG_Q1N_LO) * _u(k0, k1, stream, j + 2))
    q1 = q1n * (20.0 / speed) ** 4.0  # Q1_SPEED_REF, Q1_SPEED_EXPONENT
    r1 = 40.0 + 5.0 * _u(k0, k1, stream, j + 3)
    out[0], out[1], out[2], out[3], out[4], out[5], out[6] = a_max, a_min, a_req_sail, a_sail, q1, r1, 1.0
    out[7], out[8], out[9], out[10], out[11], out[12] = c_tg, x_min, speed, 0.0, 2.5, 50.0


@numba.njit(cache=True)
def drivers_batch(kind, speeds, keys, vehicle, out):  # pragma: no cover - compiled
    """:func:`driver_values` for every row: ``speeds`` ``(n,)`` [m/s], ``keys`` ``(n, 2)``,
    the vehicle's index ``vehicle`` (its stream ``DRIVER_STREAM + vehicle``); ``out`` ``(n,
    len(DRIVER_FIELDS))``."""
    for i in range(speeds.shape[0]):
        driver_values(kind, speeds[i], keys[i, 0], keys[i, 1], DRIVER_STREAM + vehicle, 50, out[i])


def draw_drivers(kind: str, speeds, keys, vehicle: int) -> list[dict]:
    """Surrounding drivers of ``kind`` (``"typical"``, ``"naturalistic"``, ``"atypical"``)
    cruising at ``speeds`` [m/s] (each > 0, floored at 0.5 m/s as
    :func:`~acc_gym.scenarios.registry.driver_for` does), one per key of ``keys`` (``(n,
    2)``: :func:`key_of`), for surrounding vehicle ``vehicle``: dicts of
    :class:`~acc_gym.drivers.mpc.MPCDriverParams` fields."""
    if kind not in DRIVER_KINDS:
        raise ValueError(f"the batched driver sampler draws {sorted(DRIVER_KINDS)}, not {kind!r}")
    speeds = np.maximum(np.asarray(speeds, dtype=float).reshape(-1), 0.5)
    keys = np.asarray(keys, dtype=np.int64).reshape(-1, 2)
    out = np.empty((speeds.shape[0], len(DRIVER_FIELDS)))
    drivers_batch(DRIVER_KINDS[kind], speeds, keys, int(vehicle), out)
    return [dict(zip(DRIVER_FIELDS, row)) for row in out.tolist()]


# ------------------------------------------------------------------ scenarios
def build(scenario_id: str, seed: int, drivers: str = "typical"):
    """The scenario ``(scenario_id, seed)`` with its parameters from the counter-based
    generator (:func:`draw_params`): :func:`build_many` of one."""
    return build_many([scenario_id], [seed], drivers)[0]


def build_many(scenario_ids, seeds, drivers: str = "typical") -> list:
    """The scenarios ``(scenario_ids[j], seeds[j])``, their parameters drawn in one compiled
    call per scenario type (:func:`draw_params`).

    The rest of a scenario -- its surrounding drivers, speed profiles and geometry -- is its
    type's builder with those parameters, and the builder draws from the generator that
    :func:`acc_gym.scenarios.registry.build` gives it for ``(id, seed)``
    (:func:`~acc_gym.scenarios.registry.scenario_rngs`). Decided so, because then every
    scenario of this generator is rebuilt by the registry from what it records:
    ``acc_gym.scenarios.build(s.id, s.params, s.seed, s.drivers) == s``, as for any other
    scenario (giving the parameters never shifts the builder's draws); and it stays a pure
    function of ``(id, seed)``."""
    from acc_gym.scenarios.registry import DRIVER_CHOICES, check_seed, scenario_type

    if not isinstance(drivers, str) or drivers not in DRIVER_CHOICES:
        raise ValueError(f"unknown drivers {drivers!r}; use one of {list(DRIVER_CHOICES)}")
    scenario_ids, seeds = list(scenario_ids), [check_seed(s) for s in seeds]
    if len(scenario_ids) != len(seeds):
        raise ValueError(f"build_many needs one seed per id, got {len(scenario_ids)} ids and {len(seeds)} seeds")
    groups: dict[str, list[int]] = {}
    for j, sid in enumerate(scenario_ids):
        groups.setdefault(sid, []).append(j)
    out: list = [None] * len(seeds)
    for sid, rows in groups.items():
        stype = scenario_type(sid)
        for j, p in zip(rows, draw_params(stype, [seeds[j] for j in rows])):
            out[j] = stype.builder(stype, p, builder_rng(sid, seeds[j]), drivers, seeds[j])
    return out


def builder_rng(scenario_id: str, seed: int) -> np.random.Generator:
    """The builder's generator of ``(scenario_id, seed)``: the second of
    :func:`~acc_gym.scenarios.registry.scenario_rngs` (``SeedSequence([crc32(id), seed])``'s
    child with spawn key ``(1,)``), made alone -- the parameters' generator, the first, is
    not needed here (``tests/scenarios/test_batched.py`` checks the two agree)."""
    entropy = [zlib.crc32(scenario_id.encode()), int(seed)]
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(entropy, spawn_key=(1,))))
