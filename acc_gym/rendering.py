"""Top-view frames of a single-lane world: numpy drawing, text from matplotlib's font.

:func:`render_frame` draws one scene as an RGB ``uint8`` image ``(height_px, width_px, 3)``
(default :data:`FRAME_SHAPE`): grey asphalt with ``road.n_lanes`` lanes (solid edge lines,
white dashed lane lines, the dashes fixed to the road so they scroll as the ego moves), the
vehicles as filled rectangles with a dark outline, the ego in blue and the others coloured
by their MPC driver's :class:`~acc_gym.drivers.mpc.Mode` (grey: no mode), each vehicle's
speed [km/h] written above it, the gap from the ego's front bumper to its lead's rear
bumper drawn as a cyan line along the ego's lane centre with its length [m], and, with a
:class:`Hud`, a head-up display strip at the top: ego speed, set speed, gap, time gap,
the time gap Q is judged at, Q, time and the lead driver's mode. Travel is to the right;
lane 0 (the rightmost) is at the bottom.

Geometry (see :class:`View`): the road scene fills the rows below the HUD strip
(``hud_rows`` of them, 0 without a HUD; :func:`hud_rows`); below, "row" is a row of that
scene, frame row ``hud_rows + row``. The window follows the ego, from ``x_ego -
view_behind`` at the left edge to ``x_ego + view_ahead`` at the right edge, so ``sx =
width_px / (view_behind + view_ahead)`` px/m. Vertically, with ``aspect="fill"`` (default)
the road fills the scene between two verges of ``margin = max(2, scene_px // 10)`` px
each (``scene_px = height_px - hud_rows``), so ``sy = (scene_px - 2 margin) / (n_lanes
lane_width)`` px/m -- usually larger than ``sx``: the picture is stretched sideways so lane
positions stay readable in a wide, flat frame. ``aspect="equal"`` uses ``sy = sx`` (true
proportions) and centres the road vertically. A vehicle occupies columns
``[round(col(x - length)), round(col(x)))`` and rows ``[round(row(y + width/2)),
round(row(y - width/2)))``; the scene's top is the road's left edge. The gap line fills
columns ``[round(col(x_ego)), round(col(x_lead - length_lead)))`` -- from just past the
ego's box to just before the lead's -- in rows ``round(row(y_ego)) - 1`` and
``round(row(y_ego))``.

Text is drawn with numpy from glyphs that matplotlib (its Agg renderer and its bundled
DejaVu Sans Mono, under matplotlib's default text settings whatever the user's rcParams)
rasterises once per size and process (:func:`draw_text`); the choice and its measurements
are in ``docs/design/rendering.md``. Only printable ASCII is drawn (anything else as ``?``).

:class:`HumanViewer` shows frames in a matplotlib window; it imports pyplot only on the
first :meth:`HumanViewer.show`.
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from acc_gym.drivers.mpc import Mode

FRAME_SHAPE = (200, 640, 3)  # [px] (height, width, RGB): render_frame's default and the environments' frames

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
GAP = (0, 215, 230)  # cyan: the ego's gap to its lead
LABEL = (245, 245, 245)  # vehicle speed labels
HUD_BG = (24, 26, 32)
HUD_TEXT = (235, 235, 235)
HUD_DIM = (150, 150, 160)
Q_OK = (90, 220, 110)  # Q >= 0
Q_BAD = (255, 80, 70)  # Q < 0: inside Gapsafe

DASH = 6.0  # [m] painted length of a lane-line dash
DASH_PERIOD = 18.0  # [m] dash + gap
LINE_WIDTH = 0.15  # [m] painted line width (drawn at least 1 px)
LABEL_PX = 9  # [px] font size of the vehicle and gap labels
HUD_PX = 10  # [px] font size of the HUD
HUD_PAD = 2  # [px] above and below the HUD's lines
FONT_FILE = "DejaVuSansMono.ttf"  # matplotlib's bundled monospace font
_CHARS = "".join(chr(c) for c in range(32, 127))  # printable ASCII: the glyphs drawn
_GLYPH_PAD = 2  # [px] each glyph cell's margin left and right (for overhangs)


# ---------------------------------------------------------------------------------------------- text
@dataclass(frozen=True)
class Font:
    """Glyph coverages of one size: ``atlas[ord(c) - 32]`` is ``(height, advance + 2 pad)`` in [0, 1]."""

    atlas: np.ndarray  # [-] float32 (95, height, advance + 2 pad), read-only
    advance: int  # [px] the monospace advance
    pad: int  # [px] margin of each cell left and right
    height: int  # [px] a line's height (the cell's)


@lru_cache(maxsize=8)
def font(size_px: int) -> Font:
    """The glyphs of matplotlib's DejaVu Sans Mono at ``size_px`` px (1 pt = 1 px at 72 dpi),
    rasterised once by matplotlib's Agg canvas, white on black, one cell per character."""
    size_px = _check_int("size_px", size_px, 4)
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.font_manager import FontProperties
    from matplotlib.transforms import IdentityTransform

    keys = ("text.hinting", "text.hinting_factor", "text.kerning_factor", "text.antialiased")
    with matplotlib.rc_context({k: matplotlib.rcParamsDefault[k] for k in keys if k in matplotlib.rcParamsDefault}):
        prop = FontProperties(fname=os.path.join(matplotlib.get_data_path(), "fonts", "ttf", FONT_FILE),
                              size=size_px)
        fig = Figure(dpi=72)
        canvas = FigureCanvasAgg(fig)
        width, _, _ = canvas.get_renderer().get_text_width_height_descent("M" * 10, prop, ismath=False)
        advance = max(1, int(round(width / 10)))  # [px] the hinted advance
        pad = _GLYPH_PAD
        cell = advance + 2 * pad
        height = size_px + 4
        baseline = int(math.ceil(0.24 * size_px)) + 1  # [px] from the cell's bottom: room for descenders
        fig.set_size_inches(len(_CHARS) * cell / 72, height / 72)
        fig.patch.set_facecolor("black")
        for i, c in enumerate(_CHARS):
            fig.text(i * cell + pad, baseline, c, fontproperties=prop, color="white", transform=IdentityTransform(),
                     ha="left", va="baseline")
        canvas.draw()
        coverage = np.asarray(canvas.buffer_rgba())[..., 0].astype(np.float32) / 255.0
    atlas = np.ascontiguousarray(coverage.reshape(height, len(_CHARS), cell).transpose(1, 0, 2))
    atlas.flags.writeable = False
    return Font(atlas=atlas, advance=advance, pad=pad, height=height)


def text_width(text: str, size_px: int = HUD_PX) -> int:
    """The width [px] :func:`draw_text` gives ``text`` (its glyph cells, margins included)."""
    f = font(size_px)
    return len(text) * f.advance + 2 * f.pad if text else 0


def draw_text(frame: np.ndarray, text: str, row: int, col: int, colour, size_px: int = HUD_PX,
              align: str = "left") -> int:
    """Blend ``text`` into ``frame`` (``(H, W, 3)`` uint8, in place), its line's top at ``row``;
    ``col`` its left edge (``align="left"``), centre (``"centre"``) or right edge (``"right"``).
    ``colour``: one ``(R, G, B)`` or one per character (``(len(text), 3)``). Clipped to the
    frame. Returns the column just right of the text's last glyph cell (without its margin),
    where a piece drawn next continues it."""
    f = font(size_px)
    width = text_width(text, size_px)
    if align == "centre":
        col = int(round(col - width / 2))
    elif align == "right":
        col = int(col) - width
    elif align != "left":
        raise ValueError(f"align must be 'left', 'centre' or 'right', got {align!r}")
    row, col = int(row), int(col)
    if not text:
        return col
    n = len(text)
    colours = np.asarray(colour, dtype=np.float32)
    if colours.shape not in ((3,), (n, 3)):
        raise ValueError(f"colour must be (R, G, B) or one per character ({n}, 3), got shape {colours.shape}")
    h, w = frame.shape[:2]
    r0, r1, c0, c1 = max(row, 0), min(row + f.height, h), max(col, 0), min(col + width, w)
    if r0 < r1 and c0 < c1:
        cov = _text_coverage(text, size_px)[r0 - row:r1 - row, c0 - col:c1 - col, None]
        if colours.ndim == 2:  # each column the colour of the character whose advance holds it
            chars = np.clip((np.arange(c0 - col, c1 - col) - f.pad) // f.advance, 0, n - 1)
            colours = colours[chars][None]
        region = frame[r0:r1, c0:c1].astype(np.float32)
        region += (colours - region) * cov
        frame[r0:r1, c0:c1] = (region + 0.5).astype(np.uint8)
    return col + width - 2 * f.pad


@lru_cache(maxsize=1024)
def _text_coverage(text: str, size_px: int) -> np.ndarray:
    """:func:`_coverage` of ``text``, read-only, kept for the labels and HUD pieces that repeat."""
    cov = _coverage(_codes(text), font(size_px))
    cov.flags.writeable = False
    return cov


def _codes(text: str) -> np.ndarray:
    codes = np.frombuffer(text.encode("ascii", "replace"), dtype=np.uint8).astype(np.int64) - 32
    codes[(codes < 0) | (codes >= len(_CHARS))] = ord("?") - 32
    return codes


def _coverage(codes: np.ndarray, f: Font) -> np.ndarray:
    """The glyphs of ``codes`` side by side, ``(height, n advance + 2 pad)``: cell ``i`` at
    column ``i advance``, overlapping its neighbours by the margins (their maximum)."""
    n, adv, cell = codes.size, f.advance, f.advance + 2 * f.pad
    cov = np.zeros((f.height, n * adv + 2 * f.pad), dtype=np.float32)
    if 2 * adv < cell:  # margins wider than an advance (tiny fonts): one cell at a time
        for i, c in enumerate(codes.tolist()):
            part = cov[:, i * adv:i * adv + cell]
            np.maximum(part, f.atlas[c], out=part)
        return cov
    for parity in (0, 1):  # every other cell: those do not overlap, so each half is one block copy
        sel = codes[parity::2]
        if sel.size:
            block = np.zeros((f.height, sel.size, 2 * adv), dtype=np.float32)
            block[:, :, :cell] = f.atlas[sel].transpose(1, 0, 2)
            start = parity * adv
            stop = min(start + block.shape[1] * block.shape[2], cov.shape[1])
            part = cov[:, start:stop]
            np.maximum(part, block.reshape(f.height, -1)[:, :stop - start], out=part)
    return cov


# ---------------------------------------------------------------------------------------------- HUD
@dataclass(frozen=True)
class Hud:
    """What the head-up display strip shows (a field left None is not shown)."""

    v: float  # [m/s] the ego's speed
    gap: float = math.inf  # [m] bumper to bumper to the vehicle ahead (inf: none)
    set_speed: float | None = None  # [m/s] the ego's set speed
    tau1: float | None = None  # [s] the time gap Q is judged at
    q: float | None = None  # [m] Q = gap - Gapsafe (inf: nothing ahead), info["q"]
    t: float | None = None  # [s] the scene's time
    lead_mode: int | None = None  # the lead's MPC driver mode (-1 or None: none)
    caption: str | None = None  # e.g. the scenario's id

    def __post_init__(self) -> None:
        for name in ("v", "set_speed", "tau1", "t"):
            value = getattr(self, name)
            if (value is not None or name == "v") and not (isinstance(value, (int, float, np.integer, np.floating))
                                                           and math.isfinite(value)):
                raise ValueError(f"Hud.{name} must be a finite number, got {value!r}")
        for name in ("gap", "q"):
            value = getattr(self, name)
            if value is not None and not (isinstance(value, (int, float, np.integer, np.floating))
                                          and not math.isnan(value)):
                raise ValueError(f"Hud.{name} must be a number (inf: nothing ahead), got {value!r}")
        if self.lead_mode is not None and self.lead_mode not in MODE_COLOURS and self.lead_mode != -1:
            raise ValueError(f"Hud.lead_mode must be -1, None or a Mode ({sorted(MODE_COLOURS)}), "
                             f"got {self.lead_mode!r}")
        if self.caption is not None and not isinstance(self.caption, str):
            raise ValueError(f"Hud.caption must be a str or None, got {type(self.caption).__name__}")

    def lines(self) -> list[list[tuple[str, tuple]]]:
        """The strip's lines, each a list of ``(text, colour)`` pieces drawn in turn."""
        sep = ("   ", HUD_TEXT)
        first = [(f"v {self.v * 3.6:5.1f} km/h", HUD_TEXT)]
        if self.set_speed is not None:
            first += [sep, (f"set {self.set_speed * 3.6:.0f} km/h", HUD_TEXT)]
        has = math.isfinite(self.gap)
        first += [sep, (f"gap {self.gap:5.1f} m" if has else "gap   -  ", HUD_TEXT)]
        headway = self.gap / self.v if has and self.v >= 0.1 else None  # [s]
        first += [sep, (f"time gap {headway:4.2f} s" if headway is not None and headway < 100 else "time gap  -  ",
                        HUD_TEXT)]
        if self.tau1 is not None:
            first += [(f" (tau1 {self.tau1:.2f} s)", HUD_DIM)]
        if self.q is not None:
            q_text = f"Q {self.q:+6.1f} m" if math.isfinite(self.q) else "Q   -"
            first += [sep, (q_text, Q_BAD if self.q < 0 else Q_OK if math.isfinite(self.q) else HUD_TEXT)]
        second = []
        if self.t is not None:
            second += [(f"t {self.t:5.1f} s", HUD_TEXT), sep]
        if self.lead_mode is not None and self.lead_mode >= 0:
            second += [("lead driver ", HUD_TEXT), (Mode(self.lead_mode).name.lower(), MODE_COLOURS[self.lead_mode]),
                       sep]
        if self.caption:
            second += [(self.caption, HUD_DIM)]
        return [first, second] if second else [first]


def hud_rows(hud: Hud | None, text: str | None = None) -> int:
    """The rows [px] of the HUD strip for ``hud`` and a caption ``text`` (0 for neither)."""
    n = (len(hud.lines()) if hud is not None else 0) + (1 if text else 0)
    return n * font(HUD_PX).height + 2 * HUD_PAD if n else 0


def _joined(pieces) -> tuple[str, np.ndarray]:
    """``(text, colour)`` pieces as one string and its colour per character ``(n, 3)``."""
    colours = np.repeat(np.array([c for _, c in pieces], dtype=np.float32), [len(p) for p, _ in pieces], axis=0)
    return "".join(p for p, _ in pieces), colours


def _draw_hud(strip: np.ndarray, hud: Hud | None, text: str | None) -> None:
    strip[:] = np.array(HUD_BG, dtype=np.uint8)
    lines = hud.lines() if hud is not None else []
    if text:
        lines.append([(text, HUD_TEXT)])
    h = font(HUD_PX).height
    end = 0
    for i, pieces in enumerate(lines):  # each line in one call, each piece in its colour
        line, colours = _joined(pieces)
        end = draw_text(strip, line, HUD_PAD + i * h, 4, colours)
    if hud is not None:  # the mode colours' legend, right-aligned on the last line, if there is room
        legend, colours = _joined([piece for m in Mode for piece in ((" ", HUD_TEXT), (m.name.lower(),
                                                                                      MODE_COLOURS[int(m)]))][1:])
        right = strip.shape[1] - 4
        if right - text_width(legend) > end + 16:
            draw_text(strip, legend, HUD_PAD + (len(lines) - 1) * h, right, colours, align="right")


# ---------------------------------------------------------------------------------------------- scene
@dataclass(frozen=True)
class View:
    """Metres -> pixels of a scene: ``col(x) = (x - x_left) sx``, ``row(y) = margin + (y_top - y) sy``."""

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
    """The :class:`View` of a scene ``height_px`` rows high (the frame's rows below its HUD)
    following the ego at ``x_ego`` [m] on ``road``."""
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
    """Rows ``[r0, r1)`` of a painted line centred on lateral position ``y`` [m], clipped to the scene."""
    t = max(1, int(round(LINE_WIDTH * view.sy)))  # [px]
    r0 = int(round(float(view.row(y)) - 0.5 * t))
    return min(max(r0, 0), height_px), min(max(r0 + t, 0), height_px)


@lru_cache(maxsize=16)
def _background(view: View, width_px: int, height_px: int, n_lanes: int, lane_width: float) -> np.ndarray:
    """The static part of a scene (verges, asphalt, edge lines), read-only (``view``: only its rows matter)."""
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


def render_frame(x, y, present, lengths, widths, road, modes=None, v=None, *, ego: int = 0, lead: int = -1,
                 hud: Hud | None = None, text: str | None = None, width_px: int = FRAME_SHAPE[1],
                 height_px: int = FRAME_SHAPE[0], view_behind: float = 30.0, view_ahead: float = 120.0,
                 aspect: str = "fill") -> np.ndarray:
    """One scene as an RGB ``uint8`` array ``(height_px, width_px, 3)`` (see the module docstring).

    ``x`` [m] front bumpers, ``y`` [m] lateral centres, ``present`` (bool), ``lengths`` and
    ``widths`` [m]: 1-D over the slots (``lengths``, ``widths``, ``y`` may be scalars).
    ``road`` a :class:`~acc_gym.simulation.single_lane.Road`. ``modes``: each slot's MPC
    mode (``-1`` none; default none) colours the non-ego vehicles. ``v`` [m/s]: if given,
    each drawn vehicle's speed is written above it in km/h (rounded). ``ego``: the slot the
    window follows (drawn in blue). ``lead``: the ego's vehicle ahead (``-1``: none): the gap
    from the ego's front to its rear is drawn (:data:`GAP`) with its length in metres, the
    label left out where it does not fit between the two. ``hud``: a :class:`Hud` drawn in a
    strip at the top (:func:`hud_rows` rows; the scene gets the rest); ``text``: a caption
    line in that strip (a strip of one line without ``hud``). ``aspect``: ``"fill"`` (the
    road fills the scene's height) or ``"equal"`` (true proportions). Vehicles partly
    outside the window are clipped; absent ones are not drawn.
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
    lead = _check_int("lead", lead, -1)
    if lead >= n or lead == ego:
        raise ValueError(f"lead must be -1 or a slot index < {n} other than the ego's ({ego}), got {lead}")
    width_px = _check_int("width_px", width_px, 8)
    height_px = _check_int("height_px", height_px, 8)
    for name, value in (("view_behind", view_behind), ("view_ahead", view_ahead)):
        if not isinstance(value, (int, float, np.integer, np.floating)) or not 0 <= value < np.inf:
            raise ValueError(f"{name} must be finite and >= 0 [m], got {value!r}")
    if not view_behind + view_ahead > 0:
        raise ValueError(f"view_behind + view_ahead must be > 0, got {view_behind!r} + {view_ahead!r}")
    if text is not None and not isinstance(text, str):
        raise ValueError(f"text must be a str or None, got {type(text).__name__}")
    if hud is not None and not isinstance(hud, Hud):
        raise ValueError(f"hud must be a Hud or None, got {type(hud).__name__}")
    top = hud_rows(hud, text)
    scene_px = height_px - top
    if scene_px < 8:
        raise ValueError(f"height_px must leave at least 8 rows below the HUD's {top}, got {height_px}")

    frame = np.empty((height_px, width_px, 3), dtype=np.uint8)
    if top:
        _draw_hud(frame[:top], hud, text)
    view = make_view(x[ego], road, width_px, scene_px, float(view_behind), float(view_ahead), aspect)
    rows_only = View(0.0, 1.0, view.y_top, view.sy, view.margin)  # cache key: the background has no x
    scene = frame[top:]
    scene[:] = _background(rows_only, width_px, scene_px, int(road.n_lanes), float(road.lane_width))

    # dashed lane lines, dashes fixed in world x
    if road.n_lanes > 1:
        x_cols = view.x_left + (np.arange(width_px) + 0.5) / view.sx  # [m] column centres
        dashed = np.mod(x_cols, DASH_PERIOD) < DASH
        for k in range(1, int(road.n_lanes)):
            r0, r1 = _line_rows(view, (k - 0.5) * road.lane_width, scene_px)
            scene[r0:r1, dashed] = LINE

    # vehicles' pixel boxes [c0, c1) x [r0, r1)
    c0 = np.rint(view.col(x - lengths)).astype(np.int64)
    c1 = np.maximum(np.rint(view.col(x)).astype(np.int64), c0 + 1)
    r0 = np.rint(view.row(y + 0.5 * widths)).astype(np.int64)
    r1 = np.maximum(np.rint(view.row(y - 0.5 * widths)).astype(np.int64), r0 + 1)
    visible = present & (c1 > 0) & (c0 < width_px) & (r1 > 0) & (r0 < scene_px)

    # the ego's gap to its lead, under the vehicles
    gap_label = None
    if lead >= 0 and present[lead] and present[ego]:
        g0, g1 = max(int(c1[ego]), 0), min(int(c0[lead]), width_px)
        rc = int(np.rint(view.row(y[ego])))
        if g0 < g1 and 1 <= rc < scene_px:
            scene[rc - 1:rc + 1, g0:g1] = GAP
            tick = max(1, int(r1[ego] - r0[ego]) // 4)
            for c in {g0, g1 - 1} & {int(c1[ego]), int(c0[lead]) - 1}:  # end ticks where the span is not clipped
                scene[max(rc - tick, 0):rc + tick, c] = GAP
            label = f"{x[lead] - lengths[lead] - x[ego]:.1f} m"
            if text_width(label, LABEL_PX) + 4 <= g1 - g0:
                gap_label = (label, rc + 2, (g0 + g1) / 2)

    # vehicles (the ego last, on top)
    colours = _PALETTE[modes + 1]
    colours[ego] = EGO
    order = [s for s in range(n) if s != ego] + [ego]
    for s in order:
        if not visible[s]:
            continue
        if c1[s] - c0[s] >= 3 and r1[s] - r0[s] >= 3:  # outline, then fill inside it (each clipped)
            scene[max(r0[s], 0):r1[s], max(c0[s], 0):c1[s]] = OUTLINE
            scene[max(r0[s] + 1, 0):r1[s] - 1, max(c0[s] + 1, 0):c1[s] - 1] = colours[s]
        else:
            scene[max(r0[s], 0):r1[s], max(c0[s], 0):c1[s]] = colours[s]

    # labels: each vehicle's speed above it, the gap's length under its line
    if v is not None:
        h = font(LABEL_PX).height
        for s in order:
            if visible[s]:
                draw_text(scene, f"{max(v[s], 0.0) * 3.6:.0f}", int(r0[s]) - h + 1, (c0[s] + c1[s]) / 2, LABEL,
                          LABEL_PX, align="centre")
    if gap_label is not None:
        draw_text(scene, gap_label[0], gap_label[1], gap_label[2], GAP, LABEL_PX, align="centre")
    return frame


def _world_modes(world, b: int) -> np.ndarray:
    """Each slot's driver's last ``info["mode"]`` in scene ``b`` (``-1``: no model, no mode, or
    no step since the scene's reset)."""
    modes = np.full(world.S, -1, dtype=np.int64)
    stepped = np.broadcast_to(getattr(world, "k", 1), (world.B,))[b] > 0  # scene b's step count (scalar or (B,))
    for s, model in enumerate(getattr(world, "drivers", []) if stepped else []):
        info = (getattr(model, "info", None) or {}) if model is not None else {}
        if "mode" in info:
            modes[s] = int(np.asarray(info["mode"]).reshape(-1)[b])
    return modes


def frame_from_world(world, b: int = 0, modes=None, **kw) -> np.ndarray:
    """:func:`render_frame` of scene ``b`` of a :class:`~acc_gym.simulation.single_lane.SingleLaneWorld`.

    ``modes`` (``(S,)``, ``-1`` none): the caller's; by default each slot's driver's last
    ``info["mode"]`` (``-1`` where a slot has no model or no mode, and before the first step
    after a reset, when ``info`` is empty or left over from the previous episode).
    ``kw`` go to :func:`render_frame`: ``v`` defaults to the world's speeds, ``lead`` to the
    ego's vehicle ahead (``world.neighbours``), ``road`` to the world's road.
    """
    B, S = world.x.shape
    if isinstance(b, bool) or not isinstance(b, (int, np.integer)) or not 0 <= b < B:
        raise ValueError(f"b must be a scene index in 0..{B - 1}, got {b!r}")
    if modes is None:
        modes = _world_modes(world, b)
    kw.setdefault("v", world.v[b])
    kw.setdefault("lead", int(world.neighbours.lead[b, kw.get("ego", 0)]))
    road = kw.pop("road", world.road)
    return render_frame(world.x[b], world.y[b], world.present[b], world.lengths[b], world.width[b], road,
                        modes, **kw)


def batch_hud(batch, row: int = 0) -> Hud:
    """The :class:`Hud` of scene ``row`` of an :class:`~acc_gym.envs.core.EpisodeBatch` (what an
    environment holds at render time): the ego's speed, its gap to the vehicle ahead and Q
    as that step's ``info`` has them (Q from the same formula and judged time gap ``tau1``),
    the scenario's set speed and id, the scene's time and its lead driver's mode."""
    sc = batch.scenarios[row]
    if sc is None:
        raise RuntimeError("call reset() before render()")
    w = batch.world
    rows = np.array([row])
    lead, has, gap, v_lead = batch._lead_state(rows)
    tau1 = batch.tau1[rows]
    q = float(batch._q(w.v[rows, 0], v_lead, gap, has, tau1)[0])
    lead = int(lead[0])
    return Hud(v=float(w.v[row, 0]), gap=float(gap[0]) if lead >= 0 else math.inf,
               set_speed=float(batch.set_speed[row]), tau1=float(tau1[0]), q=q, t=float(w.t[row]),
               lead_mode=int(_world_modes(w, row)[lead]) if lead >= 0 else None, caption=sc.id)


def frame_from_batch(batch, row: int = 0, **kw) -> np.ndarray:
    """The frame an environment renders: :func:`frame_from_world` of scene ``row`` of an
    :class:`~acc_gym.envs.core.EpisodeBatch` on its scenario's road, with :func:`batch_hud`
    (``kw`` go to :func:`render_frame`; ``hud=None`` leaves the HUD out)."""
    if batch.scenarios[row] is None:
        raise RuntimeError("call reset() before render()")
    if "hud" not in kw:
        kw["hud"] = batch_hud(batch, row)
    kw.setdefault("road", batch.scenarios[row].road)
    return frame_from_world(batch.world, row, **kw)


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
