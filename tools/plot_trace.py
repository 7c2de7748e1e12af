#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Plot a `toonforce sim` trace (columns: tools/sim/include/toonforce/sim/sim_trace.hpp).

Usage: plot_trace.py [--kind auto|stroke|wall|cliff|overview] [--title TEXT]
                     [--gap XMIN XMAX] [--threshold SPEED] TRACE.csv OUT.png|OUT.svg

--gap and --threshold describe a cliff whose gap runs along x (metres, m/s) for the cliff
layout; `toonforce sim` passes them when the scene has such a cliff.

Layouts:
  stroke    figure 1: speed along the stroke against the hand's intended speed, how far the
            handle leads or lags the hand's aim, and the tangential force;
  wall      figures 2-3: height of the handle against time (true and as measured), the
            hand's aim, the surface, contact and the impact transient;
  cliff     figure 4: the handle's path (height against x) over the gap, and height and
            lateral speed against time with the cliff's state;
  overview  position, velocity and force against time;
  auto      cliff if the scene has a cliff, wall if an impact transient ran, else overview.

Needs matplotlib (Debian: python3-matplotlib; tools/setup-deps installs it). Output is
deterministic: no dates or versions are written into the files.
"""

import argparse
import csv
import math
import re
import sys

try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    sys.exit("plot_trace.py: matplotlib is missing: install python3-matplotlib (tools/setup-deps does)")

MM = 1000.0


def read_trace(path):
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        needed = {"t", "x", "z", "true_x", "true_z", "hand_x", "hand_z", "fx", "fz", "contact"}
        missing = needed - set(reader.fieldnames or [])
        if missing:
            sys.exit(f"plot_trace.py: {path}: not a sim trace (missing columns: {', '.join(sorted(missing))})")
        columns = {name: [] for name in reader.fieldnames}
        for row in reader:
            for name, value in row.items():
                columns[name].append(float(value) if value not in ("", None) else math.nan)
    if not columns["t"]:
        sys.exit(f"plot_trace.py: {path}: the trace has no rows")
    # The effects' values are named after their effect ("surface1.impact_t", "cliff1.state"):
    # the figures use any surface's running impact and the first cliff's state.
    n = len(columns["t"])
    impacts = [columns[name] for name in columns if re.fullmatch(r"surface\d+\.impact_t", name)]
    columns["impact_t"] = [next((col[i] for col in impacts if not math.isnan(col[i])), math.nan) for i in range(n)]
    cliff = next((name for name in columns if re.fullmatch(r"cliff\d+\.state", name)), None)
    columns["cliff_state"] = columns[cliff] if cliff else [math.nan] * n
    return columns


def spans(t, flags):
    """(start, end) time intervals where flags are true."""
    out, start = [], None
    for i, flag in enumerate(flags):
        if flag and start is None:
            start = t[i]
        if not flag and start is not None:
            out.append((start, t[i]))
            start = None
    if start is not None:
        out.append((start, t[-1]))
    return out


def shade(ax, intervals, color, label):
    for i, (a, b) in enumerate(intervals):
        ax.axvspan(a, b, color=color, alpha=0.18, lw=0, label=label if i == 0 else None)


def derivative(t, values):
    out = [0.0] * len(values)
    for i in range(1, len(values)):
        dt = t[i] - t[i - 1]
        out[i] = (values[i] - values[i - 1]) / dt if dt > 0 else out[i - 1]
    if len(values) > 1:
        out[0] = out[1]
    return out


def contact_spans(c):
    return spans(c["t"], [v == 1.0 for v in c["contact"]])


def plot_stroke(c, fig):
    t = c["t"]
    speed = [math.hypot(vx, vy) for vx, vy in zip(c["true_vx"], c["true_vy"])]
    hand_speed = [math.hypot(a, b) for a, b in zip(derivative(t, c["hand_x"]), derivative(t, c["hand_y"]))]
    lead = [(x - h) * MM for x, h in zip(c["true_x"], c["hand_x"])]
    axes = fig.subplots(3, 1, sharex=True)
    touching = contact_spans(c)
    axes[0].plot(t, speed, color="tab:blue", label="handle")
    axes[0].plot(t, hand_speed, color="0.3", ls="--", label="hand's intent")
    axes[0].set_ylabel("speed along x [m/s]")
    axes[1].plot(t, lead, color="tab:purple")
    axes[1].axhline(0.0, color="0.5", lw=0.8)
    axes[1].set_ylabel("handle ahead of\nthe hand's aim [mm]")
    axes[2].plot(t, c["fx"], color="tab:red", label="tangential $f_x$")
    axes[2].plot(t, c["fz"], color="tab:green", label="normal $f_z$")
    axes[2].set_ylabel("commanded force [N]")
    axes[2].set_xlabel("time [s]")
    for ax in axes:
        shade(ax, touching, "tab:orange", "in contact")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper left", fontsize=8)
    axes[2].legend(loc="upper left", fontsize=8)


def plot_wall(c, fig):
    t = c["t"]
    axes = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    touching = contact_spans(c)
    transient = spans(t, [not math.isnan(v) for v in c["impact_t"]])
    ax = axes[0]
    ax.plot(t, [z * MM for z in c["true_z"]], color="tab:blue", label="handle height")
    ax.plot(t, [z * MM for z in c["z"]], color="tab:cyan", lw=0.8, alpha=0.8, label="as measured (delayed, 20 um steps)")
    ax.plot(t, [z * MM for z in c["hand_z"]], color="0.3", ls="--", label="hand's aim")
    ax.axhline(0.0, color="k", lw=1.2, label="wall surface")
    ax.set_ylabel("height z [mm]")
    # Zoom on the contact: the approach leaves the top, the rebound and oscillation fill it.
    contact_z = [z * MM for z, contact in zip(c["true_z"], c["contact"]) if contact == 1.0]
    first = next((i for i, contact in enumerate(c["contact"]) if contact == 1.0), None)
    if contact_z and first is not None:
        after = [z * MM for z in c["true_z"][first:]] + [z * MM for z in c["hand_z"][first:]]
        ax.set_ylim(min(after) - 1.0, max(15.0, max(after) + 2.0))
    axes[1].plot(t, c["fz"], color="tab:green", label="commanded $f_z$")
    axes[1].plot(t, c["device_fz"], color="tab:olive", lw=0.8, ls=":", label="device (saturated, quantised)")
    axes[1].set_ylabel("force [N]")
    axes[1].set_xlabel("time [s]")
    for a in axes:
        shade(a, touching, "tab:orange", "in contact")
        shade(a, transient, "tab:red", "impact transient")
        a.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize=8)
    axes[1].legend(loc="upper right", fontsize=8)


def plot_cliff(c, fig, gap=None, threshold=None):
    t = c["t"]
    fallen = [v == 1.0 for v in c["cliff_state"]]
    axes = fig.subplots(3, 1, gridspec_kw={"height_ratios": [1.3, 1, 1]})
    ax = axes[0]
    ax.plot([x * MM for x in c["true_x"]], [z * MM for z in c["true_z"]], color="tab:blue", label="handle path")
    ax.plot([x * MM for x, f in zip(c["true_x"], fallen) if f], [z * MM for z, f in zip(c["true_z"], fallen) if f],
            ".", ms=2, color="tab:red", label="fallen")
    if gap is None:
        ax.axhline(0.0, color="k", lw=1.2, label="ground")
    else:
        lo, hi = min(c["true_x"] + [gap[0]]) * MM - 5.0, max(c["true_x"] + [gap[1]]) * MM + 5.0
        ax.plot([lo, gap[0] * MM], [0.0, 0.0], color="k", lw=2.0, label="ground (ledges)")
        ax.plot([gap[1] * MM, hi], [0.0, 0.0], color="k", lw=2.0)
        ax.axvspan(gap[0] * MM, gap[1] * MM, color="0.5", alpha=0.15, lw=0, label="gap")
    low = min(min(c["true_z"]) * MM, -12.0)
    ax.set_ylim(low - 1.0, 3.0)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("height z [mm]")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left", fontsize=8)
    speed = [math.hypot(vx, vy) for vx, vy in zip(c["vx"], c["vy"])]
    axes[1].plot(t, [z * MM for z in c["true_z"]], color="tab:blue", label="handle height")
    axes[1].plot(t, [z * MM for z in c["hand_z"]], color="0.3", ls="--", label="hand's aim")
    axes[1].set_ylabel("z [mm]")
    axes[1].set_ylim(low - 1.0, 3.0)
    axes[2].plot(t, speed, color="tab:purple", label="lateral speed the controller saw")
    if threshold is not None:
        axes[2].axhline(threshold, color="tab:red", ls="--", lw=1.0, label="speed threshold")
    axes[2].set_ylabel("speed [m/s]")
    axes[2].set_xlabel("time [s]")
    for a in axes[1:]:
        shade(a, spans(t, fallen), "tab:red", "cliff state: fallen")
        a.grid(alpha=0.3)
        a.legend(loc="upper right", fontsize=8)


def plot_overview(c, fig):
    t = c["t"]
    axes = fig.subplots(3, 1, sharex=True)
    for name, color in (("true_x", "tab:blue"), ("true_y", "tab:orange"), ("true_z", "tab:green")):
        axes[0].plot(t, [v * MM for v in c[name]], color=color, label=name[-1])
    axes[0].set_ylabel("position [mm]")
    for name, color in (("true_vx", "tab:blue"), ("true_vy", "tab:orange"), ("true_vz", "tab:green")):
        axes[1].plot(t, c[name], color=color, label=name[-2:])
    axes[1].set_ylabel("velocity [m/s]")
    for name, color in (("fx", "tab:blue"), ("fy", "tab:orange"), ("fz", "tab:green")):
        axes[2].plot(t, c[name], color=color, label=name)
    axes[2].set_ylabel("force [N]")
    axes[2].set_xlabel("time [s]")
    for a in axes:
        shade(a, contact_spans(c), "tab:orange", "in contact")
        a.grid(alpha=0.3)
        a.legend(loc="upper right", fontsize=8)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kind", default="auto", choices=["auto", "stroke", "wall", "cliff", "overview"])
    parser.add_argument("--title", default="")
    parser.add_argument("--gap", nargs=2, type=float, metavar=("XMIN", "XMAX"))
    parser.add_argument("--threshold", type=float)
    parser.add_argument("trace")
    parser.add_argument("out")
    args = parser.parse_args()
    if not (args.out.endswith(".png") or args.out.endswith(".svg")):
        sys.exit(f"plot_trace.py: {args.out}: the plot must be a .png or .svg file")
    c = read_trace(args.trace)
    kind = args.kind
    if kind == "auto":
        if any(v >= 0 for v in c["cliff_state"] if not math.isnan(v)):
            kind = "cliff"
        elif any(not math.isnan(v) for v in c["impact_t"]):
            kind = "wall"
        else:
            kind = "overview"
    matplotlib.rcParams["svg.hashsalt"] = "toonforce"
    fig = plt.figure(figsize=(8.0, 6.4), layout="constrained")
    if kind == "cliff":
        plot_cliff(c, fig, args.gap, args.threshold)
    else:
        {"stroke": plot_stroke, "wall": plot_wall, "overview": plot_overview}[kind](c, fig)
    if args.title:
        fig.suptitle(args.title, fontsize=11)
    metadata = {"Software": None} if args.out.endswith(".png") else {"Date": None, "Creator": None}
    fig.savefig(args.out, dpi=100, metadata=metadata)


if __name__ == "__main__":
    main()
