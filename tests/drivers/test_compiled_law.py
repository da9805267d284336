"""A baseline model's law as a compiled loop runs it (``compiled_law`` and ``_baseline_kernels.law``)
gives what the model's ``act`` gives; ``act_checked`` is ``act`` without the check."""

import numpy as np
import pytest

from acc_gym.drivers import _baseline_kernels as K
from acc_gym.drivers.base import Observation
from acc_gym.drivers.baselines import (ACC, GM, IDM, MODELS, Fuzzy, FuzzyParams, Gipps, GippsParams, IDMParams,
                                       Newell, Pipes, Tyler, mp_cacc_params)

N = 64


def models():
    """Every law, some with per-vehicle parameters (and Gipps's theta both given and None)."""
    rng = np.random.default_rng(0)
    return [IDM(IDMParams(a=rng.uniform(1.0, 2.5, N), time_gap=rng.uniform(0.8, 2.0, N)), n=N), Gipps(n=N),
            Gipps(GippsParams(theta=rng.uniform(0.0, 0.5, N)), n=N, dt=0.1), GM(n=N),
            Fuzzy(FuzzyParams(step=rng.uniform(0.1, 0.5, N)), n=N), Pipes(n=N), Newell(n=N, dt=0.1), Tyler(n=N),
            ACC(n=N), ACC(mp_cacc_params(), n=N)]


def scene(rng):
    gap = rng.uniform(-2.0, 80.0, N)
    gap[rng.random(N) < 0.2] = np.inf
    gap2 = np.where(np.isfinite(gap), gap + rng.uniform(5.0, 60.0, N), np.inf)
    return Observation(v=rng.uniform(0.0, 35.0, N), a=rng.uniform(-3.0, 2.0, N), gap=gap,
                       v_lead=rng.uniform(0.0, 35.0, N), a_lead=rng.uniform(-6.0, 2.0, N), gap2=gap2,
                       v_lead2=rng.uniform(0.0, 35.0, N), a_lead2=rng.uniform(-6.0, 2.0, N))


@pytest.mark.parametrize("model", models(), ids=lambda m: m.name)
def test_law_by_code_equals_the_models_own_kernel(model):
    rng = np.random.default_rng(1)
    now, seen = scene(rng), scene(rng)
    expect = np.empty(N)
    model.act_into(now, seen, np.arange(N), expect)
    law = model.compiled_law()
    assert law.kind == K.KINDS[model.name] and law.params.shape == (N, K.MAX_PARAMS) and law.dt == model.dt
    got = [K.law(law.kind, law.params[r], law.dt, law.two_ahead, now.v[r], seen.v[r], seen.gap[r], seen.v_lead[r],
                 seen.a_lead[r], now.gap2[r], now.v_lead2[r], now.a_lead2[r]) for r in range(N)]
    if model.name == "acc":  # ACC reads the current scene (it has no reaction delay)
        got = [K.law(law.kind, law.params[r], law.dt, law.two_ahead, now.v[r], now.v[r], now.gap[r], now.v_lead[r],
                     now.a_lead[r], now.gap2[r], now.v_lead2[r], now.a_lead2[r]) for r in range(N)]
    np.testing.assert_array_equal(got, expect)


def test_compiled_law_states_the_delay_and_the_second_vehicle_ahead():
    assert IDM(IDMParams(tau=0.4, time_gap=1.0)).compiled_law().delay_steps == 2  # 0.4 s of 0.2 s steps
    assert Gipps(GippsParams(tau=1.0)).compiled_law().delay_steps == 4  # a speed model: one step less
    assert ACC(mp_cacc_params()).compiled_law().two_ahead and not ACC().compiled_law().two_ahead
    assert np.isnan(Gipps().compiled_law().params[0, 4])  # theta None
    assert set(K.KINDS) == set(MODELS)


def test_a_subclass_has_no_compiled_law():
    class Cautious(IDM):
        def act_into(self, now, seen, rows, out):
            super().act_into(now, seen, rows, out)
            out[rows] -= 0.5

    assert Cautious().compiled_law() is None and IDM().compiled_law() is not None


def test_act_checked_is_act_without_the_check():
    rng = np.random.default_rng(2)
    obs = scene(rng)
    a, b = Gipps(GippsParams(tau=0.6), n=N), Gipps(GippsParams(tau=0.6), n=N)
    for _ in range(4):  # through the delay buffer too
        np.testing.assert_array_equal(a.act(obs), b.act_checked(obs))
    bad = Observation(**{**obs.__dict__, "v": np.full(N, np.nan)})
    with pytest.raises(ValueError, match="observation.v"):
        a.act(bad)
    assert np.all(np.isfinite(b.act_checked(bad)))  # the caller vouched for the values: no check
