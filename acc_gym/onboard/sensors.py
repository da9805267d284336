"""The radar between the world and a controller's observation of the vehicle ahead.

Without a sensor model (``SensorConfig()``, the ``ideal`` preset) the observation's gap,
relative speed and in-range flag (fields 2-4) are the true ones of the current step, as
far as the environment's ``sensor_range``. With one, each step of each scene runs:

1. **Detection.** A vehicle ahead is *visible* when it is within the radar's range and in
   its beam: two beams like a long-range radar's, far (``far_range``, full azimuth
   ``far_fov``) and near (``near_range``, ``near_fov``), from the middle of the ego's front
   bumper. A vehicle is in a beam when its nearest lateral edge (its lateral offset from
   the ego's centre line less half its width, at least 0) is within ``gap tan(fov / 2)``:
   a vehicle cutting in close ahead is acquired only once it has moved into the beam. The
   target is the vehicle ahead in the ego's lane (the world's lead) when visible, else the
   second vehicle ahead when visible (a real radar keeps its old target until the cut-in
   is acquired).
2. **Dropouts** come in bursts: a two-state Markov chain per scene (Gilbert's channel),
   from "detecting" to "dropped" with probability ``p`` per step and back with ``r``;
   ``r = min(1, dt / dropout_burst)`` (bursts last ``dropout_burst`` seconds on average,
   geometrically distributed in steps) and ``p = r share / (1 - share)``, so that the long-run
   share of dropped steps is ``dropout_share``. A dropped step detects nothing.
3. **Errors.** A detection measures ``gap + gap_bias + gap_sd N(0, 1)`` [m] and
   ``v_rel + rate_bias + rate_sd N(0, 1)`` [m/s], independent normal draws each step.
4. **Track.** The controller sees the radar's track: the last detection; when a step
   detects nothing, the track coasts at its relative speed (``gap += v_rel dt``, the
   constant-velocity prediction of an alpha-beta tracker with no measurement) for up to
   ``coast`` seconds, then is dropped (the observation shows nothing in range). ``coast = 0``
   drops it at once.
5. **Latency.** The observation at step ``k`` shows the track of step ``k - L``,
   ``L = ceil(latency / dt)`` steps: the newest track that has arrived by then (a 0.1 s
   latency at the 0.2 s step delays by one step).

The ego's own speed and acceleration (wheel speeds and an inertial sensor, far more
accurate than the radar) and the set speed and time gap are not changed.

**Randomness.** Each scene's draws come from its own generator, which the environment spawns
from the scene's generator at every reset (:meth:`numpy.random.Generator.spawn`: the scene's
own stream, and so its scenarios, stay those without a sensor model). Draws are made in blocks of
:data:`BLOCK` steps: the block's uniforms for the chain, then its two normals per step (so a
scene's numbers depend on :data:`BLOCK`, which is a constant of the model, not a setting).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from acc_gym.onboard import _radar_kernel as K

BLOCK = 256  # steps of draws made at once per scene
MAX_DROPOUT_SHARE = 0.9  # a scaled dropout share is capped here


def _number(cls: str, name: str, value, low: float, high: float, *, low_open: bool = False,
            high_open: bool = False, unit: str = "") -> float:
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    if ok:
        v = float(value)
        ok = not math.isnan(v) and (v > low if low_open else v >= low) and (v < high if high_open else v <= high)
    if not ok:
        lo, hi = ("(" if low_open else "["), (")" if high_open else "]")
        raise ValueError(f"{cls}.{name} must be a number{unit} in {lo}{low:g}, {high:g}{hi}, got {value!r}")
    return v


@dataclass(frozen=True)
class SensorConfig:
    """A radar's range, beams, errors, dropouts, track coasting and latency; validated on
    construction (a value out of its range is a ``ValueError`` naming it). The defaults are
    the ideal sensor (module docstring)."""

    far_range: float = math.inf  # [m] the far beam's reach
    far_fov: float = 180.0  # [deg] the far beam's full azimuth
    near_range: float = 0.0  # [m] the near beam's reach (0: no near beam)
    near_fov: float = 180.0  # [deg] the near beam's full azimuth
    gap_sd: float = 0.0  # [m] standard deviation of the gap's error
    gap_bias: float = 0.0  # [m] the gap's constant error
    rate_sd: float = 0.0  # [m/s] standard deviation of the relative speed's error
    rate_bias: float = 0.0  # [m/s] the relative speed's constant error
    dropout_share: float = 0.0  # [-] long-run share of steps that detect nothing
    dropout_burst: float = 0.0  # [s] mean length of a dropout burst
    coast: float = 0.0  # [s] how long the track coasts through missed detections
    latency: float = 0.0  # [s] from measurement to observation

    def __post_init__(self) -> None:
        c = "SensorConfig"
        object.__setattr__(self, "far_range", _number(c, "far_range", self.far_range, 0.0, math.inf, low_open=True,
                                                      unit=" of metres"))
        object.__setattr__(self, "near_range", _number(c, "near_range", self.near_range, 0.0, math.inf,
                                                       unit=" of metres"))
        for name in ("far_fov", "near_fov"):
            object.__setattr__(self, name, _number(c, name, getattr(self, name), 0.0, 180.0, low_open=True,
                                                   unit=" of degrees"))
        for name, top in (("gap_sd", 50.0), ("rate_sd", 20.0)):
            object.__setattr__(self, name, _number(c, name, getattr(self, name), 0.0, top))
        for name, top in (("gap_bias", 50.0), ("rate_bias", 20.0)):
            object.__setattr__(self, name, _number(c, name, getattr(self, name), -top, top))
        object.__setattr__(self, "dropout_share", _number(c, "dropout_share", self.dropout_share, 0.0, 1.0,
                                                          high_open=True))
        for name in ("dropout_burst", "coast", "latency"):
            object.__setattr__(self, name, _number(c, name, getattr(self, name), 0.0, 60.0, unit=" of seconds"))
        if self.dropout_share > 0 and self.dropout_burst <= 0:
            raise ValueError(f"SensorConfig.dropout_burst must be > 0 s when dropout_share > 0 "
                             f"(got dropout_share={self.dropout_share!r}, dropout_burst={self.dropout_burst!r})")

    @property
    def ideal(self) -> bool:
        """The true values of the current step (nothing to model)."""
        return self == SensorConfig()

    def latency_steps(self, dt: float) -> int:
        """``L = ceil(latency / dt)`` (a latency within 1e-9 of a whole number of steps is that number)."""
        return int(math.ceil(self.latency / dt - 1e-9))

    def chain(self, dt: float, share: float | None = None) -> tuple[float, float]:
        """``(p, r)``: the per-step probabilities of a dropout starting and ending, for the
        config's dropout share or ``share`` in its place."""
        share = self.dropout_share if share is None else share
        if share == 0.0:
            return 0.0, 1.0
        r = min(1.0, dt / self.dropout_burst)
        return min(1.0, r * share / (1.0 - share)), r


class Radar:
    """The radars of ``n`` scenes (module docstring for what one step does; the step is
    :func:`acc_gym.onboard._radar_kernel.sense`, over the records :attr:`radar` and
    :attr:`scenes`).

    :meth:`reset` starts scenes; :meth:`sense` advances every scene by one step from the
    world's true state and returns the observed fields."""

    def __init__(self, config: SensorConfig, n: int, dt: float, obs_range: float):
        self.config = config
        self.n = int(n)
        self.dt = float(dt)
        self.obs_range = float(obs_range)  # [m] the observation's gap for nothing in range
        p_start, p_end = config.chain(self.dt)

        def tan(fov):
            return math.tan(math.radians(fov) / 2.0) if fov < 180.0 else math.inf

        self.L = config.latency_steps(self.dt)
        self.radar = np.zeros(1, dtype=K.RADAR)  # the radar-wide record
        for name, value in (("far_reach", min(config.far_range, self.obs_range)), ("far_tan", tan(config.far_fov)),
                            ("near_reach", min(config.near_range, self.obs_range)), ("near_tan", tan(config.near_fov)),
                            ("gap_sd", config.gap_sd), ("gap_bias", config.gap_bias), ("rate_sd", config.rate_sd),
                            ("rate_bias", config.rate_bias), ("p_end", p_end), ("coast", config.coast),
                            ("dt", self.dt), ("obs_range", self.obs_range), ("latency", self.L)):
            self.radar[name] = value
        n = self.n
        self.scenes = np.zeros(n, dtype=K.SCENE)  # one record per scene
        self.scenes["gap"], self.scenes["scale"] = self.obs_range, 1.0
        self.scenes["share"], self.scenes["p_start"], self.scenes["pos"] = config.dropout_share, p_start, BLOCK
        self.reports = np.zeros((self.L + 1, n, 3))  # the reports of the last L + 1 steps
        self.draws = np.zeros((n, BLOCK, 3))  # each scene's next draws: uniform, normal, normal
        self._rngs: list[np.random.Generator | None] = [None] * n
        self._all = np.arange(n, dtype=np.int64)
        # the largest next draw position of any scene (BLOCK: some block is used up), which the kernel writes
        self.pos_max = np.full(1, BLOCK, dtype=np.int64)

    def _refill(self, rows: np.ndarray) -> None:
        """New blocks of draws for the scenes of ``rows`` that have used theirs."""
        pos = self.scenes["pos"]
        for r in rows[pos[rows] >= BLOCK].tolist():
            rng = self._rngs[r]
            if rng is None:
                raise RuntimeError(f"scene {r}'s radar has not been reset")
            self.draws[r, :, 0] = rng.random(BLOCK)
            self.draws[r, :, 1:] = rng.standard_normal((BLOCK, 2))
            pos[r] = 0

    def reset(self, rows, rngs, truth, scales=None) -> np.ndarray:
        """Start scenes ``rows`` with their radars' generators ``rngs`` in the world's state
        ``truth`` (:meth:`sense`'s), each with its multiple ``scales[j]`` of the config's errors
        and dropout share (None: 1); returns their observed ``(len(rows), 3)``. The chain starts
        in its long-run distribution; the latency's buffer holds the first report."""
        rows = np.asarray(rows, dtype=np.int64)
        sc = self.scenes
        for j, r in enumerate(rows.tolist()):
            self._rngs[r] = rngs[j]
            c = 1.0 if scales is None else float(scales[j])
            share = min(self.config.dropout_share * c, MAX_DROPOUT_SHARE)
            rec = sc[r]  # (a structured scalar: a view of the scene's record)
            rec["pos"], rec["scale"], rec["share"], rec["p_start"] = BLOCK, c, share, self.config.chain(self.dt, share)[0]
        self._refill(rows)
        out = np.empty((rows.shape[0], 3))
        K.sense(self.radar, sc, self.reports, self.draws, *truth, rows, True, out)
        self.pos_max[0] = sc["pos"].max()
        return out

    def ready(self) -> None:
        """Make sure every scene has a draw left for the next step (new blocks for those that
        used theirs up): before each :meth:`sense` or compiled step of the radar."""
        if self.pos_max[0] >= BLOCK:
            self._refill(self._all)

    def sense(self, truth) -> np.ndarray:
        """One step of every scene in the world's state ``truth`` (``obs, y, width, lead, lead2``:
        :func:`acc_gym.onboard._radar_kernel.sense`'s world arrays); the observed ``(n, 3)``: gap
        [m], relative speed [m/s] and in-range flag."""
        self.ready()
        out = np.empty((self.n, 3))
        self.pos_max[0] = K.sense(self.radar, self.scenes, self.reports, self.draws, *truth, self._all, False, out)
        return out
