#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""A second, independent worst case of a function of a linked Cortex-M3 image: its own decoder
(LLVM's llvm-objdump), its own reading of the ELF, and a plain longest path instead of an integer
program. It shares no code with wcet.py, and CTest requires the two to agree (compare_bounds.py).

Method. Per function: the control-flow graph of its basic blocks; its natural loops (a back edge
is an edge whose target dominates its source; a retreating edge that is not one is an irreducible
cycle: refused); each loop bounded by the image's annotations (section .toonforce.loop_bounds:
pairs of words, an address inside a loop's body and the most times that body runs per entry into
the loop; an annotation bounds the innermost loop holding its address). Loops are collapsed
innermost first into one node whose cost, per edge leaving the loop, is the dearest admissible
sequence of passes through one iteration (a pass: a path from the header that ends on a back
edge, or on that exit edge), then the function is a plain longest path on the acyclic graph left
(dynamic programming in topological order). A callee's own bound is a constant cost of its call
site (context-insensitive).

Why collapsing gives the IPET optimum (wcet.py's integer program: per loop, back edges taken at
most bound x entries, and each annotated block run at most bound x entries). Inside a loop whose
inner loops are collapsed the body without its back edges is acyclic, so each entry's flow is a
sequence of passes: k ending on a back edge, one ending on an exit edge. The constraints are
k <= n and, for each annotated block b, "passes through b" <= n (a pass visits b at most once).
With at most n + 1 passes the second only binds when k = n: then some pass must avoid b. So the
loop's cost towards an exit edge is the larger of (n - 1) x the dearest back pass + the dearest
exit pass, and the dearest n back passes and exit pass among which every annotated block is
avoided by one; the passes are computed per set of annotated blocks they visit (a bit mask), so
this is exact, not an upper estimate. Costs of a pass do not depend on the entry (context-
insensitive), so the per-entry optimum times the entries is the aggregate optimum.

Cycles: the strict model (Cortex-M3 Technical Reference Manual r2p1, section 3.3, table 3-1,
every range at its top, no pipelining credit), see `own_cycles` and `pair_cycles`.

Refused (exit status 2, naming the function and the address): an indirect branch or call, a jump
table (TBB/TBH), SVC, WFI, WFE, SEV, DMB, DSB, ISB, BKPT, any instruction the model does not know,
a loop without an annotation, an irreducible cycle, recursion, a call to an address that starts
no function, a conditional branch out of the function, running off the end of a function.
`b .` and UDF end a trap: a halt, the path ends there.

    longest_path.py IMAGE.elf --entry LABEL=REGEX ... [--wait-states N] [--json OUT]

prints "LABEL<TAB>instructions<TAB>cycles<TAB>function" per matching function.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import struct
import subprocess
import sys

LOOP_SECTION = ".toonforce.loop_bounds"
REFILL = 3  # P, the pipeline refill after a taken branch or a write of the PC: 1 to 3 (TRM 3.3)
CODE_REGION_END = 0x20000000  # ARMv7-M ARM B3.1: the Code region, 0x00000000-0x1FFFFFFF
SHF_ALLOC, SHF_EXECINSTR = 0x2, 0x4
SHT_NOBITS = 8
NEG = float("-inf")


class Refused(Exception):
    pass


# ---- the ELF, read by Python -------------------------------------------------------------------

def read_sections(path: str) -> list:
    """(name, address, size, flags, type, bytes or None) per section header (ELF32, little-endian)."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:4] != b"\x7fELF" or data[4] != 1 or data[5] != 1:
        raise Refused(f"{path}: not a little-endian ELF32 file")
    shoff, = struct.unpack_from("<I", data, 0x20)
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", data, 0x2E)
    raw = [struct.unpack_from("<IIIIIIIIII", data, shoff + k * shentsize) for k in range(shnum)]
    names_at = raw[shstrndx][4]
    out = []
    for name, stype, flags, addr, offset, size, *_ in raw:
        end = data.index(b"\0", names_at + name)
        contents = data[offset:offset + size] if stype != SHT_NOBITS else None
        out.append((data[names_at + name:end].decode(), addr, size, flags, stype, contents))
    return out


def loop_annotations(sections: list) -> list:
    """(address, bound) pairs of the loop-bound section; an address 0 is a dropped function's."""
    for name, _, _, _, _, contents in sections:
        if name == LOOP_SECTION and contents:
            words = struct.unpack_from(f"<{len(contents) // 4}I", contents)
            return [(words[k] & ~1, words[k + 1]) for k in range(0, len(words) - 1, 2) if words[k]]
    return []


def data_in_code_region(sections: list) -> bool:
    """Whether any allocated, non-executable section lies in the Code region (where a load
    competes with instruction fetch for the code memory, TRM 3.3.1). Not data a load reads: an
    empty section, a NOBITS one under a word (the padding a linker script's ALIGN(4) leaves
    after no input), and the vector table (.vectors), which the exception entry reads (ARMv7-M
    ARM B1.5.6), not a load instruction."""
    return any(flags & SHF_ALLOC and not flags & SHF_EXECINSTR and addr < CODE_REGION_END
               and size and not (stype == SHT_NOBITS and size < 4) and name != ".vectors"
               for name, addr, size, flags, stype, _ in sections)


# ---- the disassembly, read from llvm-objdump --------------------------------------------------

class Ins:
    __slots__ = ("addr", "size", "op", "cond", "args", "text")

    def __init__(self, addr, size, op, cond, args, text):
        self.addr, self.size, self.op, self.cond, self.args, self.text = addr, size, op, cond, args, text


CONDS = {"eq", "ne", "cs", "hs", "cc", "lo", "mi", "pl", "vs", "vc", "hi", "ls", "ge", "lt", "gt", "le", "al"}
# Base mnemonics the model knows (without the S flag suffix and condition), by class.
ALU = {"mov", "mvn", "add", "adc", "sub", "sbc", "rsb", "and", "orr", "eor", "bic", "orn", "lsl", "lsr", "asr",
       "ror", "rrx", "cmp", "cmn", "tst", "teq", "neg", "clz", "rbit", "rev", "rev16", "revsh", "sxth", "sxtb",
       "uxth", "uxtb", "ubfx", "sbfx", "bfi", "bfc", "ssat", "usat", "movw", "movt", "adr", "addw", "subw", "nop",
       "mul"}
LOADS = {"ldr", "ldrb", "ldrh", "ldrsb", "ldrsh", "ldrex", "ldrexb", "ldrexh", "ldrd"}
STORES = {"str", "strb", "strh", "strex", "strexb", "strexh", "strd"}
MULTI_LOADS = {"ldm", "ldmia", "ldmfd", "ldmdb", "pop"}
MULTI_STORES = {"stm", "stmia", "stmea", "stmdb", "stmfd", "push"}
BRANCHES = {"b", "bl", "bx", "cbz", "cbnz"}
SLOW = {"mla": 2, "mls": 2, "umull": 5, "smull": 5, "umlal": 7, "smlal": 7, "udiv": 12, "sdiv": 12,
        "mrs": 2, "msr": 2, "cpsid": 2, "cpsie": 2}
FORBIDDEN = {"svc", "wfi", "wfe", "sev", "dmb", "dsb", "isb", "bkpt", "blx", "tbb", "tbh"}
HALTS = {"udf"}
KNOWN = ALU | LOADS | STORES | MULTI_LOADS | MULTI_STORES | BRANCHES | set(SLOW) | FORBIDDEN | HALTS


def parse_mnemonic(m: str) -> tuple:
    """(base, condition) of an LLVM mnemonic: "bls" -> ("b", "ls"), "addseq.w" -> ("add", "eq"),
    "ittt" -> ("it", ""); (m, "") for one the model does not know."""
    m = m.split(".")[0]
    if re.fullmatch(r"it[te]{0,3}", m):
        return "it", ""
    candidates = [(m, "")]
    if len(m) > 2 and m[-2:] in CONDS:
        candidates.append((m[:-2], m[-2:]))
    for stem, cond in candidates:
        if stem in KNOWN:
            return stem, cond
        if stem.endswith("s") and stem[:-1] in ALU | {"mla", "mul"}:  # flag-setting form
            return stem[:-1], cond
    return m, ""


_LINE = re.compile(r"^\s*([0-9a-f]+):\s+((?:[0-9a-f]{2} )+)\s*\t(\S+)\s*(.*)$")


def disassemble(elf: str, llvm_objdump: str) -> list:
    out = subprocess.run([llvm_objdump, "-d", "--triple=thumbv7m-none-eabi", elf],
                         check=True, capture_output=True, text=True).stdout
    ins = []
    for line in out.splitlines():
        m = _LINE.match(line)
        if not m or m.group(3).startswith("."):  # .word/.short/.byte: data in the text ($d)
            continue
        args = re.sub(r"\s*@.*$", "", m.group(4)).strip()
        op, cond = parse_mnemonic(m.group(3))
        ins.append(Ins(int(m.group(1), 16), len(m.group(2).split()), op, cond, args, line.strip()))
    return ins


def function_symbols(elf: str, llvm_objdump: str) -> list:
    """(start, size, demangled name) of each function symbol, the largest when several share a start."""
    out = subprocess.run([llvm_objdump, "-t", "-C", elf], check=True, capture_output=True, text=True).stdout
    best = {}
    for line in out.splitlines():
        m = re.match(r"^([0-9a-f]{8}) (.{7}) (\S+)\s+([0-9a-f]{8}) (.+)$", line)
        if not m or "F" not in m.group(2):
            continue
        start, size = int(m.group(1), 16) & ~1, int(m.group(4), 16)
        if start not in best or size > best[start][1]:
            best[start] = (start, size, m.group(5).strip())
    return sorted(best.values())


# ---- registers an instruction reads for its address, and writes as a data-processing result ---

_REG = re.compile(r"\b(r1[0-5]|r[0-9]|sb|sl|fp|ip|sp|lr|pc)\b")
_ALIAS = {"sb": "r9", "sl": "r10", "fp": "r11", "ip": "r12", "sp": "r13", "lr": "r14", "pc": "r15"}


def regs(text: str) -> set:
    return {_ALIAS.get(r, r) for r in _REG.findall(text)}


def is_load(i: Ins) -> bool:
    return i.op in LOADS or i.op in MULTI_LOADS


def is_memory(i: Ins) -> bool:
    return i.op in LOADS | STORES | MULTI_LOADS | MULTI_STORES


def address_regs(i: Ins) -> set:
    if i.op in ("push", "pop"):
        return {"r13"}
    if i.op in MULTI_LOADS | MULTI_STORES:
        return regs(i.args.split(",")[0])
    if i.op in LOADS | STORES:
        m = re.search(r"\[([^\]]*)\]", i.args)
        return regs(m.group(1)) if m else set()
    return set()


def result_regs(i: Ins) -> set:
    """Registers a data-processing instruction writes (TRM 3.3.1's "data processing operation":
    everything that computes a register value, multiplies, divides and MRS included; not loads,
    stores, branches, compares)."""
    if i.op in ("cmp", "cmn", "tst", "teq", "nop", "msr", "cpsid", "cpsie", "it") or i.op not in ALU | set(SLOW):
        return set()
    fields = [f.strip() for f in i.args.split(",")]
    return regs(",".join(fields[:2] if i.op in ("umull", "smull", "umlal", "smlal") else fields[:1]))


def words_moved(i: Ins) -> int:
    if i.op in ("ldrd", "strd"):
        return 2
    if i.op in MULTI_LOADS | MULTI_STORES:
        m = re.search(r"\{([^}]*)\}", i.args)
        n = 0
        for part in m.group(1).split(","):
            r = re.fullmatch(r"\s*r(\d+)\s*-\s*r(\d+)\s*", part)
            n += int(r.group(2)) - int(r.group(1)) + 1 if r else 1
        return n
    return 1 if i.op in LOADS | STORES else 0


def writes_pc(i: Ins) -> bool:
    if i.op in MULTI_LOADS:
        return "pc" in i.args
    return i.args.split(",")[0].strip() == "pc" and i.op not in STORES | MULTI_STORES | {"cmp", "cmn", "tst", "teq"}


def own_cycles(i: Ins, wait: int, code_data: bool) -> int:
    """Cycles of one instruction by itself, not counting a taken branch's refill (TRM table 3-1,
    the top of each range), + `wait` per fetch and per data word, + 1 for a load that may read
    the code memory (it shares it with instruction fetch through the D-code bus, TRM 3.3.1 and
    2.3): a PC-relative one always, any other when the image keeps data in the Code region."""
    if i.op in SLOW:
        c = SLOW[i.op]
    elif i.op in ("ldrd", "strd"):
        c = 3
    elif i.op in LOADS | STORES:
        c = 2
    elif i.op in MULTI_LOADS | MULTI_STORES:
        c = 1 + words_moved(i)
    else:
        c = 1
    c += wait * (1 + words_moved(i))
    if is_load(i) and (code_data or "r15" in address_regs(i)):
        # TRM 3.3.1: "LDR Rx,[PC,#imm] might add a cycle because of contention with the fetch
        # unit"; that contention is the code memory's, so one cycle, for every load that may
        # read it (one cause, charged once, not twice for a literal load)
        c += 1
    return c


def pair_cycles(written: set, i: Ins) -> int:
    """+1 when a load or store's address register may be the result of the data-processing
    instruction just before it (`written`: what that one, or any that may be the last to run
    before it, writes). TRM 3.3.1: "Any load or store that generates an address dependent on
    the result of a preceding data processing operation will stall the pipeline for an
    additional cycle"."""
    return 1 if is_memory(i) and written & address_regs(i) else 0


def after(written: set, i: Ins) -> set:
    """What may have been written just before the instruction after `i`: an IT is looked
    through (it folds into the next instruction); after a conditional instruction that is not a
    branch (in an IT block) either it or the one before it ran last, so both count (the dearest)."""
    if i.op == "it":
        return written
    if i.op == "bl":
        return set()  # the callee's return ran just before the next instruction
    if i.cond and i.op not in BRANCHES:
        return written | result_regs(i)
    return result_regs(i)


# ---- functions and their graphs ----------------------------------------------------------------

class Fn:
    def __init__(self, start, size, name):
        self.start, self.end, self.name, self.ins = start, start + size, name, []


def target_of(args: str):
    """The address of a direct branch: its last operand, "0x6e <name+0x2e>" as llvm-objdump prints it."""
    m = re.fullmatch(r"(?:0x)?([0-9a-f]+)", args.split(" <")[0].split(",")[-1].strip())
    return int(m.group(1), 16) if m else None


class Program:
    def __init__(self, elf: str, llvm_objdump: str, wait: int):
        self.elf, self.wait = elf, wait
        sections = read_sections(elf)
        self.annotations = loop_annotations(sections)
        self.code_data = data_in_code_region(sections)
        self.fns = {}
        for start, size, name in function_symbols(elf, llvm_objdump):
            self.fns[start] = Fn(start, size, name)
        starts = sorted(self.fns)
        import bisect
        for i in disassemble(elf, llvm_objdump):
            k = bisect.bisect_right(starts, i.addr) - 1
            if k >= 0 and i.addr < self.fns[starts[k]].end:
                self.fns[starts[k]].ins.append(i)
        self.memo = {}
        self.stack = []

    def where(self, f: Fn, addr: int) -> str:
        return f"{addr:#x} in {f.name}"

    # kind of the end of a block: (successors [(target or "exit", taken)], call, tail call)
    def bound(self, start: int) -> dict:
        if start in self.memo:
            return self.memo[start]
        f = self.fns.get(start)
        if f is None:
            raise Refused(f"no function starts at {start:#x}")
        if start in self.stack:
            raise Refused("recursion: " + " -> ".join(self.fns[s].name for s in self.stack[self.stack.index(start):])
                          + f" -> {f.name}")
        self.stack.append(start)
        try:
            result = self._bound(f)
        finally:
            self.stack.pop()
        self.memo[start] = result
        return result

    def _bound(self, f: Fn) -> dict:
        ins = f.ins
        if not ins:
            raise Refused(f"{f.name} at {f.start:#x}: no instructions")
        at = {i.addr: k for k, i in enumerate(ins)}
        # what each instruction does to control flow
        flow = []
        for k, i in enumerate(ins):
            if i.op in FORBIDDEN:
                raise Refused(f"`{i.text.split(chr(9), 1)[-1]}` at {self.where(f, i.addr)}: not bounded by the model")
            if i.op not in KNOWN and i.op != "it":
                raise Refused(f"unknown instruction `{i.op}` at {self.where(f, i.addr)}")
            t = None
            if i.op in ("b", "bl", "cbz", "cbnz"):
                t = target_of(i.args)
                if t is None:
                    raise Refused(f"branch without a target at {self.where(f, i.addr)}")
            if i.op == "b" and not i.cond and t == i.addr or i.op in HALTS:
                kind = "halt"
            elif i.op == "b" or i.op in ("cbz", "cbnz"):
                cond = bool(i.cond) or i.op != "b"
                if t in at:
                    kind = "cbranch" if cond else "branch"
                elif cond:
                    raise Refused(f"conditional branch out of {f.name} at {self.where(f, i.addr)}")
                elif t in self.fns:
                    kind = "tail"
                else:
                    raise Refused(f"jump to an address that starts no function at {self.where(f, i.addr)}")
            elif i.op == "bl":
                if i.cond:
                    raise Refused(f"conditional call at {self.where(f, i.addr)}")
                if t not in self.fns:
                    raise Refused(f"call to an address that starts no function at {self.where(f, i.addr)}")
                kind = "call"
            elif i.op == "bx":
                if i.args != "lr":
                    raise Refused(f"indirect branch `bx {i.args}` at {self.where(f, i.addr)}")
                kind = "creturn" if i.cond else "return"
            elif writes_pc(i):
                popped = i.op == "pop" or (i.op in MULTI_LOADS and re.match(r"^sp!", i.args)) or \
                    (i.op == "ldr" and re.fullmatch(r"pc,\s*\[sp\],\s*#4", i.args))
                if not popped:
                    raise Refused(f"indirect branch `{i.op} {i.args}` at {self.where(f, i.addr)}")
                kind = "creturn" if i.cond else "return"
            else:
                kind = "plain"
            flow.append((kind, t))
        leaders = {ins[0].addr}
        for k, (kind, t) in enumerate(flow):
            if kind in ("branch", "cbranch"):
                leaders.add(t)
            if kind not in ("plain", "call") and k + 1 < len(ins):
                leaders.add(ins[k + 1].addr)
        # blocks: start -> dict(ins, succ [(dst, taken)], calls [callee])
        blocks, order = {}, []
        cur = None
        for k, i in enumerate(ins):
            if i.addr in leaders:
                cur = {"ins": [], "succ": [], "calls": [], "returns": False, "off": False, "noreturn": None}
                blocks[i.addr] = cur
                order.append(i.addr)
            cur["ins"].append(i)
            kind, t = flow[k]
            nxt = ins[k + 1].addr if k + 1 < len(ins) else None
            ends = nxt is None or nxt in leaders
            if kind == "call":
                cur["calls"].append(t)
            if kind == "branch":
                cur["succ"].append((t, True))
            elif kind == "cbranch":
                cur["succ"].append((t, True))
                if nxt is not None:
                    cur["succ"].append((nxt, False))
            elif kind == "tail":
                cur["calls"].append(t)
                cur["succ"].append(("exit", True))
                cur["tail"] = t
            elif kind in ("return", "creturn"):
                cur["succ"].append(("exit", True))
                cur["returns"] = True
                if kind == "creturn" and nxt is not None:
                    cur["succ"].append((nxt, False))
            elif kind == "halt":
                cur["succ"].append(("exit", False))
            elif ends:
                if nxt is not None:
                    cur["succ"].append((nxt, False))
                elif kind == "call":  # the function's last instruction calls: that callee must not return
                    cur["succ"].append(("exit", False))
                    cur["noreturn"] = t
                else:
                    cur["off"] = True
        entry = ins[0].addr
        # reachable blocks
        seen, todo = set(), [entry]
        while todo:
            b = todo.pop()
            if b in seen:
                continue
            seen.add(b)
            if blocks[b]["off"]:
                raise Refused(f"{f.name} runs off its end at {blocks[b]['ins'][-1].addr:#x}")
            todo += [s for s, _ in blocks[b]["succ"] if s != "exit"]
        blocks = {b: blocks[b] for b in order if b in seen}
        preds = {b: [] for b in blocks}
        for b, blk in blocks.items():
            for s, _ in blk["succ"]:
                if s != "exit":
                    preds[s].append(b)

        # callees first (their bounds are constants here), and whether this function returns
        returns = False
        for blk in blocks.values():
            for c in blk["calls"]:
                self.bound(c)
            if blk["noreturn"] is not None and self.memo[blk["noreturn"]]["returns"]:
                raise Refused(f"{f.name} runs off its end after calling {self.fns[blk['noreturn']].name}, which returns")
            if "tail" in blk:
                returns = returns or self.memo[blk["tail"]]["returns"]
            elif blk["returns"]:
                returns = True

        # costs: per block, instructions and cycles when it does not branch; a taken branch's refill per edge
        cost_i, cost_c, refill = {}, {}, {}
        exit_written = {}
        for b, blk in blocks.items():
            w = set()
            for i in blk["ins"]:
                w = after(w, i)
            exit_written[b] = w
        for b, blk in blocks.items():
            # what may have been written just before the block's first instruction: the union
            # over its predecessors (the dearest); nothing at the function's entry (the caller's BL)
            written = set()
            for p in preds[b]:
                written |= exit_written[p]
            n, c = 0, 0
            for i in blk["ins"]:
                n += 1
                c += own_cycles(i, self.wait, self.code_data)
                if i.op != "it":
                    c += pair_cycles(written, i)
                written = after(written, i)
            for callee in blk["calls"]:
                n += self.memo[callee]["instructions"]
                c += self.memo[callee]["cycles"]
                if "tail" not in blk or callee != blk["tail"]:
                    c += REFILL  # the BL's own refill (its return's is the callee's)
            cost_i[b], cost_c[b] = n, c
            last = blk["ins"][-1]
            refill[b] = REFILL if (last.op in BRANCHES or writes_pc(last)) else 0

        instructions = self._longest(f, blocks, preds, entry, lambda b, taken: cost_i[b])
        cycles = self._longest(f, blocks, preds, entry, lambda b, taken: cost_c[b] + (refill[b] if taken else 0))
        return {"instructions": instructions, "cycles": cycles, "returns": returns}

    # ---- loops and the longest path ------------------------------------------------------------

    def _longest(self, f: Fn, blocks: dict, preds: dict, entry: int, weight) -> int:
        names = list(blocks)
        # dominators: the plain iterative data-flow solution
        dom = {b: set(names) for b in names}
        dom[entry] = {entry}
        changed = True
        while changed:
            changed = False
            for b in names:
                if b == entry:
                    continue
                new = set.intersection(*[dom[p] for p in preds[b]]) | {b}
                if new != dom[b]:
                    dom[b], changed = new, True
        # back edges (target dominates source) and natural loops
        loops = {}
        for b, blk in blocks.items():
            for s, _ in blk["succ"]:
                if s != "exit" and s in dom[b]:
                    body = loops.setdefault(s, {s})
                    todo = [b]
                    while todo:
                        x = todo.pop()
                        if x not in body:
                            body.add(x)
                            todo += preds[x]
        # every cycle must be a natural loop: removing back edges leaves a DAG
        state = {}

        def dfs(root):
            stack = [(root, iter([s for s, _ in blocks[root]["succ"] if s != "exit"]))]
            state[root] = 1
            while stack:
                node, it = stack[-1]
                for s in it:
                    if s in dom[node]:  # back edge
                        continue
                    if state.get(s) == 1:
                        raise Refused(f"irreducible cycle through {s:#x} in {f.name}")
                    if s not in state:
                        state[s] = 1
                        stack.append((s, iter([t for t, _ in blocks[s]["succ"] if t != "exit"])))
                        break
                else:
                    state[node] = 2
                    stack.pop()
        dfs(entry)
        # bounds: an annotation bounds the innermost loop holding its block
        block_at = {}
        for b, blk in blocks.items():
            for i in blk["ins"]:
                block_at[i.addr] = b
        bound, marked = {}, {h: set() for h in loops}
        for addr, n in self.annotations:
            b = None
            for a in range(addr, addr - 4, -2):  # the annotation may point inside a 32-bit instruction
                if a in block_at:
                    b = block_at[a]
                    break
            if b is None:
                continue
            holding = [h for h, body in loops.items() if b in body]
            if not holding:
                continue  # the compiler unrolled that loop completely
            h = min(holding, key=lambda h: len(loops[h]))
            if h in bound and bound[h] != n:
                raise Refused(f"loop at {self.where(f, h)} has two different bounds, {bound[h]} and {n}")
            bound[h] = n
            marked[h].add(b)
        for h in sorted(loops):
            ops = [i.op for i in blocks[h]["ins"]]
            if h not in bound and loops[h] == {h} and len(ops) <= 5 and ops[0] in ("ldrex", "ldrexb", "ldrexh") \
                    and any(o.startswith("strex") for o in ops) and ops[-1] in ("b", "cbnz"):
                # An exclusive load/store retry (std::atomic's exchange), one block: the store fails
                # only when the local monitor was cleared in between, which on one core takes an
                # exception entry or return (ARMv7-M ARM A3.4, "Synchronization and semaphores");
                # with no interrupt inside the function (the analysis's assumption) it runs once.
                bound[h] = 1
                marked[h].add(h)
            if h not in bound:
                raise Refused(f"loop without a bound: header {self.where(f, h)}")
        # loop nesting: a loop's parent is the smallest other loop holding its header
        parent = {}
        for h in loops:
            holders = [g for g in loops if g != h and h in loops[g]]
            parent[h] = min(holders, key=lambda g: len(loops[g])) if holders else None
        # the innermost loop holding each block
        owner = {}
        for b in blocks:
            holding = [h for h in loops if b in loops[h]]
            owner[b] = min(holding, key=lambda h: len(loops[h])) if holding else None

        def node_of(b, level):
            """The node standing for block b in the region of loop `level` (None: the function):
            b itself, or the outermost loop inside `level` holding it."""
            h = owner[b]
            if h is None or h == level:
                return ("b", b)
            while parent[h] != level:
                h = parent[h]
            return ("l", h)

        # loop_cost[h]: {original exit edge (src, dst, taken): cost of the whole loop leaving by it}
        loop_cost = {}

        def out_edges(node, level):
            """(successor node, the original edge, weight) in `level`'s region; the successor is
            ("back",) for a back edge of `level`, ("out", dst) for an edge leaving `level`."""
            out = []
            if node[0] == "b":
                b = node[1]
                edges = [((b, s, taken), weight(b, taken)) for s, taken in blocks[b]["succ"]]
            else:
                edges = list(loop_cost[node[1]].items())
            for (src, dst, taken), w in edges:
                if w == NEG:
                    continue
                if level is not None and dst == level:
                    out.append((("back",), (src, dst, taken), w))
                elif dst == "exit" or (level is not None and dst not in loops[level]):
                    out.append((("out",), (src, dst, taken), w))
                else:
                    out.append((node_of(dst, level), (src, dst, taken), w))
            return out

        def region_dp(level, start, marks):
            """Longest paths from `start` through `level`'s region, per set of marked blocks
            visited: returns ({mask: best back pass}, {exit edge: {mask: best}})."""
            bit = {b: 1 << k for k, b in enumerate(sorted(marks))}
            best = {start: {bit.get(start[1], 0) if start[0] == "b" else 0: 0}}
            topo, seen = [], set()

            def visit(n):  # postorder, iteratively
                stack = [(n, iter(out_edges(n, level)))]
                seen.add(n)
                while stack:
                    x, it = stack[-1]
                    for s, _, _ in it:
                        if s[0] in ("b", "l") and s not in seen:
                            seen.add(s)
                            stack.append((s, iter(out_edges(s, level))))
                            break
                    else:
                        topo.append(x)
                        stack.pop()
            visit(start)
            topo.reverse()
            back, exits = {}, {}
            for n in topo:
                for m, v in best.get(n, {}).items():
                    for s, edge, w in out_edges(n, level):
                        if s[0] == "back":
                            back[m] = max(back.get(m, NEG), v + w)
                        elif s[0] == "out":
                            e = exits.setdefault(edge, {})
                            e[m] = max(e.get(m, NEG), v + w)
                        else:
                            m2 = m | (bit.get(s[1], 0) if s[0] == "b" else 0)
                            d = best.setdefault(s, {})
                            d[m2] = max(d.get(m2, NEG), v + w)
            return back, exits, (1 << len(marks)) - 1

        # collapse loops innermost first (deepest first)
        def depth(h):
            d = 0
            while parent[h] is not None:
                h, d = parent[h], d + 1
            return d
        for h in sorted(loops, key=depth, reverse=True):
            n = bound[h]
            back, exits, full = region_dp(h, ("b", h), marked[h])
            # the dearest n back passes, per the AND of their masks (which marked blocks all of them visit)
            runs = {full: 0}
            for _ in range(n):
                nxt = {}
                for m, v in runs.items():
                    for mb, vb in back.items():
                        k = m & mb
                        nxt[k] = max(nxt.get(k, NEG), v + vb)
                runs = nxt
            dearest_back = max(back.values(), default=NEG)
            cost = {}
            for edge, by_mask in exits.items():
                c = NEG
                for mx, vx in by_mask.items():
                    if n >= 1:  # n - 1 back passes: no marked block can be in more than n passes
                        c = max(c, (n - 1) * dearest_back + vx if dearest_back != NEG else vx)
                    for m, v in runs.items():  # n back passes: each marked block avoided by one pass
                        if m & mx == 0:
                            c = max(c, v + vx)
                cost[edge] = c
            loop_cost[h] = cost
        back, exits, _ = region_dp(None, node_of(entry, None), set())
        total = max((max(v.values()) for v in exits.values()), default=NEG)
        if total == NEG:
            raise Refused(f"{f.name}: no bounded path from its entry to an exit")
        return int(total)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("elf")
    p.add_argument("--entry", action="append", required=True, metavar="LABEL=REGEX",
                   help="bound every function whose demangled name matches REGEX, under LABEL")
    p.add_argument("--wait-states", type=int, default=0)
    p.add_argument("--llvm-objdump", default="llvm-objdump")
    p.add_argument("--json", help="write the bounds here as JSON")
    args = p.parse_args(argv)
    results = []
    try:
        prog = Program(args.elf, args.llvm_objdump, args.wait_states)
        for spec in args.entry:
            label, _, regex = spec.partition("=")
            found = sorted((fn for fn in prog.fns.values() if re.search(regex, fn.name)), key=lambda fn: fn.name)
            if not found:
                raise Refused(f"no function matches {regex!r} ({label})")
            for fn in found:
                b = prog.bound(fn.start)
                results.append({"label": label, "function": fn.name, "address": fn.start,
                                "instructions": b["instructions"], "cycles": b["cycles"]})
                print(f"{label}\t{b['instructions']}\t{b['cycles']}\t{fn.name}")
    except Refused as e:
        print(f"longest_path: {os.path.basename(args.elf)}: cannot bound: {e}", file=sys.stderr)
        return 2
    if args.json:
        with open(args.json, "w") as out:
            json.dump({"elf": args.elf, "wait_states": args.wait_states, "bounds": results}, out, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
