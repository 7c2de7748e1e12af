#!/usr/bin/python3
"""The bounds table of docs/PERFORMANCE.md (issue 29), from check_bound.py's JSON of each scene
image: per scene and loop variant the static bound in instructions and cycles, the dearest tick
measured under QEMU over the bundled motions and with the searched inputs, that tick as a share
of the bound (the witness), how much of the longest path no tick ran, and the highest servo
rate whose period the cycle bound fits in at the AN385's 25 MHz.

The table sits between the two marker lines below in the document. --check (CTest
mcu_m3_wcet_bounds_table) fails when the document's table is not the one the images give, so
the figures cannot drift from the code; --write puts it there.

    bounds_table.py --doc docs/PERFORMANCE.md (--check | --write) SCENE.json...
"""
import argparse
import json
import sys

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


def main() -> int:
    p = argparse.ArgumentParser()
    p.add_argument("--doc", required=True)
    mode = p.add_mutually_exclusive_group(required=True)
    mode.add_argument("--check", action="store_true")
    mode.add_argument("--write", action="store_true")
    p.add_argument("json", nargs="+")
    a = p.parse_args()
    with open(a.doc) as f:
        doc = f.read().split("\n")
    if doc.count(BEGIN) != 1 or doc.count(END) != 1 or doc.index(BEGIN) > doc.index(END):
        print(f"bounds_table: {a.doc} must hold the line '{BEGIN}' once, then '{END}' once", file=sys.stderr)
        return 1
    begin, end = doc.index(BEGIN), doc.index(END)
    want = table(a.json)
    have = doc[begin + 1:end]
    if a.write:
        with open(a.doc, "w") as f:
            f.write("\n".join(doc[:begin + 1] + want + doc[end:]))
        return 0
    if have != want:
        for k in range(max(len(have), len(want))):
            h = have[k] if k < len(have) else "(none)"
            w = want[k] if k < len(want) else "(none)"
            if h != w:
                print(f"bounds_table: {a.doc} line {begin + 2 + k}:\n  has  {h}\n  want {w}", file=sys.stderr)
        print(f"bounds_table: {a.doc}'s bounds table is not the images' (a bound or a measured tick changed): "
              f"tools/mcu/wcet/bounds_table.py --doc {a.doc} --write " + " ".join(a.json), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
