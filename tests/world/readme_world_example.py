#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Runs the README's world example (the block after <!-- world-command -->: `sim`, then `run`)
as written, with the built program and the traces in a scratch folder, and checks what the
README says of each: the couplings' forces on the two devices are exact negations on every row,
and after the right device's cable is pulled every device is held at zero force from the tick
after its fault."""
import argparse
import csv
import re
import shlex
import subprocess
import sys
import tempfile
from pathlib import Path


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--source-dir", required=True)
    parser.add_argument("--binary", required=True)
    args = parser.parse_args()
    source = Path(args.source_dir)
    readme = (source / "README.md").read_text(encoding="utf-8")
    m = re.search(r"<!-- world-command -->\n```sh\n(.+?)\n```", readme, re.S)
    if not m:
        print("README.md: no <!-- world-command --> block")
        return 1
    lines = [line for line in m.group(1).splitlines() if line.strip()]
    commands = [shlex.split(line)[1] if len(shlex.split(line)) > 1 else "" for line in lines]
    if commands != ["sim", "run"]:
        print(f"README.md: the world block should run `sim`, then `run`: {m.group(1)}")
        return 1
    failed = 0
    for line in lines:
        failed += check_command(line, source, args.binary)
    return 1 if failed else 0


def check_command(line: str, source: Path, binary: str) -> int:
    words = shlex.split(line)
    if words[0] != "build/release/bin/toonforce" or "--trace" not in words:
        print(f"README.md: the world command should run build/release/bin/toonforce with --trace: {line}")
        return 1
    with tempfile.TemporaryDirectory() as scratch:
        trace = Path(scratch) / "two_players.csv"
        words[0] = binary
        words[words.index("--trace") + 1] = str(trace)
        done = subprocess.run(words, cwd=source, capture_output=True, text=True, timeout=300)
        if done.returncode != 0:
            print(f"{words[1]}: exit {done.returncode}\n{done.stdout}\n{done.stderr}")
            return 1
        print(done.stdout, end="")
        with trace.open(newline="") as f:
            rows = list(csv.DictReader(f))
    problems = []
    # `run` skips (and counts) the deadlines a loaded host misses: fewer rows than `sim`.
    if len(rows) < (1000 if words[1] == "sim" else 500):
        problems.append(f"only {len(rows)} rows")
    coupled = 0
    held_seen = False
    held_rows = 0
    for row in rows:
        for axis in "xyz":
            left, right = float(row[f"left.coupling_f{axis}"]), float(row[f"right.coupling_f{axis}"])
            if left != -right:
                problems.append(f"t = {row['t']}: left.coupling_f{axis} {left} is not -right's {right}")
        coupled += abs(float(row["left.coupling_fx"])) > 0.1
        if held_seen:
            held_rows += 1
            for name in ("left.fx", "left.fy", "left.fz", "right.fx", "right.fy", "right.fz"):
                if float(row[name]) != 0.0:
                    problems.append(f"t = {row['t']}: {name} = {row[name]} while every device is held")
        held_seen = held_seen or row["held"] == "1"
    if coupled < (100 if words[1] == "sim" else 20):
        problems.append(f"the coupling pulled on only {coupled} rows: nothing was compared")
    if held_rows < (100 if words[1] == "sim" else 20):
        problems.append(f"held for only {held_rows} rows after the fault")
    if "device 'right' latched a fault" not in done.stdout:
        problems.append("the summary does not say which device stopped the world")
    for p in problems[:20]:
        print(f"{words[1]}: {p}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
