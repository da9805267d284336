"""ASAM OpenSCENARIO XML (1.0-1.3): read a file's longitudinal content and run it with a
controller under test as the ego.

    from acc_gym.scenarios import openscenario as osc
    sc = osc.read("alks_scenario_4_4_2_cut_in_unavoidable_collision_template.xosc")
    result, trace = osc.run_file(sc.path, load_controller("acc"))

:mod:`~.reader` (what is read, what is out of scope), :mod:`~.expressions` (parameters),
:mod:`~.runtime` (the storyboard and the entities' motion), :mod:`~.run` (the ego under test).
``acc-gym run FILE.xosc --controller NAME`` is the command line (``docs/openscenario.md``).
"""

from acc_gym.scenarios.openscenario._xml import OpenScenarioError
from acc_gym.scenarios.openscenario.reader import read
from acc_gym.scenarios.openscenario.run import Trace, run_file

__all__ = ["OpenScenarioError", "Trace", "read", "run_file"]
