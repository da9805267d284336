"""A campaign over an OpenSCENARIO logical scenario: a template file and its variation file
(:mod:`acc_gym.scenarios.openscenario.variation`), one episode per concrete scenario.

:class:`VariationSweep` stands where a suite stands in :func:`acc_gym.campaigns.run_campaign`
(the attributes :data:`acc_gym.campaigns.plan.SUITE_ATTRIBUTES`), so a sweep gets every campaign
output: the pinned manifest, atomic and checksummed Parquet chunks, resume after a kill, any
number of workers or a Dask cluster, and the summary. Decided:

* **The plan** is the variation's concrete scenarios in its own order (``len(variation)``; the
  combinations that violate the template's constraints left out), not hours of traffic: the
  campaign's ``hours`` is recorded as 0.
* **Pinned**: ``suite`` is ``openscenario:<template's name>``, ``suite_hash`` the sha256 of the
  variation file, the template and every file beside it (catalogs, roads), ``root_seed`` the
  variation's ``randomSeed`` (0 for a deterministic one), ``env_id`` ``openscenario``.
* **A row** is the template run with the scenario's parameters by
  :func:`acc_gym.scenarios.openscenario.run_file` (paper 003's report of the controlled
  time); ``scenario_id`` is ``<template's name>#<index>`` (:meth:`VariationSweep.parameters`
  gives its parameters), ``scenario_seed`` and ``seed`` are 0 (nothing in a run is random),
  ``duration`` and ``simulated`` the run's length. A collision's ``preventable`` is UN R157's
  verdict: the cc-driver runs the same concrete scenario.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

ENV_ID = "openscenario"


@dataclass(frozen=True)
class _Point:
    """What a campaign row needs of a concrete scenario (``id``, ``seed``, ``duration``)."""

    id: str
    seed: int
    duration: float


class VariationSweep:
    """The concrete scenarios of a variation file (``scenario``: another template to apply it to,
    default its own ``ScenarioFile``)."""

    version = "1"
    env_id = ENV_ID

    def __init__(self, variation, scenario=None):
        from acc_gym.scenarios.openscenario.variation import Variation, read_variation

        self.variation = variation if isinstance(variation, Variation) else read_variation(variation)
        self.template = Path(scenario).resolve() if scenario is not None else self.variation.scenario
        if not self.template.is_file():
            raise ValueError(f"scenario file {self.template} does not exist")
        self.name = f"openscenario:{self.template.stem}"
        self._hash = None

    @property
    def n_points(self) -> int:
        return len(self.variation)

    def root_seed(self, split: str) -> int:
        return int(self.variation.seed)

    def hash(self, split: str) -> str:
        if self._hash is None:
            self._hash = self.variation.digest()
        return self._hash

    def parameters(self, index: int) -> dict:
        """The parameters of concrete scenario ``index``."""
        return self.variation[int(index)]

    def scenario(self, index: int, split: str = "test") -> _Point:
        return _Point(f"{self.template.name}#{int(index)}", 0, 0.0)

    def run(self, index: int, controller, reference=None) -> dict:
        """Concrete scenario ``index`` driven by ``controller``: a campaign row (with the
        ``reference`` controller's verdict when it collides)."""
        from acc_gym.campaigns.episodes import row_from_info
        from acc_gym.scenarios.openscenario import read, run_file

        sc = read(self.template, parameters=self.parameters(index))
        result, _ = run_file(sc.path, controller, scenario=sc)
        report = result["report"]
        if report is None:
            raise ValueError(f"{self.template.name}#{index}: the controller never drove (its controller is "
                             f"activated at {result['activated_at']} s, the run ended at {result['duration']} s)")
        report = {**report, "metrics": {**report["metrics"], "collision": bool(result["collided"])}}
        preventable = None
        if result["collided"]:
            again, _ = run_file(sc.path, reference, scenario=sc)
            preventable = not again["collided"]
        point = _Point(f"{self.template.name}#{int(index)}", 0, float(result["duration"]))
        return row_from_info(index, 0, point, {"report": report}, preventable)

    def run_chunk(self, task) -> list[dict]:
        """The rows of a campaign chunk (what :func:`acc_gym.campaigns.episodes.run_chunk` calls)."""
        from acc_gym.evaluation.runner import load_controller
        from acc_gym.standards.r157 import REFERENCE

        controller, reference = load_controller(task.controller), load_controller(REFERENCE)
        return [self.run(i, controller, reference) for i in task.chunk.indices]
