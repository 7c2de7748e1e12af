#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Gate: every tick an image measured under QEMU stays within the static bound.

For IMAGE.elf, wcet.py bounds each scene's three counted functions (replay's loop tick
`spec_tick`, the every-stage tick `full_tick`, the effects plus safety `effects_and_safety`);
the image's run (firmware/main.cpp's "count SCENE MOTION TICKS loop SUM MAX every SUM MAX
effects SUM MAX" lines in COUNTS) gives the dearest tick measured for each. The gate is exact:
measured <= bound + window, where the window is what the count sees besides the function,
measured from the image itself (windows()): the caller's instructions between the two SysTick
readings of main.cpp's count() around the call (the `bl`, and argument loads: 7 around
spec_tick in wall.elf), less the instructions between the two readings of calibrate()'s empty
count, which the image subtracts from every count (its "calibration EMPTY NOPS" line; the
window of its 100 NOPs, measured the same way, must give NOPS, or the gate fails). An analyser
under-count of one instruction fails it. Deterministic counts only; fails (exit 1) when a
measured tick passes its bound + window, and when the analyser refuses the image or no window
can be measured (exit 2).

A ratchet besides: with --ceilings FILE, a bound above the one FILE records for that image,
scene and variant fails too (a change made a tick dearer in the worst case; if that is meant,
--update-ceilings rewrites the image's rows with its bounds, to commit with the change). The
budgets (docs/performance/wcet.md) are reported against; --gate-budget GATE fails on one (tests.cmake gates the
effects plus safety's 1,500 instructions, which every scene meets, the every-stage loop's 2,000
instructions in the images of the scenes that meet them (every-instructions), and its 2,000
instructions and 2,500 cycles in those of the scenes that meet both (every); the others stay
reported until they do).

With --covered TB_STARTS (the run's translation-block starts, run_image.cmake's COVERAGE), it
reports per variant how much of the longest path is code no tick of the run executed: where
the gap between the bound and the dearest measured tick lies. With --min-witness P it fails
when that dearest tick is under P % of its bound: the witness that the bound is tight (the
scene images play inputs built for it: the searched strikes, with and without late ticks).

    check_bound.py IMAGE.elf COUNTS [--json OUT] [--wait-states N] [--covered TB_STARTS]
                   [--min-witness PERCENT] [--ceilings FILE [--update-ceilings]]
"""
import argparse
import json
import os
import re
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import wcet  # noqa: E402  (the image's disassembly, to measure the windows)
VARIANTS = {"loop": "spec_tick", "every": "full_tick", "effects": "effects_and_safety"}


def scene_of(function: str) -> str:
    """wall from Run<toonforce::mcu::image::WallScene>::spec_tick(...)."""
    m = re.search(r"Run<toonforce::mcu::image::(\w+)Scene>::", function)
    if not m:
        raise SystemExit(f"check_bound: no scene in {function}")
    return re.sub(r"(?<!^)([A-Z])", r"_\1", m.group(1)).lower()


def bounds(elf: str, wait: int, covered: str | None) -> tuple[dict, dict, dict]:
    """(scene, variant) -> (instructions, cycles); and, with `covered`, -> how many instructions
    of that longest path the run never executed; and -> the function's name."""
    args = [sys.executable, os.path.join(HERE, "wcet.py"), elf, "--wait-states", str(wait)]
    if covered:
        args += ["--covered", covered]
    for label, fn in VARIANTS.items():
        args += ["--entry", f"{label}=::{fn}\\("]
    r = subprocess.run(args, capture_output=True, text=True)
    if r.returncode != 0:
        sys.stderr.write(r.stderr)
        raise SystemExit(r.returncode)
    out, never, names = {}, {}, {}
    for line in r.stdout.splitlines():
        label, instructions, cycles, function, *rest = line.split("\t")
        out[(scene_of(function), label)] = (int(instructions), int(cycles))
        names[(scene_of(function), label)] = function
        if rest:
            never[(scene_of(function), label)] = int(rest[0])
    return out, never, names


# ---- the count's window outside the counted function, from the image ---------------------------

SYST_CVR = 0xE000E018  # SysTick Current Value Register (ARMv7-M B3.3.2): what board::systick_now() reads
CALLER_SAVED = {"r0", "r1", "r2", "r3", "r12", "r14"}  # a call may change them (AAPCS 5.1.1)


class NoWindow(Exception):
    """A counted call whose window the image does not show in a straight line."""


def _targets(insns: list) -> set:
    """Addresses a branch can reach inside the function (another path may enter there)."""
    out = set()
    for k, insn in enumerate(insns):
        kind, target = wcet._classify(insn)
        if target is not None:
            out.add(target)
        if kind in ("jump", "cjump", "return", "creturn", "halt", "indirect") and k + 1 < len(insns):
            out.add(insns[k + 1].addr)
    return out


def _written(insn) -> set:
    """The registers an instruction may write (its first operand, pairs, lists and writeback)."""
    op = wcet.operation(insn)
    ops = insn.operands
    out = set()
    if "!" in ops or re.search(r"\]\s*,", ops) or op in ("push", "pop"):
        out |= wcet.address_registers(insn)
    if op in wcet._MULTIPLE_LOADS:
        m = re.search(r"\{([^}]*)\}", ops)
        out |= wcet._registers(m.group(1)) if m else set()
        return out
    if op in wcet._SINGLE_STORES or op in wcet._MULTIPLE_STORES or op in ("strd", "cmp", "cmn", "tst", "teq", "it",
                                                                           "nop", "msr", "b", "cbz", "cbnz", "bx"):
        if op in ("strex", "strexb", "strexh"):
            out |= wcet._registers(ops.split(",")[0])
        return out
    fields = [f.strip() for f in ops.split(",")]
    n = 2 if op in ("ldrd", "umull", "smull", "umlal", "smlal") else 1
    return out | wcet._registers(",".join(fields[:n]))


def _immediate(text: str):
    m = re.search(r"#(-?(?:0x[0-9a-f]+|\d+))", text)
    return int(m.group(1), 0) if m else None


def constants(image, insns: list) -> list:
    """For each instruction, the registers that hold a known constant whenever it runs: a
    forward data flow over the function's branches (a literal load, MOV/MOVW of an immediate
    and MOVT; a call forgets the caller-saved registers; where paths join, what they agree on)."""
    index = {insn.addr: k for k, insn in enumerate(insns)}
    state: list = [None] * len(insns)   # None: not reached yet
    state[0] = {}
    work = [0]
    while work:
        k = work.pop()
        insn = insns[k]
        regs = dict(state[k])
        kind, target = wcet._classify(insn)
        if kind == "call":
            for r in CALLER_SAVED:
                regs.pop(r, None)
        else:
            op = wcet.operation(insn)
            conditional = bool(wcet.split_mnemonic(insn.mnemonic)[1]) and kind == "plain"
            for r in _written(insn):
                value = None
                m = re.match(r"^\w+,\s*\[pc,\s*#(-?\d+)\]$", insn.operands)
                if op == "ldr" and m:
                    value = image.words.get(((insn.addr + 4) & ~3) + int(m.group(1)))
                elif op in ("mov", "movw") and re.match(r"^\w+,\s*#", insn.operands):
                    value = _immediate(insn.operands)
                elif op == "movt" and r in regs and _immediate(insn.operands) is not None:
                    value = (regs[r] & 0xFFFF) | (_immediate(insn.operands) << 16)
                if value is None or (conditional and regs.get(r) != value & 0xFFFFFFFF):
                    regs.pop(r, None)
                else:
                    regs[r] = value & 0xFFFFFFFF
        succs = []
        if kind in ("plain", "call", "creturn", "cjump") and k + 1 < len(insns):
            succs.append(k + 1)
        if kind in ("jump", "cjump") and target in index:
            succs.append(index[target])
        for s_ in succs:
            old = state[s_]
            new = dict(regs) if old is None else {r: v for r, v in old.items() if regs.get(r) == v}
            if new != old:
                state[s_] = new
                work.append(s_)
    return [st or {} for st in state]


def is_counter_read(insns: list, k: int, known: list) -> bool:
    """A plain LDR of the SysTick current value (board::systick_now())."""
    insn = insns[k]
    m = re.match(r"^(\w+),\s*\[(\w+)(?:,\s*#(-?\d+))?\]$", insn.operands)
    if wcet.split_mnemonic(insn.mnemonic) != ("ldr", "") or not m or m.group(2) == "pc":
        return False
    base = known[k].get(wcet._ALIASES.get(m.group(2), m.group(2)))
    return base is not None and base + int(m.group(3) or 0) == SYST_CVR


def _read_around(insns: list, k: int, step: int, targets: set, known: list):
    """(index, instructions stepped over) of the counter reading nearest insns[k] going `step`
    (-1 back, +1 on) along the one path there is: no branch, no other call in between, and no
    branch target, except going back into a block that only an unconditional B enters (GCC puts
    a literal pool before the call and jumps over it): the path goes on from that B, which is
    one instruction of the window. None when there is no such reading."""
    j, passed = k, 0
    while True:
        nxt = j + step
        if nxt < 0 or nxt >= len(insns):
            return None
        if insns[max(j, nxt)].addr in targets:
            if step > 0:
                return None
            entry = insns[j].addr
            jumps = [i for i, x in enumerate(insns) if wcet._classify(x) == ("jump", entry)]
            before_block = nxt  # the padding NOPs before a literal pool do not run
            while before_block > 0 and wcet.operation(insns[before_block]) == "nop":
                before_block -= 1
            falls = wcet._classify(insns[before_block])[0] in ("plain", "call", "cjump", "creturn")
            others = [i for i, x in enumerate(insns) if wcet._classify(x)[1] == entry and i not in jumps]
            if len(jumps) != 1 or falls or others:
                return None
            nxt = jumps[0]
        j = nxt
        if is_counter_read(insns, j, known):
            return j, passed
        passed += 1
        if wcet._classify(insns[j])[0] != "plain" and not (step < 0 and wcet._classify(insns[j])[0] == "jump"):
            return None


def windows(image, counted: dict) -> tuple[dict, tuple]:
    """{function start: instructions the count sees besides the function} for each counted
    function (dict of starts), and (between the empty count's readings, between the NOPs
    count's): the window of a count is its instructions strictly between its two readings,
    the function's own excepted, less those of calibrate()'s empty count (which main.cpp
    subtracts from every count). Several counted calls of one function: the widest."""
    out: dict = {}
    reads_in: dict = {}
    for f in image.functions.values():
        insns = f.insns
        if not insns or not any(wcet.split_mnemonic(i.mnemonic)[0] == "ldr" and "[pc" not in i.operands
                                for i in insns):
            continue
        targets = _targets(insns)
        known = constants(image, insns)
        for k, insn in enumerate(insns):
            kind, target = wcet._classify(insn)
            if kind == "call" and target in counted:
                before = _read_around(insns, k, -1, targets, known)
                after = _read_around(insns, k, +1, targets, known)
                if before is None or after is None:
                    continue  # a call no count is around (the plain pass)
                out[target] = max(out.get(target, 0), before[1] + 1 + after[1])
            elif kind != "call" and is_counter_read(insns, k, known):
                reads_in.setdefault(f.start, []).append(k)
    # calibrate(): the count of 100 NOPs, straight after the empty count.
    calibration = None
    for start, reads in reads_in.items():
        insns = image.functions[start].insns
        for i in range(2, len(reads)):
            a, b = reads[i - 2], reads[i - 1]
            c, d = reads[i], reads[i + 1] if i + 1 < len(reads) else None
            if d is None:
                continue
            body = insns[c + 1:d]
            if sum(1 for x in body if wcet.operation(x) == "nop") != 100:
                continue
            if calibration is not None:
                raise NoWindow("two counts of 100 NOPs")
            calibration = (b - a - 1, d - c - 1)
    if calibration is None:
        raise NoWindow("no calibration (a count of nothing, then of 100 NOPs) in the image")
    return {start: w - calibration[0] for start, w in out.items()}, calibration


def read_calibration(counts: str):
    """(EMPTY, NOPS) of the COUNTS file's calibration line, or None."""
    with open(counts) as f:
        for line in f:
            m = re.match(r"^calibration (\d+) (\d+)$", line.strip())
            if m:
                return int(m.group(1)), int(m.group(2))
    return None


SEARCHED = "search_"  # the searched inputs' motions (images.cmake names them search_SCENE_K[_late])


def measured(counts: str) -> tuple[dict, dict]:
    """(scene, variant) -> the dearest tick measured: over every motion, and over the bundled
    motions alone (not the searched inputs)."""
    worst, bundled = {}, {}
    pattern = re.compile(r"^count (\S+) (\S+) (\d+) loop \d+ (\d+) every \d+ (\d+) effects \d+ (\d+)$")
    with open(counts) as f:
        for line in f:
            m = pattern.match(line.strip())
            if not m:
                continue
            scene, searched = m.group(1), m.group(2).startswith(SEARCHED)
            for label, value in zip(VARIANTS, m.group(4, 5, 6)):
                for into in (worst,) if searched else (worst, bundled):
                    into[(scene, label)] = max(into.get((scene, label), 0), int(value))
    return worst, bundled


BUDGETS = {"every": (2000, 2500), "effects": (1500, None)}  # instructions, cycles (docs/performance/wcet.md)
# What --gate-budget can gate: a variant's whole budget, or the every-stage loop's instructions
# alone (met by more scenes than its cycles are): gate -> (variant, instructions, cycles or None).
GATES = {"every": ("every", 2000, 2500), "every-instructions": ("every", 2000, None), "effects": ("effects", 1500, None)}


def read_ceilings(path: str) -> dict:
    """(image, scene, variant) -> (instructions, cycles) from lines "IMAGE SCENE VARIANT INSTR CYCLES"."""
    out = {}
    with open(path) as f:
        for line in f:
            fields = line.split("#", 1)[0].split()
            if not fields:
                continue
            if len(fields) != 5:
                raise SystemExit(f"check_bound: {path}: expected IMAGE SCENE VARIANT INSTRUCTIONS CYCLES: {line.strip()}")
            out[tuple(fields[:3])] = (int(fields[3]), int(fields[4]))
    return out


def write_ceilings(path: str, image: str, b: dict) -> None:
    """Replaces `image`'s rows of the file (keeping its comments and the other images' rows)."""
    kept = []
    if os.path.exists(path):
        with open(path) as f:
            kept = [l for l in f if l.startswith("#") or not l.strip() or l.split()[0] != image]
    rows = [f"{image} {scene} {variant} {i} {c}\n" for (scene, variant), (i, c) in sorted(b.items())]
    with open(path, "w") as f:
        f.writelines(kept + rows)


def main() -> int:
    p = argparse.ArgumentParser()
    p.add_argument("elf")
    p.add_argument("counts")
    p.add_argument("--json")
    p.add_argument("--wait-states", type=int, default=0)
    p.add_argument("--covered", help="the run's translation-block starts (run_image.cmake COVERAGE): report the "
                                     "longest paths' code that no tick executed")
    p.add_argument("--min-witness", type=float, metavar="PERCENT",
                   help="fail when a variant's dearest measured tick is under PERCENT %% of its bound (the witness "
                        "that the bound is tight: the aim is 90)")
    p.add_argument("--ceilings", help="fail when a bound passes the one this file records (a ratchet)")
    p.add_argument("--update-ceilings", action="store_true", help="write this image's bounds into --ceilings")
    p.add_argument("--gate-budget", action="append", default=[], choices=sorted(GATES), metavar="GATE",
                   help="fail when a bound passes the budget GATE names (one the scenes meet: a variant's, "
                        "or every-instructions, the every-stage loop's instructions alone); the other budgets are "
                        "reported")
    a = p.parse_args()
    if not os.path.exists(a.counts):
        print(f"check_bound: {a.counts}: no output of the image (its run test failed or did not run)", file=sys.stderr)
        return 1
    if a.covered and not os.path.exists(a.covered):
        print(f"check_bound: {a.covered}: no coverage of the image's run (its run test failed or did not run)",
              file=sys.stderr)
        return 1
    b, never, names = bounds(a.elf, a.wait_states, a.covered)
    m, m_bundled = measured(a.counts)
    if not m:
        print(f"check_bound: {a.counts}: no count lines", file=sys.stderr)
        return 1
    image_ = wcet.Image(a.elf, "arm-none-eabi-objdump")
    starts = {image_.by_name[n].start: key for key, n in names.items()}
    try:
        per_start, (empty_between, nops_between) = windows(image_, starts)
    except NoWindow as e:
        print(f"check_bound: {a.elf}: cannot measure the count's window: {e}", file=sys.stderr)
        return 2
    window = {starts[s]: w for s, w in per_start.items()}
    failed = False
    # The image's own calibration must see what its disassembly says: 100 NOPs between the
    # readings of the NOPs count, less the empty count's, is the NOPS it printed.
    calibration = read_calibration(a.counts)
    if calibration is None or nops_between - empty_between != calibration[1]:
        print(f"over: the calibration: the image's NOPs count holds {nops_between} instructions between its readings "
              f"and its empty count {empty_between}, so it should print {nops_between - empty_between}; COUNTS has "
              f"{calibration}: the window measure does not hold for this image", file=sys.stderr)
        failed = True
    else:
        print(f"calibration: empty count {empty_between} instructions between its readings (EMPTY {calibration[0]}), "
              f"NOPs count {nops_between} (NOPS {calibration[1]})")
    rows = []
    for key in sorted(m):
        if key not in b:
            print(f"check_bound: no bound for {key[0]} {key[1]} in {a.elf}", file=sys.stderr)
            return 1
        instructions, cycles = b[key]
        worst = m[key]
        if key not in window:
            print(f"check_bound: no counted call of {names[key]} in {a.elf} (no two SysTick readings straight "
                  "around it)", file=sys.stderr)
            return 2
        w = window[key]
        ok = worst <= instructions + w
        failed = failed or not ok
        print(f"{'ok:  ' if ok else 'over:'} {key[0]} {key[1]}: measured {worst} {'<=' if ok else '>'} bound {instructions} "
              f"+ window {w} instructions; bound {cycles} cycles")
        row = {"scene": key[0], "variant": key[1], "measured_max": worst, "measured_max_bundled": m_bundled.get(key, 0),
               "bound_instructions": instructions, "bound_cycles": cycles, "window": w}
        if a.min_witness is not None and 100 * worst < a.min_witness * instructions:
            failed = True
            print(f"loose: {key[0]} {key[1]}: the dearest tick measured, {worst}, is {100 * worst / instructions:.1f} % "
                  f"of the bound {instructions}, under {a.min_witness:g} %: the bound is not shown tight (run with "
                  f"--covered to see which of its path no tick ran)")
        if key in never:
            # Where the gap between the bound and the dearest tick is: the longest path's code
            # that no tick of the run executed (wcet.py --covered --path LABEL lists it by line).
            row["path_never_run"] = never[key]
            print(f"      {key[0]} {key[1]}: measured {100 * worst / instructions:.0f} % of the bound; of the longest "
                  f"path's {instructions} instructions {never[key]} are code no tick ran; bound - never run = "
                  f"{instructions - never[key]}")
        rows.append(row)
    image = os.path.splitext(os.path.basename(a.elf))[0]
    if a.ceilings and a.update_ceilings:
        write_ceilings(a.ceilings, image, b)
        print(f"check_bound: {a.ceilings}: {image}'s bounds written")
    elif a.ceilings:
        ceilings = read_ceilings(a.ceilings)
        for (scene, variant), (instructions, cycles) in sorted(b.items()):
            ceiling = ceilings.get((image, scene, variant))
            if ceiling is None:
                print(f"over: {scene} {variant}: no ceiling in {a.ceilings} for {image} (--update-ceilings adds it)")
                failed = True
                continue
            if instructions > ceiling[0] or cycles > ceiling[1]:
                print(f"over: {scene} {variant}: bound {instructions} instructions, {cycles} cycles passes the "
                      f"recorded {ceiling[0]}, {ceiling[1]} ({a.ceilings}: a tick got dearer in the worst case)")
                failed = True
            elif (instructions, cycles) != ceiling:
                print(f"note: {scene} {variant}: bound {instructions}, {cycles} under the recorded {ceiling[0]}, "
                      f"{ceiling[1]}: --update-ceilings lowers the ratchet")
    for (scene, variant), (instructions, cycles) in sorted(b.items()):
        if variant in BUDGETS:
            max_i, max_c = BUDGETS[variant]
            meets = instructions <= max_i and (max_c is None or cycles <= max_c)
            status = "met" if meets else "instructions met, cycles not" if instructions <= max_i else "not met"
            gates = [g for g in a.gate_budget if GATES[g][0] == variant]
            print(f"budget ({'gated: ' + ', '.join(gates) if gates else 'reported'}): {scene} {variant}: "
                  f"{instructions} instructions, {cycles} cycles against {max_i}{'' if max_c is None else f', {max_c}'}: "
                  f"{status}")
            for g in gates:
                _, gate_i, gate_c = GATES[g]
                if instructions > gate_i or (gate_c is not None and cycles > gate_c):
                    print(f"check_bound: {scene} {variant}: over the gated budget {g} ({gate_i} instructions"
                          f"{'' if gate_c is None else f', {gate_c} cycles'})", file=sys.stderr)
                    failed = True
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"elf": a.elf, "wait_states": a.wait_states, "rows": rows}, f, indent=1)
    if failed:
        print("check_bound: a measured tick passes its static bound (the analysis is unsound), a bound passes "
              "its recorded ceiling or a --gate-budget budget, or no measured tick comes within --min-witness of a "
              "bound", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
