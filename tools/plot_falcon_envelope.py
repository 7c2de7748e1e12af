#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Map of the Novint Falcon's force envelope over its workspace (docs/FALCON.md, "Force envelope").

Usage:
  build/release/bin/toonforce falcon envelope --csv ENVELOPE.csv [--calibration FILE]
  /usr/bin/python3 tools/plot_falcon_envelope.py ENVELOPE.csv OUT.png

Reads the grid `toonforce falcon envelope --csv` writes (scene frame: x right, y away from the
user, z up; the force the +-4095 motor words allow along x, y, z and in every direction) and
draws, for four depths y, the x-z plane as the person at the Falcon sees it, one row per
direction. Grey: out of the kinematics' reach. Contours at 4 N and 8 N. Needs matplotlib
(Debian: python3-matplotlib). Deterministic output: no dates or versions in the file.
"""

import csv
import math
import sys

try:
    import matplotlib

    matplotlib.use("Agg")
    matplotlib.rcParams["svg.hashsalt"] = "toonforce"
    import matplotlib.pyplot as plt
    import numpy as np
except ImportError as e:  # pragma: no cover
    sys.exit(f"plot_falcon_envelope.py needs matplotlib and numpy (Debian: python3-matplotlib): {e}")

ROWS = [("along_x_n", "along x (left-right)"), ("along_z_n", "along z (up-down)"),
        ("along_y_n", "along y (in-out)"), ("every_direction_n", "in every direction")]
DEPTHS_MM = [-50.0, -20.0, 0.0, 25.0]  # y: toward the user (grip pulled out) ... pushed in
VMAX_N = 20.0


def main(argv):
    if len(argv) != 3:
        sys.exit(__doc__)
    source, out = argv[1], argv[2]
    title = ""
    points = {}
    with open(source, newline="") as f:
        first = f.readline()
        if first.startswith("#"):
            title = first[1:].strip().replace("toonforce falcon envelope; ", "")
        else:
            f.seek(0)
        for row in csv.DictReader(f):
            key = tuple(round(float(row[c]) * 1000.0, 3) for c in ("x_m", "y_m", "z_m"))
            points[key] = {name: (float(row[name]) if row[name] != "" else math.nan) for name, _ in ROWS}
    xs = sorted({k[0] for k in points})
    ys = sorted({k[1] for k in points})
    zs = sorted({k[2] for k in points})
    depths = [min(ys, key=lambda y: abs(y - d)) for d in DEPTHS_MM]

    fig, axes = plt.subplots(len(ROWS), len(depths), figsize=(3.2 * len(depths), 3.0 * len(ROWS)),
                             sharex=True, sharey=True, constrained_layout=True)
    cmap = plt.get_cmap("viridis").copy()
    cmap.set_bad("#c8c8c8")
    image = None
    for r, (name, label) in enumerate(ROWS):
        for c, y in enumerate(depths):
            grid = np.array([[points.get((x, y, z), {}).get(name, math.nan) for x in xs] for z in zs])
            ax = axes[r][c]
            image = ax.imshow(np.ma.masked_invalid(grid), origin="lower", cmap=cmap, vmin=0.0, vmax=VMAX_N,
                              extent=(xs[0], xs[-1], zs[0], zs[-1]), aspect="equal", interpolation="nearest")
            finite = np.where(np.isfinite(grid), grid, VMAX_N)
            contours = ax.contour(xs, zs, finite, levels=[4.0, 8.0], colors=["#d62728", "white"], linewidths=1.0)
            ax.clabel(contours, fmt="%.0f N", fontsize=7)
            ax.plot([0], [0], marker="+", color="black")
            if r == 0:
                ax.set_title(f"y = {y:.0f} mm" + (" (toward you)" if y < 0 else " (away)" if y > 0 else " (centre)"),
                             fontsize=9)
            if c == 0:
                ax.set_ylabel(f"{label}\nz [mm]", fontsize=9)
            if r == len(ROWS) - 1:
                ax.set_xlabel("x [mm]", fontsize=9)
    fig.colorbar(image, ax=axes, shrink=0.6, label="largest force the motor words allow [N]")
    fig.suptitle("Novint Falcon: force envelope over the workspace (scene frame, seen by the user)\n" + title, fontsize=10)
    fig.savefig(out, dpi=90, metadata={"Software": None} if out.endswith(".png") else None)


if __name__ == "__main__":
    main(sys.argv)
