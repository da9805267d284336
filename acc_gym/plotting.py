"""Episode plots: speed, gap, acceleration and driver mode over time (headless, no pyplot).

:func:`plot_episode` draws one scene of a :class:`~acc_gym.simulation.single_lane.WorldTrace`
as stacked panels sharing the time axis (those with nothing to show left out), in the manner of the MPC driver paper's
result figures; :func:`save_figure` writes a figure atomically (temporary file in the
same directory, then ``os.replace``), so a reader never sees a half-written image.
"""

from __future__ import annotations

import base64
import html
import io
from pathlib import Path

import matplotlib
import numpy as np
from matplotlib.backend_bases import FigureCanvasBase
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from acc_gym._io import atomic_write
from acc_gym.drivers.mpc import Mode

SLOT_LABELS = ("ego", "POV", "POV2")  # slot 0, 1, 2 (scenario roles SV, POV, POV2)
SLOT_COLOURS = ("tab:blue", "tab:red", "tab:green")
MODE_NAMES = tuple(m.name for m in sorted(Mode))  # y tick labels of the mode panel, at values 0..3


def _label(s: int) -> str:
    return SLOT_LABELS[s] if s < len(SLOT_LABELS) else f"slot {s}"


def _colour(s: int) -> str:
    return SLOT_COLOURS[s] if s < len(SLOT_COLOURS) else f"C{s + 1}"


def plot_episode(trace, b: int = 0, *, title: str | None = None, path=None, scenario=None) -> Figure:
    """Scene ``b`` of ``trace`` as a :class:`~matplotlib.figure.Figure` of up to four panels.

    From the top: speed [m/s] of each present vehicle (and the ego's set speed when
    ``scenario`` is given); bumper gap [m] of each vehicle to the one ahead (only
    vehicles that ever have one; ``inf`` stretches are left blank); applied acceleration
    [m/s^2]; each vehicle's driver mode as a step plot with the mode names as tick labels
    (vehicles without a mode, e.g. the ego or scripted ones, are skipped). A panel with nothing
    to show -- no vehicle ever has one ahead, no vehicle has a driver mode -- is left out (the
    figure is shorter). Acceleration
    and mode are held over the step that ends at each sample (``steps-pre``).
    ``scenario``: its id (and seed) go in the title. ``path``: also save a PNG there
    (atomically, see :func:`save_figure`).
    """
    t = np.asarray(trace.t, dtype=float)
    B, S = np.shape(trace.present)
    if isinstance(b, bool) or not isinstance(b, (int, np.integer)) or not 0 <= b < B:
        raise ValueError(f"b must be a scene index in 0..{B - 1}, got {b!r}")
    for name in ("x", "v", "a", "gap", "mode"):
        if np.shape(getattr(trace, name)) != (t.size, B, S):
            raise ValueError(f"trace.{name} must have shape {(t.size, B, S)}, got {np.shape(getattr(trace, name))}")
    slots = [s for s in range(S) if trace.present[b, s]]
    has_gap = any(np.any(np.isfinite(np.asarray(trace.gap[:, b, s], dtype=float))) for s in slots)
    has_mode = any(np.any(np.asarray(trace.mode[:, b, s]) >= 0) for s in slots)
    panels = ["v", *(["gap"] if has_gap else []), "a", *(["mode"] if has_mode else [])]  # empty ones left out

    fig = Figure(figsize=(8.0, 2.0 + 1.75 * len(panels)), layout="constrained")
    axes = dict(zip(panels, np.atleast_1d(fig.subplots(len(panels), 1, sharex=True))))
    ax_v, ax_a = axes["v"], axes["a"]
    ax_gap, ax_mode = axes.get("gap"), axes.get("mode")
    for s in slots:
        style = dict(color=_colour(s), label=_label(s), lw=1.4)
        ax_v.plot(t, trace.v[:, b, s], **style)
        gap = np.asarray(trace.gap[:, b, s], dtype=float)
        if ax_gap is not None and np.any(np.isfinite(gap)):
            ax_gap.plot(t, np.where(np.isfinite(gap), gap, np.nan), **style)
        ax_a.plot(t, trace.a[:, b, s], drawstyle="steps-pre", **style)
        mode = np.asarray(trace.mode[:, b, s])
        if ax_mode is not None and np.any(mode >= 0):
            ax_mode.plot(t, np.where(mode >= 0, mode, np.nan), drawstyle="steps-pre", **style)
    if scenario is not None:
        ax_v.axhline(scenario.set_speed, color="0.4", ls="--", lw=1.0, label="set speed")

    ax_v.set_ylabel("speed [m/s]")
    if ax_gap is not None:
        ax_gap.set_ylabel("gap [m]")
    ax_a.set_ylabel("acceleration [m/s$^2$]")
    ax_a.axhline(0.0, color="0.7", lw=0.8, zorder=0)
    if ax_mode is not None:
        ax_mode.set_ylabel("mode")
        ax_mode.set_yticks(range(len(MODE_NAMES)), MODE_NAMES)
        ax_mode.set_ylim(-0.5, len(MODE_NAMES) - 0.5)
    bottom = axes[panels[-1]]
    bottom.set_xlabel("time [s]")
    if t.size:
        bottom.set_xlim(t[0], t[-1] if t[-1] > t[0] else t[0] + 1.0)
    for ax in axes.values():
        ax.grid(True, alpha=0.3)
        if ax.get_lines() and any(not ln.get_label().startswith("_") for ln in ax.get_lines()):
            ax.legend(loc="best", fontsize=8)

    parts = [title] if title else []
    if scenario is not None:
        parts.append(f"{scenario.id} (seed {scenario.seed})")
    if B > 1:
        parts.append(f"scene {b}")
    fig.suptitle(" -- ".join(parts) if parts else "episode")
    if path is not None:
        save_figure(fig, path)
    return fig


def plot_string_stability(report, *, path=None) -> Figure:
    """A :class:`~acc_gym.evaluation.string_stability.StringStabilityReport` as two panels:
    ``|Gamma_i(j w)|`` against frequency for each vehicle pair (log-log, the gain 1 dashed, the
    unstable bands shaded), and the disturbance's space-time diagram (each vehicle's position
    in a frame moving at the operating speed, over time, coloured by its speed). ``path``: also
    save a PNG there (atomically)."""
    from matplotlib.collections import LineCollection

    fig = Figure(figsize=(11.0, 4.5), layout="constrained")
    ax_g, ax_st = fig.subplots(1, 2)
    f = np.asarray(report.frequencies, dtype=float)
    pairs = report.pair_gains.shape[1]
    cmap = matplotlib.colormaps["viridis"]
    for i in range(pairs):
        g = report.pair_gains[:, i]
        if np.any(np.isfinite(g)):
            ax_g.plot(f, g, color=cmap(i / max(pairs - 1, 1)), lw=1.2, marker=".", ms=3,
                      label=f"{i} -> {i + 1}" if pairs <= 10 or i in (0, pairs - 1) else None)
    ax_g.axhline(1.0, color="k", ls="--", lw=0.9)
    for lo, hi in report.unstable_bands:
        ax_g.axvspan(lo, hi, color="tab:red", alpha=0.12, lw=0)
    ax_g.set_xscale("log")
    ax_g.set_yscale("log")
    ax_g.set_xlabel("frequency [Hz]")
    ax_g.set_ylabel(r"$|\Gamma_i(j\omega)| = |V_i / V_{i-1}|$")
    verdict = {True: "string stable", False: "not string stable", None: "no verdict"}[report.string_stable]
    ax_g.set_title(f"largest gain {report.max_gain:.3f}: {verdict}", fontsize=10)
    ax_g.grid(True, which="both", alpha=0.3)
    if ax_g.get_lines():
        ax_g.legend(title="pair", fontsize=7, loc="lower left")
    d = report.disturbance if report.disturbance is not None else report.trace
    if d is None:
        ax_st.text(0.5, 0.5, "no disturbance run", transform=ax_st.transAxes, ha="center", va="center")
    else:
        v0 = float(d.v[0, 0])
        y = d.x - v0 * d.t[:, None]
        norm = matplotlib.colors.Normalize(float(np.nanmin(d.v)), float(np.nanmax(d.v)) + 1e-9)
        for i in range(d.x.shape[1]):
            pts = np.stack([d.t, y[:, i]], axis=1)
            lc = LineCollection(np.stack([pts[:-1], pts[1:]], axis=1), cmap="RdYlGn", norm=norm, lw=1.6)
            lc.set_array(0.5 * (d.v[:-1, i] + d.v[1:, i]))
            ax_st.add_collection(lc)
        ax_st.set_xlim(float(d.t[0]), float(d.t[-1]))
        ax_st.set_ylim(float(np.nanmin(y)) - 5.0, float(np.nanmax(y)) + 5.0)
        fig.colorbar(matplotlib.cm.ScalarMappable(norm=norm, cmap="RdYlGn"), ax=ax_st, label="speed [m/s]")
        ax_st.set_xlabel("time [s]")
        ax_st.set_ylabel(f"position - {v0:g} m/s x t [m]")
        ax_st.set_title(f"{d.name}: lead drops {d.lead_drop:.2f} m/s, last follower {d.drops[-1]:.2f} m/s",
                        fontsize=10)
    c = report.config
    fig.suptitle(f"{report.controller}: {c.vehicles} vehicles at {c.speed:g} m/s, time gap {report.time_gap:g} s")
    if path is not None:
        save_figure(fig, path)
    return fig


def plot_robustness(result: dict, *, path=None) -> Figure:
    """A :func:`acc_gym.evaluation.robustness.robustness` sweep as its degradation curves, one
    panel per axis: share qualified and mean score / 100 against the level, collisions
    (preventable ones filled) as markers on a second scale, and the column's largest
    string-stability gain where it was measured. ``path``: also save a PNG there (atomically)."""
    axes_names = [a for a in ("lag", "delay", "noise") if any(r["axis"] == a for r in result["levels"])]
    fig = Figure(figsize=(4.2 * max(len(axes_names), 1), 3.8), layout="constrained")
    panels = np.atleast_1d(fig.subplots(1, max(len(axes_names), 1)))
    units = {"lag": "actuator lag [s]", "delay": "actuator dead time [s]",
             "noise": "radar errors and dropouts [x typical]"}
    for ax, axis in zip(panels, axes_names):
        rows = [r for r in result["levels"] if r["axis"] == axis]
        x = np.array([r["value"] for r in rows])
        ax.plot(x, [r["share_qualified"] for r in rows], "o-", color="tab:green", label="share qualified")
        ax.plot(x, [r["mean_score"] / 100.0 for r in rows], "s--", color="tab:blue", label="mean score / 100")
        gains = [(v, r["max_gain"]) for v, r in zip(x, rows) if r["max_gain"] is not None]
        if gains:
            ax.plot(*zip(*gains), "^:", color="tab:purple", label="largest string-stability gain")
            ax.axhline(1.0, color="k", lw=0.6, ls=":")
        ax2 = ax.twinx()
        ax2.bar(x, [r["collisions"] for r in rows], width=0.04 * max(float(np.ptp(x)), 1.0), color="tab:red",
                alpha=0.35, label="collisions")
        ax2.bar(x, [r["preventable_collisions"] for r in rows], width=0.04 * max(float(np.ptp(x)), 1.0),
                color="tab:red", alpha=0.9, label="preventable")
        ax2.set_ylabel("collisions")
        ax2.set_ylim(0, max(1, max(r["collisions"] for r in rows)) * 1.3)
        ax.set_xlabel(units[axis])
        ax.set_ylim(0, max(1.05, 1.05 * max([g for _, g in gains] or [1.0])))
        ax.grid(True, alpha=0.3)
        if axis == axes_names[0]:
            ax.legend(fontsize=7, loc="lower left")
            ax2.legend(fontsize=7, loc="lower right")
    fig.suptitle(f"{result['controller']} on {result['suite']} ({result['split']}, {result['episodes']} episodes)")
    if path is not None:
        save_figure(fig, path)
    return fig


def png_base64(fig: Figure, dpi: int = 90) -> str:
    """``fig`` as a base64 PNG (for a self-contained HTML report)."""
    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def img(fig: Figure, alt: str) -> str:
    """An ``<img>`` element holding ``fig`` (:func:`png_base64`)."""
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{png_base64(fig)}">'


def save_figure(fig: Figure, path, *, dpi: int = 100) -> Path:
    """Save ``fig`` to ``path`` atomically (PNG unless the suffix names another format); returns the path."""
    path = Path(path)
    if type(fig.canvas) is FigureCanvasBase:  # a bare Figure: give it an Agg canvas (no pyplot involved)
        FigureCanvasAgg(fig)
    fmt = path.suffix[1:].lower() or "png"
    return atomic_write(path, lambda fh: fig.savefig(fh, format=fmt, dpi=dpi))
