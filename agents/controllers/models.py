"""The package's car-following models as controllers on the environment's observation.

:class:`ModelController` turns the observation vector into an
:class:`~acc_gym.drivers.base.Observation` (gap ``inf`` when nothing is in range, the
vehicle ahead's speed from the relative speed, its acceleration and the second vehicle
ahead from the V2V entries when the environment has ``v2v=True``; without V2V the
acceleration is estimated from the change of the vehicle ahead's speed over a step and
there is no second vehicle), asks a
batched model of :mod:`acc_gym.drivers` for the desired acceleration, and maps it onto
the action scale. The model is (re)built whenever the observed set speed or time gap
changes -- a new episode -- so each episode starts with fresh delay buffers and the
model's desired speed and time gap follow the scenario's.
"""

from __future__ import annotations

import numpy as np

from acc_gym.drivers.base import Observation
from acc_gym.drivers.baselines import (ACC, GM, IDM, ACCParams, Fuzzy, FuzzyParams, Gipps, GippsParams, GMParams,
                                       IDMParams)
from acc_gym.drivers.mpc import MPCDriver, MPCDriverParams
from acc_gym_agents.controllers.linear import _Policy


V2V_WIDTHS = (11, 23)  # the observation's widths with V2V fields: -v0 (11) and -v1 (11 + 12 margin features)
WIDTHS = (7, 11, 13, 23)  # -v0, -v0 with V2V, -v1 (7 + 6 margin features), -v1 with V2V


def has_v2v(o: np.ndarray) -> bool:
    """Whether observation rows ``(n, m)`` carry the V2V fields 7-10 (by the width: a -v1
    observation without V2V has 13 fields, whose field 7 is a margin feature, not an acceleration)."""
    if o.shape[1] not in WIDTHS:
        raise ValueError(f"an observation has {' or '.join(map(str, WIDTHS))} fields (-v0 / -v1, with or without "
                         f"V2V), got {o.shape[1]}")
    return o.shape[1] in V2V_WIDTHS


def observation(o: np.ndarray) -> Observation:
    """An :class:`Observation` (arrays ``(n,)``) from observation vectors ``(n, m)``, m in :data:`WIDTHS`."""
    v = o[:, 0].copy()
    seen = o[:, 4] > 0.5
    kw = {}
    v2v = has_v2v(o)
    if v2v:
        seen2 = o[:, 10] > 0.5
        kw = dict(gap2=np.where(seen2, o[:, 8], np.inf), v_lead2=np.maximum(v + o[:, 9], 0.0), a_lead2=np.zeros_like(v))
    return Observation(v=v, a=o[:, 1].copy(), gap=np.where(seen, o[:, 2], np.inf),
                       v_lead=np.maximum(v + o[:, 3], 0.0),
                       a_lead=o[:, 7].copy() if v2v else np.zeros_like(v), **kw)


class ModelController(_Policy):
    """A model of :mod:`acc_gym.drivers` as a controller. ``make(set_speed, time_gap, n)``
    returns the model for ``n`` vehicles (arrays of set speeds [m/s] and time gaps [s])."""

    def __init__(self, name: str, make, accel_max: float = 3.0, decel_max: float = 8.0, dt: float = 0.2,
                 time_gap: float | None = None):
        super().__init__(accel_max, decel_max)
        self.name, self.make, self.dt = name, make, dt
        if time_gap is not None:  # a model with its own time gap declares it, and is judged at it
            self.time_gap = float(time_gap)
        self.reset()

    def reset(self) -> None:
        self._model, self._key, self._v_lead = None, None, None

    def _accel(self, o: np.ndarray) -> np.ndarray:
        key = (o.shape[0], tuple(o[:, 5].round(6)), tuple(o[:, 6].round(6)))
        if key != self._key:
            self._model, self._key = self.make(o[:, 5].astype(float), o[:, 6].astype(float), o.shape[0]), key
            self._v_lead = None
        obs = observation(o.astype(float))
        if not has_v2v(o):  # no V2V: estimate the vehicle ahead's acceleration from its speed (as radar ACCs do)
            seen = np.isfinite(obs.gap)
            prev = self._v_lead
            if prev is not None:
                known = seen & np.isfinite(prev)
                obs.a_lead = np.where(known, np.clip((obs.v_lead - np.where(known, prev, 0.0)) / self.dt, -10.0, 10.0),
                                      0.0)
            self._v_lead = np.where(seen, obs.v_lead, np.nan)
        return self._model.act(obs)

    def __repr__(self) -> str:
        return f"ModelController({self.name!r})"


_OWN = ("accel_max", "decel_max", "dt", "time_gap")  # ModelController's own settings


def _split(name: str, kw: dict, params_type, from_scene: tuple[str, ...]) -> tuple[dict, dict]:
    """``kw`` as (ModelController's settings, the model's parameters); a name that is neither, or
    one the scenario sets (the set speed, the time gap), is a ``ValueError`` naming it."""
    from dataclasses import fields

    own = {k: v for k, v in kw.items() if k in _OWN}
    model = {k: v for k, v in kw.items() if k not in _OWN}
    allowed = sorted(f.name for f in fields(params_type) if f.name not in from_scene)
    bad = sorted(set(model) - set(allowed))
    if bad:
        raise ValueError(f"controller {name!r} has no parameter {', '.join(map(repr, bad))}: its parameters are "
                         f"{allowed} (and {list(_OWN)})")
    if model:
        params_type(**model)  # validated now, not at the first step
    return own, model


def cacc(**kw) -> ModelController:
    """CACC (paper 004 Eq. 2): the linear ACC plus 0.6 x the vehicle ahead's acceleration, at the
    scenario's time gap; with ``v2v=True`` the acceleration is communicated, without it estimated
    from the vehicle ahead's speed. Keyword arguments: ModelController's settings and the law's
    :class:`ACCParams` (``k1``, ``k2``, ``k3``, ``s0``, ...)."""
    own, model = _split("cacc", kw, ACCParams, ("time_gap", "v_set", "predecessors"))
    law = {"k1": 0.3, "k2": 1.2, "k3": 0.6, "s0": 2.5, **model}
    return ModelController("cacc", lambda vs, h, n: ACC(ACCParams(**law, time_gap=h, v_set=vs), n=n), **own)


def mp_cacc(**kw) -> ModelController:
    """Multi-predecessor CACC (Eq. 3): one CACC law per vehicle ahead (the second one's acceleration is
    not observed: k3 acts on the first only), the minimum taken; needs ``v2v=True``."""
    own, model = _split("mp-cacc", kw, ACCParams, ("time_gap", "v_set", "predecessors"))
    law = {"k1": 0.3, "k2": 1.2, "k3": 0.6, "s0": 2.5, **model}
    return ModelController("mp-cacc", lambda vs, h, n: ACC(ACCParams(**law, time_gap=h, v_set=vs, predecessors=2),
                                                           n=n), **own)


def idm(**kw) -> ModelController:
    """IDM (Treiber et al. 2000) at the scenario's set speed and time gap; keyword arguments:
    ModelController's settings and :class:`IDMParams` (``a``, ``b``, ``s0``, ``delta``, ``tau``)."""
    own, model = _split("idm", kw, IDMParams, ("time_gap", "v_desired"))
    return ModelController("idm", lambda vs, h, n: IDM(IDMParams(**model, v_desired=vs, time_gap=h), n=n), **own)


def gipps(**kw) -> ModelController:
    """Gipps (1981) with its default braking (-3 m/s^2 wished, -3.5 assumed for the leader).

    It keeps its own time gap, not the scenario's: its safe speed leaves a reaction time
    ``tau`` plus the safety margin ``theta`` (0.6 + 0.3 s), so it declares ``time_gap`` =
    0.9 s and is judged there, as paper 003 judges it (its Gapsafe takes the driver's own
    reaction time)."""
    own, model = _split("gipps", kw, GippsParams, ("v_desired",))
    p = GippsParams(**model)
    own.setdefault("time_gap", p.tau + (p.tau / 2.0 if p.theta is None else p.theta))
    return ModelController("gipps", lambda vs, h, n: Gipps(GippsParams(**model, v_desired=vs), n=n), **own)


def gm(**kw) -> ModelController:
    """GM / Gazis-Herman-Rothery with the free-road law (paper 003's GM)."""
    own, model = _split("gm", kw, GMParams, ("v_desired",))
    return ModelController("gm", lambda vs, h, n: GM(GMParams(**model, v_desired=vs), n=n), **own)


def fuzzy(**kw) -> ModelController:
    """Paper 003's fuzzy-reasoning follower at the scenario's time gap."""
    own, model = _split("fuzzy", kw, FuzzyParams, ("v_desired", "h"))
    return ModelController("fuzzy", lambda vs, h, n: Fuzzy(FuzzyParams(**model, v_desired=vs, h=h), n=n), **own)


def mpc(**kw) -> ModelController:
    """An MPC-ACC: the human-like driver's QP machinery (12 s horizon, jerk bound 2.5 m/s^3, soft
    gap constraints, terminal stoppability) with ACC settings: time gap = the scenario's, 2.5 m
    standstill gap, braking down to -4 m/s^2 outside emergencies and the tyre limit in them."""
    def make(vs, h, n):
        return MPCDriver(MPCDriverParams(a_max=2.0, a_min=-4.0, a_req_sail=-1.0, a_sail=-0.3, q1=1.0, r1=40.0,
                                         c_tg=h, x_min=2.5, v_desired=vs), n=n)
    return ModelController("mpc", make, **kw)
