"""OpenSCENARIO variation files (``ParameterValueDistribution``): a logical scenario as the list
of its concrete ones.

:func:`read_variation` reads a variation file and its ``ScenarioFile``; the
:class:`Variation` it returns is a sequence of parameter assignments (name -> value), each a
concrete scenario of the template:

* **Deterministic**: the Cartesian product of every ``DeterministicSingleParameterDistribution``
  (a ``DistributionSet``'s elements, or a ``DistributionRange``'s values from ``lowerLimit`` to
  ``upperLimit`` in steps of ``stepWidth``, both limits included) and every
  ``DeterministicMultiParameterDistribution`` (its ``ValueSetDistribution``'s
  ``ParameterValueSet``s), in file order, the last one varying fastest.
* **Stochastic**: ``numberOfTestRuns`` draws of every ``StochasticDistribution`` (normal and
  log-normal with an optional truncating ``Range`` (redrawn until inside), uniform, Poisson,
  histogram, probability set). Draw ``i`` comes from its own generator,
  ``numpy.random.default_rng([randomSeed, i])`` (``randomSeed`` 0 when the file gives none),
  so a run is a pure function of its index, whatever the order runs are made in. The
  log-normal's ``expectedValue`` and ``variance`` are the distribution's own (its underlying
  normal's are derived from them).

Decided: the combinations whose parameters violate the template's value constraints are not
concrete scenarios of it: they are left out when the variation is read (:attr:`Variation.invalid`
counts them, :meth:`Variation.invalid_examples` names the first). The constraints are checked
on the template's parameter declarations alone, before anything is run.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from acc_gym.scenarios.openscenario._xml import Node, OpenScenarioError, parse
from acc_gym.scenarios.openscenario.expressions import Scope, convert, declare, resolve

MAX_POINTS = 10_000_000  # a deterministic product larger than this is refused (a typo in a step width)


def _num(node: Node, name: str, scope: Scope, default=...):
    if name not in node.attrib:
        if default is ...:
            raise node.error(f"<{node.tag}> needs the attribute {name!r}")
        return default
    return convert(resolve(node.attrib[name], scope, node), "double", f"<{node.tag}> {name}", node)


def _range_values(d: Node, scope: Scope) -> list:
    r = d.find("Range")
    if r is None:
        raise d.error("a DistributionRange needs a Range")
    lo, hi = _num(r, "lowerLimit", scope), _num(r, "upperLimit", scope)
    step = _num(d, "stepWidth", scope)
    if not step > 0:
        raise d.error(f"stepWidth must be > 0, got {step!r}")
    if hi < lo:
        raise r.error(f"upperLimit {hi!r} is below lowerLimit {lo!r}")
    n = int(math.floor((hi - lo) / step + 1e-9)) + 1
    if n > MAX_POINTS:
        raise d.error(f"the range has {n} values (more than {MAX_POINTS})")
    return [round(lo + k * step, 12) for k in range(n)]


@dataclass(frozen=True)
class _Stochastic:
    name: str
    kind: str
    params: dict
    where: Node = field(repr=False, compare=False)

    def draw(self, rng: np.random.Generator):
        p, k = self.params, self.kind
        if k == "ProbabilityDistributionSet":
            w = np.asarray(p["weights"], float)
            return p["values"][int(rng.choice(len(w), p=w / w.sum()))]
        if k == "HistogramBin":
            w = np.asarray([b[2] for b in p["bins"]], float)
            lo, hi, _ = p["bins"][int(rng.choice(len(w), p=w / w.sum()))]
            return float(rng.uniform(lo, hi))
        if k == "UniformDistribution":
            return float(rng.uniform(p["lo"], p["hi"]))
        lo, hi = p.get("lo", -math.inf), p.get("hi", math.inf)
        for _ in range(10_000):
            if k == "NormalDistribution":
                x = float(rng.normal(p["mean"], math.sqrt(p["variance"])))
            elif k == "LogNormalDistribution":
                s2 = math.log1p(p["variance"] / p["mean"] ** 2)
                x = float(rng.lognormal(math.log(p["mean"]) - 0.5 * s2, math.sqrt(s2)))
            else:  # PoissonDistribution
                x = float(rng.poisson(p["mean"]))
            if lo <= x <= hi:
                return x
        raise self.where.error(f"{self.kind} of {self.name!r}: no draw fell inside [{lo}, {hi}] in 10,000 tries")


@dataclass(frozen=True)
class Variation:
    """A variation file, read: ``len(v)`` concrete scenarios, ``v[i]`` the parameters of the
    ``i``-th (name -> value as text or number)."""

    path: str
    scenario: Path  # the template (ScenarioFile)
    kind: str  # "deterministic" or "stochastic"
    points: tuple  # deterministic: every valid assignment; stochastic: the valid run indices
    invalid: int  # combinations (or runs) left out: they violate the template's constraints
    first_invalid: str | None  # why the first one was left out
    seed: int = 0  # stochastic: randomSeed
    dists: tuple = ()  # stochastic: the distributions

    def __len__(self) -> int:
        return len(self.points)

    def __getitem__(self, i: int) -> dict:
        if self.kind == "deterministic":
            return dict(self.points[i])
        return _draw(self.dists, self.seed, self.points[i])

    def digest(self) -> str:
        """sha256 of the variation file, the template and every file beside the template (its
        catalogs and roads): what a campaign's results depend on."""
        h = hashlib.sha256()
        for f in [Path(self.path), *sorted(p for p in self.scenario.parent.rglob("*") if p.is_file())]:
            h.update(f.name.encode())
            h.update(f.read_bytes())
        return h.hexdigest()


def _draw(dists, seed: int, i: int) -> dict:
    rng = np.random.default_rng([int(seed), int(i)])
    return {d.name: d.draw(rng) for d in dists}


def _axes(det: Node, scope: Scope) -> list[list[dict]]:
    axes = []
    for d in det.children:
        if d.tag == "DeterministicSingleParameterDistribution":
            name = str(resolve(d.attrib.get("parameterName", ""), scope, d)).lstrip("$")
            if not name:
                raise d.error("a DeterministicSingleParameterDistribution needs a parameterName")
            body = d.only("distribution")
            if body.tag == "DistributionSet":
                vals = [resolve(e.attrib.get("value", ""), scope, e) for e in body.findall("Element")]
                if not vals:
                    raise body.error("a DistributionSet needs at least one Element")
            elif body.tag == "DistributionRange":
                vals = _range_values(body, scope)
            elif body.tag == "UserDefinedDistribution":
                raise body.error("a UserDefinedDistribution is not read here (its values are unknown)")
            else:
                raise body.error(f"<{body.tag}> is not a deterministic distribution")
            axes.append([{name: v} for v in vals])
        elif d.tag == "DeterministicMultiParameterDistribution":
            vsd = d.only("distribution")
            if vsd.tag != "ValueSetDistribution":
                raise vsd.error(f"<{vsd.tag}> is not a multi-parameter distribution read here")
            sets = []
            for pvs in vsd.findall("ParameterValueSet"):
                sets.append({str(a.attrib.get("parameterRef", "")).lstrip("$"): resolve(a.attrib.get("value", ""),
                                                                                      scope, a)
                             for a in pvs.findall("ParameterAssignment")})
            if not sets:
                raise vsd.error("a ValueSetDistribution needs at least one ParameterValueSet")
            axes.append(sets)
        else:
            raise d.error(f"<{d.tag}> is not a deterministic distribution")
    return axes


def _stochastic(st: Node, scope: Scope) -> tuple:
    dists = []
    for d in st.findall("StochasticDistribution"):
        name = str(resolve(d.attrib.get("parameterName", ""), scope, d)).lstrip("$")
        body = d.only("distribution")
        k, p = body.tag, {}
        rng_node = body.find("Range")
        if rng_node is not None:
            p["lo"], p["hi"] = _num(rng_node, "lowerLimit", scope), _num(rng_node, "upperLimit", scope)
        if k in ("NormalDistribution", "LogNormalDistribution"):
            p["mean"], p["variance"] = _num(body, "expectedValue", scope), _num(body, "variance", scope)
            if p["variance"] < 0 or (k == "LogNormalDistribution" and p["mean"] <= 0):
                raise body.error(f"{k}: expectedValue {p['mean']!r} and variance {p['variance']!r} are not a "
                                 f"valid distribution's")
        elif k == "PoissonDistribution":
            p["mean"] = _num(body, "expectedValue", scope)
        elif k == "UniformDistribution":
            if rng_node is None:
                raise body.error("a UniformDistribution needs a Range")
        elif k == "Histogram":
            bins = []
            for b in body.findall("HistogramBin"):
                r = b.find("Range")
                if r is None:
                    raise b.error("a HistogramBin needs a Range")
                bins.append((_num(r, "lowerLimit", scope), _num(r, "upperLimit", scope), _num(b, "weight", scope)))
            if not bins:
                raise body.error("a Histogram needs at least one HistogramBin")
            k, p = "HistogramBin", {"bins": bins}
        elif k == "ProbabilityDistributionSet":
            els = body.findall("Element")
            if not els:
                raise body.error("a ProbabilityDistributionSet needs at least one Element")
            p = {"values": [resolve(e.attrib.get("value", ""), scope, e) for e in els],
                 "weights": [_num(e, "weight", scope) for e in els]}
        else:
            raise body.error(f"<{k}> is not a stochastic distribution read here")
        dists.append(_Stochastic(name, k, p, body))
    if not dists:
        raise st.error("a Stochastic variation needs at least one StochasticDistribution")
    return tuple(dists)


def _valid(template_decls: Node | None, values: dict) -> str | None:
    """None if ``values`` satisfy the template's declarations and constraints, else why not."""
    try:
        declare(template_decls, Scope(), {k: v if isinstance(v, str) else repr(float(v)) for k, v in values.items()})
    except OpenScenarioError as exc:
        return str(exc)
    return None


def read_variation(path) -> Variation:
    """Read the variation file ``path`` (see the module docstring)."""
    path = Path(path)
    root = parse(path)
    pvd = root.find("ParameterValueDistribution")
    if root.tag != "OpenSCENARIO" or pvd is None:
        raise OpenScenarioError("not a variation file (no <ParameterValueDistribution>)", str(path))
    scope = declare(root.find("ParameterDeclarations"), Scope())
    sf = pvd.find("ScenarioFile")
    if sf is None:
        raise pvd.error("a ParameterValueDistribution needs a ScenarioFile")
    scenario = (path.parent / str(resolve(sf.attrib.get("filepath", ""), scope, sf))).resolve()
    if not scenario.is_file():
        raise sf.error(f"the ScenarioFile {sf.attrib.get('filepath')!r} does not exist ({scenario})")
    decls = parse(scenario).find("ParameterDeclarations")
    det, sto = pvd.find("Deterministic"), pvd.find("Stochastic")
    if (det is None) == (sto is None):
        raise pvd.error("a ParameterValueDistribution holds exactly one of Deterministic and Stochastic")
    keep, invalid, first = [], 0, None
    if det is not None:
        axes = _axes(det, scope)
        n = math.prod(len(a) for a in axes) if axes else 0
        if n > MAX_POINTS:
            raise det.error(f"the deterministic variation has {n} combinations (more than {MAX_POINTS})")
        for k in range(n):
            values, rest = {}, k
            for a in reversed(axes):  # the last axis varies fastest
                rest, j = divmod(rest, len(a))
                values.update(a[j])
            values = {name: values[name] for a in axes for name in a[0]}  # file order
            why = _valid(decls, values)
            if why is None:
                keep.append(tuple(values.items()))
            else:
                invalid += 1
                first = first or why
        return Variation(str(path), scenario, "deterministic", tuple(keep), invalid, first)
    runs = int(_num(sto, "numberOfTestRuns", scope))
    seed = int(_num(sto, "randomSeed", scope, 0))
    if runs < 1 or runs > MAX_POINTS:
        raise sto.error(f"numberOfTestRuns must be in 1..{MAX_POINTS}, got {runs}")
    dists = _stochastic(sto, scope)
    for i in range(runs):
        why = _valid(decls, _draw(dists, seed, i))
        if why is None:
            keep.append(i)
        else:
            invalid += 1
            first = first or why
    return Variation(str(path), scenario, "stochastic", tuple(keep), invalid, first, seed, dists)
