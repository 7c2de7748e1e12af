#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""A static bound on the stack a function of a linked Cortex-M3 image uses, its callees' included.

The deepest stack of a function is its own frame plus the deepest of its callees'; the call graph
is the image's own (arm-none-eabi-objdump's disassembly: every `bl`/`blx` target, and a branch to
another function's start, a tail call, counted as a call from inside the frame: sound, maybe
loose), libgcc's and newlib's helpers included. A frame comes from GCC's -fstack-usage (the .su
file beside each object: "static", or "dynamic,bounded", where GCC's manual says the figure is an
upper bound of all the function's stack adjustments), matched to the image's symbol through the
same function's node in -fcallgraph-info=su's .ci file (its title is the symbol, its label the .su
line's name and source position). A function without a .su line (a library helper) takes the sum
of every stack decrement in its disassembly (push, stmdb sp!, sub sp #n, a pre-indexed store
below sp, vpush): at least its deepest point, as long as no loop leaves the stack deeper each
time round (a balanced function); each such frame is reported as "disassembly".

It refuses (exit status 2, naming the function) what it cannot bound: a "dynamic" frame (alloca,
a variable-length array), recursion, an indirect call or branch, a call to an address outside any
function, a write of sp it does not understand in a function without a .su line, a .su line that
matches no symbol or two.

--painted TARGET checks an image's measured depths ("stackfn SCENE FUNCTION BYTES" lines,
main.cpp) against the bounds: each measurement at most its function's bound. --reserved checks
every bound against the image's reserved stack (__stack_size, mps2.ld).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
from dataclasses import dataclass, field


class Refusal(Exception):
    """What cannot be bounded, with where."""


@dataclass
class Function:
    symbol: str            # as in the symbol table (mangled)
    start: int
    end: int
    local_file: str | None  # the FILE symbol before a local symbol, None for a global one
    insns: list = field(default_factory=list)  # (address, mnemonic, operands)
    name: str = ""          # demangled


def run(*args: str) -> str:
    return subprocess.run(list(args), check=True, capture_output=True, text=True).stdout


# ---- the image --------------------------------------------------------------------------------

def read_image(elf: str, objdump: str) -> tuple[dict, dict]:
    """Functions by start address, and absolute symbols (value by name)."""
    functions: dict[int, Function] = {}
    absolute: dict[str, int] = {}
    current_file = None
    for line in run(objdump, "-t", elf).splitlines():
        m = re.match(r"^([0-9a-f]{8}) (.{7}) (\S+)\s+([0-9a-f]{8}) (.*)$", line)
        if not m:
            continue
        flags, section, name = m.group(2), m.group(3), m.group(5).strip().removeprefix(".hidden ")
        value = int(m.group(1), 16)
        if "f" in flags[5:]:  # "df": the object's source file, which the local symbols after it are of
            current_file = os.path.basename(name)
            continue
        if section == "*ABS*":
            absolute[name] = value
        if "F" not in flags:
            continue
        start = value & ~1
        local = current_file if flags[0] == "l" else None
        f = functions.get(start)
        size = int(m.group(4), 16)
        if f is None or size > f.end - f.start:
            functions[start] = Function(name, start, start + size, local)
    current = None
    for line in run(objdump, "-d", "--no-show-raw-insn", elf).splitlines():
        fm = re.match(r"^([0-9a-f]+) <(.+)>:$", line)
        if fm:
            current = functions.get(int(fm.group(1), 16))
            continue
        m = re.match(r"^\s*([0-9a-f]+):\s+(\S+)\s*(.*)$", line)
        if m and current is not None and not m.group(2).startswith("."):
            operands = re.sub(r"\s*[;@].*$", "", m.group(3)).strip()
            current.insns.append((int(m.group(1), 16), m.group(2), operands))
    starts = sorted(functions)
    for i, start in enumerate(starts):  # no size in the symbol table (assembly): up to its last instruction
        f = functions[start]
        if f.end <= f.start and f.insns:
            f.end = f.insns[-1][0] + 4
            if i + 1 < len(starts):
                f.end = min(f.end, starts[i + 1])
    names = [f.symbol for f in functions.values()]
    demangled = run("arm-none-eabi-c++filt", *names).splitlines() if names else []
    for f, d in zip(functions.values(), demangled):
        f.name = d
    return functions, absolute


# ---- the frames GCC reported ------------------------------------------------------------------

_SU = re.compile(r"^(.*:\d+:\d+):(.*)\t(\d+)\t(\S+)$")
_CI_NODE = re.compile(r'^node: \{ title: "(.*?)" label: "(.*?)"')


def read_frames(objects: list) -> dict:
    """(local file or None, symbol) -> (bytes, qualifier, .su line), from the .su and .ci files
    under the object directories."""
    su: dict = {}
    ci: dict = {}
    for top in objects:
        for root, _, files in os.walk(top):
            for fname in files:
                path = os.path.join(root, fname)
                if fname.endswith(".su"):
                    for line in open(path):
                        m = _SU.match(line.rstrip("\n"))
                        if not m:
                            raise Refusal(f"{path}: a line that is not -fstack-usage's: {line.strip()!r}")
                        su.setdefault((m.group(1), m.group(2)), set()).add((int(m.group(3)), m.group(4), line.strip()))
                elif fname.endswith(".ci"):
                    for line in open(path):
                        m = _CI_NODE.match(line)
                        if not m:
                            continue
                        parts = m.group(2).split("\\n")
                        if len(parts) < 3 or not parts[2].endswith(")"):
                            continue  # a callee's node (no frame of its own here)
                        title = m.group(1)
                        # A local symbol is titled "SOURCE:symbol" (symbols have no ':').
                        source, _, symbol = title.rpartition(":")
                        local = os.path.basename(source) if source else None
                        ci[(parts[1], parts[0])] = (local, symbol)
    frames: dict = {}
    for key, entries in su.items():
        if key not in ci:
            raise Refusal(f"no -fcallgraph-info node for the .su line of {key[1]} ({key[0]}): cannot match it to a symbol")
        if len(entries) > 1:
            raise Refusal(f"two .su frames for {key[1]} ({key[0]}): {sorted(entries)}")
        frames[ci[key]] = next(iter(entries))
    return frames


# ---- the bound --------------------------------------------------------------------------------

_BRANCH = re.compile(r"^(b|bl|blx|cbz|cbnz)(eq|ne|cs|cc|hs|lo|mi|pl|vs|vc|hi|ls|ge|lt|gt|le)?(\.n|\.w)?$")


def reg_count(operands: str) -> int:
    inside = re.search(r"\{(.*)\}", operands)
    if not inside:
        raise Refusal(f"no register list in {operands!r}")
    n = 0
    for part in inside.group(1).split(","):
        part = part.strip()
        rng = re.match(r"^([a-z]+)(\d+)-[a-z]+(\d+)$", part)
        n += int(rng.group(3)) - int(rng.group(2)) + 1 if rng else 1
    return n


def scanned_frame(f: Function) -> int:
    """Every stack decrement in the function's body, added up."""
    total = 0
    for addr, mnemonic, ops in f.insns:
        base = re.sub(r"(\.n|\.w)$", "", mnemonic)
        if base in ("push", "stmdb") and (base == "push" or ops.startswith("sp!")):
            total += 4 * reg_count(ops)
        elif base == "vpush":
            total += (8 if "{d" in ops else 4) * reg_count(ops)
        elif re.match(r"^subw?$", base) and re.match(r"^sp, (sp, )?#\d+$", ops):
            total += int(ops.rsplit("#", 1)[1])
        elif re.match(r"^str[bhd]?$", base) and re.search(r"\[sp, #-(\d+)\]!$", ops):
            total += int(re.search(r"\[sp, #-(\d+)\]!$", ops).group(1))
        elif base in ("pop", "ldmia", "ldm") or (base == "add" and re.match(r"^sp, (sp, )?#\d+$", ops)) \
                or re.match(r"^ldr[bhd]?$", base) and re.search(r"\[sp\], #\d+$", ops):
            continue  # the stack given back
        elif ops.startswith("sp,") and base not in ("cmp", "cmn", "tst", "teq") \
                and not re.match(r"^(str|ldr)", base):
            raise Refusal(f"{f.name} at {addr:#x}: `{mnemonic} {ops}` writes sp in a way this does not bound")
        elif base == "msr" and re.match(r"^(msp|psp)", ops):
            raise Refusal(f"{f.name} at {addr:#x}: `{mnemonic} {ops}` changes the stack pointer")
    return total


def fixed_frame(f: Function) -> bool:
    """Whether f moves sp only in its prologue (every decrement before its first branch or call)
    and otherwise only gives the stack back: then its sp at every call is the one it has after
    its prologue, which is where main.cpp's painted window starts."""
    branched = False
    for _, mnemonic, ops in f.insns:
        base = re.sub(r"(\.n|\.w)$", "", mnemonic)
        if _BRANCH.match(mnemonic) or base.startswith("bx") or base in ("tbb", "tbh"):
            branched = True
            continue
        decrement = (base in ("push", "vpush") or (base == "stmdb" and ops.startswith("sp!"))
                     or (re.match(r"^subw?$", base) and ops.startswith("sp,"))
                     or re.search(r"\[sp, #-\d+\]!$", ops) is not None)
        other = ops.startswith("sp,") and not decrement and base not in ("cmp", "cmn", "tst", "teq", "add") \
            and not re.match(r"^(str|ldr)", base)
        if (decrement and branched) or other:
            return False
    return True


def callees(f: Function, functions: dict) -> list:
    out = []
    for addr, mnemonic, ops in f.insns:
        m = _BRANCH.match(mnemonic)
        if m:
            t = re.match(r"^(?:r\d+, )?([0-9a-f]+)\b", ops)
            if not t:  # blx rN
                raise Refusal(f"{f.name} at {addr:#x}: indirect call `{mnemonic} {ops}`")
            target = int(t.group(1), 16)
            if m.group(1) in ("bl", "blx") or not (f.start <= target < f.end):
                callee = functions.get(target)
                if callee is None:
                    raise Refusal(f"{f.name} at {addr:#x}: `{mnemonic} {ops}` goes to {target:#x}, no function's start")
                out.append(callee)
        elif mnemonic.startswith("bx") and ops != "lr":
            raise Refusal(f"{f.name} at {addr:#x}: indirect branch `{mnemonic} {ops}`")
        elif re.match(r"^(mov|add|ldr)", mnemonic) and ops.startswith("pc,") and not re.search(r"\[sp\]", ops):
            raise Refusal(f"{f.name} at {addr:#x}: indirect branch `{mnemonic} {ops}`")
        elif re.match(r"^(ldm|pop)", mnemonic) and "pc" in ops and not (mnemonic.startswith("pop") or ops.startswith("sp!")):
            raise Refusal(f"{f.name} at {addr:#x}: indirect branch `{mnemonic} {ops}`")
    return out


@dataclass
class Depth:
    bytes: int
    chain: list  # (function name, frame bytes, where the frame came from), outermost first


class Analysis:
    def __init__(self, functions: dict, frames: dict):
        self.functions = functions
        self.frames = frames
        self.done: dict[int, Depth] = {}

    def frame(self, f: Function) -> tuple[int, str]:
        # A local symbol: its own object's line. A global or weak one (GCC titles a weak
        # function's node with its source too): the largest of the objects' lines of that symbol
        # (copies of one inline function; one of them was linked).
        keys = [(f.local_file, f.symbol)] if f.local_file else [k for k in self.frames if k[1] == f.symbol]
        keys = [k for k in keys if k in self.frames]
        if keys:
            size, qualifier, _ = max(self.frames[k] for k in keys)
            if qualifier not in ("static", "dynamic,bounded"):
                raise Refusal(f"{f.name}: its frame is {qualifier} (-fstack-usage: {size} bytes and more)")
            return size, f".su {qualifier}"
        return scanned_frame(f), "disassembly"

    def depth(self, f: Function, active: tuple = ()) -> Depth:
        if f.start in self.done:
            return self.done[f.start]
        if f.start in active:
            raise Refusal(f"recursion: {' -> '.join(self.functions[a].name for a in active)} -> {f.name}")
        size, source = self.frame(f)
        deepest = Depth(0, [])
        for c in callees(f, self.functions):
            d = self.depth(c, active + (f.start,))
            if d.bytes > deepest.bytes:
                deepest = d
        result = Depth(size + deepest.bytes, [(f.name, size, source)] + deepest.chain)
        self.done[f.start] = result
        return result


def scene_of(function: str) -> str:
    """wall from Run<toonforce::mcu::image::WallScene>::spec_tick(...) (as check_bound.py)."""
    m = re.search(r"Run<toonforce::mcu::image::(\w+)Scene>::", function)
    return re.sub(r"(?<!^)([A-Z])", r"_\1", m.group(1)).lower() if m else "-"


def read_painted(path: str) -> dict:
    painted = {}
    for line in open(path):
        w = line.split()
        if len(w) == 4 and w[0] == "stackfn":
            painted[(w[1], w[2])] = int(w[3])
    return painted


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("elf")
    p.add_argument("--objects", action="append", required=True, metavar="DIR",
                   help="a directory with the image's objects' .su and .ci files (searched recursively)")
    p.add_argument("--entry", action="append", required=True, metavar="LABEL=REGEX",
                   help="a function to bound: LABEL=REGEX on demangled names (each match is bounded)")
    p.add_argument("--objdump", default="arm-none-eabi-objdump")
    p.add_argument("--painted", metavar="TARGET",
                   help="the image's output: each 'stackfn SCENE LABEL BYTES' must be at most the bound of LABEL's "
                        "function of SCENE's Run<> (SCENE '-' for a function of no scene), and every bound must have one")
    p.add_argument("--reserved", action="store_true", help="each bound must be within __stack_size")
    p.add_argument("--fixed-callers", action="store_true",
                   help="each function that calls a bounded one must have a fixed frame (sp moved only in its "
                        "prologue, fixed_frame): what --painted's measurement below the caller's sp assumes")
    p.add_argument("--chain", action="store_true", help="print each bound's deepest chain")
    p.add_argument("--json", help="write the bounds here as JSON")
    args = p.parse_args(argv)
    name = os.path.basename(args.elf)
    try:
        functions, absolute = read_image(args.elf, args.objdump)
        analysis = Analysis(functions, read_frames(args.objects))
        results = []
        for spec in args.entry:
            label, _, regex = spec.partition("=")
            matches = [f for f in functions.values() if re.search(regex, f.name)]
            if not matches:
                raise Refusal(f"no function matches {regex!r} ({label})")
            for f in sorted(matches, key=lambda f: f.name):
                d = analysis.depth(f)
                results.append({"label": label, "function": f.name, "scene": scene_of(f.name), "bytes": d.bytes,
                                "chain": d.chain})
    except Refusal as e:
        print(f"stack_bound: {name}: cannot bound: {e}", file=sys.stderr)
        return 2
    failed = False
    if args.fixed_callers:
        bounded = {f.start for f in functions.values() if any(f.name == r["function"] for r in results)}
        for f in functions.values():
            calls = set()
            for _, mnemonic, ops in f.insns:
                t = re.match(r"^(?:r\d+, )?([0-9a-f]+)\b", ops) if _BRANCH.match(mnemonic) else None
                if t:
                    calls.add(int(t.group(1), 16))
            if calls & bounded and not fixed_frame(f):
                print(f"stack_bound: {name}: {f.name} calls a bounded function and moves sp after its prologue: "
                      f"a depth painted below its sp is not the callee's alone", file=sys.stderr)
                failed = True
    painted = read_painted(args.painted) if args.painted else None
    reserved = absolute.get("__stack_size")
    if args.reserved and reserved is None:
        print(f"stack_bound: {name}: no __stack_size symbol", file=sys.stderr)
        return 2
    for r in results:
        line = f"{r['label']}\t{r['bytes']}"
        if painted is not None:
            measured = painted.get((r["scene"], r["label"]))
            if measured is None:
                print(f"stack_bound: {name}: no painted depth of {r['label']} for scene {r['scene']!r}", file=sys.stderr)
                failed = True
            else:
                r["painted"] = measured
                line += f"\tpainted {measured}"
                if measured > r["bytes"]:
                    print(f"stack_bound: {name}: {r['function']} used {measured} bytes of stack under QEMU, "
                          f"past its static bound of {r['bytes']}", file=sys.stderr)
                    failed = True
        if args.reserved and r["bytes"] > reserved:
            print(f"stack_bound: {name}: {r['function']} may use {r['bytes']} bytes of stack, past the "
                  f"{reserved} reserved (__stack_size)", file=sys.stderr)
            failed = True
        print(f"{line}\t{r['function']}")
        if args.chain:
            for fn, size, source in r["chain"]:
                print(f"    {size:6d}  {source:18s} {fn}")
    if args.reserved:
        print(f"reserved\t{reserved}")
    if args.json:
        with open(args.json, "w") as out:
            json.dump({"elf": args.elf, "reserved": reserved, "bounds": results}, out, indent=1)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
