"""What a new user reads first holds: counts and times agree with the package and with each
other across the README and the guide, the README's example controller gets what the README
says it gets, and a ``-v0`` id warns once, in one sentence, what its ``-v1`` changes.

The pages read are README.md and docs/*.md (the archive and the changelog record the past
and are not read).
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from acc_gym import scenarios
from acc_gym.suites import list_suites

ROOT = Path(__file__).resolve().parents[2]
PAGES = [ROOT / "README.md", *sorted(p for p in (ROOT / "docs").glob("*.md") if p.name != "changelog.md")]
NUMBERS = {w: k for k, w in enumerate("zero one two three four five six seven eight nine ten eleven twelve".split())}
NUMBER = r"(zero|one|two|three|four|five|six|seven|eight|nine|ten|eleven|twelve|\d+)"
# "the five built-in suites", "all five suites", "Five versioned suites ship", "the leaderboard's five
# suites" -- the count of the suites there are; not "tested on three suites" (a claim about some of
# them) nor "the four suites' 365 test episodes" (a measurement of that time's suites)
SUITE_COUNT = re.compile(rf"(?:\b(?:all|the|leaderboard's)\s+{NUMBER}\s+(?:(?:built-in|versioned|shipped)\s+)*suites\b"
                         rf"|\b{NUMBER}\s+(?:built-in|versioned|shipped)\s+suites\b)(?!')", re.I)


def text(page: Path) -> str:
    return re.sub(r"\s+", " ", page.read_text(encoding="utf-8"))  # a phrase may break across lines


def value(word: str) -> int:
    return int(word) if word.isdigit() else NUMBERS[word.lower()]


def test_every_page_that_counts_the_suites_counts_list_suites():
    n = len(list_suites())
    found = {}
    for page in PAGES:
        for m in SUITE_COUNT.finditer(text(page)):
            found.setdefault(page.name, []).append((m.group(0), value(m.group(1) or m.group(2))))
    assert "README.md" in found and "index.md" in found, f"the README and docs/index.md must name the count: {found}"
    wrong = {name: [p for p, k in hits if k != n] for name, hits in found.items()}
    assert not any(wrong.values()), f"list_suites() has {n} suites; these pages say otherwise: {wrong}"


def test_the_pages_that_list_the_suites_list_every_one():
    names = list_suites()
    readme = text(ROOT / "README.md")
    ship = re.search(r"\w+ versioned suites ship as data.*?\.(?= [A-Z`])", readme)
    assert ship, "the README's sentence on the shipped suites is gone"
    assert all(f"`{name}`" in ship.group(0) for name in names), (names, ship.group(0))
    for page in (ROOT / "README.md", ROOT / "docs" / "scenarios.md"):
        lines = [line for line in page.read_text(encoding="utf-8").splitlines() if line.startswith("list_suites()")]
        assert lines, f"{page.name} no longer calls list_suites()"
        for line in lines:
            listed = re.findall(r"[a-z]+-v\d+", line.split("#", 1)[1])
            assert sorted(listed) == sorted(names), f"{page.name}: {line!r} against list_suites() = {names}"


def test_the_scenario_count_on_the_pages_is_list_scenarios():
    n = len(scenarios.list_scenarios())
    stated = []
    for page in PAGES:
        for line in page.read_text(encoding="utf-8").splitlines():
            if "list_scenarios()" in line and (m := re.search(r"#\s*(\d+) ids", line)):
                stated.append((page.name, int(m.group(1))))
    assert stated, "no page states how many scenario ids list_scenarios() returns"
    assert all(k == n for _, k in stated), f"list_scenarios() has {n} ids; the pages say {stated}"


def test_the_leaderboards_running_time_is_the_same_on_every_page():
    times = []
    for page in PAGES:
        for line in page.read_text(encoding="utf-8").splitlines():
            if re.search(r"acc-gym leaderboard\s+#", line) and (m := re.search(r"~\s*([\d.]+) min", line)):
                times.append((page.name, float(m.group(1))))
    names = {name for name, _ in times}
    assert {"README.md", "index.md"} <= names, times
    assert len({t for _, t in times}) == 1, f"the pages disagree on how long `acc-gym leaderboard` takes: {times}"


def _block(page: Path, first: str) -> str:
    return next(b for b in re.findall(r"^```python\n(.*?)^```", page.read_text(encoding="utf-8"), flags=re.S | re.M)
                if first in b)


def test_the_guide_shows_the_readmes_example_controller():
    readme = _block(ROOT / "README.md", "# mycontroller.py")
    index = _block(ROOT / "docs" / "index.md", "class Gap")
    law = [line.strip() for line in readme.splitlines() if line.strip().startswith("a = ")]
    assert len(law) == 1 and law[0] in index, "docs/index.md's Gap is not the README's"


def test_the_readmes_example_controller_gets_what_the_readme_says(tmp_path, monkeypatch):
    """The README's `Gap`, run as its command runs it (20 episodes of CarFollowing-v1, seed 0), has
    the mean score, share qualified and collisions the README (and docs/index.md) state."""
    (tmp_path / "mycontroller.py").write_text(_block(ROOT / "README.md", "# mycontroller.py"), encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    from acc_gym.evaluation.runner import evaluate

    summary = evaluate("mycontroller:Gap", env_id="acc_gym/CarFollowing-v1", episodes=20, seed=0)
    claim = re.compile(r"mean score ([\d.]+), (\d+) % of the (?:20 )?episodes qualified, no collision")
    for page in (ROOT / "README.md", ROOT / "docs" / "index.md"):
        m = claim.search(text(page))
        assert m, f"{page.name} no longer says what the example controller gets"
        assert float(m.group(1)) == pytest.approx(summary["mean_score"], abs=0.05), (page.name, summary["mean_score"])
        assert int(m.group(2)) == round(100 * summary["share_qualified"]), (page.name, summary["share_qualified"])
    assert summary["collisions"] == 0
    assert summary["share_qualified"] >= 0.9  # it qualifies in most episodes, as the brief asks of an example


WARN_SCRIPT = r"""
import warnings, gymnasium as gym, acc_gym
from acc_gym.envs.registration import ENV_IDS
caught = []
with warnings.catch_warnings(record=True) as w:
    for env_id in sorted(ENV_IDS):
        for _ in range(2):
            gym.make(env_id).close()
    gym.make_vec("acc_gym/SingleLane-v0", num_envs=2, vectorization_mode="vector_entry_point").close()
    obs_v0 = gym.make("acc_gym/CarFollowing-v0").observation_space.shape
for x in w:
    if "acc_gym" in str(x.message):
        print(x.category.__name__, "|", x.message, "|", x.filename)
print("SHAPE", obs_v0, type(gym.make("acc_gym/SingleLane-v0").unwrapped).__name__)
"""


def test_a_v0_id_warns_once_in_one_sentence_what_v1_changes():
    proc = subprocess.run([sys.executable, "-c", WARN_SCRIPT], capture_output=True, text=True, timeout=300,
                          cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    lines = [line for line in proc.stdout.splitlines() if "|" in line]
    assert "SHAPE (7,) ACCEnv" in proc.stdout  # the -v0 ids make the env they always made
    messages = [line.split(" | ")[1] for line in lines]
    v0 = sorted(i for i in ("acc_gym/CarFollowing-v0", "acc_gym/NCAP-v0", "acc_gym/SingleLane-v0",
                            "acc_gym/StopAndGo-v0"))
    # once per id (made twice each, and a vector env), never for a -v1 id, never gymnasium's generic notice
    assert sorted(m.split(" ", 1)[0] for m in messages) == v0, messages
    assert not any("You should consider upgrading to version" in m for m in messages), messages
    for m in messages:
        env_id = m.split(" ", 1)[0]
        assert m.count(". ") == 0 and m.endswith(".")  # one sentence
        assert f"upgrading to {env_id[:-1]}1" in m and "six safety-margin features" in m and "MarginReward" in m
    assert all(line.split(" | ")[2] == "<string>" for line in lines), lines  # the line that made the env
    assert all(line.split(" | ")[0] == "V0IdWarning" for line in lines), lines
    cf = next(m for m in messages if m.startswith("acc_gym/CarFollowing-v0"))
    assert "varied car-following traffic" in cf


def test_the_commands_that_pin_v0_ids_print_no_warning(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "acc_gym", "evaluate", "acc", "--env", "acc_gym/CarFollowing-v0",
                           "--episodes", "1"], capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "out of date" not in proc.stderr and "V0IdWarning" not in proc.stderr, proc.stderr
