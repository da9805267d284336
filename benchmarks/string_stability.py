"""String stability of the built-in controllers and of the human-like driver populations.

    python benchmarks/string_stability.py            # the table (about a minute on 2 cores)
    python benchmarks/string_stability.py --json     # ... and one JSON object on the last line
    python benchmarks/string_stability.py --plot docs/string_stability.png

Every built-in controller is measured as ``acc-gym string-stability NAME`` measures it
(8 copies at 20 m/s, the full 25-frequency grid, the Gunter-like disturbance), ``cacc``
and ``mp-cacc`` also with V2V, and the human-like MPC drivers (``human``, each population)
alone and with the linear ACC in a quarter of the positions, each as driver model 5 (the
environments' drivers, ``PlatoonConfig``'s default) and as driver model 6 (a 1.0 s reaction
time with anticipation, a reflex and a following rule; ``acc_gym.drivers.mpc.DRIVER_MODELS``).
Printed per row: the largest gain and the verdict, the frequencies where the gain exceeds 1,
the disturbance's drop at the lead and at the last vehicle, and the wall time of the whole
measurement (median of
``--repeats`` runs; the sweep and the disturbance are one batched simulation). ``--plot``
draws the linear ACC at 1.5 s and at 0.6 s beside CACC at 0.6 s.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

from acc_gym.evaluation.string_stability import PlatoonConfig, StringStabilityError, string_stability

ROWS = [  # (label, controller, config settings)
    ("acc", "acc", {}),
    ("acc, time gap 0.6 s", "acc", {"time_gap": 0.6}),
    ("cacc", "cacc", {}),
    ("cacc, V2V, time gap 0.6 s", "cacc", {"time_gap": 0.6, "v2v": True}),
    ("mp-cacc, V2V", "mp-cacc", {"v2v": True}),
    ("idm", "idm", {}),
    ("gipps", "gipps", {}),
    ("gm", "gm", {}),
    ("fuzzy", "fuzzy", {}),
    ("mpc", "mpc", {}),
    ("constant", "constant", {}),
    ("ppo-acc", "ppo-acc", {}),
    ("ppo", "ppo", {}),
    ("human (typical), driver model 5", "human", {"drivers": "typical"}),
    ("human (atypical), driver model 5", "human", {"drivers": "atypical"}),
    ("human (naturalistic), driver model 5", "human", {"drivers": "naturalistic"}),
    ("acc in 1 of 4 positions, naturalistic humans, driver model 5", "acc",
     {"penetration": 0.25, "drivers": "naturalistic"}),
    ("human (typical), driver model 6", "human", {"drivers": "typical", "driver_model": 6}),
    ("human (atypical), driver model 6", "human", {"drivers": "atypical", "driver_model": 6}),
    ("human (naturalistic), driver model 6", "human", {"drivers": "naturalistic", "driver_model": 6}),
    ("acc in 1 of 4 positions, naturalistic humans, driver model 6", "acc",
     {"penetration": 0.25, "drivers": "naturalistic", "driver_model": 6}),
]


def measure(label: str, controller: str, settings: dict, repeats: int) -> dict:
    times, report = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        try:
            report = string_stability(controller, PlatoonConfig(**settings), name=label)
        except StringStabilityError as exc:
            return {"row": label, "failed": str(exc), "wall_s": time.perf_counter() - t0}
        times.append(time.perf_counter() - t0)
    d = report.disturbance
    return {"row": label, "max_gain": report.max_gain, "string_stable": report.string_stable,
            "unstable_bands_hz": report.unstable_bands, "time_gap": report.time_gap,
            "driver_model": report.config.driver_model if len(report.positions) < report.config.vehicles else None,
            "measured_pairs": int(report.steady.sum()), "pairs": int(report.steady.size),
            "lead_drop": d.lead_drop if d else None, "last_drop": float(d.drops[-1]) if d else None,
            "errors": [str(e) for e in report.errors], "wall_s": statistics.median(times), "report": report}


def table(rows: list[dict]) -> str:
    lines = ["| column | max gain | verdict | gain > 1 at [Hz] | disturbance drop: lead -> last [m/s] | "
             "sinusoidal pairs | time [s] |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        if "failed" in r:
            lines.append(f"| {r['row']} | - | no steady state | - | - | - | {r['wall_s']:.1f} |")
            continue
        verdict = {True: "stable", False: "**unstable**", None: "no verdict"}[r["string_stable"]]
        bands = ", ".join(f"{a:.3g}-{b:.3g}" for a, b in r["unstable_bands_hz"]) or "-"
        drop = "-" if r["lead_drop"] is None else f"{r['lead_drop']:.2f} -> {r['last_drop']:.2f}"
        lines.append(f"| {r['row']} | {r['max_gain']:.3f} | {verdict} | {bands} | {drop} | "
                     f"{r['measured_pairs']} of {r['pairs']} | {r['wall_s']:.1f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3, help="runs per row for the wall time's median (default 3)")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--plot", default=None, help="save the ACC/CACC comparison figure here")
    args = ap.parse_args(argv)
    rows = [measure(label, c, s, args.repeats) for label, c, s in ROWS]
    print(table(rows))
    if args.plot:
        plot(args.plot)
        print(f"plot: {args.plot}")
    if args.json:
        print(json.dumps([{k: v for k, v in r.items() if k != "report"} for r in rows]))
    return 0


def plot(path: str) -> None:
    import matplotlib
    from matplotlib.figure import Figure

    from acc_gym.plotting import save_figure

    cases = [("acc, 1.5 s", "acc", PlatoonConfig(time_gap=1.5)), ("acc, 0.6 s", "acc", PlatoonConfig(time_gap=0.6)),
             ("cacc, 0.6 s (V2V)", "cacc", PlatoonConfig(time_gap=0.6, v2v=True))]
    fig = Figure(figsize=(12.0, 7.5), layout="constrained")
    axes = fig.subplots(2, 3)
    cmap = matplotlib.colormaps["viridis"]
    for k, (title, name, cfg) in enumerate(cases):
        r = string_stability(name, cfg)
        ax = axes[0, k]
        for i in range(r.pair_gains.shape[1]):
            ax.plot(r.frequencies, r.pair_gains[:, i], color=cmap(i / 7), lw=1.1, marker=".", ms=3,
                    label=f"{i} -> {i + 1}" if i in (0, 7) else None)
        ax.axhline(1.0, color="k", ls="--", lw=0.8)
        ax.set_xscale("log")
        ax.set_ylim(0.0, 1.2)
        ax.set_title(f"{title}: max gain {r.max_gain:.3f}", fontsize=10)
        ax.set_xlabel("frequency [Hz]")
        ax.grid(True, which="both", alpha=0.3)
        d = r.disturbance
        ax2 = axes[1, k]
        y = d.x - d.v[0, 0] * d.t[:, None]
        for i in range(d.x.shape[1]):
            ax2.scatter(d.t[::5], y[::5, i], c=d.v[::5, i], cmap="RdYlGn", vmin=16.0, vmax=20.5, s=2)
        ax2.set_xlim(0, 120)
        ax2.set_title(f"disturbance: lead -{d.lead_drop:.2f}, last -{d.drops[-1]:.2f} m/s", fontsize=10)
        ax2.set_xlabel("time [s]")
    axes[0, 0].set_ylabel(r"$|\Gamma_i(j\omega)|$")
    axes[0, 0].legend(title="pair", fontsize=7)
    axes[1, 0].set_ylabel("position - 20 m/s x t [m]")
    fig.colorbar(matplotlib.cm.ScalarMappable(matplotlib.colors.Normalize(16.0, 20.5), cmap="RdYlGn"),
                 ax=axes[1, :], label="speed [m/s]")
    save_figure(fig, path)


if __name__ == "__main__":
    raise SystemExit(main())
