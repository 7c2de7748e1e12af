#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""The bounds table of docs/performance/wcet.md, from check_bound.py's JSON of each scene
image: per scene and loop variant the static bound in instructions and cycles, the dearest tick
measured under QEMU over the bundled motions and with the searched inputs, that tick as a share
of the bound (the witness), how much of the longest path no tick ran, and the highest servo
rate whose period the cycle bound fits in at the AN385's 25 MHz.

The table sits between the two marker lines below in the document. --check (CTest
mcu_m3_wcet_bounds_table) fails when the document's table is not the one the images give, so
the figures cannot drift from the code; --write puts it there.

    bounds_table.py --doc docs/performance/wcet.md (--check | --write) SCENE.json...
"""
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import doc_section  # noqa: E402

BEGIN = "<!-- wcet bounds: tools/mcu/wcet/bounds_table.py writes the table below -->"
END = "<!-- wcet bounds: end -->"
CLOCK_HZ = 25e6  # the AN385's Cortex-M3
VARIANTS = {"loop": "replay's loop", "every": "every-stage loop", "effects": "effects + safety"}
HEADER = ["| scene | variant | bound [instructions] | bound [cycles] | measured max, bundled | with the searched "
          "| of the bound | never run | rate the bound fits at 25 MHz |",
          "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]


def table(paths: list) -> list:
    lines = list(HEADER)
    for path in paths:
        with open(path) as f:
            rows = {r["variant"]: r for r in json.load(f)["rows"]}
        for variant, name in VARIANTS.items():
            r = rows.get(variant)
            if r is None:
                raise SystemExit(f"bounds_table: {path}: no {variant} row")
            bound, cycles = r["bound_instructions"], r["bound_cycles"]
            share = f"{100 * r['measured_max'] / bound:.0f} %"
            lines.append(f"| {r['scene']} | {name} | {bound:,} | {cycles:,} | {r['measured_max_bundled']:,} | "
                         f"{r['measured_max']:,} | {share} | {r.get('path_never_run', '-')} | "
                         f"{round(CLOCK_HZ / cycles):,} Hz |")
    return lines


if __name__ == "__main__":
    sys.exit(doc_section.main("bounds_table", BEGIN, END, "json", table,
                              "bounds table is not the images' (a bound or a measured tick changed)"))
