"""Top-view frames of a single-lane world, drawn with plain numpy (no matplotlib needed).

:func:`render_frame` draws one scene as an RGB ``uint8`` image ``(height_px, width_px, 3)``:
grey asphalt with ``road.n_lanes`` lanes (solid edge lines, white dashed lane lines, the
dashes fixed to the road so they scroll as the ego moves), the vehicles as filled
rectangles with a dark outline, the ego in blue and the others coloured by their MPC
driver's :class:`~acc_gym.drivers.mpc.Mode` (grey: no mode). Travel is to the right;
lane 0 (the rightmost) is at the bottom.

Geometry (see :class:`View`): the window follows the ego, from ``x_ego - view_behind`` at
the left edge to ``x_ego + view_ahead`` at the right edge, so ``sx = width_px / (view_behind
+ view_ahead)`` px/m. Vertically, with ``aspect="fill"`` (default) the road fills the frame
between two verges of ``margin = max(2, height_px // 10)`` px each, so ``sy = (height_px -
2 margin) / (n_lanes lane_width)`` px/m -- usually larger than ``sx``: the picture is
stretched sideways so lane positions stay readable in a wide, flat frame (at the
defaults a car looks about square). ``aspect="equal"`` uses ``sy = sx`` (true
proportions) and centres the road vertically. A vehicle occupies columns
``[round(col(x - length)), round(col(x)))`` and rows ``[round(row(y + width/2)),
round(row(y - width/2)))``; the frame's top is the road's left edge.

:class:`HumanViewer` shows frames in a matplotlib window; it imports pyplot only on the
first :meth:`HumanViewer.show`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from acc_gym.drivers.mpc import Mode

# colours (R, G, B)
VERGE = (104, 124, 88)
ASPHALT = (88, 88, 92)
LINE = (255, 255, 255)
OUTLINE = (20, 20, 24)
EGO = (40, 110, 235)
NO_MODE = (175, 175, 175)
MODE_COLOURS = {
    int(Mode.ACCELERATE): (40, 190, 60),  # green
    int(Mode.SAIL): (240, 210, 40),  # yellow
    int(Mode.BRAKE): (245, 120, 20),  # orange
    int(Mode.EMERGENCY): (225, 30, 200),  # magenta
}
_PALETTE = np.array([NO_MODE] + [MODE_COLOURS[m] for m in sorted(MODE_COLOURS)], dtype=np.uint8)  # index mode + 1

DASH = 6.0  # [m] painted length of a lane-line dash
DASH_PERIOD = 18.0  # [m] dash + gap
LINE_WIDTH = 0.15  # [m] painted line width (drawn at least 1 px)
SPEED_BAR_MAX = 50.0  # [m/s] speed at which the ego's speed bar spans a quarter of the frame


@dataclass(frozen=True)
class View:
    """Metres -> pixels for one frame: ``col(x) = (x - x_left) sx``, ``row(y) = margin + (y_top - y) sy``."""

    x_left: float  # [m] world x at the frame's left edge
    sx: float  # [px/m] horizontal scale
    y_top: float  # [m] lateral position of the road's left (top) edge
    sy: float  # [px/m] vertical scale
    margin: float  # [px] verge above (and below) the road

    def col(self, x):
        return (np.asarray(x, dtype=float) - self.x_left) * self.sx

    def row(self, y):
        return self.margin + (self.y_top - np.asarray(y, dtype=float)) * self.sy


def make_view(x_ego: float, road, width_px: int, height_px: int, view_behind: float, view_ahead: float,
              aspect: str = "fill") -> View:
    """The :class:`View` of a frame following the ego at ``x_ego`` [m] on ``road``."""
    return _view(float(x_ego), int(road.n_lanes), float(road.lane_width), width_px, height_px,
                 float(view_behind), float(view_ahead), aspect)


def _view(x_ego, n_lanes, lane_width, width_px, height_px, view_behind, view_ahead, aspect) -> View:
    sx = width_px / (view_behind + view_ahead)
    road_m = n_lanes * lane_width  # [m] the road's width
    if aspect == "fill":
        margin = float(max(2, height_px // 10))
        sy = (height_px - 2 * margin) / road_m
    elif aspect == "equal":
        sy = sx
        margin = 0.5 * (height_px - road_m * sy)
    else:
        raise ValueError(f"aspect must be 'fill' or 'equal', got {aspect!r}")
    return View(x_left=x_ego - view_behind, sx=sx, y_top=(n_lanes - 0.5) * lane_width, sy=sy, margin=margin)


def _line_rows(view: View, y: float, height_px: int) -> tuple[int, int]:
    """Rows ``[r0, r1)`` of a painted line centred on lateral position ``y`` [m], clipped to the frame."""
    t = max(1, int(round(LINE_WIDTH * view.sy)))  # [px]
    r0 = int(round(float(view.row(y)) - 0.5 * t))
    return min(max(r0, 0), height_px), min(max(r0 + t, 0), height_px)


@lru_cache(maxsize=16)
def _background(view: View, width_px: int, height_px: int, n_lanes: int, lane_width: float) -> np.ndarray:
    """The static part of a frame (verges, asphalt, edge lines), read-only (``view``: only its rows matter)."""
    colours = np.empty((height_px, 3), dtype=np.uint8)
    colours[:] = VERGE
    colours[max(0, int(round(view.margin))):max(0, int(round(height_px - view.margin)))] = ASPHALT
    for k in (0, n_lanes):  # road edges: solid
        r0, r1 = _line_rows(view, (k - 0.5) * lane_width, height_px)
        colours[r0:r1] = LINE
    frame = np.ascontiguousarray(np.broadcast_to(colours[:, None, :], (height_px, width_px, 3)))
    frame.flags.writeable = False
    return frame


def _vector(name: str, value, n: int, dtype=float) -> np.ndarray:
    arr = np.asarray(value)
    if arr.ndim > 1:
        raise ValueError(f"{name} must be a scalar or 1-D array over the {n} slots, got shape {arr.shape}")
    try:
        arr = np.broadcast_to(arr, (n,)).astype(dtype)
    except (ValueError, TypeError):
        raise ValueError(f"{name} must have shape ({n},) like x, got shape {arr.shape}") from None
    if dtype is float and not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr}")
    return arr


def _check_int(name: str, value, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    return int(value)


def render_frame(x, y, present, lengths, widths, road, modes=None, v=None, *, ego: int = 0,
                 width_px: int = 640, height_px: int = 160, view_behind: float = 30.0,
                 view_ahead: float = 120.0, aspect: str = "fill", text=None) -> np.ndarray:
    """One scene as an RGB ``uint8`` array ``(height_px, width_px, 3)`` (see the module docstring).

    ``x`` [m] front bumpers, ``y`` [m] lateral centres, ``present`` (bool), ``lengths`` and
    ``widths`` [m]: 1-D over the slots (``lengths``, ``widths``, ``y`` may be scalars).
    ``road`` a :class:`~acc_gym.simulation.single_lane.Road`. ``modes``: each slot's MPC
    mode (``-1`` none; default none) colours the non-ego vehicles. ``v`` [m/s]: if given,
    the ego's speed is drawn as a bar in the top-left verge (a quarter of the width at
    50 m/s). ``ego``: the slot the window follows (drawn in blue). ``aspect``: ``"fill"``
    (the road fills the height) or ``"equal"`` (true proportions). Vehicles partly outside
    the window are clipped; absent ones are not drawn. ``text`` is accepted so callers can
    pass a caption through but is not drawn (no font here; :class:`HumanViewer` shows it
    as the window title).
    """
    x = np.asarray(x, dtype=float)
    if x.ndim != 1 or x.size == 0:
        raise ValueError(f"x must be a non-empty 1-D array over the slots, got shape {x.shape}")
    n = x.size
    if not np.all(np.isfinite(x)):
        raise ValueError(f"x must be finite, got {x}")
    y = _vector("y", y, n)
    present = _vector("present", present, n, dtype=bool)
    lengths = _vector("lengths", lengths, n)
    widths = _vector("widths", widths, n)
    if np.any(lengths <= 0) or np.any(widths <= 0):
        raise ValueError(f"lengths and widths must be > 0, got lengths={lengths}, widths={widths}")
    if modes is None:
        modes = np.full(n, -1, dtype=np.int64)
    else:
        raw = np.asarray(modes)
        if raw.dtype.kind == "f" and not np.all(np.isfinite(raw)):
            raise ValueError(f"modes must be finite integers in -1..3, got {raw}")
        modes = _vector("modes", raw, n, dtype=np.int64)
        if np.any((modes < -1) | (modes >= len(_PALETTE) - 1)) or np.any(raw != modes):
            raise ValueError(f"modes must be integers in -1..{len(_PALETTE) - 2} (-1: no mode), got {raw}")
    if v is not None:
        v = _vector("v", v, n)
    if not hasattr(road, "n_lanes") or not hasattr(road, "lane_width"):
        raise ValueError(f"road must be a Road (with n_lanes and lane_width), got {road!r}")
    ego = _check_int("ego", ego, 0)
    if ego >= n:
        raise ValueError(f"ego must be a slot index < {n}, got {ego}")
    width_px = _check_int("width_px", width_px, 8)
    height_px = _check_int("height_px", height_px, 8)
    for name, value in (("view_behind", view_behind), ("view_ahead", view_ahead)):
        if not isinstance(value, (int, float, np.integer, np.floating)) or not 0 <= value < np.inf:
            raise ValueError(f"{name} must be finite and >= 0 [m], got {value!r}")
    if not view_behind + view_ahead > 0:
        raise ValueError(f"view_behind + view_ahead must be > 0, got {view_behind!r} + {view_ahead!r}")
    if text is not None and not isinstance(text, str):
        raise ValueError(f"text must be a str or None, got {type(text).__name__}")

    view = make_view(x[ego], road, width_px, height_px, float(view_behind), float(view_ahead), aspect)
    rows_only = View(0.0, 1.0, view.y_top, view.sy, view.margin)  # cache key: the background has no x
    frame = _background(rows_only, width_px, height_px, int(road.n_lanes), float(road.lane_width)).copy()

    # dashed lane lines, dashes fixed in world x
    if road.n_lanes > 1:
        x_cols = view.x_left + (np.arange(width_px) + 0.5) / view.sx  # [m] column centres
        dashed = np.mod(x_cols, DASH_PERIOD) < DASH
        for k in range(1, int(road.n_lanes)):
            r0, r1 = _line_rows(view, (k - 0.5) * road.lane_width, height_px)
            frame[r0:r1, dashed] = LINE

    # vehicles (the ego last, on top)
    c0 = np.rint(view.col(x - lengths)).astype(np.int64)
    c1 = np.maximum(np.rint(view.col(x)).astype(np.int64), c0 + 1)
    r0 = np.rint(view.row(y + 0.5 * widths)).astype(np.int64)
    r1 = np.maximum(np.rint(view.row(y - 0.5 * widths)).astype(np.int64), r0 + 1)
    colours = _PALETTE[modes + 1]
    colours[ego] = EGO
    order = [s for s in range(n) if s != ego] + [ego]
    for s in order:
        if not present[s] or c1[s] <= 0 or c0[s] >= width_px or r1[s] <= 0 or r0[s] >= height_px:
            continue
        if c1[s] - c0[s] >= 3 and r1[s] - r0[s] >= 3:  # outline, then fill inside it (each clipped)
            frame[max(r0[s], 0):r1[s], max(c0[s], 0):c1[s]] = OUTLINE
            frame[max(r0[s] + 1, 0):r1[s] - 1, max(c0[s] + 1, 0):c1[s] - 1] = colours[s]
        else:
            frame[max(r0[s], 0):r1[s], max(c0[s], 0):c1[s]] = colours[s]

    if v is not None:  # the ego's speed bar in the top verge
        bar_h = max(1, min(6, int(view.margin) // 3))  # [px]
        top = max(0, (int(view.margin) - bar_h) // 2)
        full = width_px // 4
        frame[top:top + bar_h, 2:2 + full] = OUTLINE
        length = int(round(min(max(v[ego], 0.0) / SPEED_BAR_MAX, 1.0) * full))
        frame[top:top + bar_h, 2:2 + length] = EGO
    return frame


def frame_from_world(world, b: int = 0, modes=None, **kw) -> np.ndarray:
    """:func:`render_frame` of scene ``b`` of a :class:`~acc_gym.simulation.single_lane.SingleLaneWorld`.

    ``modes`` (``(S,)``, ``-1`` none): the caller's; by default each slot's driver's last
    ``info["mode"]`` (``-1`` where a slot has no model or no mode, and before the first step
    after a reset, when ``info`` is empty or left over from the previous episode).
    ``kw`` go to :func:`render_frame` (``v`` defaults to the world's speeds).
    """
    B, S = world.x.shape
    if isinstance(b, bool) or not isinstance(b, (int, np.integer)) or not 0 <= b < B:
        raise ValueError(f"b must be a scene index in 0..{B - 1}, got {b!r}")
    if modes is None:
        modes = np.full(S, -1, dtype=np.int64)
        stepped = np.broadcast_to(getattr(world, "k", 1), (B,))[b] > 0  # scene b's step count (scalar or (B,))
        for s, model in enumerate(getattr(world, "drivers", []) if stepped else []):
            info = (getattr(model, "info", None) or {}) if model is not None else {}
            if "mode" in info:
                modes[s] = int(np.asarray(info["mode"]).reshape(-1)[b])
    kw.setdefault("v", world.v[b])
    return render_frame(world.x[b], world.y[b], world.present[b], world.lengths[b], world.width[b], world.road,
                        modes, **kw)


class HumanViewer:
    """Shows frames in a matplotlib window (interactive mode), reusing one image.

    Nothing is imported or opened until the first :meth:`show`; closing the window and
    showing again opens a new one. Use as a context manager or call :meth:`close`.
    """

    def __init__(self, title: str = "acc_gym"):
        self.title = title
        self._plt = None
        self._fig = None
        self._image = None

    def show(self, frame: np.ndarray, text: str | None = None) -> None:
        """Display ``frame`` (``(H, W, 3)`` uint8); ``text`` becomes the axes title."""
        frame = np.asarray(frame)
        if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
            raise ValueError(f"frame must be an (H, W, 3) uint8 array, got {frame.dtype} {frame.shape}")
        if self._plt is None:
            import matplotlib.pyplot as plt

            self._plt = plt
        plt = self._plt
        if self._fig is None or not plt.fignum_exists(self._fig.number) or self._image.get_array().shape != frame.shape:
            if self._fig is not None:
                plt.close(self._fig)
            plt.ion()
            h, w = frame.shape[:2]
            self._fig = plt.figure(self.title, figsize=(w / 100, h / 100 + 0.3), dpi=100)
            ax = self._fig.add_axes((0, 0, 1, h / (h + 30)))
            ax.set_axis_off()
            self._image = ax.imshow(frame, interpolation="nearest")
        else:
            self._image.set_data(frame)
        self._image.axes.set_title(text or "", fontsize=9)
        self._fig.canvas.draw_idle()
        with warnings.catch_warnings():  # a non-interactive backend (Agg) warns that it cannot show
            warnings.filterwarnings("ignore", message=".*non-interactive.*", category=UserWarning)
            plt.pause(1e-3)

    def close(self) -> None:
        """Close the window (if any); the viewer can show again afterwards."""
        if self._fig is not None:
            self._plt.close(self._fig)
        self._fig = self._image = None

    def __enter__(self) -> "HumanViewer":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
