"""The linear ACC, slowed down when ACC_GYM_TEST_SLOW is set (seconds per step), so that a test can
kill a campaign in the middle of a chunk. Same actions as the built-in ``acc``."""

import os
import time

from acc_gym_agents.controllers import LinearACC


class SlowACC(LinearACC):
    def predict(self, obs, deterministic=True):
        delay = float(os.environ.get("ACC_GYM_TEST_SLOW", "0"))
        if delay:
            time.sleep(delay)
        return super().predict(obs, deterministic=deterministic)
