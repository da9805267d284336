"""Write ``reference_scores.json``: scores of reference suite episodes, to be reproduced on
any machine within ``acc_gym.reproducibility.SCORE_TOLERANCE``. Rerun it only when the
suites or the scoring change on purpose: ``python tests/suites/make_reference_scores.py``."""

import json
from pathlib import Path

import gymnasium as gym

from acc_gym.evaluation.runner import run_episode
from acc_gym.reproducibility import SCORE_TOLERANCE
from acc_gym.suites import get_suite, list_suites

CONTROLLERS = ("acc", "idm")
EPISODES = (0, 1, 2)


def main() -> None:
    rows = []
    for name in list_suites():
        suite = get_suite(name)
        env = gym.make(suite.env_id)
        for k in EPISODES:
            sc = suite.episodes("test")[k]
            for controller in CONTROLLERS:
                info, _ = run_episode(env, controller, scenario=sc, record=False)
                rows.append({"suite": name, "episode": k, "id": sc.id, "controller": controller,
                             "score": float(info["score"]), "qualified": bool(info["qualified"])})
        env.close()
    doc = {"score_tolerance": SCORE_TOLERANCE, "episodes": rows}
    path = Path(__file__).with_name("reference_scores.json")
    path.write_text(json.dumps(doc, indent=1) + "\n")
    print(path)


if __name__ == "__main__":
    main()
