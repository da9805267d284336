"""Probability laws for the parameters of test scenarios.

Van Tongeren et al. (2007), "Traffic modelling validation of advanced driver assistance
systems", describe each parameter of a scenario (an initial speed, a gap, a lead
vehicle's deceleration, ...) by a probability law fitted to naturalistic driving data,
Eqs. (6)-(9): the normal, the log-normal and the Laplace law for single parameters, and
the bivariate normal for pairs of correlated parameters:

* normal       f(x) = exp(-(x - mu)^2 / (2 sigma^2)) / (sigma sqrt(2 pi))
* log-normal   f(x) = exp(-(ln x - M)^2 / (2 S^2)) / (S sqrt(2 pi) x),  x > 0
* Laplace      f(x) = exp(-|x - mu| / b) / (2 b)
* bivariate    f(x) = exp(-(x - m)' C^-1 (x - m) / 2) / (2 pi sqrt(det C)),  x in R^2

Location and scale parameters (mu, sigma, b, m, sqrt C) carry the unit of the scenario
quantity (m, m/s, s, m/s^2); M and S are the location and scale of ln x and are
dimensionless. :class:`Constant` stands in for a parameter that is held fixed.

Every law is a frozen, hashable dataclass, validated on construction, that samples from
a ``numpy.random.Generator`` passed in (never the global RNG) and serialises to a
JSON-safe dict (``to_dict`` / :func:`from_dict`). The univariate laws take optional
truncation bounds ``low`` / ``high``; they are sampled exactly by the inverse CDF
restricted to ``[F(low), F(high)]`` and ``logpdf`` is renormalised to the interval.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Mapping
from dataclasses import MISSING, dataclass, fields
from functools import cached_property
from typing import Any, ClassVar, NamedTuple

import numpy as np
from scipy.special import ndtr, ndtri

_LOG_2PI = math.log(2.0 * math.pi)
Size = int | tuple[int, ...] | None


# ----------------------------------------------------------------------------- helpers
def _real(label: str, value: Any, *, allow_inf: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{label} must be a real number, got {value!r}")  # noqa: TRY004 (a bad parameter value)
    v = float(value)
    if math.isnan(v) or (math.isinf(v) and not allow_inf):
        raise ValueError(f"{label} must be {'a number or None' if allow_inf else 'finite'}, got {v!r}")
    return v


def _bound(label: str, value: Any, default: float) -> float:
    """A truncation bound: ``None`` or an infinity means 'unbounded on this side'."""
    return default if value is None else _real(label, value, allow_inf=True)


def _check_rng(rng: Any) -> None:
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")


def _out(arr: np.ndarray) -> float | np.ndarray:
    return float(arr) if np.ndim(arr) == 0 else arr


def _json_bound(v: float) -> float | None:
    return None if math.isinf(v) else v


class _StdLaw(NamedTuple):
    """A standard law symmetric about 0: log-density, CDF and inverse CDF."""

    logpdf: Callable[[np.ndarray], np.ndarray]
    cdf: Callable[[np.ndarray], np.ndarray]
    ppf: Callable[[np.ndarray], np.ndarray]


def _laplace_cdf(z):
    z = np.asarray(z, dtype=float)
    return np.where(z < 0, 0.5 * np.exp(np.minimum(z, 0.0)), 1.0 - 0.5 * np.exp(-np.maximum(z, 0.0)))


def _laplace_ppf(u):
    if isinstance(u, float) and 0.0 < u < 1.0:  # one draw (a scenario's): the branch np.where takes, on the number
        return np.log(2.0 * u) if u < 0.5 else -np.log(2.0 - 2.0 * u)
    u = np.asarray(u, dtype=float)
    with np.errstate(divide="ignore"):
        return np.where(u < 0.5, np.log(2.0 * np.minimum(u, 0.5)), -np.log(2.0 - 2.0 * np.maximum(u, 0.5)))


_STD_NORMAL = _StdLaw(lambda z: -0.5 * np.square(z) - 0.5 * _LOG_2PI, ndtr, ndtri)
_STD_LAPLACE = _StdLaw(lambda z: -np.abs(z) - math.log(2.0), _laplace_cdf, _laplace_ppf)


# ------------------------------------------------------------------- univariate laws
class _Univariate:
    """Shared machinery: a law is an affine (or log-affine) map of a symmetric standard law.

    Subclasses define ``_to_z`` / ``_from_z`` (data <-> standard variable), ``_log_jac``
    (log dz/dx), ``_support`` and ``_median``; truncation happens in z-space. An interval
    lying above the median is handled through the survival function (``F(-z)``), so a
    bound far in the upper tail keeps its precision.
    """

    kind: ClassVar[str]
    _std: ClassVar[_StdLaw]
    _positive: ClassVar[tuple[str, ...]] = ()
    low: float
    high: float

    def __post_init__(self) -> None:
        name = type(self).__name__
        for f in fields(self):  # type: ignore[arg-type]
            label, value = f"{name}.{f.name}", getattr(self, f.name)
            if f.name == "low":
                v = _bound(label, value, -math.inf)
            elif f.name == "high":
                v = _bound(label, value, math.inf)
            else:
                v = _real(label, value)
                if f.name in self._positive and not v > 0:
                    raise ValueError(f"{label} must be > 0, got {v!r}")
            object.__setattr__(self, f.name, v)
        if not self.low < self.high:
            raise ValueError(f"{name}.low must be < {name}.high, got low={self.low!r}, high={self.high!r}")
        if not self._mass() > 0:
            raise ValueError(f"{name} truncated to [{self.low!r}, {self.high!r}] has zero probability mass")

    # subclass hooks
    def _to_z(self, x: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _from_z(self, z: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _log_jac(self, x: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _support(self, x: np.ndarray) -> np.ndarray:
        return np.ones(np.shape(x), dtype=bool)

    @property
    def _median(self) -> float:
        raise NotImplementedError

    # truncation in z-space
    def _z_bounds(self) -> tuple[float, float, bool]:
        """Standardised bounds, reflected (z -> -z) when the interval lies above the median."""
        zl, zh = (float(v) for v in self._to_z(np.array([self.low, self.high])))
        return (-zh, -zl, True) if zl > 0 else (zl, zh, False)

    @cached_property
    def _cdf_bounds(self) -> tuple:
        """``(F(a), F(b), flip)`` of :meth:`_z_bounds`, what :meth:`sample` maps uniforms through.
        Cached on first use: a law is frozen, so this never goes stale (scenario resets sample
        the same laws over and over)."""
        a, b, flip = self._z_bounds()
        return self._std.cdf(a), self._std.cdf(b), flip

    def _mass(self) -> float:
        """Probability of [low, high] under the untruncated law."""
        a, b, _ = self._z_bounds()
        return float(self._std.cdf(b) - self._std.cdf(a))

    def sample(self, rng: np.random.Generator, size: Size = None) -> float | np.ndarray:
        """Draw from the (truncated) law by the inverse CDF; a float if ``size`` is None."""
        _check_rng(rng)
        ua, ub, flip = self._cdf_bounds
        if size is None:  # one draw (resets draw a few): the same operations on a number, clipped without numpy
            z = self._std.ppf(ua + (ub - ua) * rng.random())
            x = float(self._from_z(-z if flip else z))
            return min(max(x, self.low), self.high)
        z = self._std.ppf(ua + (ub - ua) * rng.random(size))
        x = np.clip(self._from_z(-z if flip else z), self.low, self.high)
        return _out(x)

    def logpdf(self, x: Any) -> float | np.ndarray:
        """Log-density at ``x``; with bounds, of the law renormalised to [low, high] (-inf outside)."""
        x = np.asarray(x, dtype=float)
        inside = (x >= self.low) & (x <= self.high) & self._support(x)
        xs = np.where(inside, x, self._median)  # keeps logs of the excluded points finite
        val = self._std.logpdf(self._to_z(xs)) + self._log_jac(xs) - math.log(self._mass())
        return _out(np.where(np.isnan(x), np.nan, np.where(inside, val, -np.inf)))

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe description; infinite bounds become None."""
        return {"kind": self.kind, **{f.name: _json_bound(getattr(self, f.name)) for f in fields(self)}}  # type: ignore[arg-type]


@dataclass(frozen=True)
class Normal(_Univariate):
    """Normal law N(mu, sigma^2), optionally truncated to [low, high]."""

    mu: float
    sigma: float
    low: float = -math.inf
    high: float = math.inf
    kind: ClassVar[str] = "normal"
    _std: ClassVar[_StdLaw] = _STD_NORMAL
    _positive: ClassVar[tuple[str, ...]] = ("sigma",)

    def _to_z(self, x):
        return (x - self.mu) / self.sigma

    def _from_z(self, z):
        return self.mu + self.sigma * z

    def _log_jac(self, x):
        return -math.log(self.sigma)

    @property
    def _median(self) -> float:
        return self.mu

    @property
    def mean(self) -> float:
        """Mean of the untruncated law (bounds ignored): ``mu``."""
        return self.mu


@dataclass(frozen=True)
class LogNormal(_Univariate):
    """Log-normal law: ln x ~ N(M, S^2), x > 0, optionally truncated to [low, high]."""

    M: float
    S: float
    low: float = -math.inf
    high: float = math.inf
    kind: ClassVar[str] = "lognormal"
    _std: ClassVar[_StdLaw] = _STD_NORMAL
    _positive: ClassVar[tuple[str, ...]] = ("S",)

    def _to_z(self, x):
        x = np.asarray(x, dtype=float)
        pos = x > 0
        return np.where(pos, (np.log(np.where(pos, x, 1.0)) - self.M) / self.S, -np.inf)

    def _from_z(self, z):
        return np.exp(self.M + self.S * z)

    def _log_jac(self, x):
        return -math.log(self.S) - np.log(x)

    def _support(self, x):
        return x > 0

    @property
    def _median(self) -> float:
        return math.exp(self.M)

    @property
    def mean(self) -> float:
        """Mean of the untruncated law (bounds ignored): ``exp(M + S^2 / 2)``."""
        return math.exp(self.M + 0.5 * self.S**2)


@dataclass(frozen=True)
class Laplace(_Univariate):
    """Laplace law with location mu and scale b (std b sqrt 2), optionally truncated."""

    mu: float
    b: float
    low: float = -math.inf
    high: float = math.inf
    kind: ClassVar[str] = "laplace"
    _std: ClassVar[_StdLaw] = _STD_LAPLACE
    _positive: ClassVar[tuple[str, ...]] = ("b",)

    def _to_z(self, x):
        return (x - self.mu) / self.b

    def _from_z(self, z):
        return self.mu + self.b * z

    def _log_jac(self, x):
        return -math.log(self.b)

    @property
    def _median(self) -> float:
        return self.mu

    @property
    def mean(self) -> float:
        """Mean of the untruncated law (bounds ignored): ``mu``."""
        return self.mu


@dataclass(frozen=True)
class Constant:
    """A parameter held at ``value`` (a point mass); ``logpdf`` is its log-probability: 0 at value, -inf elsewhere."""

    value: float
    kind: ClassVar[str] = "constant"

    def __post_init__(self) -> None:
        object.__setattr__(self, "value", _real("Constant.value", self.value))

    def sample(self, rng: np.random.Generator, size: Size = None) -> float | np.ndarray:
        """``value`` (or an array of it); ``rng`` is not advanced."""
        _check_rng(rng)
        return self.value if size is None else np.full(size, self.value)

    def logpdf(self, x: Any) -> float | np.ndarray:
        x = np.asarray(x, dtype=float)
        return _out(np.where(np.isnan(x), np.nan, np.where(x == self.value, 0.0, -np.inf)))

    @property
    def mean(self) -> float:
        return self.value

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "value": self.value}


# ------------------------------------------------------------------ bivariate normal
_MIN_ACCEPTANCE = 1e-6


@dataclass(frozen=True)
class BivariateNormal:
    """Bivariate normal law N(mean, cov) of a correlated pair, optionally truncated to the box [low, high].

    ``mean`` is a pair, ``cov`` a symmetric positive-definite 2x2 matrix, both stored as
    tuples. Truncation is sampled by rejection in a bounded number of rounds; ``logpdf``
    is renormalised by the box probability, computed by 1-D adaptive quadrature.
    """

    mean: tuple[float, float]
    cov: tuple[tuple[float, float], tuple[float, float]]
    low: tuple[float, float] = (-math.inf, -math.inf)
    high: tuple[float, float] = (math.inf, math.inf)
    kind: ClassVar[str] = "bivariate_normal"
    max_rounds: ClassVar[int] = 100
    _batch_max: ClassVar[int] = 1 << 20

    def __post_init__(self) -> None:
        name = "BivariateNormal"
        mean = self._pair("mean", self.mean, lambda lab, v: _real(lab, v))
        try:
            rows = [tuple(r) for r in self.cov]
        except TypeError:
            rows = []
        if len(rows) != 2 or any(len(r) != 2 for r in rows):
            raise ValueError(f"{name}.cov must be a 2x2 matrix, got {self.cov!r}")
        c = [[_real(f"{name}.cov[{i}][{j}]", rows[i][j]) for j in range(2)] for i in range(2)]
        if abs(c[0][1] - c[1][0]) > 1e-12 * max(abs(c[0][0]), abs(c[1][1]), abs(c[0][1])):
            raise ValueError(f"{name}.cov must be symmetric, got {self.cov!r}")
        c01 = 0.5 * (c[0][1] + c[1][0])
        if not (c[0][0] > 0 and c[0][0] * c[1][1] - c01 * c01 > 0):
            raise ValueError(f"{name}.cov must be positive definite, got {self.cov!r}")
        low = self._pair("low", self.low, lambda lab, v: _bound(lab, v, -math.inf))
        high = self._pair("high", self.high, lambda lab, v: _bound(lab, v, math.inf))
        if not (low[0] < high[0] and low[1] < high[1]):
            raise ValueError(f"{name}.low must be < {name}.high elementwise, got low={low!r}, high={high!r}")
        object.__setattr__(self, "mean", mean)
        object.__setattr__(self, "cov", ((c[0][0], c01), (c01, c[1][1])))
        object.__setattr__(self, "low", low)
        object.__setattr__(self, "high", high)

    @staticmethod
    def _pair(field: str, value: Any, conv: Callable[[str, Any], float]) -> tuple[float, float]:
        label = f"BivariateNormal.{field}"
        try:
            items = tuple(value)
        except TypeError:
            items = ()
        if len(items) != 2:
            raise ValueError(f"{label} must be a pair, got {value!r}")
        return (conv(f"{label}[0]", items[0]), conv(f"{label}[1]", items[1]))

    @property
    def correlation(self) -> float:
        """Correlation coefficient cov01 / sqrt(cov00 cov11) of the untruncated law."""
        (c00, c01), (_, c11) = self.cov
        return c01 / math.sqrt(c00 * c11)

    @property
    def bounded(self) -> bool:
        return any(math.isfinite(v) for v in (*self.low, *self.high))

    def _cholesky(self) -> tuple[float, float, float]:
        """``(l00, l10, l11)``: the lower Cholesky factor of ``cov``."""
        (c00, c01), (_, c11) = self.cov
        l00 = math.sqrt(c00)
        return l00, c01 / l00, math.sqrt(c11 - c01 * c01 / c00)

    def _draw(self, rng: np.random.Generator, n: int) -> np.ndarray:
        return self._draw_from(rng.standard_normal((n, 2)), *self._cholesky())

    def _inside(self, x: np.ndarray) -> np.ndarray:
        return np.all((x >= np.array(self.low)) & (x <= np.array(self.high)), axis=-1)

    def _rejection(self, rng: np.random.Generator, n: int) -> np.ndarray:
        out = np.empty((n, 2))
        filled = drawn = accepted = 0
        for _ in range(self.max_rounds):
            need = n - filled
            if need == 0:
                return out
            rate = accepted / drawn if accepted else 0.0
            batch = math.ceil(1.2 * need / rate) + 64 if rate > 0 else 4 * max(drawn, need)
            batch = min(self._batch_max, max(1024, batch))
            x = self._draw(rng, batch)
            ok = x[self._inside(x)]
            take = min(need, len(ok))
            out[filled:filled + take] = ok[:take]
            filled, drawn, accepted = filled + take, drawn + batch, accepted + len(ok)
            if filled < n and drawn >= 4 * self._batch_max and accepted / drawn < _MIN_ACCEPTANCE:
                raise self._too_rare(accepted, drawn)
        if filled < n:
            raise self._too_few(filled, n, accepted, drawn)
        return out

    def _too_rare(self, accepted: int, drawn: int) -> RuntimeError:
        """The rejection loop's error when the box holds almost no probability."""
        return RuntimeError(f"BivariateNormal truncated to low={self.low}, high={self.high}: acceptance "
                            f"{accepted / drawn:.2g} < {_MIN_ACCEPTANCE:g} after {drawn} draws; the box holds "
                            "almost no probability")

    def _too_few(self, filled: int, n: int, accepted: int, drawn: int) -> RuntimeError:
        """The rejection loop's error when its rounds ran out."""
        return RuntimeError(f"BivariateNormal truncated to low={self.low}, high={self.high}: only {filled} of {n} "
                            f"samples after {self.max_rounds} rounds (acceptance {accepted / drawn:.2g})")

    def _first_inside(self, rng: np.random.Generator) -> np.ndarray:
        """:meth:`_rejection` of one pair (a scenario's draw), with the same batches, the same
        numbers and the same generator state after it: each round's batch is drawn whole, as
        there, and its rows are searched in Python floats (the same IEEE operations as
        :meth:`_draw`'s arrays) before numpy's vector check -- in a scenario's box almost
        every first row is inside. ``tests/scenarios/test_distributions.py`` compares the two."""
        l00, l10, l11 = self._cholesky()
        m0, m1 = self.mean
        (lo0, lo1), (hi0, hi1) = self.low, self.high
        drawn = 0
        for _ in range(self.max_rounds):
            batch = min(self._batch_max, max(1024, 4 * max(drawn, 1)))  # _rejection's while nothing was accepted
            z = rng.standard_normal((batch, 2))
            for z0, z1 in z[:4].tolist():
                x0 = m0 + l00 * z0
                x1 = m1 + l10 * z0 + l11 * z1
                if lo0 <= x0 <= hi0 and lo1 <= x1 <= hi1:
                    return np.array([x0, x1])
            x = self._draw_from(z[4:], l00, l10, l11)
            ok = np.flatnonzero(self._inside(x))
            if ok.size:
                return x[ok[0]].copy()
            drawn += batch
            if drawn >= 4 * self._batch_max:  # nothing accepted: _rejection's condition
                raise self._too_rare(0, drawn)
        raise self._too_few(0, 1, 0, drawn)

    def _draw_from(self, z: np.ndarray, l00: float, l10: float, l11: float) -> np.ndarray:
        """:meth:`_draw`'s pairs from given standard normals ``z`` ``(n, 2)``."""
        return np.stack([self.mean[0] + l00 * z[:, 0], self.mean[1] + l10 * z[:, 0] + l11 * z[:, 1]], axis=1)

    def sample(self, rng: np.random.Generator, size: Size = None) -> np.ndarray:
        """Draw pairs: shape (2,) if ``size`` is None, else (size, 2) (or (*size, 2))."""
        _check_rng(rng)
        if size is None and self.bounded:  # one pair (a scenario's), the same numbers as the general path
            return self._first_inside(rng)
        shape = () if size is None else ((size,) if isinstance(size, numbers.Integral) else tuple(size))
        n = math.prod(shape)
        x = self._rejection(rng, n) if self.bounded else self._draw(rng, n)
        return x.reshape(*shape, 2)

    @cached_property
    def box_probability(self) -> float:
        """Probability of the box [low, high] under the untruncated law (1 without bounds).

        P = integral over u = Phi(z0) in [Phi(a0), Phi(b0)] of P(a1 <= z1 <= b1 | z0), in
        standardised coordinates; a coordinate whose interval lies above its mean is
        reflected so that tail boxes keep their precision.
        """
        if not self.bounded:
            return 1.0
        (c00, _), (_, c11) = self.cov
        rho = self.correlation
        a0, b0 = ((lim - self.mean[0]) / math.sqrt(c00) for lim in (self.low[0], self.high[0]))
        a1, b1 = ((lim - self.mean[1]) / math.sqrt(c11) for lim in (self.low[1], self.high[1]))
        if a0 > 0:
            a0, b0, rho = -b0, -a0, -rho
        if a1 > 0:
            a1, b1, rho = -b1, -a1, -rho
        r = math.sqrt(1.0 - rho * rho)

        def conditional(u: float) -> float:
            z0 = float(ndtri(u))
            return float(ndtr((b1 - rho * z0) / r) - ndtr((a1 - rho * z0) / r))

        from scipy.integrate import quad  # late: scipy.integrate adds about 0.5 s to every process start

        val, _ = quad(conditional, float(ndtr(a0)), float(ndtr(b0)), epsabs=0.0, epsrel=1e-11, limit=500)
        return val

    def logpdf(self, x: Any) -> float | np.ndarray:
        """Log-density at points of shape (..., 2); with bounds, renormalised to the box (-inf outside)."""
        x = np.asarray(x, dtype=float)
        if x.shape[-1:] != (2,):
            raise ValueError(f"x must have shape (..., 2), got {x.shape}")
        (c00, c01), (_, c11) = self.cov
        det = c00 * c11 - c01 * c01
        d0, d1 = x[..., 0] - self.mean[0], x[..., 1] - self.mean[1]
        val = -_LOG_2PI - 0.5 * math.log(det) - 0.5 * (c11 * d0 * d0 - 2.0 * c01 * d0 * d1 + c00 * d1 * d1) / det
        if self.bounded:
            mass = self.box_probability
            if not mass > 0:
                raise ValueError(f"BivariateNormal truncated to low={self.low}, high={self.high} has zero "
                                 "probability mass")
            nan = np.isnan(x).any(axis=-1)
            val = np.where(nan, np.nan, np.where(self._inside(x), val - math.log(mass), -np.inf))
        return _out(val)

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe description; infinite bounds become None."""
        return {"kind": self.kind, "mean": list(self.mean), "cov": [list(r) for r in self.cov],
                "low": [_json_bound(v) for v in self.low], "high": [_json_bound(v) for v in self.high]}


# ------------------------------------------------------------------------ (de)serialise
Law = Normal | LogNormal | Laplace | BivariateNormal | Constant
_KINDS: dict[str, type] = {cls.kind: cls for cls in (Normal, LogNormal, Laplace, BivariateNormal, Constant)}


def from_dict(d: Mapping[str, Any]) -> Law:
    """Rebuild a law from ``to_dict`` output (e.g. after a JSON round trip).

    Raises ``ValueError`` naming an unknown ``kind``, missing keys or unexpected keys;
    bounds may be omitted or None (unbounded).
    """
    if not isinstance(d, Mapping):
        raise TypeError(f"a law description must be a mapping, got {type(d).__name__}")
    if "kind" not in d:
        raise ValueError(f"law description is missing key 'kind' (one of {sorted(_KINDS)}), got keys {sorted(d)}")
    cls = _KINDS.get(d["kind"]) if isinstance(d["kind"], str) else None
    if cls is None:
        raise ValueError(f"unknown law kind {d['kind']!r}; expected one of {sorted(_KINDS)}")
    names = {f.name: f for f in fields(cls)}
    given = set(d) - {"kind"}
    missing = sorted(n for n, f in names.items() if f.default is MISSING and n not in given)
    if missing:
        raise ValueError(f"{d['kind']} law description is missing key(s) {missing}")
    extra = sorted(map(str, given - names.keys()))
    if extra:
        raise ValueError(f"{d['kind']} law description has unexpected key(s) {extra}; allowed {sorted(names)}")
    return cls(**{k: d[k] for k in given})
