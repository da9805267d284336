"""The command line: acc-gym demo."""

import json
import subprocess
import sys

import numpy as np
import pytest

from acc_gym.cli import main


def test_driver_demo_json_reports_what_the_driver_did(capsys):
    assert main(["driver-demo", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    modes = [m["mode"] for m in out["modes"]]
    # standing behind the stopped lead the brake holds the car (driver model 2); then it drives off
    assert modes[0] == "BRAKE" and modes[1] == "ACCELERATE" and "BRAKE" in modes[2:]
    assert not out["collided"]
    assert out["min_gap_m"] >= out["x_min_m"] - 1e-6
    assert out["max_abs_jerk_mps3"] <= 2.5 + 1e-6
    assert out["solver"]["fallback"] == 0
    assert sum(out["solve_paths"].values()) == out["solver"]["steps"]


def test_driver_demo_text_and_bad_arguments():
    r = subprocess.run([sys.executable, "-m", "acc_gym.cli", "driver-demo", "--driver", "#13"], capture_output=True,
                       text=True)
    assert r.returncode == 0 and "modes:" in r.stdout and "#13" in r.stdout
    bad = subprocess.run([sys.executable, "-m", "acc_gym.cli", "driver-demo", "--driver", "#99"],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and "unknown MPC driver preset" in bad.stderr
    bad = subprocess.run([sys.executable, "-m", "acc_gym.cli", "driver-demo", "--speed", "nan"], capture_output=True,
                         text=True)
    assert bad.returncode == 2 and "--speed" in bad.stderr


def test_scenarios_command_lists_describes_and_prints_json(capsys):
    from acc_gym.scenarios import Scenario, build

    assert main(["scenarios", "--family", "ncap"]) == 0
    ids = capsys.readouterr().out.split()
    assert len(ids) == 9 + 11 + 4 and "ncap/ccrb/6-40" in ids
    assert main(["scenarios", "singlelane/2/cut-in"]) == 0
    text = capsys.readouterr().out
    assert "cuts in" in text and "lc_duration" in text
    assert main(["scenarios", "carfollowing/90", "--seed", "4", "--json"]) == 0
    assert Scenario.from_json(capsys.readouterr().out) == build("carfollowing/90", seed=4)


def test_score_command_scores_a_recorded_csv(tmp_path, capsys):
    import numpy as np

    from acc_gym.evaluation import EgoTrace, score_episode

    n = 60
    tr = EgoTrace(t=np.arange(n) * 0.2, v=np.full(n, 20.0), a=np.zeros(n), gap=np.full(n, 32.0),
                  v_lead=np.full(n, 20.0))
    path = tmp_path / "drive.csv"
    tr.to_csv(path)
    assert main(["score", str(path), "--time-gap", "1.5", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    expected = score_episode(EgoTrace.from_csv(path, time_gap=1.5)).to_dict()
    assert out == expected and out["qualified"]  # G = 2 m in (0, 6 m)
    r = subprocess.run([sys.executable, "-m", "acc_gym.cli", "score", str(tmp_path / "missing.csv")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "missing.csv" in r.stderr


def test_demo_runs_a_scored_episode_and_saves_its_plot(tmp_path, capsys):
    from acc_gym.evaluation import EgoTrace, score_episode  # noqa: F401

    plot = tmp_path / "demo.png"
    assert main(["demo", "--scenario", "carfollowing/60", "--seed", "3", "--plot", str(plot), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["scenario"] == "carfollowing/60" and out["qualified"]  # the linear ACC qualifies there
    assert 60.0 < out["score"] <= 100.0 and out["score"] == out["report"]["score"]
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["demo", "--scenario", "ncap/ccrs/30", "--controller", "constant", "--plot", ""]) == 0
    text = capsys.readouterr().out
    assert "NOT qualified" in text and "collision True" in text


def test_evaluate_prints_the_summary_and_rejects_bad_controllers(capsys, tmp_path, monkeypatch):
    assert main(["evaluate", "acc", "--env", "acc_gym/NCAP-v0", "--episodes", "4", "--seed", "1", "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["episodes"] == 4 and s["collisions"] == 0 and len(s["scores"]) == 4
    assert s["mean_score"] == sum(s["scores"]) / 4
    # a module:attribute controller, scored through the same path
    (tmp_path / "my_ctrl.py").write_text(
        "from acc_gym_agents.controllers import ConstantSpeed\nblind = ConstantSpeed()\nclass Bad:\n    pass\n"
        "class Wide:\n    def predict(self, obs, deterministic=True):\n        return [0.0, 0.0], None\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert main(["evaluate", "my_ctrl:blind", "--env", "acc_gym/NCAP-v0", "--episodes", "2", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["collisions"] >= 1
    for ref, message in [("nosuchmodule:x", "cannot import module"), ("my_ctrl:missing", "no attribute"),
                         ("my_ctrl:Bad", "no predict"), ("my_ctrl:Wide", "shape (2,)"), ("pid", "unknown controller")]:
        with pytest.raises(SystemExit):
            main(["evaluate", ref, "--episodes", "1"])
        assert message in capsys.readouterr().err


# ---------------------------------------------------------------- errors name the subcommand
@pytest.mark.parametrize("argv, usage", [
    (["evaluate", "--episodes", "x"], "usage: acc-gym evaluate"),  # argparse's own (a type error)
    (["evaluate", "acc", "--episodes", "0"], "usage: acc-gym evaluate"),  # the command's, after parsing
    (["score", "no-such-file.csv"], "usage: acc-gym score"),
    (["driver-demo", "--speed", "nan"], "usage: acc-gym driver-demo"),
    (["campaign", "--suite", "bogus-v9", "--hours", "1", "--controller", "acc", "--out", "{tmp}/c"],
     "usage: acc-gym campaign"),
    (["string-stability", "acc", "--vehicles", "0"], "usage: acc-gym string-stability"),
    (["conformance", "acc", "--standard", "iso9999"], "usage: acc-gym conformance"),
])
def test_an_error_prints_the_usage_of_its_subcommand(argv, usage, capsys, tmp_path):
    with pytest.raises(SystemExit) as exc:
        main([a.replace("{tmp}", str(tmp_path)) for a in argv])
    err = capsys.readouterr().err
    assert exc.value.code == 2
    assert err.startswith(usage) and f"{usage[len('usage: '):]}: error: " in err
    assert "{scenarios,score,demo" not in err  # not the top-level usage listing every subcommand


def test_a_controller_file_with_a_syntax_error_is_one_line_naming_the_file_and_line(tmp_path):
    (tmp_path / "badctl.py").write_text("class C:\n    def predict(self, obs, deterministic=True)\n"
                                        "        return [0.0], None\n")
    (tmp_path / "raises.py").write_text("import math\n\nx = math.sqrt(-1)\n")
    r = subprocess.run([sys.executable, "-m", "acc_gym.cli", "evaluate", "badctl:C", "--episodes", "1"],
                       capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    last = r.stderr.strip().splitlines()[-1]
    assert last == (f"acc-gym evaluate: error: controller 'badctl:C': {tmp_path / 'badctl.py'}, line 2: "
                    "SyntaxError: expected ':'")
    r = subprocess.run([sys.executable, "-m", "acc_gym.cli", "evaluate", "raises:x", "--episodes", "1"],
                       capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert r.stderr.strip().splitlines()[-1] == (
        f"acc-gym evaluate: error: controller 'raises:x': importing module 'raises' raised ValueError: math domain "
        f"error ({tmp_path / 'raises.py'}, line 3)")


# ---------------------------------------------------------------- score and evaluate: one report
def test_score_reports_a_colliding_drive_as_the_environment_does(tmp_path, capsys):
    """The same drive, scored by the environment (what ``evaluate`` and ``demo`` report) and by
    ``acc-gym score`` from its CSV: the same u and min TTC (0 for a collision), and the same text."""
    import gymnasium as gym

    from acc_gym.evaluation import EgoTrace
    from acc_gym.evaluation.runner import run_episode

    env = gym.make("acc_gym/CarFollowing-v0", scenarios=("carfollowing/90",))
    info, world = run_episode(env, "constant", seed=0, scenario="carfollowing/90")  # drives into the braking lead
    sc = env.unwrapped.scenario
    env.close()
    assert info["report"]["metrics"]["collision"] and info["report"]["metrics"]["min_ttc"] == 0.0
    path = tmp_path / "drive.csv"
    EgoTrace.from_world(world, 0, sc).to_csv(path)
    assert main(["score", str(path), "--set-speed", repr(sc.set_speed), "--time-gap", repr(sc.time_gap),
                 "--json"]) == 0
    scored = json.loads(capsys.readouterr().out)
    for key in ("score", "u", "r1", "r2", "qualified"):
        assert scored[key] == info["report"][key], key
    assert scored["metrics"] == info["report"]["metrics"]
    # the text: score prints what demo prints for the same report
    from acc_gym.commands.demo import _print_report

    assert main(["score", str(path), "--set-speed", repr(sc.set_speed), "--time-gap", repr(sc.time_gap)]) == 0
    text = capsys.readouterr().out
    _print_report(info["report"])
    assert text.split("\n", 1)[1] == capsys.readouterr().out


def test_a_collision_has_a_time_to_collision_of_0_and_an_undefined_u_reads_n_a(tmp_path, capsys):
    """A recorded drive that collides without ever closing in by its speed columns (a vehicle
    ahead appears overlapping the ego, faster): min TTC is 0, not inf, and u (no steady
    following, no set speed) is n/a, not nan -- in the text and the JSON alike."""
    from acc_gym.evaluation import EgoTrace, score_episode

    n = 20
    gap = np.r_[np.full(5, np.inf), np.linspace(-0.5, 5.0, n - 5)]
    tr = EgoTrace(t=np.arange(n) * 0.2, v=np.full(n, 10.0), a=np.zeros(n), gap=gap,
                  v_lead=np.where(np.isfinite(gap), 12.0, 0.0))
    report = score_episode(tr)
    assert report.metrics["collision"] and report.metrics["min_ttc"] == 0.0
    path = tmp_path / "cut.csv"
    tr.to_csv(path)
    assert main(["score", str(path)]) == 0
    text = capsys.readouterr().out
    assert "u = n/a" in text and "min TTC 0.00 s" in text and "nan" not in text and "inf" not in text
    assert main(["score", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["u"] is None and out["metrics"]["min_ttc"] == 0.0


# ---------------------------------------------------------------- the table of subcommands
def test_the_command_table_lists_every_subcommand_and_each_module_adds_the_one_it_names(capsys):
    """acc-gym --help lists the table's subcommands in its order, then the entry points' (train);
    each table module's add_parser adds exactly the subcommand the table names it by."""
    import argparse
    import importlib
    import re

    from acc_gym.cli import COMMANDS
    from acc_gym.controllers import cli_plugins

    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    listed = re.search(r"\{([^}]*)\}", capsys.readouterr().out).group(1).split(",")
    assert listed == [name for name, _ in COMMANDS] + list(cli_plugins()) and "train" in listed
    assert len(set(listed)) == len(listed)
    for name, module in COMMANDS:
        sub = argparse.ArgumentParser().add_subparsers()
        importlib.import_module(module).add_parser(sub)
        assert list(sub.choices) == [name], module



# ---------------------------------------------------------------- controllers: what each one is
def test_controllers_lists_each_name_with_what_it_is(capsys):
    from acc_gym.controllers import controller_factory, first_sentence, register_controller, \
        registered_controllers, unregister_controller

    class NoDoc:
        def predict(self, obs, deterministic=True):
            return np.zeros(1), None

    NoDoc.__doc__ = None
    register_controller("test-described", NoDoc, description="A test controller that brakes for nothing.")
    register_controller("test-undocumented", NoDoc)
    try:
        assert main(["controllers"]) == 0
        lines = capsys.readouterr().out.splitlines()
    finally:
        unregister_controller("test-described")
        unregister_controller("test-undocumented")
    names = registered_controllers()
    rows = {line.split()[0]: line for line in lines}
    assert set(rows) == set(names) | {"test-described", "test-undocumented"} and len(rows) == len(lines)
    assert rows["constant"].endswith(f"[{names['constant']}]")  # where it comes from, on the same line
    assert "Holds the set speed and ignores everything ahead: the floor every controller should beat." in rows["constant"]
    assert rows["idm"].split(None, 1)[1].startswith("IDM (Treiber et al. 2000) at the scenario's set speed")
    assert "A test controller that brakes for nothing." in rows["test-described"]
    assert "(no description" in rows["test-undocumented"]
    for name in ("acc", "gipps", "mpc"):  # every built-in's line is its docstring's first sentence
        assert first_sentence(controller_factory(name).__doc__) in rows[name]
    assert first_sentence("CACC (paper 004 Eq. 2): the ``law``, e.g. this. Then more.\n\nOther.") == \
        "CACC (paper 004 Eq. 2): the law, e.g. this."
    assert first_sentence(":class:`~acc_gym.vehicle.Vehicle` on a road") == "Vehicle on a road"
    assert first_sentence("x " * 80).endswith("...") and len(first_sentence("x " * 80)) == 100


# ---------------------------------------------------------------- conformance without the ncap extra
def test_conformance_without_the_ncap_extra_says_what_to_install_and_what_is_still_judged(monkeypatch, capsys):
    from acc_gym.standards import ncap

    monkeypatch.setattr(ncap, "calculator_version", lambda: None)
    for name in [m for m in sys.modules if m.split(".")[0] == "euroncap_rating_2026"] + ["euroncap_rating_2026"]:
        monkeypatch.setitem(sys.modules, name, None)  # import euroncap_rating_2026 -> ImportError
    monkeypatch.setattr(ncap, "ACC_POINTS", ncap.ACC_POINTS[:1])
    monkeypatch.setattr(ncap, "FC_POINTS", ncap.FC_POINTS[:1])
    assert main(["conformance", "acc", "--standard", "ncap"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "Scored by not installed" not in text
    assert ("Not scored: the Euro NCAP score needs Euro NCAP's rating calculator (euroncap-rating-2026), which is "
            'not installed: `pip install "acc-gym[ncap]"`.') in text
    assert "every test point driven once and measured" in text and "ISO 15622" in text and "UN R157" in text
    assert f"| {ncap.ACC_POINTS[0].scenario_id} |" in text  # the point was still driven and reported


# ---------------------------------------------------------------- progress bars
def test_a_progress_bar_is_drawn_on_a_terminal_only():
    import io

    from rich.console import Console

    from acc_gym._progress import progress_bar

    term = io.StringIO()
    with progress_bar("risk", 128, unit="episodes", console=Console(file=term, force_terminal=True)) as bar:
        assert bar.shown
        bar.advance(64)
    drawn = term.getvalue()
    assert "risk" in drawn and "64/128" in drawn and "episodes" in drawn and "0:00:0" in drawn  # elapsed time
    pipe = io.StringIO()
    with progress_bar("risk", 128, console=Console(file=pipe, force_terminal=False)) as bar:
        assert not bar.shown
        bar.advance(64)
    assert pipe.getvalue() == ""
    off = io.StringIO()
    with progress_bar("risk", 128, enabled=False, console=Console(file=off, force_terminal=True)) as bar:
        bar.advance(64)
    assert off.getvalue() == "" and not bar.shown


@pytest.mark.parametrize("argv", [
    ["string-stability", "acc", "--vehicles", "2", "--frequencies", "0.1", "--no-disturbance"],
    ["conformance", "acc", "--standard", "iso15622", "--seeds", "0"],
])
def test_the_long_commands_draw_their_bar_on_stderr_and_json_keeps_both_streams_clean(argv):
    import os

    env = {**os.environ, "TTY_COMPATIBLE": "1", "COLUMNS": "120"}  # rich draws as on a terminal
    r = subprocess.run([sys.executable, "-m", "acc_gym.cli", *argv], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr
    assert argv[0] in r.stderr and "0:00:" in r.stderr  # the bar, with its elapsed time
    r = subprocess.run([sys.executable, "-m", "acc_gym.cli", *argv, "--json"], capture_output=True, text=True,
                       env=env)
    assert r.returncode == 0 and r.stderr == ""
    json.loads(r.stdout)  # one JSON object, nothing else
