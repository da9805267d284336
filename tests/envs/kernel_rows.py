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
    """The :class:`StepIndicators` of kernel rows ``(fl, bo)``, as the environment core builds
    them for a reward that takes the indicators path."""
    return StepIndicators(v=fl[K.F_V], a=fl[K.F_A], jerk=fl[K.F_JERK], set_speed=set_speed, has_lead=bo[K.B_HAS],
                          gap=fl[K.F_GAP], gap_safe=fl[K.F_GS], q=fl[K.F_Q], in_band=bo[K.B_IN_BAND],
                          following=bo[K.B_FOLLOWING], free=bo[K.B_FREE], u=fl[K.F_U], violation=bo[K.B_VIOLATION],
                          collision=bo[K.B_COLLISION], a_comfort=a_comfort, followable=bo[K.B_FOLLOWABLE],
                          v_lead=fl[K.F_VLEAD], tau1=tau1, steps_left=steps_left)
