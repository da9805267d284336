"""Random step-kernel rows and random-action episodes for the envs' fast-path tests (shared
by the -v0 and -v1 tests)."""

import gymnasium
import numpy as np

from acc_gym.envs import _kernel as K
from acc_gym.envs.reward import StepIndicators


def random_rows(rng, n, v_max=35.0, a_range=(-9.0, 4.0), jerk_sd=20.0, gap_max=150.0):
    """``(fl, bo)``: ``n`` rows of the kernel's float and bool fields, with out-of-range gaps,
    negative gaps and missing utilisations mixed in."""
    fl = np.empty((K.N_FLOAT, n))
    fl[K.F_V] = rng.uniform(0.0, v_max, n)
    fl[K.F_A] = rng.uniform(*a_range, n)
    fl[K.F_JERK] = rng.normal(0.0, jerk_sd, n)
    fl[K.F_GAP] = np.where(rng.random(n) < 0.8, rng.uniform(-2.0, gap_max, n), np.inf)
    fl[K.F_GS] = rng.uniform(-5.0, 50.0, n)
    fl[K.F_Q] = fl[K.F_GAP] - fl[K.F_GS]
    fl[K.F_U] = np.where(rng.random(n) < 0.7, rng.uniform(0.0, 1.0, n), np.nan)
    fl[K.F_VLEAD] = rng.uniform(0.0, 35.0, n)
    fl[K.F_ALEAD] = rng.uniform(-5.0, 3.0, n)
    bo = rng.random((K.N_BOOL, n)) < 0.5
    return fl, bo


def rollout(env_id, reward_fn, steps, rng_seed=3, reset_seed=4):
    """``[reset, step, step, ..., reset, ...]``: ``steps`` uniform random actions in
    ``gymnasium.make(env_id, reward_fn=reward_fn)``, reset when an episode ends (its
    ``reset()`` output appended after the last step)."""
    env = gymnasium.make(env_id, reward_fn=reward_fn)
    rng = np.random.default_rng(rng_seed)
    out = [env.reset(seed=reset_seed)]
    for _ in range(steps):
        step = env.step(rng.uniform(-1.0, 1.0, 1).astype(np.float32))
        out.append(step)
        if step[2] or step[3]:
            out.append(env.reset())
    return out


def indicators(fl, bo, set_speed, tau1, steps_left=None, a_comfort=2.5):
    """The :class:`StepIndicators` of kernel rows ``(fl, bo)``, built as the environment core
    builds them for a reward that takes the indicators path (:meth:`StepIndicators.from_rows`)."""
    return StepIndicators.from_rows(fl, bo, set_speed, tau1, a_comfort, steps_left=steps_left)


def scenes(n, **arrays):
    """A :data:`acc_gym.envs._kernel.SCENES` record of ``n`` scenes holding ``arrays`` (shared,
    so what a kernel writes into them is seen here), the other fields filled with placeholders."""
    from acc_gym.envs import _kernel as K

    values = {name: (np.zeros((len(K.RECORD), n, 1)) if name == "rec" else
                     np.zeros(n, dtype=np.int64) if name in ("lead_prev", "steps") else np.ones(n))
              for name, _ in K.SCENE_FIELDS}
    values.update(arrays)
    return K.record_of(K.SCENE_FIELDS, values)
