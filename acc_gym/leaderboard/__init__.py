"""The benchmark leaderboard: controllers scored on versioned suites, ranked, reported.

    from acc_gym.leaderboard import run_leaderboard, load_results
    results = run_leaderboard(["ncap-v1"], "test", ["acc", "idm", "mymodule:MyController"], out="leaderboard")
    results["ranking"]                       # controller names, best first
    load_results("leaderboard/results.json") # the same dict, checksum verified

* :mod:`~acc_gym.leaderboard.run` -- :func:`run_leaderboard` and its defaults;
* :mod:`~acc_gym.leaderboard.isolation` -- one process per controller, step and total
  time budgets, failures reported with their reasons;
* :mod:`~acc_gym.leaderboard.results` -- aggregation, ranking, the files (atomic) and
  :func:`load_results`;
* :mod:`~acc_gym.leaderboard.report` -- the self-contained HTML report.
* :mod:`~acc_gym.leaderboard.iso15622` -- the ISO 15622 column (the ``iso15622-v1``
  battery driven through each controller's sandbox).

Controllers are given by reference (a registered name of :mod:`acc_gym.controllers`,
``"module:attribute"`` or a saved model path) and loaded in their own sandboxed process;
the module must be importable there -- it gets the runner's ``sys.path`` and working
directory (see :mod:`~acc_gym.leaderboard.sandbox`), so put your module on
``PYTHONPATH`` or run from its directory.
"""

from acc_gym.leaderboard.results import load_results, write_files
from acc_gym.leaderboard.run import run_leaderboard

__all__ = ["load_results", "run_leaderboard", "write_files"]
