"""A never-braking controller shared by the risk tests (asks for no acceleration, whatever it sees)."""

import numpy as np


class Hold:
    """A constant controller: action 0 (no acceleration asked) whatever it sees."""

    vectorised = True

    def predict(self, obs, deterministic=True):
        o = np.atleast_2d(np.asarray(obs, dtype=float))
        act = np.zeros((o.shape[0], 1), dtype=np.float32)
        return (act[0] if np.ndim(obs) == 1 else act), None
