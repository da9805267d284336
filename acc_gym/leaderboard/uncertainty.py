"""The leaderboard's uncertainty: 95 % intervals on its figures, and paired comparisons.

A leaderboard of a few hundred episodes measures each controller with sampling error;
this module says how much, and whether adjacent rows of the ranking really differ.

**Means** (mean points, mean paper score, share of comfortable acceleration, share of safe
spacing: per-episode figures averaged over episodes) get a **percentile bootstrap** over
episodes: :data:`B` = 2000 resamples, the 2.5th and 97.5th percentiles of the resampled
means. Over several suites the bootstrap is **stratified**: each suite's episodes are
resampled within the suite and the overall figure of a resample is the same equal-weight
mean of the suites' figures as the overall figure itself. An episode without a value (a
metric that is ``None``) counts in no mean, resampled or not.

**Shares of episodes** (share qualified, collisions per episode) get the **exact
Clopper-Pearson** interval, ``Beta(alpha/2; x, n-x+1)`` to ``Beta(1-alpha/2; x+1, n-x)``:
never narrower than its level promises, and a count of 0 (of ``n``) still has an upper
bound, ``1 - (alpha/2)^(1/n)`` (about 3.7 / n), where a bootstrap would give the point 0.
Collisions per hour are collisions per episode times episodes per scheduled hour (the
hours are fixed by the schedule), so their interval is the collision rate's, scaled.
Overall, collisions pool all episodes (as the figure pools all hours); the share
qualified is the equal-weight mean of the suites' shares, whose interval is
Clopper-Pearson at Kish's effective sample size ``S^2 / sum_s(1/n_s)`` (``S`` suites of
``n_s`` episodes; the count ``share * n_eff``, not an integer -- the beta quantiles take
it), which is the exact interval for one suite and for suites of equal size.

**Adjacent rows** (:func:`compare`): both controllers ran the same episodes; records are
matched by (suite, episode index, scenario id, scenario seed), and the figure compared is
the ranking's own -- **points** (the 100-point score, 0 after a collision), each suite
weighing the same. ``diff`` is the lower row's mean points minus the upper row's over the
matched episodes, with a 95 % **paired percentile bootstrap** interval (the matched pairs
resampled within each suite, :data:`B` resamples). The difference is **significant** when
the interval excludes 0; otherwise the lower row is a **tie** with the row above it. This
only annotates: the order stays :func:`acc_gym.leaderboard.results.rank`'s, by mean
points.

**Determinism**: every resample comes from its own generator,
``numpy.random.default_rng([SEED, crc32(suite name)])`` -- never numpy's global one -- so
the same records give byte-identical intervals, and the intervals depend on the records
alone: a controller's name, the other controllers and how many ran in parallel change
nothing (the same controller under two names gets the same intervals, and ties exactly).
All resamples of a suite are one ``(B, n)`` index matrix, used for every figure.
"""

from __future__ import annotations

import math
import warnings
import zlib

import numpy as np

B = 2000
LEVEL = 0.95
SEED = 0x0ACC_6E7B  # fixed: the resamples are part of the published method
ALPHA = 1.0 - LEVEL

#: summary keys with a bootstrap interval (``KEY_ci``) and the per-episode values they average
MEANS = {"mean_points": lambda e: e["points"], "mean_score": lambda e: e["score"],
         "share_comfortable": lambda e: e["metrics"].get("share_comfortable"),
         "share_safe_spacing": lambda e: e["metrics"].get("share_safe_spacing")}
#: summary keys whose figures lie in [0, 1] (and so must their intervals)
SHARES = ("share_qualified", "share_comfortable", "share_safe_spacing", "collision_rate")
MATCH = ("suite", "episode", "scenario", "scenario_seed")


def generator(name: str) -> np.random.Generator:
    """The generator of ``name``'s resamples (a suite's name)."""
    return np.random.default_rng([SEED, zlib.crc32(name.encode("utf-8"))])


def resample_indices(n: int, rng: np.random.Generator, b: int = B) -> np.ndarray:
    """``b`` bootstrap resamples of ``n`` items as one ``(b, n)`` index matrix."""
    return rng.integers(0, n, size=(b, n))


def resampled_means(values, idx: np.ndarray) -> np.ndarray:
    """The mean of ``values`` (NaN: no value) in each resample (row of ``idx``); NaN where a
    resample drew no value."""
    v = np.asarray(values, dtype=float)
    present = ~np.isnan(v)
    if present.all():
        return v[idx].mean(axis=1)
    sums = np.where(present, v, 0.0)[idx].sum(axis=1)
    counts = present[idx].sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)


def percentile_interval(replicates: np.ndarray, level: float = LEVEL) -> list[float] | None:
    """The percentile interval of bootstrap ``replicates`` (``None`` if none is finite)."""
    r = np.asarray(replicates, dtype=float)
    r = r[np.isfinite(r)]
    if r.size == 0:
        return None
    lo, hi = np.percentile(r, [50 * (1 - level), 50 * (1 + level)])
    return [float(lo), float(hi)]


def bootstrap_mean_interval(values, name: str = "sample", b: int = B, level: float = LEVEL) -> list[float] | None:
    """Percentile bootstrap interval of the mean of ``values`` (resampled with ``name``'s generator)."""
    v = np.asarray(values, dtype=float)
    if v.size == 0:
        return None
    return percentile_interval(resampled_means(v, resample_indices(v.size, generator(name), b)), level)


def clopper_pearson(x: float, n: float, level: float = LEVEL) -> list[float] | None:
    """Exact (Clopper-Pearson) interval of a share of ``x`` in ``n`` (``x`` may be fractional:
    an effective count); ``None`` when ``n`` is 0."""
    from scipy.special import betaincinv

    if n <= 0:
        return None
    a = 1.0 - level
    x = min(max(float(x), 0.0), float(n))
    lo = 0.0 if x <= 0 else float(betaincinv(x, n - x + 1, a / 2))
    hi = 1.0 if x >= n else float(betaincinv(x + 1, n - x, 1 - a / 2))
    return [lo, hi]


def _scaled(ci, factor):
    return None if ci is None else [ci[0] * factor, ci[1] * factor]


def _mean_rows(rows: list[np.ndarray]) -> np.ndarray:
    """Per resample, the equal-weight mean over the suites that have a value."""
    with warnings.catch_warnings():  # a resample where no suite has a value: NaN, dropped later
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmean(np.vstack(rows), axis=0)


def _values(episodes: list[dict], get) -> np.ndarray:
    out = []
    for e in episodes:
        v = get(e)
        out.append(np.nan if v is None or isinstance(v, str) else float(v))
    return np.array(out, dtype=float)


def add_intervals(per_suite: dict, overall: dict, episodes_by_suite: dict[str, list[dict]]) -> None:
    """Add the ``*_ci`` keys (and ``collision_rate``) to each suite's summary and the overall
    one, in place (see the module docstring)."""
    replicates = {key: [] for key in MEANS}
    n_by_suite, qualified_suites = [], []
    for name, s in per_suite.items():
        eps = episodes_by_suite[name]
        n = len(eps)
        idx = resample_indices(n, generator(name)) if n else None
        for key, get in MEANS.items():
            if idx is None or s.get(key) is None:
                s[f"{key}_ci"] = None
                continue
            r = resampled_means(_values(eps, get), idx)
            s[f"{key}_ci"] = percentile_interval(r)
            replicates[key].append(r)
        qualified = sum(bool(e["qualified"]) for e in eps)
        s["share_qualified_ci"] = clopper_pearson(qualified, n)
        s["collision_rate"] = s["collisions"] / n if n else None
        s["collision_rate_ci"] = clopper_pearson(s["collisions"], n)
        s["collisions_per_hour_ci"] = _scaled(s["collision_rate_ci"], n / s["hours"]) if s["hours"] else None
        if n and s.get("share_qualified") is not None:
            n_by_suite.append(n)
            qualified_suites.append(s["share_qualified"])
    for key in MEANS:
        rows = replicates[key]
        overall[f"{key}_ci"] = percentile_interval(_mean_rows(rows)) if rows and overall.get(key) is not None \
            else None
    if n_by_suite:  # Kish's effective sample size of an equal-weight mean of suites
        n_eff = len(n_by_suite) ** 2 / sum(1.0 / n for n in n_by_suite)
        overall["share_qualified_ci"] = clopper_pearson(float(np.mean(qualified_suites)) * n_eff, n_eff)
    else:
        overall["share_qualified_ci"] = None
    n = overall["episodes"]
    overall["collision_rate"] = overall["collisions"] / n if n else None
    overall["collision_rate_ci"] = clopper_pearson(overall["collisions"], n)
    overall["collisions_per_hour_ci"] = _scaled(overall["collision_rate_ci"], n / overall["hours"]) \
        if overall["hours"] else None


def _matched(upper: list[dict], lower: list[dict]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per suite, the two controllers' points on the episodes both ran (in schedule order)."""
    key = lambda e: tuple(e.get(k) for k in MATCH)  # noqa: E731
    up = {key(e): e["points"] for e in upper}
    pairs: dict[str, list] = {}
    for e in lower:
        k = key(e)
        if k in up:
            pairs.setdefault(e["suite"], []).append((k[1:], up[k], e["points"]))
    out = {}
    for suite, rows in pairs.items():
        rows.sort(key=lambda r: tuple((0, x, "") if _finite(x) else (1, 0, str(x)) for x in r[0]))
        out[suite] = (np.array([r[1] for r in rows], dtype=float), np.array([r[2] for r in rows], dtype=float))
    return out


def compare(upper: dict, lower: dict, level: float = LEVEL) -> dict | None:
    """``lower``'s mean points minus ``upper``'s (controller entries with ``name`` and
    ``episodes``) over their matched episodes, with its paired bootstrap interval:
    ``{"controller": upper's name, "diff", "ci": [lo, hi], "significant", "pairs"}``, or
    ``None`` if they share no episode."""
    matched = _matched(upper.get("episodes") or [], lower.get("episodes") or [])
    if not matched:
        return None
    diffs, reps, pairs = [], [], 0
    for suite in sorted(matched):
        a, b = matched[suite]
        d = b - a
        pairs += d.size
        diffs.append(float(d.mean()))
        reps.append(resampled_means(d, resample_indices(d.size, generator(suite))))
    ci = percentile_interval(_mean_rows(reps), level)
    return {"controller": upper["name"], "diff": float(np.mean(diffs)), "ci": ci,
            "significant": bool(ci[0] > 0 or ci[1] < 0), "pairs": pairs}


def verdict(vs_above: dict | None) -> str | None:
    """What the table says of a row against the row above: ``"tie"`` (not significant),
    ``"worse"`` / ``"better"`` (significant), ``None`` (nothing above, or no comparison)."""
    if not vs_above:
        return None
    if not vs_above["significant"]:
        return "tie"
    return "worse" if vs_above["ci"][1] < 0 else "better"


# -- checking a results file's intervals -------------------------------------------------------
def _finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _check_interval(where: str, ci, unit: bool = False) -> None:
    if ci is None:
        return
    if not isinstance(ci, list) or len(ci) != 2 or not all(_finite(x) for x in ci):
        raise ValueError(f"{where} is not an interval [low, high] of two finite numbers: {ci!r}")
    if ci[0] > ci[1]:
        raise ValueError(f"{where} has its low end above its high end: {ci!r}")
    if unit and not (0.0 <= ci[0] and ci[1] <= 1.0):
        raise ValueError(f"{where} is the interval of a share and must lie in [0, 1]: {ci!r}")


def check_results(results: dict) -> None:
    """``ValueError`` naming the first malformed interval or comparison in ``results``
    (keys this module adds; files without them pass)."""
    controllers = results.get("controllers") if isinstance(results, dict) else None
    if not isinstance(controllers, list):
        return
    for c in controllers:
        if not isinstance(c, dict):
            continue
        name = c.get("name")
        summary = c.get("summary")
        if isinstance(summary, dict):
            parts = [("overall", summary.get("overall"))]
            suites = summary.get("suites")
            if isinstance(suites, dict):
                parts += [(f"suites.{s}", v) for s, v in suites.items()]
            for label, part in parts:
                if not isinstance(part, dict):
                    continue
                for key, ci in part.items():
                    if key.endswith("_ci"):
                        _check_interval(f"controller {name!r}: summary.{label}.{key}", ci,
                                        unit=key[:-3] in SHARES)
        if "vs_above" not in c or c["vs_above"] is None:
            continue
        v, where = c["vs_above"], f"controller {name!r}: vs_above"
        expected = {"controller", "diff", "ci", "significant", "pairs"}
        if not isinstance(v, dict) or set(v) != expected:
            raise ValueError(f"{where} must be null or an object with the keys {sorted(expected)}: {v!r}")
        if not isinstance(v["controller"], str) or not _finite(v["diff"]) or not isinstance(v["significant"], bool) \
                or not isinstance(v["pairs"], int) or isinstance(v["pairs"], bool) or v["pairs"] < 1:
            raise ValueError(f"{where} is malformed (controller: a name, diff: a finite number, significant: true or "
                             f"false, pairs: a positive count): {v!r}")
        _check_interval(f"{where}.ci", v["ci"])
        if v["ci"] is None:
            raise ValueError(f"{where}.ci is missing")
        if v["significant"] != (v["ci"][0] > 0 or v["ci"][1] < 0):
            raise ValueError(f"{where}.significant is {str(v['significant']).lower()}, but its interval {v['ci']!r} "
                             f"{'excludes' if not v['significant'] else 'includes'} 0")
