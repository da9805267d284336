"""What the evaluation needs of an episode: the ego's trace, from a simulation or a CSV file.

An :class:`EgoTrace` holds 1-D arrays over samples: time, the ego's speed and
acceleration, the bumper-to-bumper gap to the vehicle ahead (``inf`` where there is
none) and that vehicle's speed. Optional: the vehicle ahead's acceleration and identity
(to tell a new target after a cut-in from the old one), the ego's lateral acceleration
and its contour distances to the road edge (``d2``) and the carriageway's boundary line
(``d3``), and the scenario's set speed and nominal time gap.

A recorded drive is enough: ``EgoTrace.from_csv(path)`` reads a CSV with a header and
the columns ``t, v, a, gap, v_lead`` (optional ``a_lead, lead_id, a_y, d2, d3``); an empty
``gap`` cell or ``inf`` means no vehicle ahead. Blank lines are skipped; every error
names the file and the line the sample was read from (the header is line 1), and a column
named twice in the header is refused rather than one of them silently winning.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass, fields
from pathlib import Path

import math

import numba
import numpy as np

from acc_gym.simulation.single_lane import VEHICLE_WIDTH, Road

REQUIRED_COLUMNS = ("t", "v", "a", "gap", "v_lead")
OPTIONAL_COLUMNS = ("a_lead", "lead_id", "a_y", "d2", "d3")
_ARRAY_COLUMNS = REQUIRED_COLUMNS + OPTIONAL_COLUMNS
_EMPTY = np.empty(0)  # an absent optional column, for _columns_valid
_SCALARS = ("set_speed", "time_gap", "declared_time_gap")  # per-episode values, not columns


@numba.njit(cache=True)
def _columns_valid(t, v, a, gap, v_lead, a_lead, lead_id, a_y, d2, d3):  # pragma: no cover - compiled
    """:class:`EgoTrace`'s column checks for float64 columns of one length (an optional column
    absent: empty): at least 2 samples, nothing NaN, ``gap`` not -inf, ``v_lead`` finite
    where ``gap`` is finite and +0.0 elsewhere (what the checks would set), every other
    column finite, ``t`` strictly increasing, ``v`` >= 0."""
    n = t.shape[0]
    if n < 2:
        return False
    for i in range(n):
        g = gap[i]
        if math.isnan(g) or g == -np.inf:
            return False
        vl = v_lead[i]
        if math.isfinite(g):
            if not math.isfinite(vl):
                return False
        elif not (vl == 0.0 and math.copysign(1.0, vl) > 0.0):
            return False
        if not (math.isfinite(t[i]) and math.isfinite(v[i]) and math.isfinite(a[i]) and v[i] >= 0.0):
            return False
        if i > 0 and not t[i] > t[i - 1]:
            return False
    return _all_finite(a_lead) and _all_finite(lead_id) and _all_finite(a_y) and _all_finite(d2) and _all_finite(d3)


@numba.njit(cache=True)
def _all_finite(col):  # pragma: no cover - compiled
    for i in range(col.shape[0]):
        if not math.isfinite(col[i]):
            return False
    return True


def _scalars_valid(*values) -> bool:
    """:class:`EgoTrace`'s per-episode values (:data:`_SCALARS`) as its checks accept them:
    each None or a finite number > 0."""
    for value in values:
        if value is None or (type(value) is float and 0.0 < value < math.inf):  # a plain float: no numpy
            continue
        if not (np.isfinite(value) and value > 0):
            return False
    return True


_LANE_CENTRED = Road(3.75, 1).d2(0.0, VEHICLE_WIDTH)  # [m] D2 = D3 of a lane-centred car, paper 003's road


def _read_csv(path: Path) -> tuple[dict[str, np.ndarray], list[int]]:
    """The columns of a CSV trace and, for each sample, the line of the file it starts on (the
    header's line is 1; blank lines are skipped). Errors name the file, the line and the column."""
    # utf-8-sig: a byte-order mark (what spreadsheet programs write) is not part of the first column's name
    with path.open(newline="", encoding="utf-8-sig") as fh:
        reader = csv.reader(fh)
        try:
            header = [h.strip() for h in next(reader, [])]
        except csv.Error as exc:
            raise ValueError(f"{path}, line 1: not a readable CSV header ({exc})") from None
        missing = [c for c in REQUIRED_COLUMNS if c not in header]
        if missing:
            raise ValueError(f"{path}: missing column(s) {missing}; a trace needs {list(REQUIRED_COLUMNS)}")
        unknown = [c for c in header if c not in REQUIRED_COLUMNS + OPTIONAL_COLUMNS]
        if unknown:
            raise ValueError(f"{path}: unknown column(s) {unknown}")
        repeated = sorted({c for c in header if header.count(c) > 1})
        if repeated:
            raise ValueError(f"{path}: column(s) {repeated} appear more than once in the header (line 1)")
        cols: dict[str, list[float]] = {c: [] for c in header}
        lines: list[int] = []
        while True:
            line = reader.line_num + 1  # where the next record starts
            try:
                cells = next(reader, None)
            except csv.Error as exc:  # a NUL byte, a cell over the csv module's size limit, ...
                raise ValueError(f"{path}, line {reader.line_num}: not a readable CSV record ({exc})") from None
            if cells is None:
                break
            if not cells:  # a blank line (what csv.DictReader skips too)
                continue
            if len(cells) > len(header):
                raise ValueError(f"{path}, line {line}: more cells than columns ({len(cells)} > {len(header)})")
            lines.append(line)
            for k, key in enumerate(header):
                text = cells[k].strip() if k < len(cells) else ""
                if text == "" and key in ("gap", "v_lead", "a_lead", "lead_id"):
                    value = {"gap": np.inf, "lead_id": -1.0}.get(key, 0.0)
                else:
                    try:
                        value = float(text)
                    except ValueError:
                        raise ValueError(f"{path}, line {line}: column {key!r} is not a number: {text!r}") from None
                    if np.isnan(value):
                        raise ValueError(f"{path}, line {line}: column {key!r} is NaN")
                cols[key].append(value)
    return {k: np.array(v, dtype=float) for k, v in cols.items()}, lines


@dataclass(frozen=True)
class EgoTrace:
    """One episode as seen from the ego (arrays of shape ``(n,)``)."""

    t: np.ndarray  # [s] strictly increasing
    v: np.ndarray  # [m/s] ego speed (>= 0)
    a: np.ndarray  # [m/s^2] ego longitudinal acceleration
    gap: np.ndarray  # [m] bumper gap to the vehicle ahead (D1), inf: none
    v_lead: np.ndarray  # [m/s] its speed (ignored where gap is inf)
    a_lead: np.ndarray | None = None  # [m/s^2]
    lead_id: np.ndarray | None = None  # identity of the vehicle ahead (-1: none)
    a_y: np.ndarray | None = None  # [m/s^2] ego lateral acceleration (default 0)
    d2: np.ndarray | None = None  # [m] contour to the road edge (default: lane-centred, 0.975)
    d3: np.ndarray | None = None  # [m] contour to the boundary line (default 0.975)
    set_speed: float | None = None  # [m/s] the ego's set speed
    time_gap: float | None = None  # [s] the scenario's nominal time gap
    declared_time_gap: float | None = None  # [s] the controller's own, if it declares one (judged at it)

    def __post_init__(self) -> None:
        if self._valid_as_given():
            return
        n = None
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None or f.name in _SCALARS:
                continue
            arr = np.asarray(value, dtype=float)
            if arr.ndim != 1:
                raise ValueError(f"trace column {f.name!r} must be 1-D, got shape {arr.shape}")
            if n is None:
                n = arr.size
            elif arr.size != n:
                raise ValueError(f"trace column {f.name!r} has {arr.size} samples but 't' has {n}")
            if np.any(np.isnan(arr)):
                k = int(np.flatnonzero(np.isnan(arr))[0])
                raise ValueError(f"trace column {f.name!r} is NaN at sample {k} (t index {k})")
            if f.name == "gap":
                if np.any(arr == -np.inf):
                    k = int(np.flatnonzero(arr == -np.inf)[0])
                    raise ValueError(f"trace column 'gap' must not be -inf, got -inf at sample {k}")
            elif f.name == "v_lead":
                arr = np.where(np.isfinite(np.asarray(self.gap, float)), arr, 0.0)
                if not np.all(np.isfinite(arr)):
                    k = int(np.flatnonzero(~np.isfinite(arr))[0])
                    raise ValueError(f"trace column 'v_lead' must be finite where a vehicle is ahead, got "
                                     f"{float(arr[k])!r} at sample {k}")
            elif not np.all(np.isfinite(arr)):
                k = int(np.flatnonzero(~np.isfinite(arr))[0])
                raise ValueError(f"trace column {f.name!r} must be finite, got {float(arr[k])!r} at sample {k}")
            object.__setattr__(self, f.name, arr)
        if n is None or n < 2:
            raise ValueError(f"a trace needs at least 2 samples, got {n}")
        if np.any(np.diff(self.t) <= 0):
            k = int(np.flatnonzero(np.diff(self.t) <= 0)[0])
            raise ValueError(f"trace column 't' must be strictly increasing (sample {k + 1}: {float(self.t[k + 1])!r} "
                             f"after {float(self.t[k])!r})")
        if np.any(self.v < 0):
            raise ValueError(f"trace column 'v' (ego speed) must be >= 0, got {float(self.v.min())!r} at sample "
                             f"{int(np.argmin(self.v))}")
        for name in _SCALARS:
            value = getattr(self, name)
            if value is not None and not (np.isfinite(value) and value > 0):
                raise ValueError(f"trace {name} must be > 0, got {value!r}")

    def _valid_as_given(self) -> bool:
        """The checks below in one compiled pass (:func:`_columns_valid`), for columns that are
        already 1-D float64 arrays of one length: True when they pass and the checks would
        change nothing (every ``v_lead`` without a vehicle ahead is already +0.0), so the
        columns are kept as given; False sends the trace through the checks, which convert,
        or raise naming the bad value. Traces of the environments take this path."""
        cols = [getattr(self, name) for name in _ARRAY_COLUMNS]
        t = cols[0]
        if not (type(t) is np.ndarray and t.dtype == np.float64 and t.ndim == 1):
            return False
        n = t.shape[0]
        for c in cols:
            if c is not None and not (type(c) is np.ndarray and c.dtype == np.float64 and c.shape == (n,)):
                return False
        if not _scalars_valid(self.set_speed, self.time_gap, self.declared_time_gap):
            return False
        empty = _EMPTY
        return bool(_columns_valid(*(empty if c is None else c for c in cols)))

    @property
    def n(self) -> int:
        return self.t.size

    @property
    def has_lead(self) -> np.ndarray:
        return np.isfinite(self.gap)

    @property
    def lateral_accel(self) -> np.ndarray:
        return np.zeros(self.n) if self.a_y is None else self.a_y

    @property
    def edge_distance(self) -> np.ndarray:
        return np.full(self.n, _LANE_CENTRED) if self.d2 is None else self.d2

    @property
    def line_distance(self) -> np.ndarray:
        return np.full(self.n, _LANE_CENTRED) if self.d3 is None else self.d3

    # ------------------------------------------------------------------ sources
    @classmethod
    def from_world(cls, trace, b: int = 0, scenario=None) -> "EgoTrace":
        """The ego (slot 0) of scene ``b`` of a :class:`~acc_gym.simulation.single_lane.WorldTrace`."""
        lead = trace.lead[:, b, 0]
        rows = np.arange(trace.t.size)
        safe = np.maximum(lead, 0)
        has = lead >= 0
        v_lead = np.where(has, trace.v[rows, b, safe], 0.0)
        a_lead = np.where(has, trace.a[rows, b, safe], 0.0)
        road, width = trace.road, trace.width[b, 0]
        y = trace.y[:, b, 0]
        return cls(t=trace.t, v=trace.v[:, b, 0], a=trace.a[:, b, 0], gap=trace.gap[:, b, 0], v_lead=v_lead,
                   a_lead=a_lead, lead_id=lead.astype(float), a_y=trace.a_y[:, b, 0],
                   d2=road.d2(y, width), d3=road.d3(y, width),
                   set_speed=None if scenario is None else scenario.set_speed,
                   time_gap=None if scenario is None else scenario.time_gap)

    @classmethod
    def from_csv(cls, path, set_speed: float | None = None, time_gap: float | None = None) -> "EgoTrace":
        """Read a CSV trace (see the module docstring)."""
        path = Path(path)
        try:
            cols, lines = _read_csv(path)
        except UnicodeDecodeError as exc:
            raise ValueError(f"{path}: not UTF-8 text (byte {exc.start}: {exc.reason})") from None
        try:
            return cls(**cols, set_speed=set_speed, time_gap=time_gap)
        except ValueError as exc:
            # a check of the whole trace: name the file, and the CSV line each sample was read from
            # (blank lines are skipped and a quoted cell may span lines, so it is not the sample + 2)
            def with_line(m: re.Match) -> str:
                k = int(m.group(1))
                return f"sample {k} (line {lines[k]})" if k < len(lines) else m.group(0)

            text = re.sub(r"sample (\d+)", with_line, str(exc))
            raise ValueError(f"{path}: {text}") from None

    def to_csv(self, path) -> None:
        """Write the trace as CSV (``inf`` gaps as empty cells)."""
        names = list(REQUIRED_COLUMNS) + [c for c in OPTIONAL_COLUMNS if getattr(self, c) is not None]
        with Path(path).open("w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(names)
            for k in range(self.n):
                row = []
                for c in names:
                    value = getattr(self, c)[k]
                    row.append("" if (c == "gap" and not np.isfinite(value)) else repr(float(value)))
                w.writerow(row)
