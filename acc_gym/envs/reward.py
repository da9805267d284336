"""Per-step reward from the same criteria as the 100-point score (paper 003).

:class:`StepIndicators` holds, for ``n`` scenes, what the score looks at in one step --
the car-following band, efficiency ``u_t``, speed keeping, comfort, jerk, the
proper-response safety check and a collision -- computed with the same definitions as
:mod:`acc_gym.evaluation.scoring` (car-following samples, free samples, transients).
:class:`CriteriaReward` (the default) weighs them:

==============  ===========================================================  ==========
term            per step                                                     default w
==============  ===========================================================  ==========
band            ``+w`` on a car-following sample inside ``0 < G < 0.2 Gapsafe``   1.0
efficiency      ``+w (1 - u_t)`` on a car-following sample                     0.5
speed           ``+w (1 - min(|v - v_set| / (0.2 v_set), 1))`` with nothing       1.0
                to follow in view
comfort         ``-w (a / 3 m/s^2)^2``                                         0.1
jerk            ``-w (jerk / 10 m/s^3)^2``                                      0.02
safety          ``-w`` on a proper-response violation                           2.0
collision       ``-w`` once, when the ego hits the vehicle ahead (terminates)   100
lag             ``-w min((gap - D) / D, 1)`` while a followable vehicle is       0.5
                ahead beyond ``D = 1.2 tau1 v_lead + 5 m`` (any distance)
==============  ===========================================================  ==========

Why an agent cannot do better by parking or oscillating than by following well: the
positive terms are paid only for *following* (inside the band, steady, both moving) or,
when there is nothing to follow, for holding the set speed. A parked or crawling ego
earns neither (a followable vehicle ahead at any distance makes the step a following
step, so hanging back out of sensor range earns nothing either) and pays the lag term, so
standing still behind a moving vehicle costs up to 0.5 a step rather than nothing (a PPO
agent trained without it learned to stay parked); following well earns the most a step
can give (1.5, against 1.0 for free driving). Oscillating costs comfort
and jerk and leaves the band. Tailgating pays the safety penalty once Q < 0 outlasts the
reaction time without braking. Any object with ``__call__(StepIndicators) -> (reward,
terms)`` can replace it (``reward_fn=``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from acc_gym.evaluation.scoring import ScoringConfig


@dataclass
class StepIndicators:
    """One step's criteria for ``n`` scenes (arrays ``(n,)``)."""

    v: np.ndarray  # [m/s] ego speed
    a: np.ndarray  # [m/s^2] ego acceleration applied over the step
    jerk: np.ndarray  # [m/s^3]
    set_speed: np.ndarray  # [m/s]
    has_lead: np.ndarray  # a vehicle ahead (any distance)
    gap: np.ndarray  # [m] D1 (inf: none)
    gap_safe: np.ndarray  # [m]
    q: np.ndarray  # [m] D1 - Gapsafe (inf: none)
    in_band: np.ndarray
    following: np.ndarray  # a car-following sample (scoring's definition)
    free: np.ndarray  # nothing to follow in view
    u: np.ndarray  # efficiency u_t clipped to [0, 1] (NaN where Gapsafe <= 0)
    violation: np.ndarray  # proper-response violation this step
    collision: np.ndarray  # the ego's gap reached 0 this step
    a_comfort: float = 3.0  # [m/s^2]
    followable: np.ndarray | None = None  # a vehicle ahead the ego could follow (moving, not faster than v_set)
    v_lead: np.ndarray | None = None  # [m/s]
    tau1: np.ndarray | None = None  # [s]
    steps_left: np.ndarray | None = None  # steps the scenario still had to run after this one
    a_lead: np.ndarray | None = None  # [m/s^2] the vehicle ahead's acceleration over the step (0: none)

    @classmethod
    def from_rows(cls, fl: np.ndarray, bo: np.ndarray, set_speed: np.ndarray, tau1: np.ndarray,
                  a_comfort: float = 3.0, steps_left: np.ndarray | None = None) -> "StepIndicators":
        """The indicators of the rows of :func:`acc_gym.envs._kernel.criteria`'s outputs ``fl``
        and ``bo`` (views, not copies): what the environment core hands a reward that is not
        built in."""
        from acc_gym.envs import _kernel as K

        return cls(v=fl[K.F_V], a=fl[K.F_A], jerk=fl[K.F_JERK], set_speed=set_speed, has_lead=bo[K.B_HAS],
                   gap=fl[K.F_GAP], gap_safe=fl[K.F_GS], q=fl[K.F_Q], in_band=bo[K.B_IN_BAND],
                   following=bo[K.B_FOLLOWING], free=bo[K.B_FREE], u=fl[K.F_U], violation=bo[K.B_VIOLATION],
                   collision=bo[K.B_COLLISION], a_comfort=a_comfort, followable=bo[K.B_FOLLOWABLE],
                   v_lead=fl[K.F_VLEAD], tau1=tau1, steps_left=steps_left, a_lead=fl[K.F_ALEAD])


def _rows(s: StepIndicators) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The rows of :func:`acc_gym.envs._kernel.criteria`'s outputs ``(fl, bo)`` holding the
    indicators ``s`` (scalars broadcast to the scenes), and their ``set_speed`` and ``tau1``
    as float arrays: what the compiled reward terms read. Without ``followable`` no vehicle
    ahead is followable (the lag term is 0); without ``v_lead``, ``a_lead`` or ``tau1``: 0, 0, 1 s."""
    from acc_gym.envs import _kernel as K

    n = np.shape(s.v)[0]

    def f(x, default=0.0):
        return np.broadcast_to(np.asarray(default if x is None else x, dtype=float), (n,))

    fl = np.empty((K.N_FLOAT + 1, n))
    bo = np.empty((K.N_BOOL, n), dtype=bool)
    for row, x in ((K.F_V, s.v), (K.F_A, s.a), (K.F_JERK, s.jerk), (K.F_GAP, s.gap), (K.F_GS, s.gap_safe),
                   (K.F_Q, s.q), (K.F_U, s.u), (K.F_VLEAD, s.v_lead), (K.F_ALEAD, s.a_lead)):
        fl[row] = f(x)
    fl[K.F_T] = 0.0
    for row, x in ((K.B_HAS, s.has_lead), (K.B_IN_BAND, s.in_band), (K.B_FOLLOWING, s.following),
                   (K.B_FREE, s.free), (K.B_VIOLATION, s.violation), (K.B_COLLISION, s.collision),
                   (K.B_FOLLOWABLE, s.followable)):
        bo[row] = np.broadcast_to(np.asarray(False if x is None else x, dtype=bool), (n,))
    return fl, bo, np.ascontiguousarray(f(s.set_speed)), np.ascontiguousarray(f(s.tau1, 1.0))


def _check_weights(reward, positive: tuple[str, ...]) -> None:
    """Every field of a reward dataclass a finite number >= 0, those in ``positive`` > 0."""
    name = type(reward).__name__
    for f in fields(reward):
        value = getattr(reward, f.name)
        if f.type in (bool, "bool"):  # a switch, not a weight
            if not isinstance(value, bool):
                raise ValueError(f"{name}.{f.name} must be True or False, got {value!r}")
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
            raise ValueError(f"{name}.{f.name} must be a number >= 0, got {value!r}")
        if f.name in positive and value <= 0:
            raise ValueError(f"{name}.{f.name} must be > 0, got {value!r}")


@dataclass(frozen=True)
class CriteriaReward:
    """The default reward (weights as in the module table)."""

    band: float = 1.0
    efficiency: float = 0.5
    speed: float = 1.0
    comfort: float = 0.1
    jerk: float = 0.02
    safety: float = 2.0
    collision: float = 100.0
    lag: float = 0.5
    jerk_scale: float = 10.0  # [m/s^3]

    def __post_init__(self) -> None:
        _check_weights(self, ("jerk_scale",))
        object.__setattr__(self, "_w", np.array([self.band, self.efficiency, self.speed, self.comfort, self.jerk,
                                                 self.safety, self.collision, self.lag, self.jerk_scale], dtype=float))

    def compiled_terms(self) -> tuple[int, np.ndarray, tuple[str, ...]] | None:
        """The reward's contract with the environment core: ``(code, weights, term names)`` of
        the compiled terms the core computes inside its step
        (:func:`acc_gym.envs._kernel.criteria_reward_rows`), the same numbers as
        :meth:`__call__`. A subclass that overrides :meth:`__call__` or :meth:`from_criteria`
        gets None (the core then calls it), unless it overrides this too."""
        from acc_gym.envs import _kernel as K

        kind = type(self)
        if kind.__call__ is not CriteriaReward.__call__ or kind.from_criteria is not CriteriaReward.from_criteria:
            return None
        return K.REWARD_CRITERIA, self._w, K.TERMS

    def __call__(self, s: StepIndicators) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """``(reward, terms)`` for one step of ``n`` scenes, in one compiled pass
        (:func:`acc_gym.envs._kernel.criteria_reward_rows`; missing indicators: :func:`_rows`)."""
        fl, bo, set_speed, tau1 = _rows(s)
        return self.from_criteria(fl, bo, set_speed, tau1, s.a_comfort)

    def from_criteria(self, fl: np.ndarray, bo: np.ndarray, set_speed: np.ndarray, tau1: np.ndarray,
                      a_comfort: float) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """What :meth:`__call__` returns for the :class:`StepIndicators` the environment core
        would build from the rows of :func:`acc_gym.envs._kernel.criteria`'s outputs ``fl``
        and ``bo`` (float arrays ``(n,)`` ``set_speed`` and ``tau1``), without building
        them: the core's fast path for the default reward (one step of the single env is
        a few tens of microseconds, and the indicators and their checks cost ten)."""
        from acc_gym.envs import _kernel as K

        n = fl.shape[1]
        terms = np.empty((len(K.TERMS), n))
        reward = np.empty(n)
        K.criteria_reward_rows(fl, bo, set_speed, tau1, float(a_comfort), self._w, terms, reward)
        return reward, dict(zip(K.TERMS, terms))


@dataclass(frozen=True)
class MarginReward:
    """A reward for learning ACC from scratch (the ``-v1`` ids' default): the
    score's own terms, reshaped so that their optimum sits inside the band rather than on
    the safety boundary and so that every state has a gradient.

    ==============  ====================================================================  ==========
    term            per step                                                              default w
    ==============  ====================================================================  ==========
    band            ``+w`` on a car-following sample inside ``0 < Q < 0.2 Gapsafe``          1.0
    efficiency      ``+w max(0, 1 - |u_t - peak| / max(peak, 1 - peak))`` on a                1.0
                    car-following sample: a tent over the band, highest at ``u_t = peak``
    speed           ``+w (1 - e)`` with ``e = |v - v_set| / (0.2 v_set)`` for ``e <= 1``,      1.0
                    ``-w slope (e - 1)`` beyond (no plateau) -- with nothing to follow in
                    view, and while far behind a vehicle it could follow
    response        ``-w clip((a + a_resp) / a_resp, 0, 1)`` while ``Q < 0``: braking less     1.0
                    than the score's proper response ``a_resp`` (2 m/s^2)
    comfort         ``-w (a / 3 m/s^2)^2``                                                     0.1
    jerk            ``-w (jerk / 10 m/s^3)^2``                                                 0.02
    safety          ``-w`` on a proper-response violation                                     2.0
    collision       ``-(w + c_max steps_left)`` once, when the ego hits the vehicle ahead      100
                    (terminates): ``c_max`` is the most the other terms can charge in a
                    step (:attr:`max_step_cost`), ``steps_left`` the steps the scenario
                    still had to run
    lag             ``-w x / (1 + x)``, ``x = (gap - D) / D``, while a followable vehicle      0.5
                    is ahead beyond ``D = 1.2 tau1 v_lead + 5 m`` (any distance)
    overspeed       ``-w min((v - v_set) / (overspeed_scale v_set), 5)`` above the set         0.0
                    speed, on every step (following or not)
    reach           ``-w min((Q / Gapsafe - 0.2) / 0.2, 1)`` on a car-following sample         0.0
                    beyond the band's far edge (``Q > 0.2 Gapsafe``): a slope from the
                    band's edge out to twice its width, where band, tent and lag pay
                    nothing
    behind          ``-w`` while far behind a followable vehicle (where ``speed`` and          0.0
                    ``lag`` apply): with ``w`` = the speed weight, cruising there at the
                    set speed nets 0 instead of ``+w``
    standstill      ``-w clip((s0 - d) / s0, 0, 1)`` behind a stopped vehicle               0.0
                    (``v_lead < 0.5 m/s``, any distance), ``d = gap - v^2 / (2 a_resp)``
                    the gap a stop at the proper response would leave, ``s0``
                    ``standstill_gap`` (3 m)
    demand          ``-w clip((a + a_req) / (a_req - a_resp), 0, 1)`` while ``Q < 0`` and      0.0
                    paper 001's ``a_req = (v - v_lead)^2 / (2 gap)`` (closing; counted up
                    to 9 m/s^2) exceeds ``a_resp``: braking weaker than the deceleration
                    that stops the closing in the gap left, graded from ``a_req`` (nothing)
                    to ``a_resp`` (all of it, where ``response`` takes over)
    release         ``-w (min(max(jerk, 0), 30 m/s^3) / 10 m/s^3)^2`` while ``Q < 0``: the      0.0
                    acceleration rising (the brake let go, or accelerating) inside
                    Gapsafe, on top of ``jerk``; braking harder costs ``jerk`` alone
    let_go          as ``release``, where the acceleration after the step is above           0.0
                    ``-a_resp``: only a release that ends weaker than the proper response
                    (the samples the score counts as improper responses)
    stop_demand     as ``demand``, with ``a_stop = v^2 / (2 (gap + v_lead^2 / (2 b)))``      0.0
                    in place of ``a_req``, while the vehicle ahead brakes at ``b =
                    -a_lead > 0``: the deceleration that stops the ego in the gap left
                    after the vehicle ahead's own stop. ``a_req`` assumes the vehicle
                    ahead holds its speed and reads 0.7-2 m/s^2 in the first seconds of an
                    emergency stop from 120 km/h met in the band, where stopping behind
                    it needs about 5 (docs/rl-training.md, candidate V's trace)
    ==============  ====================================================================  ==========

    ``behind_outside_margin`` (a switch, False by default): True counts the ego as far behind
    (where ``speed``, ``lag`` and ``behind`` apply to a followable vehicle) only where ``Q >= 0``.
    ``D`` follows the vehicle ahead's speed, so while it brakes hard ``D`` falls below the gap
    and an ego still inside Gapsafe counts as far behind: ``behind`` charges and ``speed``
    pays for holding speed there, beside the terms that ask it to brake (candidate W's
    collision, docs/rl-training.md). With the switch, inside Gapsafe only ``response``,
    ``demand``, ``stop_demand`` and the terms that apply everywhere act.

    The comfort and jerk terms count ``|a|`` up to 9 m/s^2 and the jerk up to 30 m/s^3, and
    the speed term's slope stops at ``e = 5`` (a parked ego), so a step costs at most
    :attr:`max_step_cost` (5.58 with the defaults; ``overspeed`` adds ``5 w``, ``reach``, ``behind``,
    ``standstill``, ``demand`` and ``stop_demand`` ``w``, ``release`` and ``let_go`` ``9 w``).

    Why these changes to :class:`CriteriaReward`:

    * **Efficiency.** The score's ``R1 = 20 (1 - u)`` pays most at ``Q = 0``, the safety
      boundary; one sample below it fails the safety item and 60 of the 100 points. A
      policy that hugs the boundary gains at most 20 points and risks 60, so under any
      uncertainty about the lead the expected score is highest inside the band: the tent
      (``peak`` 0.5 by default, the band's centre) pays there.
    * **Response.** The score forgives ``Q < 0`` only while the ego brakes at 2 m/s^2 or
      more; the graded term says so every step, not only at the violation.
    * **A collision is the worst outcome.** It ends the episode, so a flat penalty can be
      cheaper than driving on badly: with -100, a full-throttle ego that hits the lead
      halfway through paper 003's test returned more than a tailgater that finished it
      (score 0 against 30). Charging the rest of the scenario at the worst rate a step can
      cost makes any collision return less than any way of finishing.
    * **Gradient everywhere.** The v0 terms saturate: the speed term is 0 for any speed
      20 % off the set speed (a parked ego gets nothing for moving), and the lag term is
      -0.5 for any gap beyond twice the band's far edge (300 m behind is as bad as 60 m).
      Here the speed term keeps a slope beyond 20 % and also applies while far behind a
      followable vehicle (an ACC drives at its set speed until it closes in), and the lag
      term grows without a plateau.

    The terms from ``overspeed`` on are off in the ``-v1`` ids' own reward (weight 0), and
    so is the switch ``behind_outside_margin``; an env's ``reward_fn=`` takes the weights as a
    mapping. The shipped PPO training settings (``agents/rl/hyperparams/ppo.yml``,
    ``env_kwargs: {reward_fn: {...}}``) turn on all but ``standstill`` and ``release``. What
    each term is for:

    * **reach** fills the dead zone just beyond the band: between its far edge
      (``1.2 Gapsafe``) and the lag's start (``D = 1.2 Gapsafe + 5 m`` at equal speeds) no
      other term pays anything, and past ``D`` the lag's slope is about ``0.5 / D`` per metre
      (0.01 at 90 km/h). A following sample's order by its gap is unchanged: inside the band
      is still best.
    * **overspeed** charges any speed above the set speed, following or not (an ACC never
      exceeds it).
    * **behind** charges every step far behind a followable vehicle, where the speed term
      pays up to ``+1`` for driving at the set speed (so that a parked or far-behind ego has
      a gradient): with ``behind`` equal to the speed weight, being far behind never pays
      more than 0, and closing in from there to the band never loses reward (without it the
      reward drops by up to 1 at the lag's start, where the speed term stops).
    * **standstill** charges closing on a stopped vehicle so that a stop at the proper
      response would end within ``standstill_gap``, and standing there: behind a stopped
      vehicle no other term applies (it is neither followable nor free). Like ``lag`` it sees
      a vehicle at any distance ahead (a training signal, not a sensor); a vehicle ahead at
      0.5-1 m/s is neither stopped nor followable, and no term covers it.
    * **demand** grades braking beyond the proper response: ``response`` is silent once the
      ego brakes at 2 m/s^2 or more, while ``comfort`` charges ``0.1 (a / 3)^2`` a step, so
      releasing from 5.3 to 2.1 m/s^2 earns 0.26 a step however high ``a_req`` is; with
      ``demand`` 1 the same release costs 0.91 a step (at ``a_req`` 3.1). The score's optimum
      is not moved: its proper response asks for 2 m/s^2 or more while ``Q < 0``, and braking
      at ``a_req`` meets it (a collision scores 0).
    * **release** charges the half of the jerk that lets go of the brake while ``Q < 0``:
      ``release`` 0.08 on top of ``jerk`` 0.02 charges a release inside Gapsafe what ``jerk``
      0.1 would and braking harder what 0.02 does. The score's optimum is not moved: inside
      Gapsafe the score asks for braking at 2 m/s^2 or more, and a smooth release meets it.
    * **let_go** is ``release`` restricted to a release that ends weaker than the proper
      response (``a > -a_resp``), which the score already counts as an improper response:
      easing from a hard brake to 2 m/s^2 or more costs only ``jerk``.

    What each term was tried against and how it did in PPO and SAC training:
    ``docs/design/margin-reward-terms.md``.
    """

    band: float = 1.0
    efficiency: float = 1.0
    speed: float = 1.0
    response: float = 1.0
    comfort: float = 0.1
    jerk: float = 0.02
    safety: float = 2.0
    collision: float = 100.0
    lag: float = 0.5
    overspeed: float = 0.0  # 0: off in the -v1 ids' reward; the shipped PPO training turns it on
    overspeed_scale: float = 0.1  # [-] the overspeed term charges w per this share of the set speed over it
    reach: float = 0.0  # 0: off in the -v1 ids' reward; the shipped PPO training turns it on
    behind: float = 0.0  # 0: off in the -v1 ids' reward; the shipped PPO training turns it on
    standstill: float = 0.0  # 0: off in the -v1 ids' reward and in the shipped PPO training
    demand: float = 0.0  # 0: off in the -v1 ids' reward; the shipped PPO training turns it on
    release: float = 0.0  # 0: off in the -v1 ids' reward and in the shipped PPO training
    let_go: float = 0.0  # 0: off in the -v1 ids' reward; the shipped PPO training turns it on
    stop_demand: float = 0.0  # 0: off in the -v1 ids' reward; the shipped PPO training turns it on
    # False (the -v1 ids' reward): far behind counted inside Gapsafe too; the shipped PPO training sets True
    behind_outside_margin: bool = False
    standstill_gap: float = 3.0  # [m] the standstill term charges a stop (at the proper response) closer than this
    peak: float = 0.5  # [-] u_t where the efficiency tent is highest (0: the safety boundary, 1: the band's far edge)
    slope: float = 0.25  # [-] the speed term's slope beyond 20 % off the set speed, per 20 %
    response_decel: float = 2.0  # [m/s^2] braking that counts as a proper response (ScoringConfig.response_decel)
    jerk_scale: float = 10.0  # [m/s^3]

    TERMS = ("band", "efficiency", "speed", "response", "comfort", "jerk", "safety", "collision", "lag", "overspeed",
             "reach", "behind", "standstill", "demand", "release", "let_go", "stop_demand")

    def __post_init__(self) -> None:
        _check_weights(self, ("response_decel", "jerk_scale", "overspeed_scale", "standstill_gap"))
        if not 0.0 <= self.peak <= 1.0:
            raise ValueError(f"MarginReward.peak must be in [0, 1] (a position in the band), got {self.peak!r}")
        from acc_gym.envs._kernel import MARGIN_W

        # the weights and constants of the compiled terms (acc_gym.envs._kernel.margin_reward_rows),
        # computed once: the environment core's fast path for this reward
        object.__setattr__(self, "_w", np.array([float(getattr(self, name)) for name in MARGIN_W], dtype=float))

    A_COUNTED = 9.0  # [m/s^2] the comfort term counts |a| up to this (about the tyre limit)
    JERK_COUNTED = 30.0  # [m/s^3] the jerk term counts |jerk| up to this
    E_COUNTED = 5.0  # the speed term's slope stops here (a parked ego: e = 5)
    # [m/s] a vehicle ahead slower than this is stopped (the standstill term): the score's own standing speed. A
    # vehicle is followable only above ScoringConfig.moving_speed (1 m/s): one at 0.5-1 m/s gets neither term
    STOPPED = ScoringConfig.stop_speed

    @property
    def max_step_cost(self) -> float:
        """The most the terms other than the collision can charge in one step (a_comfort 3 m/s^2)."""
        return (self.speed * self.slope * (self.E_COUNTED - 1.0) + self.response + self.comfort * (self.A_COUNTED / 3.0) ** 2
                + self.jerk * (self.JERK_COUNTED / self.jerk_scale) ** 2 + self.safety + self.lag
                + self.overspeed * self.E_COUNTED + self.reach + self.behind + self.standstill + self.demand
                + (self.release + self.let_go) * (self.JERK_COUNTED / self.jerk_scale) ** 2 + self.stop_demand)

    def from_criteria(self, fl: np.ndarray, bo: np.ndarray, set_speed: np.ndarray, tau1: np.ndarray,
                      steps: np.ndarray, k: np.ndarray, a_comfort: float) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """What :meth:`__call__` returns for the :class:`StepIndicators` the environment core
        builds from the rows of :func:`acc_gym.envs._kernel.criteria`'s outputs ``fl`` and
        ``bo``, the scenes' step budgets ``steps`` and steps taken ``k`` (arrays; the collision
        term charges ``max(steps - k, 0)`` steps left), in one compiled call
        (:func:`acc_gym.envs._kernel.margin_reward_rows`), which the environment core runs
        inside its step (:meth:`compiled_terms`)."""
        from acc_gym.envs import _kernel as K

        n = fl.shape[1]
        terms = np.empty((len(K.MARGIN_TERMS), n))
        reward = np.empty(n)
        K.margin_reward_rows(fl, bo, set_speed, tau1, steps, k, float(a_comfort), self._w, terms, reward)
        return reward, dict(zip(K.MARGIN_TERMS, terms))

    def compiled_terms(self) -> tuple[int, np.ndarray, tuple[str, ...]] | None:
        """``(code, weights, term names)`` of the compiled terms the environment core computes
        inside its step (:func:`acc_gym.envs._kernel.margin_reward_rows`), as
        :meth:`CriteriaReward.compiled_terms`: None for a subclass that overrides :meth:`__call__`
        or :meth:`from_criteria` and not this."""
        from acc_gym.envs import _kernel as K

        kind = type(self)
        if kind.__call__ is not MarginReward.__call__ or kind.from_criteria is not MarginReward.from_criteria:
            return None
        return K.REWARD_MARGIN, self._w, K.MARGIN_TERMS

    def __call__(self, s: StepIndicators) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """``(reward, terms)`` for one step of ``n`` scenes, in one compiled pass
        (:meth:`from_criteria`); ``steps_left`` None: no steps left to charge a collision."""
        if s.followable is None or s.v_lead is None or s.tau1 is None:
            raise ValueError("MarginReward needs the indicators followable, v_lead and tau1 (acc_gym's environments "
                             "give them)")
        if s.a_lead is None and self.stop_demand:
            raise ValueError("MarginReward.stop_demand needs the indicator a_lead (acc_gym's environments give it)")
        fl, bo, set_speed, tau1 = _rows(s)
        n = fl.shape[1]
        steps_left = np.ascontiguousarray(np.broadcast_to(np.asarray(0.0 if s.steps_left is None else s.steps_left,
                                                                     dtype=float), (n,)))
        return self.from_criteria(fl, bo, set_speed, tau1, steps_left, np.zeros(n), s.a_comfort)
