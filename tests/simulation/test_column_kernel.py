"""The column simulation's two paths equal the per-follower loop they replaced, and stop on bad values.

``reference_column`` is ``simulate_column``'s loop as it was until the compiled column
(acc-gym 0.9.0): every follower's model called through ``act`` (which validates its
observation) every step, numpy physics. Both paths of today's ``simulate_column`` -- the
compiled run of a column of baseline models, and the per-follower loop for other columns --
must give the same trajectories (to 1e-12; bit for bit on this machine), for every baseline
law, with reaction delays, per-vehicle parameters, batches, a sensor range, a stop line and
collisions. Speed is measured in ``benchmarks/bench_env.py --peers``, not here.
"""

from dataclasses import fields

import numpy as np
import pytest

from acc_gym.drivers.base import Observation
from acc_gym.drivers.baselines import (ACC, GM, IDM, Fuzzy, FuzzyParams, Gipps, GippsParams, GMParams, IDMParams,
                                       Newell, NewellParams, Pipes, PipesParams, Tyler, TylerParams, cacc_params,
                                       mp_cacc_params)
from acc_gym.drivers.mpc import MPCDriver, preset
from acc_gym.simulation import _column_kernel as C
from acc_gym.simulation.profiles import SpeedProfile
from acc_gym.simulation.rollout import simulate_column
from acc_gym.vehicle import VehicleParams, applied_acceleration, integrate

KEYS = ("x", "v", "a", "a_des", "gap", "mode", "path", "a_req", "slack")


def reference_column(lead, followers, x0, v0, *, dt, sensor_range=np.inf, stop_position=None, batch=None):
    """The per-follower loop of acc-gym 0.9.0's ``simulate_column`` (setup checks left out)."""
    followers = list(followers)
    n = len(followers) + 1
    speeds = np.asarray(lead.speeds)
    squeeze = batch is None and speeds.ndim == 1
    B = batch if batch is not None else (speeds.shape[0] if speeds.ndim == 2 else 1)
    T = int(round(lead.duration / dt))
    veh = VehicleParams().broadcast(n)
    lengths = np.asarray(veh.length, dtype=float)
    x = np.broadcast_to(np.asarray(x0, float), (B, n)).copy()
    v = np.broadcast_to(np.asarray(v0, float), (B, n)).copy()
    a = np.zeros((B, n))
    stop = None if stop_position is None else np.broadcast_to(np.asarray(stop_position, float), (B,)).copy()
    out = {k: np.zeros((T + 1, B, n)) for k in ("x", "v", "a", "a_des", "gap", "a_req", "slack")}
    out["mode"] = np.full((T + 1, B, n), -1, dtype=np.int64)
    out["path"] = np.full((T + 1, B, n), -1, dtype=np.int64)
    out["a_req"][:] = np.nan
    out["slack"][:] = np.nan
    out["a_des"][0] = np.nan

    def gaps_of(x):
        g = np.full((B, n), np.inf)
        g[:, 1:] = x[:, :-1] - lengths[:-1] - x[:, 1:]
        return g

    for m in followers:
        m.reset()
    g = gaps_of(x)
    out["x"][0], out["v"][0], out["a"][0], out["gap"][0] = x, v, a, g
    t = np.arange(T + 1) * dt
    prof_next = lead.speed(float(lead.times[0]) + t[1:])
    if prof_next.ndim == 1:
        prof_next = np.broadcast_to(prof_next, (B, T))
    a_des = np.zeros((B, n))
    for k in range(T):
        a_des[:, 0] = (prof_next[:, k] - v[:, 0]) / dt
        for j, model in enumerate(followers, start=1):
            seen = g[:, j] <= sensor_range
            gap_j = np.where(seen, g[:, j], np.inf)
            obs2 = {}
            if j >= 2:
                gap2 = x[:, j - 2] - lengths[j - 2] - x[:, j]
                gap2 = np.where(seen & (gap2 <= sensor_range), gap2, np.inf)
                obs2 = dict(gap2=gap2, v_lead2=v[:, j - 2].copy(), a_lead2=a[:, j - 2].copy())
            obs = Observation(v=v[:, j].copy(), a=a[:, j].copy(), gap=gap_j, v_lead=v[:, j - 1].copy(),
                              a_lead=a[:, j - 1].copy(), stop_gap=None if stop is None else stop - x[:, j], **obs2)
            a_des[:, j] = model.act(obs)
            info = getattr(model, "info", None) or {}
            for key in ("mode", "path", "a_req", "slack"):
                if key in info:
                    out[key][k + 1, :, j] = info[key]
        a = applied_acceleration(a_des, v, veh)
        x, v = integrate(x, v, a, dt)
        g = gaps_of(x)
        out["a_des"][k + 1] = a_des
        out["x"][k + 1], out["v"][k + 1], out["a"][k + 1], out["gap"][k + 1] = x, v, a, g
    return {k: (val[:, 0] if squeeze else val) for k, val in out.items()}


def assert_same(tr, ref):
    for key in KEYS:
        np.testing.assert_allclose(getattr(tr, key), ref[key], rtol=1e-12, atol=1e-12, err_msg=key)


LEAD = SpeedProfile.from_segments(20.0, [(0.0, 5.0), (-3.0, 5.0), (0.0, 5.0), (2.0, 4.0), (0.0, 10.0)])


def every_law():
    """One follower of each baseline law (ACC twice: CACC, and multi-predecessor CACC)."""
    return [IDM(), Gipps(), GM(), Fuzzy(), Pipes(), Newell(), Tyler(), ACC(cacc_params()), ACC(mp_cacc_params())]


def delayed_laws():
    """Every law with a reaction delay of several steps (speed models: tau one step more)."""
    return [IDM(IDMParams(tau=0.4, time_gap=1.0)), Gipps(GippsParams(tau=1.0)), GM(GMParams(tau=0.6)),
            Fuzzy(FuzzyParams(tau=0.4)), Pipes(PipesParams(tau=0.6)), Newell(NewellParams(tau=1.2)),
            Tyler(TylerParams(tau=0.8)), ACC()]


def column(followers):
    n = len(followers) + 1
    return np.arange(n)[::-1] * 30.0, np.full(n, 20.0)


class Delegating:
    """A user's driver object (not a baseline model) driving as the model it wraps."""

    def __init__(self, model):
        self.model, self.n = model, model.n

    def reset(self):
        self.model.reset()

    def act(self, obs):
        return self.model.act(obs)


@pytest.mark.parametrize("make,dt,kw", [
    (every_law, 0.1, {}),
    (every_law, 0.2, {"sensor_range": 25.0, "stop_position": 900.0}),
    (delayed_laws, 0.2, {}),
    (delayed_laws, 0.1, {"sensor_range": 40.0}),
], ids=["every-law", "range-and-stop-line", "delays", "delays-dt-0.1"])
def test_a_column_of_baseline_models_equals_the_per_follower_loop(make, dt, kw):
    x0, v0 = column(make())
    tr = simulate_column(LEAD, make(), x0, v0, dt=dt, **kw)
    assert_same(tr, reference_column(LEAD, make(), x0, v0, dt=dt, **kw))
    assert tr.collided.any() or kw  # the runs include collisions (Pipes, GM crash): recorded, run to the end


def test_it_runs_without_calling_the_models(monkeypatch):
    """A column of baseline models is one compiled run: no act, no observation objects per step."""
    def refuse(self, obs):
        raise AssertionError("a baseline model was called per step")

    x0, v0 = column(every_law())
    ref = reference_column(LEAD, every_law(), x0, v0, dt=0.2)
    for cls in (IDM, Gipps, GM, Fuzzy, Pipes, Newell, Tyler, ACC):
        monkeypatch.setattr(cls, "act", refuse)
        monkeypatch.setattr(cls, "act_checked", refuse)
    assert_same(simulate_column(LEAD, every_law(), x0, v0, dt=0.2), ref)


def test_a_batch_with_per_column_parameters_and_delays_equals_the_per_follower_loop():
    B = 4
    rng = np.random.default_rng(3)
    lead = SpeedProfile(LEAD.times, LEAD.speeds * rng.uniform(0.7, 1.0, (B, 1)))
    x0 = np.tile(np.arange(6)[::-1] * 25.0, (B, 1)) + np.where(np.arange(6) == 0, rng.uniform(0.0, 5.0, (B, 1)), 0.0)

    def make():
        return [IDM(IDMParams(a=np.array([1.0, 1.5, 2.0, 2.5]), tau=np.array([0.0, 0.2, 0.4, 0.6]), time_gap=1.2),
                    n=B),
                Gipps(GippsParams(theta=np.array([0.1, 0.2, 0.3, 0.4])), n=B), ACC(mp_cacc_params(), n=B),
                GM(GMParams(tau=np.array([0.4, 0.8, 1.2, 1.6])), n=B), Newell(n=B)]

    tr = simulate_column(lead, make(), x0, np.full((B, 6), 18.0), dt=0.2, batch=B)
    assert tr.x.shape == (LEAD.duration / 0.2 + 1, B, 6)
    assert_same(tr, reference_column(lead, make(), x0, np.full((B, 6), 18.0), dt=0.2, batch=B))


def test_columns_with_other_drivers_take_the_per_follower_loop_and_equal_it():
    """A user's driver object or an MPC driver among baseline models: the per-follower loop
    (values checked by the compiled pass, baseline models through act_checked); and a
    delayed model object given to two slots, whose one delay buffer mixes both slots."""
    def user():
        return [IDM(), Delegating(Gipps(GippsParams(tau=1.0))), ACC(mp_cacc_params()), Pipes(PipesParams(tau=0.4))]

    x0, v0 = column(user())
    assert_same(simulate_column(LEAD, user(), x0, v0, dt=0.2, stop_position=800.0),
                reference_column(LEAD, user(), x0, v0, dt=0.2, stop_position=800.0))

    def with_mpc():
        return [IDM(), MPCDriver(preset("#57")), Gipps()]

    x0, v0 = column(with_mpc())
    tr = simulate_column(LEAD, with_mpc(), x0, v0, dt=0.2)
    assert np.all(tr.mode[1:, 2] >= 0)  # the MPC driver's diagnostics are recorded
    assert_same(tr, reference_column(LEAD, with_mpc(), x0, v0, dt=0.2))

    shared = GM(GMParams(tau=0.6))
    x0, v0 = column([0, 0, 0])
    assert_same(simulate_column(LEAD, [shared, IDM(), shared], x0, v0, dt=0.2),
                reference_column(LEAD, [shared, IDM(), shared], x0, v0, dt=0.2))


def test_a_collision_mid_run_is_recorded_not_an_error():
    """A negative gap is a collision -- what Trajectory.collided reports -- not an invalid value
    (Observation.validate allows it too): the run goes on, as it always did."""
    hard = SpeedProfile.from_segments(25.0, [(0.0, 2.0), (-8.0, 3.0), (0.0, 10.0)])

    def make():
        return [Pipes(PipesParams(tau=2.0, c=0.1)), IDM()]

    tr = simulate_column(hard, make(), [30.0, 15.0, 0.0], [25.0, 25.0, 25.0], dt=0.2)
    assert tr.collided[1] and tr.gap[-1, 1] < 0.0 and tr.t.size == 76
    assert_same(tr, reference_column(hard, make(), [30.0, 15.0, 0.0], [25.0, 25.0, 25.0], dt=0.2))


class NaNLead(SpeedProfile):
    """A lead profile whose speed is NaN from ``t_bad`` on (a recorded trace with a gap in it,
    handed over without SpeedProfile's check)."""

    def speed(self, t):
        out = np.array(super().speed(t), dtype=float)
        out[..., np.asarray(t) >= self.t_bad - 1e-9] = np.nan
        return out


def nan_lead(t_bad):
    lead = NaNLead(LEAD.times, LEAD.speeds)
    object.__setattr__(lead, "t_bad", t_bad)
    return lead


def test_a_nan_mid_run_stops_the_compiled_run_naming_the_vehicle_and_the_step():
    # the lead's profile is NaN at the end of step 7 (t = 1.6 s): the lead asks for NaN in
    # step 7, so at step 8 follower 1 sees a NaN speed ahead (its NaN gap fails the sensor
    # range test, gap <= range, and reads as nothing in range, as it always did)
    x0, v0 = column(every_law())
    with pytest.raises(ValueError, match=r"stopped at step 8 \(t = 1.6 s\): vehicle 1 observes v_lead = nan, which "
                                         r"must be finite \(the lead's speed profile asked for an acceleration of "
                                         r"nan m/s\^2 at step 7\)"):
        simulate_column(nan_lead(1.6), every_law(), x0, v0, dt=0.2)


class NaNAt:
    """A user's driver asking for ``a`` until step ``k_bad``, then for NaN."""

    def __init__(self, k_bad, n=1):
        self.k_bad, self.n, self.k = k_bad, n, 0

    def reset(self):
        self.k = 0

    def act(self, obs):
        self.k += 1
        return np.full(self.n, np.nan if self.k > self.k_bad else 0.0)


def test_a_nan_mid_run_stops_the_per_follower_loop_naming_the_vehicle_and_the_step():
    # follower 2's driver asks for NaN in step 5: at step 6 its own speed is NaN
    followers = [IDM(), NaNAt(5), IDM()]
    x0, v0 = column(followers)
    with pytest.raises(ValueError, match=r"stopped at step 6 \(t = 1.2 s\): vehicle 2 observes v = nan, which must "
                                         r"be finite and >= 0 \(vehicle 2's driver asked for an acceleration of nan "
                                         r"m/s\^2 at step 5\)"):
        simulate_column(LEAD, followers, x0, v0, dt=0.2)


def test_in_a_batch_the_error_names_the_column_too():
    B = 3
    lead = NaNLead(LEAD.times, np.tile(LEAD.speeds, (B, 1)))
    object.__setattr__(lead, "t_bad", 3.0)
    with pytest.raises(ValueError, match=r"stopped at step 15 \(t = 3 s\): vehicle 1 in column 0 observes "
                                         r"v_lead = nan"):
        simulate_column(lead, [IDM(n=B), Gipps(n=B)], [60.0, 30.0, 0.0], [20.0, 20.0, 20.0], dt=0.2, batch=B)


FIELDS = [f.name for f in fields(Observation)]


@pytest.mark.parametrize("seed", range(4))
def test_observe_builds_the_observations_and_has_the_rules_of_observation_validate(seed):
    """``observe`` gives each follower the observation the per-follower loop builds, and rejects
    exactly what ``Observation.validate`` rejects, naming the same follower and field: random
    states with NaN, +-inf and negative speeds planted in random places."""
    rng = np.random.default_rng(seed)
    B, n = 3, 5
    lengths = np.full(n, 4.7)
    rejected = 0
    for _ in range(200):
        x = np.sort(rng.uniform(0.0, 300.0, (B, n)), axis=1)[:, ::-1].copy()
        v, a = rng.uniform(0.0, 30.0, (B, n)), rng.uniform(-3.0, 3.0, (B, n))
        for which in rng.choice(3, size=rng.integers(0, 3)):
            (x, v, a)[which][rng.integers(B), rng.integers(n)] = rng.choice([np.nan, np.inf, -np.inf, -1.0])
        stop = rng.uniform(200.0, 400.0, B) if rng.integers(2) else None
        out, fault = np.empty((n - 1, len(FIELDS), B)), np.zeros(4)
        ok = C.observe(x, v, a, lengths, 120.0, np.zeros(B) if stop is None else stop, stop is not None, out, fault)
        first = None  # the first (column, follower) that validate rejects, in the kernel's order, and its message
        for j in range(1, n):
            for b in range(B):
                obs = reference_observation(x, v, a, lengths, 120.0, stop, b, j)
                try:
                    obs.validate(1)
                except ValueError as exc:
                    first = first or (b, j, str(exc))
                    continue
                if ok:
                    for i, name in enumerate(FIELDS):
                        if getattr(obs, name) is not None:
                            assert out[j - 1, i, b] == getattr(obs, name)[0], name
        if first is None:
            assert ok
        else:
            rejected += 1
            assert not ok and (int(fault[0]), int(fault[1])) == first[:2]
            assert f"observation.{FIELDS[int(fault[2])]} " in first[2], (first, FIELDS[int(fault[2])])
    assert 50 < rejected < 190


def reference_observation(x, v, a, lengths, sensor_range, stop, b, j):
    """Follower ``j``'s observation in column ``b``, as the per-follower loop builds it."""
    g = x[b, j - 1] - lengths[j - 1] - x[b, j]
    seen = g <= sensor_range
    extra = {}
    if j >= 2:
        g2 = x[b, j - 2] - lengths[j - 2] - x[b, j]
        extra = dict(gap2=[g2 if (seen and g2 <= sensor_range) else np.inf], v_lead2=[v[b, j - 2]],
                     a_lead2=[a[b, j - 2]])
    return Observation(v=np.array([v[b, j]]), a=np.array([a[b, j]]), gap=np.array([g if seen else np.inf]),
                       v_lead=np.array([v[b, j - 1]]), a_lead=np.array([a[b, j - 1]]),
                       stop_gap=None if stop is None else np.array([stop[b] - x[b, j]]),
                       **{k: np.array(val) for k, val in extra.items()})
