"""Cost of one rendered frame: the numpy renderer against drawing the same frame with matplotlib's Agg canvas.

Cases (milliseconds per frame, the median over ``--repeats`` timed runs of ``--frames``
frames each, the runs alternating over the cases, after a warm-up):

====================  ===================================================================
key (``_ms``)         case
====================  ===================================================================
``scene``             :func:`acc_gym.rendering.render_frame`, three vehicles, no text
                      (640 x 200)
``env``               ``env.render()`` of ``acc_gym/SingleLane-v1`` in
                      ``singlelane/3/car-following+cut-in``: the scene, speed labels, the
                      gap and the HUD (640 x 200; what ``RecordVideo`` records)
``env_600x150``       the same frame at 600 x 150 (:func:`acc_gym.rendering.frame_from_batch`)
``agg_600x150``       the alternative: the same content (road, lane lines, three vehicles,
                      three speed labels, the gap label, two HUD lines) drawn per frame by
                      a reused matplotlib figure on its Agg canvas, the frame copied out
====================  ===================================================================

``docs/design/rendering.md`` records the choice these figures made.

    python benchmarks/bench_render.py            # table
    python benchmarks/bench_render.py --json     # one JSON object
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import gymnasium
import numpy as np

import acc_gym  # noqa: F401  (registers the environments)
from acc_gym.rendering import frame_from_batch, render_frame
from acc_gym.simulation.single_lane import Road


def agg_renderer(width: int, height: int):
    """A function drawing one frame with a reused matplotlib figure (Agg) and returning it as uint8 RGB."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    fig = Figure(figsize=(width / 100, height / 100), dpi=100)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_axes((0, 0, 1, 0.8))
    ax.set_xlim(0, 150)
    ax.set_ylim(-2.5, 10.0)
    ax.set_axis_off()
    ax.set_facecolor((0.35, 0.35, 0.36))
    for y in (-1.875, 9.375):
        ax.axhline(y, color="white", lw=1)
    dashes = [ax.plot([], [], color="white", lw=1, ls=(0, (6, 12)))[0] for _ in (1.875, 5.625)]
    cars = [ax.add_patch(Rectangle((0, 0), 4.7, 1.8, fc=c, ec="black")) for c in ("tab:blue", "tab:green", "grey")]
    labels = [ax.text(0, 0, "", fontsize=7, color="white", ha="center") for _ in cars]
    gap = ax.text(0, 0, "", fontsize=7, color="cyan", ha="center")
    hud = [fig.text(0.01, y, "", fontsize=8, color="white", family="monospace") for y in (0.92, 0.83)]

    def draw(x, y, v, t):
        x0 = x[0] - 30.0
        for line, yl in zip(dashes, (1.875, 5.625)):
            line.set_data([-(x0 % 18.0), 150.0], [yl, yl])
        for car, label, xs, ys, vs in zip(cars, labels, x, y, v):
            car.set_xy((xs - x0 - 4.7, ys - 0.9))
            label.set_position((xs - x0 - 2.35, ys + 1.1))
            label.set_text(f"{vs * 3.6:.0f}")
        gap.set_position(((x[0] + x[1] - 4.7) / 2 - x0, y[0] - 0.6))
        gap.set_text(f"{x[1] - 4.7 - x[0]:.1f} m")
        hud[0].set_text(f"v {v[0] * 3.6:5.1f} km/h   set 100 km/h   gap {x[1] - 4.7 - x[0]:5.1f} m   Q +3.2 m")
        hud[1].set_text(f"t {t:5.1f} s   lead driver sail   singlelane/3/car-following+cut-in")
        canvas.draw()
        return np.asarray(canvas.buffer_rgba())[..., :3].copy()

    return draw


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--frames", type=int, default=50, help="frames per timed run")
    ap.add_argument("--repeats", type=int, default=5, help="timed runs of each case, alternating")
    args = ap.parse_args(argv)
    if args.frames < 1 or args.repeats < 1:
        ap.error(f"--frames and --repeats must be >= 1, got {args.frames} and {args.repeats}")

    env = gymnasium.make("acc_gym/SingleLane-v1", render_mode="rgb_array")
    env.reset(seed=0, options={"scenario": "singlelane/3/car-following+cut-in"})
    for _ in range(10):
        env.step(np.array([0.0], np.float32))
    core = env.unwrapped.core
    x, y, present = np.array([100.0, 150.0, 180.0]), np.array([0.0, 3.75, 0.0]), np.ones(3, bool)
    road = Road(n_lanes=3)
    agg = agg_renderer(600, 150)
    cases = {
        "scene": lambda k: render_frame(x + 0.1 * k, y, present, 4.7, 1.8, road, [-1, 0, 2]),
        "env": lambda k: env.render(),
        "env_600x150": lambda k: frame_from_batch(core, 0, width_px=600, height_px=150),
        "agg_600x150": lambda k: agg(x + 0.1 * k, y, [20.0 + 0.01 * k, 25.0, 30.0], 0.2 * k),
    }
    runs = {name: [] for name in cases}
    for f in cases.values():  # warm-up: glyphs rasterised, caches filled
        f(0)
    for _ in range(args.repeats):
        for name, f in cases.items():
            t0 = time.perf_counter()
            for k in range(args.frames):
                f(k)
            runs[name].append((time.perf_counter() - t0) / args.frames * 1e3)
    out = {}
    for name, r in runs.items():
        out[f"{name}_ms"] = statistics.median(r)
        out[f"{name}_ms_runs"] = r
    out["agg_over_env_600x150"] = out["agg_600x150_ms"] / out["env_600x150_ms"]
    out["frames"], out["repeats"] = args.frames, args.repeats
    env.close()
    if args.json:
        print(json.dumps(out))
    else:
        for name in cases:
            print(f"{name:14s} {out[name + '_ms']:8.3f} ms/frame   runs " + " ".join(f"{v:.3f}" for v in runs[name]))
        print(f"agg / numpy at 600x150: {out['agg_over_env_600x150']:.1f}x")
    return out


if __name__ == "__main__":
    main()
