#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Plots for `toonforce-lab report` (docs/performance/precision.md, docs/STABILITY.md).

Usage:
  plot_report.py work-precision PRECISION.csv OUT.png
  plot_report.py drift DRIFT.csv OUT.png
  plot_report.py closed-loop CLOSED_LOOP.csv OUT.png
  plot_report.py stability MAP.csv OUT.png --title T --xlabel X --ylabel Y [--linear-x] [--linear-y]

work-precision: one column per paper scene; log-log, one marker per configuration, lines join
the servo rates of one scalar type and sine method (labelled with the rate in kHz):
  top     x = RMS held (zero-order hold) error away from events against the converged double
          reference (precision.cpp), y = CPU time per simulated second (ns per tick x rate);
          a dotted vertical line marks the reference's own error (Richardson);
  middle  x = max sampled error, every tick (events included), y = ns per tick;
  bottom  x = max error against double at the same rate (the scalar type's and the sine's own
          share), y = ns per tick.
  A zero error is drawn at the bottom edge (1e-9 N) and said so in the legend.
drift: one panel per scene, the largest |difference| per bucket of simulated time against
  hours, one line per scalar and quantity (observer - port work, observer vs double, force vs
  double), with each line's fitted slope per hour in the legend.
closed-loop: to pick a scalar type and a rate for a force accuracy: one panel per scene, y = RMS
  force error of the closed loop against the converged double reference, x = the servo loop's
  CPU per simulated second on x86, measured inside the same closed-loop runs (cpu_us_per_s),
  each point labelled scalar and rate; a dotted line marks the reference's own error. When the
  CSV has Cortex-M3 figures (m3_instructions_per_s, q16.16 rows), a second row of panels puts
  those on x.
stability: the sweep's points coloured by class (decaying, bounded, unstable), the points whose eigenvalue predicts growth (rho > 1), and the bound
  drawn over them.

Needs matplotlib (Debian: python3-matplotlib; tools/setup-deps installs it). Deterministic
output: no dates or versions in the files.
"""

import argparse
import csv
import math
import sys

try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    sys.exit("plot_report.py: matplotlib is missing: install python3-matplotlib (tools/setup-deps does)")

SCENES = ["wall", "realistic_friction", "slippery", "cartoon_wall", "cliff"]
SCALAR_COLOURS = {"double": "tab:blue", "float": "tab:green", "q16.16": "tab:red"}
SINE_MARKERS = {"-": "o", "library": "o", "polynomial": "s", "table": "^"}
CLASS_COLOURS = {"decaying": "tab:green", "bounded": "tab:orange", "unstable": "tab:red"}
FLOOR = 1e-9


def read_rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def save(fig, out):
    # No metadata that changes from run to run.
    meta = {"Software": None} if out.endswith(".png") else {"Date": None}
    fig.savefig(out, dpi=110, metadata=meta)
    plt.close(fig)


def work_precision(rows, out):
    fig, axes = plt.subplots(3, len(SCENES), figsize=(22, 13), squeeze=False)
    panels = [
        ("held_away_rms_error_n", lambda r: float(r["mean_ns"]) * float(r["rate_hz"]) / 1000.0,
         "RMS held error away from events vs reference [N]", "CPU per simulated second [us]"),
        ("max_error_n", lambda r: float(r["mean_ns"]), "max sampled error, events included [N]", "ns per tick"),
        ("same_rate_max_error_n", lambda r: float(r["mean_ns"]), "max error vs double, same rate [N]", "ns per tick"),
    ]
    floored = False
    for column, scene in enumerate(SCENES):
        scene_rows = [r for r in rows if r["scene"] == scene]
        series = {}
        for r in scene_rows:
            series.setdefault((r["scalar"], r["sine"]), []).append(r)
        for row_index, (key, cost, xlabel, ylabel) in enumerate(panels):
            ax = axes[row_index][column]
            for (scalar, sine), points in sorted(series.items()):
                points.sort(key=lambda r: float(r["rate_hz"]))
                xs = []
                for r in points:
                    value = float(r[key])
                    if value <= 0.0:
                        floored = True
                    xs.append(max(value, FLOOR))
                ys = [cost(r) for r in points]
                label = scalar if sine == "-" else f"{scalar}, {sine} sine"
                ax.plot(xs, ys, marker=SINE_MARKERS.get(sine, "o"), color=SCALAR_COLOURS.get(scalar, "k"),
                        linewidth=0.8, markersize=5, label=label, alpha=0.8)
                if sine in ("-", "library", "polynomial") and (scalar != "q16.16" or sine != "library"):
                    for x, y, r in zip(xs, ys, points):
                        ax.annotate(f"{float(r['rate_hz']) / 1000:g}k", (x, y), fontsize=6,
                                    xytext=(2, 2), textcoords="offset points", color="dimgray")
            if row_index == 0 and scene_rows and "reference_away_rms_error_n" in scene_rows[0]:
                reference_error = float(scene_rows[0]["reference_away_rms_error_n"])
                if reference_error > 0.0:
                    ax.axvline(reference_error, color="k", linestyle=":", linewidth=0.8,
                               label="reference's own error")
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.grid(True, which="both", linewidth=0.3)
            ax.set_xlabel(xlabel, fontsize=8)
            if column == 0:
                ax.set_ylabel(ylabel, fontsize=8)
            if row_index == 0:
                ax.set_title(scene)
            ax.tick_params(labelsize=7)
        axes[0][column].legend(fontsize=6, loc="best")
    title = "Work-precision: force error against cost per tick (points: servo rates in kHz)"
    if floored:
        title += f"; an error of exactly 0 is drawn at {FLOOR:g} N"
    fig.suptitle(title)
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    save(fig, out)


def drift(rows, out):
    fig, axes = plt.subplots(1, len(SCENES), figsize=(22, 4.5), squeeze=False)
    styles = {"observer - port work": "-", "observer vs double": "--", "force vs double": ":"}
    for column, scene in enumerate(SCENES):
        ax = axes[0][column]
        series = {}
        for r in rows:
            if r["scene"] == scene:
                series.setdefault((r["quantity"], r["scalar"], r["unit"]), []).append(r)
        for (quantity, scalar, unit), points in sorted(series.items()):
            hours = [float(r["t_h"]) for r in points]
            values = [max(float(r["max_abs"]), FLOOR) for r in points]
            slope = float(points[0]["slope_per_h"])
            ax.plot(hours, values, marker=".", linestyle=styles.get(quantity, "-"),
                    color=SCALAR_COLOURS.get(scalar, "k"),
                    label=f"{scalar}: {quantity} [{unit}], {slope:.2g}/h")
        ax.set_yscale("log")
        ax.set_title(scene)
        ax.set_xlabel("simulated hours")
        if column == 0:
            ax.set_ylabel("largest |difference| in the bucket")
        ax.grid(True, which="both", linewidth=0.3)
        ax.legend(fontsize=5)
    fig.suptitle("Drift: the closed loop (servo loop, simulated device and seeded hand); "
                 "passivity observer against true port work, float and Q16.16 against double")
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    save(fig, out)


def closed_loop(rows, out):
    m3 = any(r.get("m3_instructions_per_s") for r in rows)
    targets = [("cpu_us_per_s", "x86: loop CPU per simulated second [us]\n(measured in the closed-loop runs)",
                ("double", "float", "q16.16"))]
    if m3:
        targets.append(("m3_instructions_per_s",
                        "Cortex-M3: instructions per simulated second\n(1 kHz motions' mean per tick x rate)",
                        ("q16.16",)))
    fig, axes = plt.subplots(len(targets), len(SCENES), figsize=(22, 5 * len(targets)), squeeze=False)
    for line, (column_name, xlabel, scalars) in enumerate(targets):
        for column, scene in enumerate(SCENES):
            ax = axes[line][column]
            scene_rows = [r for r in rows if r["scene"] == scene and not r["refused"] and r.get(column_name)]
            for scalar in scalars:
                points = sorted((r for r in scene_rows if r["scalar"] == scalar), key=lambda r: float(r["rate_hz"]))
                if not points:
                    continue
                xs = [float(r[column_name]) for r in points]
                ys = [max(float(r["force_rms_error_n"]), FLOOR) for r in points]
                ax.plot(xs, ys, marker="o", color=SCALAR_COLOURS[scalar], linewidth=0.8, label=scalar)
                for x, y, r in zip(xs, ys, points):
                    # Each scalar's labels on its own side: the three lines run close together.
                    offset = {"double": (-4, -9), "float": (4, 4), "q16.16": (4, 2)}[scalar]
                    ax.annotate(f"{scalar} {float(r['rate_hz']) / 1000:g} kHz", (x, y), fontsize=6,
                                xytext=offset, textcoords="offset points", color=SCALAR_COLOURS[scalar],
                                ha="right" if scalar == "double" else "left")
            if scene_rows:
                reference_error = float(scene_rows[0]["reference_force_rms_error_n"])
                if reference_error > 0.0:
                    ax.axhline(reference_error, color="k", linestyle=":", linewidth=0.8, label="reference's own error")
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.grid(True, which="both", linewidth=0.3)
            ax.set_title(scene)
            ax.set_xlabel(xlabel, fontsize=8)
            if column == 0:
                ax.set_ylabel("RMS rendered-force error vs converged reference [N]", fontsize=8)
            ax.legend(fontsize=6)
    fig.suptitle("Closed loop (servo loop, simulated device and seeded hand): pick the cheapest point below "
                 "the force accuracy you need")
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    save(fig, out)


def stability(rows, out, title, xlabel, ylabel, log_x, log_y):
    fig, ax = plt.subplots(figsize=(7.5, 6))
    for cls, colour in CLASS_COLOURS.items():
        points = [r for r in rows if r["kind"] == "point" and r["class"] == cls]
        ax.scatter([float(r["x"]) for r in points], [float(r["y"]) for r in points], s=22, color=colour,
                   label=f"{cls} ({len(points)})", marker="s", edgecolors="none")
    # The eigenvalue classification, where the map has a linear model: rho > 1 marked over the run's class.
    growing = [r for r in rows if r["kind"] == "point" and r.get("spectral_radius") and float(r["spectral_radius"]) > 1.0]
    if growing:
        ax.scatter([float(r["x"]) for r in growing], [float(r["y"]) for r in growing], s=10, color="black",
                   marker="x", linewidths=0.7, label=f"rho > 1 ({len(growing)})")
    bound = [r for r in rows if r["kind"] == "bound"]
    if bound:
        ax.plot([float(r["x"]) for r in bound], [float(r["y"]) for r in bound], color="black", linewidth=1.5,
                label="passivity bound (with the delay)")
    if log_x:
        ax.set_xscale("log")
    if log_y:
        ax.set_yscale("log")
    points = [r for r in rows if r["kind"] == "point"]
    if points:
        xs = [float(r["x"]) for r in points]
        ys = [float(r["y"]) for r in points]
        pad = lambda lo, hi, log: (lo / 1.15, hi * 1.15) if log else (lo - 0.03 * (hi - lo), hi + 0.03 * (hi - lo))
        ax.set_xlim(*pad(min(xs), max(xs), log_x))
        ax.set_ylim(*pad(min(ys), max(ys), log_y))
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", linewidth=0.3)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=4, frameon=False)
    fig.tight_layout()
    save(fig, out)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("kind", choices=["work-precision", "drift", "closed-loop", "stability"])
    parser.add_argument("csv")
    parser.add_argument("out")
    parser.add_argument("--title", default="")
    parser.add_argument("--xlabel", default="x")
    parser.add_argument("--ylabel", default="y")
    parser.add_argument("--linear-x", action="store_true")
    parser.add_argument("--linear-y", action="store_true")
    args = parser.parse_args()
    rows = read_rows(args.csv)
    if not rows:
        sys.exit(f"plot_report.py: {args.csv} has no rows")
    if args.kind == "work-precision":
        work_precision(rows, args.out)
    elif args.kind == "drift":
        drift(rows, args.out)
    elif args.kind == "closed-loop":
        closed_loop(rows, args.out)
    else:
        stability(rows, args.out, args.title, args.xlabel, args.ylabel, not args.linear_x, not args.linear_y)


if __name__ == "__main__":
    main()
