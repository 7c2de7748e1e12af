#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""The two worst-case analysers must agree: wcet.py (GNU objdump, an integer program solved by
glpsol) and longest_path.py (LLVM's llvm-objdump, a plain longest path on the acyclic graph),
run on the same image's counted functions, give the same instructions and the same cycles, at
each wait-state count asked for. Two computations that share no code agreeing exactly is the
check that neither has a decoding or a graph error the other would not make.

    compare_bounds.py IMAGE.elf [--wait-states 0,1] [--entry LABEL=REGEX ...] [--llvm-objdump PATH]

Prints one line per function and wait-state count; exits 1 on any difference (or when the two
bound different sets of functions), 2 when either analyser refuses the image.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
# The counted functions of the images (check_bound.py's): replay's loop, the every-stage loop,
# the effects plus safety.
ENTRIES = ["loop=::spec_tick\\(", "every=::full_tick\\(", "effects=::effects_and_safety\\("]


def run(tool: str, elf: str, wait: int, entries: list, tmp: str, *extra: str) -> dict:
    out = os.path.join(tmp, f"{tool}-{wait}.json")
    args = [sys.executable, os.path.join(HERE, tool), elf, "--wait-states", str(wait), "--json", out, *extra]
    for e in entries:
        args += ["--entry", e]
    r = subprocess.run(args, capture_output=True, text=True)
    if r.returncode != 0:
        sys.stderr.write(r.stderr)
        raise SystemExit(2)
    with open(out) as f:
        return {(b["label"], b["address"]): b for b in json.load(f)["bounds"]}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("elf")
    p.add_argument("--wait-states", default="0,1", help="comma-separated wait-state counts")
    p.add_argument("--entry", action="append", metavar="LABEL=REGEX",
                   help="functions to compare (default: the images' three counted functions)")
    p.add_argument("--llvm-objdump", default="llvm-objdump")
    args = p.parse_args(argv)
    entries = args.entry or ENTRIES
    differ = False
    with tempfile.TemporaryDirectory() as tmp:
        for wait in (int(w) for w in args.wait_states.split(",")):
            a = run("wcet.py", args.elf, wait, entries, tmp)
            d = run("longest_path.py", args.elf, wait, entries, tmp, "--llvm-objdump", args.llvm_objdump)
            if set(a) != set(d):
                print(f"different functions bounded: wcet.py {sorted(a)}, longest_path.py {sorted(d)}")
                differ = True
            for key in sorted(set(a) & set(d)):
                ba, bd = a[key], d[key]
                same = ba["instructions"] == bd["instructions"] and ba["cycles"] == bd["cycles"]
                differ |= not same
                print(f"{'ok  ' if same else 'DIFF'} W={wait} {key[0]:8s} {key[1]:#08x} instructions "
                      f"{ba['instructions']}/{bd['instructions']} cycles {ba['cycles']}/{bd['cycles']}  {ba['function'][:90]}")
    if differ:
        print(f"compare_bounds: {os.path.basename(args.elf)}: wcet.py and longest_path.py disagree", file=sys.stderr)
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
