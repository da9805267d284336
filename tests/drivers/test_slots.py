"""Per-scene replaceable drivers: MPC rows re-parameterised in place, profiles, baselines."""

from dataclasses import fields

import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from acc_gym.drivers import IDM, IDMParams, MPCDriver, Observation, preset, sample_drivers
from acc_gym.drivers.mpc import MPCSettings
from acc_gym.drivers.qp import Horizon, riccati_terminal
from acc_gym.drivers.scripted import ProfileDriver
from acc_gym.drivers.slots import SlotDrivers
from acc_gym.scenarios.spec import DriverSpec
from acc_gym.simulation import SpeedProfile


def obs_for(n, k):
    """A varied, deterministic snapshot for step k."""
    v = 15.0 + np.arange(n) + 0.1 * k
    return Observation.build(v=v, a=0.0, gap=20.0 + 3 * np.arange(n) - 0.2 * k, v_lead=v - 1.0,
                             a_lead=-0.5)


def test_set_params_gives_exactly_a_fresh_driver():
    rng = np.random.default_rng(1)
    batch = MPCDriver(sample_drivers(rng, 4, 25.0))
    for k in range(6):
        batch.act(obs_for(4, k))
    new = sample_drivers(rng, 1, 14.0)
    batch.set_params(2, new)
    fresh = MPCDriver(new)
    for k in range(30):
        a = batch.act(obs_for(4, k))
        b = fresh.act(obs_for(4, k).take([2]))
        assert a[2] == b[0], k
        assert batch.mode[2] == fresh.mode[0]
    assert batch.stats["steps"][2] == 30  # its statistics restarted
    assert batch.params.v_desired[2] == 14.0 and batch.params.v_desired[0] == 25.0


def test_set_params_with_an_explicit_speed_limit_and_bad_index():
    d = MPCDriver(preset("#57"), n=2)
    d.set_params([1], preset("#23", v_desired=20.0, v_max=26.0))
    np.testing.assert_array_equal(d.params.speed_limit, [25.0, 26.0])
    with pytest.raises(ValueError, match="out of range"):
        d.set_params([2], preset("#23"))


def test_riccati_terminal_matches_scipy():
    h = Horizon()
    rng = np.random.default_rng(0)
    for _ in range(50):
        q1, q2, r1, c = 10 ** rng.uniform(-4, 2), rng.uniform(0.1, 5), rng.uniform(1, 100), rng.uniform(0, 3)
        a = np.array([[1.0, h.dt], [0.0, 1.0]])
        b = np.array([[-(c * h.dt + 0.5 * h.dt ** 2)], [-h.dt]])
        ref = solve_discrete_are(a, b, np.diag([q1, q2]), np.array([[r1]]))
        np.testing.assert_allclose(riccati_terminal(q1, q2, r1, c, h), ref, rtol=1e-10, atol=1e-12)


def test_slot_rows_equal_their_drivers_run_alone():
    rng = np.random.default_rng(3)
    mpc_params = sample_drivers(rng, 1, 20.0)
    profile = SpeedProfile.from_segments(10.0, [(1.0, 4.0), (-2.0, 3.0), (0.0, 5.0)])
    slot = SlotDrivers(4, 0.2)
    slot.assign(0, DriverSpec.mpc(mpc_params))
    slot.assign(1, DriverSpec.from_profile(profile))
    slot.assign(2, DriverSpec("idm", {"v_desired": 22.0, "tau": 0.4}))
    slot.assign(3, None)
    alone = [MPCDriver(mpc_params), ProfileDriver(profile, n=1, dt=0.2), IDM(IDMParams(v_desired=22.0, tau=0.4), n=1)]
    for k in range(25):
        o = obs_for(4, k)
        out = slot.act(o)
        for j, model in enumerate(alone):
            assert out[j] == model.act(o.take([j]))[0], (k, j)
        assert out[3] == 0.0
        assert slot.info["mode"][0] >= 0 and np.all(slot.info["mode"][1:] == -1)
    # a new episode in row 0 only: row 1's profile clock runs on
    slot.assign(0, DriverSpec.mpc(preset("#13")))
    fresh = MPCDriver(preset("#13"))
    o = obs_for(4, 25)
    out = slot.act(o)
    assert out[0] == fresh.act(o.take([0]))[0]
    assert out[1] == alone[1].act(o.take([1]))[0]


def test_rows_path_of_mpc_absent_and_profile_rows_equals_each_driver_alone():
    """The array path taken when a batch holds MPC drivers, absent vehicles and profiles but
    no baseline model (issue 18: the single env's 1- and 2-vehicle scenes): every MPC and
    profile row equals its driver run alone, absent rows ask for 0 with mode -1, also after
    a row changes kind mid-run."""
    rng = np.random.default_rng(5)
    mpc_params = [sample_drivers(rng, 1, 20.0 + 3 * j) for j in range(2)]
    profile = SpeedProfile.from_segments(10.0, [(1.0, 4.0), (-2.0, 3.0), (0.0, 5.0)])
    slot = SlotDrivers(4, 0.2)
    slot.assign(0, DriverSpec.mpc(mpc_params[0]))
    slot.assign(1, None)
    slot.assign(2, DriverSpec.from_profile(profile))
    slot.assign(3, DriverSpec.mpc(mpc_params[1]))
    alone = {0: MPCDriver(mpc_params[0]), 2: ProfileDriver(profile, n=1, dt=0.2), 3: MPCDriver(mpc_params[1])}
    for k in range(30):
        if k == 15:  # row 3's vehicle leaves, row 1's enters
            slot.assign(3, None)
            slot.assign(1, DriverSpec.mpc(mpc_params[1]))
            alone[1] = MPCDriver(mpc_params[1])
            del alone[3]
        o = obs_for(4, k)
        rows = np.array([o.v, o.a, o.gap, o.v_lead, o.a_lead, np.full(4, np.inf), np.zeros(4), np.zeros(4)])
        out = slot.act_rows(rows)
        for j, model in alone.items():
            assert out[j] == model.act(o.take([j]))[0], (k, j)
        absent = [j for j in range(4) if j not in alone]
        assert np.all(out[absent] == 0.0) and np.all(slot.info["mode"][absent] == -1)
        assert np.all(slot.info["mode"][[j for j in alone if j != 2]] >= 0)


BASELINE_SPECS = [("idm", {"v_desired": 22.0, "tau": 0.4}), ("idm", {"v_desired": 30.0}),
                  ("idm", {"time_gap": 1.1, "tau": 1.0}), ("gipps", {"tau": 0.6}),
                  ("gipps", {"tau": 1.0, "theta": 0.3}), ("acc", {"k1": 0.3}),
                  ("acc", {"k3": 1.0, "time_gap": 0.6, "predecessors": 2}), ("gm", {}), ("fuzzy", {}),
                  ("newell", {}), ("tyler", {}), ("pipes", {})]


def test_batched_baseline_rows_equal_each_row_run_alone_through_new_episodes():
    """Baseline rows step as one law call per model (issue 18), each with its own parameters
    and reaction delay: every row's output equals, bit for bit, the model of that row alone
    (delays of 0 to 5 steps, ACC with one and two predecessors, Gipps with and without
    theta), also after some rows start new episodes with other models mid-run."""
    from acc_gym.drivers.baselines import MODELS

    n = len(BASELINE_SPECS) + 1
    slot = SlotDrivers(n, 0.2)
    alone = {}

    def give(row, model, params):
        spec = DriverSpec(model, dict(params))
        slot.assign(row, spec)
        alone[row] = MODELS[model](spec.params_object(), n=1, dt=0.2)

    for row, (model, params) in enumerate(BASELINE_SPECS):
        give(row, model, params)
    slot.assign(n - 1, None)
    delays = {row: m._delay.delay_steps for row, m in alone.items()}
    assert len(set(delays.values())) >= 3  # several different delays are mixed in one call

    def obs2(k):
        o = obs_for(n, k)
        return Observation.build(v=o.v, a=o.a, gap=o.gap, v_lead=o.v_lead, a_lead=o.a_lead - 0.05 * (k % 3),
                                 gap2=o.gap + 25.0, v_lead2=o.v_lead + 0.5, a_lead2=0.0)

    for k in range(30):
        if k == 12:  # new episodes in two rows: one changes model, one keeps it with other settings
            give(0, "gipps", {"tau": 0.8})
            give(5, "acc", {"k1": 0.1, "time_gap": 2.0})
        o = obs2(k)
        out = slot.act(o)
        for row, model in alone.items():
            assert out[row] == model.act(o.take([row]))[0], (k, row, BASELINE_SPECS[row])
        assert out[n - 1] == 0.0
    # the delay matters: a 5-step IDM row's output differs from an undelayed one's on the same rows
    assert delays[2] == 5


def test_rows_path_of_undelayed_baselines_absent_and_profile_rows_equals_each_driver_alone():
    """The array path taken when a batch holds baseline models without a reaction delay,
    absent vehicles and profiles (``drivers="idm"``; issue 35): every row equals its driver
    run alone, absent rows ask for 0, every mode is -1; when a row is given a delayed model
    mid-run the batch leaves that path (a delay needs the ring of past observations) and
    the rows still equal their drivers alone, and it takes the path again once no row is
    delayed."""
    from acc_gym.drivers.baselines import MODELS

    profile = SpeedProfile.from_segments(10.0, [(1.0, 4.0), (-2.0, 3.0), (0.0, 5.0)])
    slot = SlotDrivers(5, 0.2)
    alone = {}

    def give(row, model, params):
        spec = DriverSpec(model, dict(params))
        slot.assign(row, spec)
        alone[row] = MODELS[model](spec.params_object(), n=1, dt=0.2)

    give(0, "idm", {"v_desired": 22.0})
    give(1, "fuzzy", {})
    slot.assign(2, None)
    slot.assign(3, DriverSpec.from_profile(profile))
    alone[3] = ProfileDriver(profile, n=1, dt=0.2)
    give(4, "acc", {"k3": 1.0, "time_gap": 0.6, "predecessors": 2})
    paths = []
    for k in range(30):
        if k == 10:
            give(0, "idm", {"v_desired": 25.0, "tau": 0.4})  # same kind, now delayed
        if k == 20:
            give(0, "idm", {"time_gap": 1.1})  # no delay again
        o = obs_for(5, k)
        rows = np.array([o.v, o.a, o.gap, o.v_lead, o.a_lead, o.gap + 25.0, o.v_lead + 0.5, np.zeros(5)])
        out = slot.act_rows(rows)
        paths.append(slot.compiled_laws() is not None)  # act_world would be one compiled call
        seen = Observation(*rows)
        for row, model in alone.items():
            assert out[row] == model.act(seen.take([row]))[0], (k, row)
        assert out[2] == 0.0 and np.all(slot.info["mode"] == -1)
    assert paths == [True] * 10 + [False] * 10 + [True] * 10  # not while a row has a reaction delay


# undelayed settings of every baseline model (Gipps, GM, Pipes, Newell and Tyler perceive late by default)
UNDELAYED = {"idm": {"v_desired": 22.0}, "gipps": {"tau": 0.2}, "gipps_theta": {"tau": 0.2, "theta": 0.1},
             "gm": {"tau": 0.0, "m": 0.5}, "fuzzy": {}, "pipes": {"tau": 0.0}, "newell": {"tau": 0.2},
             "tyler": {"tau": 0.0}, "acc": {}, "acc_two": {"k3": 1.0, "time_gap": 0.6, "predecessors": 2}}


def world_obs(rng, S, B):
    """A random observation array of a world (``(S, 8, B)``, observe_all's layout)."""
    obs = np.empty((S, 8, B))
    obs[:, 0] = rng.uniform(0.0, 30.0, (S, B))
    obs[:, 1] = rng.uniform(-4.0, 2.0, (S, B))
    obs[:, 2] = np.where(rng.random((S, B)) < 0.8, rng.uniform(0.5, 120.0, (S, B)), np.inf)
    obs[:, 3] = rng.uniform(0.0, 30.0, (S, B))
    obs[:, 4] = rng.uniform(-4.0, 2.0, (S, B))
    obs[:, 5] = np.where(np.isfinite(obs[:, 2]), obs[:, 2] + rng.uniform(5.0, 40.0, (S, B)), np.inf)
    obs[:, 6] = rng.uniform(0.0, 30.0, (S, B))
    obs[:, 7] = rng.uniform(-4.0, 2.0, (S, B))
    return obs


@pytest.mark.parametrize("with_mpc", [False, True])
def test_act_world_equals_act_rows_on_the_gathered_rows(with_mpc):
    """A world's step of its surrounding slots (:meth:`SlotDrivers.act_world`, slot s of scene b
    row (s - 1) B + b) gives bit for bit what :meth:`act_rows` gives on the rows gathered by hand,
    written back to a_des[b, s] (column 0, the ego's, untouched): with every baseline model
    undelayed, profiles and absent vehicles it is one compiled call (issue 35), and each row
    equals its model run alone; with an MPC driver among them, the gathered rows' path. The
    clocks (the profiles' next samples) advance alike over 25 steps and a restart of some rows."""
    from acc_gym.drivers.baselines import MODELS

    S, B = 3, 7
    n = (S - 1) * B
    profile = SpeedProfile.from_segments(10.0, [(1.0, 1.0), (-2.0, 1.5), (0.0, 5.0)])
    specs = [DriverSpec(name.split("_")[0], dict(params)) for name, params in UNDELAYED.items()]
    specs += [DriverSpec.from_profile(profile), None, DriverSpec("idm", {"time_gap": 1.1}), None]
    if with_mpc:
        from acc_gym.drivers.population import sample_driver_values

        specs[-1] = DriverSpec("mpc", sample_driver_values(np.random.default_rng(2), 20.0))
    assert len(specs) == n
    world, rows_path = SlotDrivers(n, 0.2), SlotDrivers(n, 0.2)
    for slot in (world, rows_path):
        for r, spec in enumerate(specs):
            slot.assign(r, spec)
    alone = {r: MODELS[spec.model](spec.params_object(), n=1, dt=0.2) for r, spec in enumerate(specs)
             if spec is not None and spec.model in MODELS}
    rng = np.random.default_rng(11)
    for k in range(25):
        if k == 12:  # new episodes in some rows: their clocks restart
            for slot in (world, rows_path):
                slot.assign(10, DriverSpec.from_profile(profile))
                slot.assign(0, DriverSpec("idm", {"v_desired": 30.0}))
            alone[0] = MODELS["idm"](DriverSpec("idm", {"v_desired": 30.0}).params_object(), n=1, dt=0.2)
        obs = world_obs(rng, S, B)
        a_des = np.full((B, S), 7.0)
        world.act_world(obs, a_des)
        rows = np.ascontiguousarray(obs[1:].transpose(1, 0, 2)).reshape(8, n)
        ref = rows_path.act_rows(rows)
        assert (world.compiled_laws() is None) == with_mpc
        assert np.all(a_des[:, 0] == 7.0)  # the ego's column is the caller's
        assert np.array_equal(a_des[:, 1:].T.ravel(), ref), k
        assert np.array_equal(world.info["mode"], rows_path.info["mode"])
        seen = Observation(*rows)
        for r, model in alone.items():
            assert a_des[r % B, 1 + r // B] == model.act(seen.take([r]))[0], (k, r)
        assert a_des[11 % B, 1 + 11 // B] == 0.0  # the absent vehicle
    assert with_mpc or world._laws is not None  # the compiled call ran


def test_baseline_rows_short_assign_path_equals_building_the_model():
    """:meth:`BaselineRows.assign` with plain-number parameters of a MODELS class (every reset's
    case) reads the row's delay from a cache by (model, tau) instead of building the model: it
    leaves every row exactly as the full path (taken by numpy numbers) does -- delays, groups,
    the groups' parameter arrays and the compiled law's rows -- over models with and without a
    reaction delay, re-assigned rows and a tau seen before; and a parameter array of two values
    is still refused."""
    from acc_gym.drivers.baselines import MODELS
    from acc_gym.drivers.slots import BaselineRows

    settings = [("idm", {"v_desired": 22.0}), ("idm", {"tau": 0.4}), ("gipps", {}), ("gipps", {"theta": 0.2}),
                ("gm", {"m": 0.5}), ("fuzzy", {}), ("pipes", {"tau": 0.6}), ("newell", {}), ("tyler", {"tau": 0.0}),
                ("acc", {"predecessors": 2}), ("idm", {"tau": 0.4, "a": 1.1}), ("gipps", {"tau": 0.6, "a": 2.0})]
    short, full = BaselineRows(len(settings) + 1, 0.2), BaselineRows(len(settings) + 1, 0.2)
    for row, (name, values) in enumerate(settings + [settings[0]]):
        cls = MODELS[name]
        short.assign(row, cls, cls.params_type(**values))
        full.assign(row, cls, cls.params_type(**{k: np.float64(v) if type(v) is float else v for k, v in values.items()}))
    short.assign(3, MODELS["idm"], MODELS["idm"].params_type(tau=0.4, s0=3.0))  # a cached tau, another row's
    full.assign(3, MODELS["idm"], MODELS["idm"].params_type(tau=np.float64(0.4), s0=np.float64(3.0)))
    assert len(short._delays) > 0  # the short path ran
    for name in ("_delay", "_group", "law_kind", "law_two"):
        assert np.array_equal(getattr(short, name), getattr(full, name)), name
    assert np.array_equal(short.law_params, full.law_params, equal_nan=True)
    assert short._delay.tolist()[:3] == [0, 2, 2] and set(short._keys) == set(full._keys)
    for (key, g) in short._keys.items():
        a, b = short._models[g].params, full._models[full._keys[key]].params
        for f in fields(type(a)):
            assert np.array_equal(np.asarray(getattr(a, f.name), float), np.asarray(getattr(b, f.name), float),
                                  equal_nan=True), (key, f.name)
    with pytest.raises(ValueError, match="2 values for n=1"):
        short.assign(0, MODELS["idm"], MODELS["idm"].params_type(a=np.array([1.0, 2.0])))


def test_a_large_batch_uses_the_parallel_kernel_and_gives_the_same_numbers():
    """Vector envs of >= 128 scenes step their drivers with the parallel kernel: each row must still
    equal the driver stepped alone (what makes a large vector env equal single envs)."""
    rng = np.random.default_rng(0)
    p = sample_drivers(rng, 130, rng.uniform(10, 30, 130))
    big = MPCDriver(p, settings=MPCSettings(parallel=None))  # auto: threads from 128 drivers
    rows = (0, 57, 129)
    alone = [MPCDriver(p.take([i])) for i in rows]
    assert big._parallel and not alone[0]._parallel
    assert not MPCDriver(p)._parallel  # the default: no threads (see MPCSettings.parallel)
    idle = np.arange(130) % 3 == 1  # rows skipped by the threads (MPCDriver.set_idle); none of `rows`
    big.set_idle(idle)
    for _ in range(40):
        v = rng.uniform(5, 30, 130)
        o = Observation.build(v=v, a=rng.uniform(-1, 1, 130), gap=rng.uniform(3, 80, 130),
                              v_lead=np.maximum(v + rng.normal(0, 3, 130), 0.0), a_lead=rng.uniform(-3, 1, 130))
        a = big.act(o)
        assert np.all(a[idle] == 0.0)
        for model, i in zip(alone, rows):
            assert a[i] == model.act(o.take([i]))[0]


def test_slot_views_of_one_holder_equal_separate_slots():
    """Two slots held by one SlotDrivers (rows j n + b) and stepped as one batch give each
    slot what a separate SlotDrivers per slot gives: accelerations, modes, fallbacks."""
    from acc_gym.drivers.base import Observation
    from acc_gym.drivers.population import sample_driver_values
    from acc_gym.drivers.slots import SlotView
    from acc_gym.scenarios.spec import DriverSpec

    rng = np.random.default_rng(3)
    n = 3
    separate = [SlotDrivers(n, 0.2), SlotDrivers(n, 0.2)]
    joint = SlotDrivers(2 * n, 0.2)
    views = [SlotView(joint, j, n) for j in range(2)]
    for j in range(2):
        for b in range(n):
            spec = None if (j, b) == (1, 2) else DriverSpec("mpc", sample_driver_values(rng, float(rng.uniform(8, 30))))
            separate[j].assign(b, spec)
            views[j].assign(b, spec)
    for _ in range(40):
        rows = np.empty((8, 2 * n))
        rows[0] = rng.uniform(0.0, 30.0, 2 * n)
        rows[1] = rng.uniform(-4.0, 2.0, 2 * n)
        rows[2] = np.where(rng.random(2 * n) < 0.8, rng.uniform(1.0, 120.0, 2 * n), np.inf)
        rows[3] = rng.uniform(0.0, 30.0, 2 * n)
        rows[4] = rng.uniform(-4.0, 2.0, 2 * n)
        rows[5:] = np.inf
        both = joint.act_rows(rows)
        for j in range(2):
            alone = separate[j].act(Observation(*rows[:, j * n:(j + 1) * n]))
            assert np.array_equal(both[j * n:(j + 1) * n], alone)
            assert np.array_equal(views[j].info["mode"], separate[j].info["mode"])
            assert np.array_equal(views[j].fallbacks, separate[j].fallbacks)
    assert views[1].info["mode"][2] == -1  # the absent vehicle's row
    with pytest.raises(RuntimeError, match="joint"):
        views[0].act(None)
    with pytest.raises(ValueError, match="out of range"):
        views[0].assign(n, None)


def test_idle_rows_are_skipped_and_the_others_keep_their_numbers():
    """MPCDriver.set_idle (issue 35): marked rows ask for 0 and gain no statistics, the other
    rows' actions, modes and statistics equal an unmarked batch's bit for bit, set_params
    clears the mark; SlotDrivers marks its absent and profile rows (their planned cruise was
    computed and thrown away before)."""
    rng = np.random.default_rng(11)
    params = sample_drivers(rng, 4, 25.0)
    marked, plain = MPCDriver(params), MPCDriver(params)
    idle = np.array([False, True, False, True])
    marked.set_idle(idle)
    for k in range(25):
        o = obs_for(4, k)
        a, b = marked.act(o), plain.act(o)
        assert np.array_equal(a[~idle], b[~idle]) and np.all(a[idle] == 0.0), k
        assert np.array_equal(marked.mode[~idle], plain.mode[~idle])
    assert np.array_equal(marked.stats["steps"], [25, 0, 25, 0])
    assert np.array_equal(plain.stats["steps"], [25, 25, 25, 25])
    marked.set_params(1, params.take([1]))  # restarted: planned again
    marked.act(obs_for(4, 25))
    assert marked.stats["steps"][1] == 1 and marked.stats["steps"][3] == 0
    bad = obs_for(4, 26)
    v = np.array(bad.v, dtype=float)
    v[3] = np.nan  # an idle row's input is nobody's: not read, not checked
    a = marked.act(Observation.build(v=v, a=0.0, gap=bad.gap, v_lead=bad.v_lead, a_lead=-0.5))
    assert np.isfinite(a).all() and a[3] == 0.0
    v[0] = np.nan  # a planned row's still is
    with pytest.raises(ValueError, match="observation.v is invalid"):
        marked.act(Observation.build(v=v, a=0.0, gap=bad.gap, v_lead=bad.v_lead, a_lead=-0.5))
    with pytest.raises(ValueError, match="idle must be booleans of shape"):
        marked.set_idle(np.zeros(3, bool))
    with pytest.raises(ValueError, match="idle must be booleans"):
        marked.set_idle(np.zeros(4))

    slot = SlotDrivers(3, 0.2)
    slot.assign(0, DriverSpec.mpc(params.take([0])))
    slot.assign(1, None)
    slot.assign(2, DriverSpec.from_profile(SpeedProfile.from_segments(10.0, [(1.0, 4.0)])))
    for k in range(5):
        o = obs_for(3, k)
        slot.act_rows(np.array([o.v, o.a, o.gap, o.v_lead, o.a_lead, np.full(3, np.inf), np.zeros(3), np.zeros(3)]))
    assert np.array_equal(slot._mpc.stats["steps"], [5, 0, 0])  # without the marks: [5, 5, 5]


def test_the_path_follows_the_counted_delays_and_laws_through_assignments():
    """The counts behind ``BaselineRows.delayed`` and ``all_compiled`` (kept as rows are
    assigned, re-assigned and removed) equal the arrays they stand for, and the slot's cached
    path equals the path worked out afresh, through random assignments of delayed and undelayed
    models, a model outside the compiled loop (a subclass), profiles, absent vehicles and an
    assignment that raises."""
    from acc_gym.drivers.baselines import MODELS

    class MyIDM(MODELS["idm"]):  # not a package model: its law is not in the compiled loop
        pass

    class Broken:  # a driver whose parameters fail as it is given
        model = "idm"

        def params_object(self):
            raise ValueError("broken")

    rng = np.random.default_rng(7)
    slot = SlotDrivers(6, 0.2)
    b = slot._baseline
    choices = [("idm", {"v_desired": 20.0}), ("idm", {"tau": 0.4}), ("gipps", {}), ("fuzzy", {}), ("acc", {}),
               ("mine", {}), ("none", None), ("profile", None), ("bad", None)]
    paths = set()
    for step in range(400):
        row = int(rng.integers(6))
        name, params = choices[int(rng.integers(len(choices)))]
        if name == "none":
            slot.assign(row, None)
        elif name == "profile":
            slot.assign(row, DriverSpec.from_profile(SpeedProfile.from_segments(10.0, [(1.0, 2.0)])))
        elif name == "mine":
            b.assign(row, MyIDM, IDMParams())  # straight into the rows, as SlotDrivers does for MODELS
            slot.kind[row] = 3
            slot._stale = True  # rows written from outside assign(): the slot is told
        elif name == "bad":
            with pytest.raises(ValueError, match="broken"):
                slot.assign(row, Broken())
            assert slot.kind[row] == 0 and b._group[row] == -1  # left absent, not half-assigned
        else:
            slot.assign(row, DriverSpec(name, dict(params)))
        assigned = b._group >= 0
        assert b.delayed() == bool(np.any(b._delay[assigned] > 0)) == bool(np.any(b._delay > 0)), step
        assert b.all_compiled() == bool(np.all(b.law_kind[assigned] >= 0)), step
        compiled = slot.compiled_laws() is not None
        slot._stale = True  # worked out afresh
        assert (slot.compiled_laws() is not None) == compiled, step
        paths.add((b.delayed(), compiled))
    assert paths == {(False, True), (False, False), (True, False)}  # (a reaction delay, one compiled call)
