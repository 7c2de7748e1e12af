#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Worst case by construction: a static bound on a function of a linked Cortex-M3 image.

From the ELF (arm-none-eabi-objdump's disassembly and symbol table), for each entry function:
the control-flow graph of it and of everything it calls (libgcc's helpers included), its loops
(natural loops of the dominator tree; an irreducible cycle is refused), each loop bounded by an
annotation the build generated (section .toonforce.loop_bounds: pairs of words, an address inside
the loop's body and the most times that body runs per entry into the loop, emitted by
TOONFORCE_LOOP_BOUND from a constant expression; effects/include/toonforce/math/loop_bound.hpp),
and the longest path by implicit path enumeration: an integer program over the number of times
each edge is taken (flow conservation, one entry, each loop's back edges at most its bound times
its entries), solved by GLPK's glpsol, once for instructions and once for cycles. A callee's own
bound is a constant cost of its call site (context-insensitive: sound, maybe loose).

Cycles: the strict model, the Cortex-M3 Technical Reference Manual's timings (r2p1, section 3.3
and table 3-1 "Cortex-M3 instruction set summary") with every range at its top and no optimistic
credit. Per instruction, plus WAIT cycles (--wait-states) per instruction fetch and per data word
moved:
- data processing (MOV, MVN, ADD/ADC/SUB/SBC/RSB, AND/ORR/EOR/BIC/ORN, shifts, CMP/CMN/TST/TEQ,
  NEG, CLZ, RBIT, REV*, SXT*/UXT*, UBFX/SBFX/BFI/BFC, SSAT/USAT, MOVW/MOVT, ADR, NOP, IT): 1;
- MUL 1, MLA/MLS 2, UMULL/SMULL 5 ("3-5"), UMLAL/SMLAL 7 ("4-7"), UDIV/SDIV 12 ("2-12");
- MRS, MSR, CPSID/CPSIE 2 ("1 or 2");
- LDR/STR and their byte, halfword and exclusive forms 2; LDRD/STRD 3; LDM/STM/PUSH/POP 1 + N;
- a taken branch or any write of the PC (B, BL, BX, CBZ/CBNZ taken, POP {..pc}, LDR pc) + P,
  P = 3 ("1 to 3" for the pipeline refill); a conditional branch not taken 1.
What an instruction costs after the one before it (3.3.1 "Load/store timings", pair_cycles):
+1 for a load or store whose address register the data processing straight before it wrote (an
IT looked through; a conditional instruction may not run, so the one before it counts too);
+1 for a load that may read the code region (0x00000000-0x1FFFFFFF, where the D-code bus shares
the memory with instruction fetch): a PC-relative load always ("might add a cycle because of
contention with the fetch unit"), every load when the image has data there (an allocated,
non-empty, non-executable section other than `.vectors`, from the ELF's section headers:
Image.data_in_code); no -1 for a load or store pipelined after a load ("when possible" is no
guarantee: wait states, the write buffer and the other bus master decide it). Where a block's
first instruction may follow more than one instruction, the dearest (a branch writes no
register: the instruction laid out before it).

Assumptions left (what the bound does not cover): WAIT wait states on every fetch and data word
and no other stall (0 for the AN385's zero-wait-state SSRAM; a board with wait states or a
flash accelerator needs its own --wait-states); no interrupt or exception inside the function
(its entry, handler and exit, and an exclusive monitor cleared by one, are not counted); no
other bus master (DMA, a debugger) contending for the buses; every data access aligned (an
unaligned one takes more bus transfers; CCR.UNALIGN_TRP, ARMv7-M B3.2.8, makes it fault instead).

--path LABEL says where a bound goes: the longest path (in instructions) that the bound counts,
as instructions per source line (addr2line: the innermost inlined function's line), adding up to
the bound; callees on their own longest paths, so it is the bound's path, which no single input
need take (context-insensitive), and where a witness input would start.

It refuses (exit status 2, naming the function and address) what it cannot bound: a loop without
annotation, an irreducible cycle, an indirect branch or call, a jump table, recursion, a call to
an address outside any function; SVC, BKPT, WFI, WFE, SEV, DMB, DSB and ISB (an exception entry,
a wait or a barrier: no cycles of its own bound them; a halt like `b .` or UDF that ends a trap
stays a halt); and any instruction the model does not know (never a silent 1).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field

LOOP_SECTION = ".toonforce.loop_bounds"
CODE_REGION_END = 0x20000000  # ARMv7-M's system address map (B3.1): the Code region ends here


class Refusal(Exception):
    """What the analysis cannot bound, with where."""


# ---- the image --------------------------------------------------------------------------------

@dataclass
class Insn:
    addr: int
    size: int
    mnemonic: str   # as objdump prints it, condition and width suffix included ("bne.n", "ldr.w")
    operands: str
    text: str


@dataclass
class Function:
    name: str       # demangled
    start: int
    end: int
    insns: list = field(default_factory=list)


_FUNC = re.compile(r"^([0-9a-f]+) <(.+)>:$")
_CONDS = ("eq", "ne", "cs", "cc", "hs", "lo", "mi", "pl", "vs", "vc", "hi", "ls", "ge", "lt", "gt", "le")


class Image:
    def __init__(self, elf: str, objdump: str):
        self.elf = elf
        self.objdump = objdump
        self.functions: dict[int, Function] = {}
        self.by_name: dict[str, Function] = {}
        self._read_symbols()
        self._read_code()
        self.bounds = self._read_bounds()
        self.data_sections = self._read_data_in_code()
        self.data_in_code = bool(self.data_sections)

    def _run(self, *args: str) -> str:
        return subprocess.run([self.objdump, *args, self.elf], check=True, capture_output=True, text=True).stdout

    def _read_symbols(self) -> None:
        # objdump -t -C: "ADDR l/g  F .text  SIZE NAME"
        sizes: dict[int, tuple[int, str]] = {}
        self._named_sections = set()  # sections some symbol other than their own lies in
        for line in self._run("-t", "-C").splitlines():
            m = re.match(r"^([0-9a-f]{8}) (.{7}) (\S+)\s+([0-9a-f]{8}) (.*)$", line)
            if m and "d" not in m.group(2):
                self._named_sections.add(m.group(3))
            if not m or "F" not in m.group(2):
                continue
            addr = int(m.group(1), 16) & ~1
            size = int(m.group(4), 16)
            name = m.group(5).strip()
            if addr not in sizes or size > sizes[addr][0]:
                sizes[addr] = (size, name)
        self._sizes = sizes

    def _read_code(self) -> None:
        current = None
        self.words: dict[int, int] = {}  # literal pool words by address
        for line in self._run("-d", "-C", "--no-show-raw-insn").splitlines():
            fm = _FUNC.match(line)
            if fm:
                addr = int(fm.group(1), 16)
                size, name = self._sizes.get(addr, (0, fm.group(2)))
                current = Function(name, addr, addr + size)
                self.functions[addr] = current
                self.by_name.setdefault(name, current)
                continue
            m = re.match(r"^\s*([0-9a-f]+):\s+(\S+)\s*(.*)$", line)
            if m and current is not None:
                addr = int(m.group(1), 16)
                mnemonic = m.group(2)
                operands = re.sub(r"\s*[;@].*$", "", m.group(3)).strip()
                if mnemonic.startswith("."):  # literal pool words ($d), not instructions
                    if mnemonic == ".word" and re.match(r"^0x[0-9a-f]+$", operands):
                        self.words[addr] = int(operands, 16)
                    continue
                current.insns.append(Insn(addr, 0, mnemonic, operands, line.strip()))
        for f in self.functions.values():
            for i, insn in enumerate(f.insns):
                nxt = f.insns[i + 1].addr if i + 1 < len(f.insns) else None
                insn.size = 4 if (".w" in insn.mnemonic or (nxt is not None and nxt - insn.addr == 4)) else 2
            if f.end <= f.start and f.insns:  # no size in the symbol table: up to its last instruction
                f.end = f.insns[-1].addr + f.insns[-1].size

    def _read_data_in_code(self) -> list:
        """The sections that put data in the code region (0x00000000-0x1FFFFFFF, where a load
        contends with instruction fetch), from the ELF's section headers (readelf -S): allocated,
        not executable and not empty. Empty: no bytes, or alignment padding (no contents, under a
        word and no symbol in it: what a linker script's ALIGN(4) leaves after no input).
        `.vectors` is no such data: the core reads it on an exception entry, no load in a
        function does. Literal pools are inside the executable code (charged as PC-relative)."""
        readelf = self.objdump.replace("objdump", "readelf")
        out = subprocess.run([readelf, "-S", "-W", self.elf], check=True, capture_output=True, text=True).stdout
        found = []
        for line in out.splitlines():
            m = re.match(r"^\s*\[\s*\d+\]\s+(\S+)\s+(\S+)\s+([0-9a-f]+)\s+[0-9a-f]+\s+([0-9a-f]+)\s+[0-9a-f]+\s+"
                         r"([A-Za-z]*)\s+\d+\s+\d+\s+\d+$", line)
            if not m:
                continue
            name, kind, addr, size, flags = m.group(1), m.group(2), int(m.group(3), 16), int(m.group(4), 16), m.group(5)
            if "A" not in flags or "X" in flags or addr >= CODE_REGION_END or name == ".vectors":
                continue
            if size == 0 or (kind == "NOBITS" and size < 4 and name not in self._named_sections):
                continue
            found.append(name)
        return found

    def _read_bounds(self) -> list[tuple[int, int]]:
        out = subprocess.run([self.objdump, "-s", "-j", LOOP_SECTION, self.elf], capture_output=True, text=True)
        if out.returncode != 0 or "Contents of section" not in out.stdout:
            return []
        data = bytearray()
        for line in out.stdout.splitlines():
            m = re.match(r"^ ([0-9a-f]{4,8}) ((?:[0-9a-f]{2,8} ){1,4})", line)
            if m:
                data += bytes.fromhex(m.group(2).replace(" ", ""))
        words = [int.from_bytes(data[i:i + 4], "little") for i in range(0, len(data) - 3, 4)]
        return [(words[i] & ~1, words[i + 1]) for i in range(0, len(words) - 1, 2) if words[i] != 0]

    def function_at(self, addr: int):
        for f in self.functions.values():
            if f.start <= addr < f.end:
                return f
        return None

    def lines(self, addresses: list) -> list:
        """(function, file:line) of each address, by one addr2line run: the innermost inlined
        function's name and line; ("??", "??:0") where the image has no line for it, or for all
        when addr2line cannot run."""
        unknown = [("??", "??:0")] * len(addresses)
        addr2line = self.objdump.replace("objdump", "addr2line")
        try:
            r = subprocess.run([addr2line, "-e", self.elf, "-f", "-C", *[hex(a) for a in addresses]],
                               capture_output=True, text=True, timeout=30)
        except (OSError, subprocess.TimeoutExpired):
            return unknown
        out = r.stdout.splitlines()
        if r.returncode != 0 or len(out) != 2 * len(addresses):
            return unknown
        found = []
        for fn, where in zip(out[0::2], out[1::2]):
            where = re.sub(r" \(discriminator \d+\)$", "", where)
            found.append((fn, os.path.relpath(where) if where.startswith("/") else where))
        return found

    def where(self, addr: int) -> str:
        f = self.function_at(addr)
        _, source = self.lines([addr])[0]
        line = "" if source.startswith("??") else f" ({source})"
        return f"{addr:#x} in {f.name if f else '?'}{line}"


# ---- instruction classes and the TRM's timings -------------------------------------------------
#
# The strict model: the Cortex-M3 Technical Reference Manual r2p1, section 3.3 and table 3-1
# ("Cortex-M3 instruction set summary"), every range at its top and no optimistic credit.

_DATA_PROCESSING = {
    "mov", "mvn", "add", "addw", "adc", "sub", "subw", "sbc", "rsb", "and", "orr", "eor", "bic", "orn", "lsl", "lsr",
    "asr", "ror", "rrx", "cmp", "cmn", "tst", "teq", "neg", "clz", "rbit", "rev", "rev16", "revsh", "sxth", "sxtb",
    "uxth", "uxtb", "ubfx", "sbfx", "bfi", "bfc", "ssat", "usat", "movw", "movt", "adr", "nop",
}
# Own cycles of what is not a load, a store or a branch (table 3-1, the top of each range):
# MUL 1, MLA/MLS 2, UMULL/SMULL "3-5", UMLAL/SMLAL "4-7", UDIV/SDIV "2-12", and MRS, MSR,
# CPSID/CPSIE "1 or 2" (the core may wait for the previous instruction's flags or registers).
_OWN = {op: 1 for op in _DATA_PROCESSING} | {
    "mul": 1, "mla": 2, "mls": 2, "umull": 5, "smull": 5, "umlal": 7, "smlal": 7, "udiv": 12, "sdiv": 12,
    "mrs": 2, "msr": 2, "cpsid": 2, "cpsie": 2,
}
_FLAG_SETTING = _DATA_PROCESSING | {"mul", "umull", "smull", "umlal", "smlal"}  # take an "s" (ADDS, MULS)
_SINGLE_LOADS = {"ldr", "ldrb", "ldrh", "ldrsb", "ldrsh", "ldrex", "ldrexb", "ldrexh"}
_SINGLE_STORES = {"str", "strb", "strh", "strex", "strexb", "strexh"}
_MULTIPLE_LOADS = {"pop", "ldm", "ldmia", "ldmfd", "ldmdb", "ldmea"}
_MULTIPLE_STORES = {"push", "stm", "stmia", "stmea", "stmdb", "stmfd"}
_LOADS = _SINGLE_LOADS | _MULTIPLE_LOADS | {"ldrd"}
_MEMORY = _LOADS | _SINGLE_STORES | _MULTIPLE_STORES | {"strd"}
_BRANCHES = {"b", "bl", "bx", "cbz", "cbnz"}
_INDIRECT = {"blx", "tbb", "tbh"}  # refused by the control-flow graph (a target the disassembly lacks)
_HALTS = {"udf"}                   # a trap's end: the run stops there
# Refused in a counted function: what waits for something outside it (an event, an interrupt, the
# bus draining) or hands the core to an exception, so that no cycle count of its own bounds it.
_REFUSED = {
    "svc": "a supervisor call (an exception entry and a handler outside the analysis)",
    "bkpt": "a breakpoint (halts the core or enters the debug monitor)",
    "wfi": "a wait for an interrupt (unbounded)",
    "wfe": "a wait for an event (unbounded)",
    "sev": "an event sent (wakes a core that waits: a side effect outside the analysis)",
    "dmb": "a memory barrier (waits for the bus to drain: no bound in table 3-1)",
    "dsb": "a memory barrier (waits for the bus to drain: no bound in table 3-1)",
    "isb": "a barrier that flushes the pipeline (no bound in table 3-1)",
}
_KNOWN = (set(_OWN) | _MEMORY | _BRANCHES | _INDIRECT | _HALTS | set(_REFUSED) | {"it"})
_BASES = _KNOWN | {op + "s" for op in _FLAG_SETTING}
_IT = re.compile(r"^it[te]{0,3}$")


def split_mnemonic(mnemonic: str) -> tuple[str, str]:
    """(base, condition) of objdump's mnemonic: "bne.n" -> ("b", "ne"), "popeq" -> ("pop", "eq")."""
    base = mnemonic.split(".")[0]
    for c in _CONDS:
        if base.endswith(c) and len(base) > len(c):
            stem = base[: -len(c)]
            # "bls", "bhi", "teq", "bics", "adcs" and "mls" must not split wrongly: only a stem that
            # is an instruction takes a condition.
            if stem in _BASES:
                return stem, c
    return base, ""


def operation(insn: Insn) -> str | None:
    """The instruction's operation as the model names it ("adds.w" -> "add", "ittt" -> "it"), or
    None when the model does not know it."""
    base, _ = split_mnemonic(insn.mnemonic)
    if _IT.match(base):
        return "it"
    if base in _KNOWN:
        return base
    if base.endswith("s") and base[:-1] in _FLAG_SETTING:
        return base[:-1]
    return None


def check_known(insn: Insn, where) -> None:
    """Refuses (Refusal) what the model has no cycles for, and what it refuses outright."""
    op = operation(insn)
    if op is None:
        raise Refusal(f"an instruction the cycle model does not know `{insn.mnemonic} {insn.operands}` at {where()}")
    if op in _REFUSED:
        raise Refusal(f"`{insn.mnemonic} {insn.operands}`, {_REFUSED[op]}, at {where()}")


def reg_list_len(operands: str) -> int:
    m = re.search(r"\{([^}]*)\}", operands)
    if not m:
        return 1
    n = 0
    for part in m.group(1).split(","):
        part = part.strip()
        r = re.match(r"r(\d+)-r(\d+)", part)
        n += int(r.group(2)) - int(r.group(1)) + 1 if r else 1
    return n


PIPELINE_REFILL = 3  # P: "1 to 3" cycles to refill the pipeline after a taken branch (TRM table 3-1), the top


def writes_pc(base: str, operands: str) -> bool:
    if base in _MULTIPLE_LOADS:
        return "pc" in operands
    first = operands.split(",")[0].strip()
    return first == "pc" and base not in _SINGLE_STORES | _MULTIPLE_STORES | {"strd", "cmp", "cmn", "tst", "teq"}


def cycles(insn: Insn, wait: int) -> tuple[int, int]:
    """(cycles when it does not branch, extra cycles when it does) for one instruction, on its
    own (pair_cycles adds what it costs after the one before it)."""
    op = operation(insn)
    base, _ = split_mnemonic(insn.mnemonic)
    ops = insn.operands
    fetch = wait  # each instruction fetched once (pessimistic: two 16-bit ones share a word)
    if op in _SINGLE_LOADS or op in _SINGLE_STORES:
        c = 2 + wait                      # LDR/STR and their byte, halfword and exclusive forms: 2
    elif op in ("ldrd", "strd"):
        c = 3 + 2 * wait                  # LDRD/STRD: 1 + N, N = 2
    elif op in _MULTIPLE_LOADS or op in _MULTIPLE_STORES:
        n = reg_list_len(ops)
        c = 1 + n + n * wait              # LDM/STM/PUSH/POP: 1 + N
    elif op in _OWN:
        c = _OWN[op]
    else:
        c = 1                             # B, BL, BX, CBZ/CBNZ, IT, UDF: 1 (+ P below when they branch)
    taken = 0
    if op in _BRANCHES or writes_pc(base, ops):
        taken = PIPELINE_REFILL
    return c + fetch, taken


# The TRM's "Load/store timings" (r2p1, 3.3.1) change a load's or store's cost by what ran just
# before it, so a block's cycles are not only the sum of its instructions' own:
# - "Any load or store that generates an address dependent on the result of a preceding data
#   processing operation will stall the pipeline for an additional cycle": +1 (any instruction
#   that writes a register and is not a load, a store or a branch counts as data processing);
# - "LDR Rx,[PC,#imm] might add a cycle because of contention with the fetch unit": +1, and the
#   same for every load that may read the code region (0x00000000-0x1FFFFFFF), where the D-code
#   bus shares the memory with instruction fetch: every load when the image has data there
#   (code_loads: Image.data_in_code), PC-relative loads only when all its data is above;
# - "LDR [any] are pipelined when possible": NOT taken (no -1). "When possible" is no guarantee:
#   wait states, the write buffer and the other bus master decide it, and none is known here.
# STR Rx,[Ry,#imm]'s single cycle through the write buffer is not taken either (whether the
# buffer can accept depends on the bus): a store stays at 2.

_ALIASES = {"sb": "r9", "sl": "r10", "fp": "r11", "ip": "r12", "sp": "r13", "lr": "r14", "pc": "r15"}


def _registers(text: str) -> set:
    return {_ALIASES.get(r, r) for r in re.findall(r"\b(r1[0-5]|r[0-9]|sb|sl|fp|ip|sp|lr|pc)\b", text)}


def _is_it(insn: Insn) -> bool:
    return operation(insn) == "it"


def address_registers(insn: Insn) -> set:
    """The registers a load or store computes its address from (empty for anything else)."""
    op = operation(insn)
    if op in ("push", "pop"):
        return {"r13"}
    if op in _MULTIPLE_LOADS or op in _MULTIPLE_STORES:
        return _registers(insn.operands.split(",")[0])
    if op in _MEMORY:
        m = re.search(r"\[([^\]]*)\]", insn.operands)
        return _registers(m.group(1)) if m else set()
    return set()


def data_processing_writes(insn: Insn) -> set:
    """The registers a data-processing instruction writes (empty for loads, stores, branches,
    compares and hints)."""
    op = operation(insn)
    if op not in _OWN or op in ("cmp", "cmn", "tst", "teq", "nop", "msr", "cpsid", "cpsie"):
        return set()
    fields = [f.strip() for f in insn.operands.split(",")]
    written = fields[:2] if op in ("umull", "smull", "umlal", "smlal") else fields[:1]
    return _registers(",".join(written))


def is_load(insn: Insn) -> bool:
    return operation(insn) in _LOADS


def pair_cycles(written: set, insn: Insn, code_loads: bool) -> int:
    """Cycles `insn` costs beyond cycles(insn) when the data processing that may have run just
    before it wrote the registers `written` (empty: none, or a branch, a call or a return)."""
    address = address_registers(insn)
    if not address:
        return 0
    extra = 1 if is_load(insn) and ("r15" in address or code_loads) else 0
    if written & address:
        extra += 1
    return extra


def _conditional(insn: Insn) -> bool:
    """A conditional instruction that is not a branch (in an IT block): it may not run, and then
    the instruction before it is the one just before the next."""
    base, cond = split_mnemonic(insn.mnemonic)
    return bool(cond) and operation(insn) not in _BRANCHES


def written_before(insns: list, k: int) -> set:
    """The registers the data processing that may run just before insns[k] (laid out before it,
    falling through) writes: the instruction before it, looking through an IT, and through a
    conditional one to the one before it too (either may be the last to run: the dearest)."""
    written: set = set()
    j = k - 1
    while j >= 0:
        insn = insns[j]
        j -= 1
        if _is_it(insn):
            continue
        written |= data_processing_writes(insn)
        if not _conditional(insn):
            break
    return written


def block_cycles(insns: list, before: set, wait: int, code_loads: bool) -> int:
    """A block's cycles when it does not branch: its instructions' own, and what each pairs with
    the one before it (an IT looked through). `before`: what written_before gives for its first
    instruction (a branch into it writes no register: the fall-through is the dearest)."""
    total = 0
    written = set(before)
    for insn in insns:
        total += cycles(insn, wait)[0]
        if _is_it(insn):
            continue
        total += pair_cycles(written, insn, code_loads)
        if _conditional(insn):
            written |= data_processing_writes(insn)
        else:
            written = data_processing_writes(insn)
    return total

# ---- control-flow graph of one function --------------------------------------------------------

@dataclass
class Block:
    start: int
    insns: list
    succs: list = field(default_factory=list)   # (target block start or "exit", taken: bool)
    calls: list = field(default_factory=list)   # callee start addresses, in order
    call_sites: list = field(default_factory=list)  # the address of each of those calls
    falls_off: bool = False
    noreturn_call: int | None = None
    tail_call: int | None = None
    returns: bool = False  # ends in a return (or a tail call), not a halt


def _target(operands: str) -> int | None:
    m = re.match(r"^([0-9a-f]+)\b", operands.strip())
    return int(m.group(1), 16) if m else None


def _classify(insn: Insn) -> tuple[str, int | None]:
    """kind, target: "call", "jump", "cjump" (conditional), "return", "creturn", "indirect", "halt",
    "plain" (falls through)."""
    base, cond = split_mnemonic(insn.mnemonic)
    ops = insn.operands
    if base in ("cbz", "cbnz"):
        return "cjump", _target(ops.split(",")[1])
    if base == "b":
        if not cond and _target(ops) == insn.addr:
            return "halt", None  # `b .`: the core spins here for good (a trap's end), the run is over
        return ("cjump" if cond else "jump"), _target(ops)
    if base == "bl":
        if cond:
            raise Refusal(f"conditional call at {insn.addr:#x}")
        return "call", _target(ops)
    if base == "bx":
        if ops == "lr":
            return ("creturn" if cond else "return"), None
        return "indirect", None
    if base == "blx" or base in ("tbb", "tbh"):
        return "indirect", None
    if writes_pc(base, ops):
        if base in ("pop", "ldm", "ldmia", "ldmfd") and ("sp!" in ops or base == "pop"):
            return ("creturn" if cond else "return"), None
        if base == "ldr" and re.match(r"^pc,\s*\[sp\],\s*#4$", ops):
            return ("creturn" if cond else "return"), None
        return "indirect", None
    if base in _HALTS:
        return "halt", None
    return "plain", None


class Cfg:
    def __init__(self, image: Image, func: Function):
        self.image = image
        self.func = func
        insns = func.insns
        if not insns:
            raise Refusal(f"{func.name} at {func.start:#x}: no instructions")
        index = {i.addr: k for k, i in enumerate(insns)}
        leaders = {insns[0].addr}
        kinds = []
        for k, insn in enumerate(insns):
            check_known(insn, lambda: image.where(insn.addr))
            kind, target = _classify(insn)
            if kind == "indirect":
                raise Refusal(f"indirect branch or call `{insn.mnemonic} {insn.operands}` at {image.where(insn.addr)}")
            kinds.append((kind, target))
            if kind in ("jump", "cjump"):
                if target is None:
                    raise Refusal(f"branch without a target at {image.where(insn.addr)}")
                if target in index:
                    leaders.add(target)
                elif kind == "cjump":
                    raise Refusal(f"conditional branch out of {func.name} at {image.where(insn.addr)}")
            if kind in ("jump", "cjump", "return", "creturn", "halt") and k + 1 < len(insns):
                leaders.add(insns[k + 1].addr)
        self.blocks: dict[int, Block] = {}
        current = None
        for k, insn in enumerate(insns):
            if insn.addr in leaders:
                current = Block(insn.addr, [])
                self.blocks[insn.addr] = current
            current.insns.append(insn)
            kind, target = kinds[k]
            nxt = insns[k + 1].addr if k + 1 < len(insns) else None
            last = k + 1 == len(insns) or insns[k + 1].addr in leaders
            if kind == "call":
                if target is None or target not in image.functions:
                    raise Refusal(f"call to an address that starts no function at {image.where(insn.addr)}")
                current.calls.append(target)
                current.call_sites.append(insn.addr)
            if kind == "jump":
                if target in index:
                    current.succs.append((target, True))
                else:  # a tail call: the callee, then its return is this function's
                    if target not in image.functions:
                        raise Refusal(f"jump out of {func.name} to an address that starts no function at "
                                      f"{image.where(insn.addr)}")
                    current.calls.append(target)
                    current.call_sites.append(insn.addr)
                    current.succs.append(("exit", True))
                    current.returns = True  # if the callee does (checked)
                    current.tail_call = target
            elif kind == "cjump":
                current.succs.append((target, True))
                if nxt is not None:
                    current.succs.append((nxt, False))
            elif kind == "return":
                current.succs.append(("exit", True))
                current.returns = True
            elif kind == "creturn":
                current.succs.append(("exit", True))
                current.returns = True
                if nxt is not None:
                    current.succs.append((nxt, False))
            elif kind == "halt":
                current.succs.append(("exit", False))  # the run stops here
            elif last:
                if nxt is None and kind == "call":  # a call that must not return (checked)
                    current.succs.append(("exit", False))
                    current.noreturn_call = target
                elif nxt is None:  # padding before a literal pool, unless reached
                    current.falls_off = True
                else:
                    current.succs.append((nxt, False))
            if last:
                continue
        self.entry = insns[0].addr
        self._reachable()
        self._loops()

    def _reachable(self) -> None:
        seen, stack = set(), [self.entry]
        while stack:
            b = stack.pop()
            if b in seen:
                continue
            seen.add(b)
            if self.blocks[b].falls_off:
                raise Refusal(f"{self.func.name} runs off its end at {self.blocks[b].insns[-1].addr:#x}")
            stack.extend(s for s, _ in self.blocks[b].succs if s != "exit")
        self.blocks = {a: b for a, b in self.blocks.items() if a in seen}

    def _loops(self) -> None:
        order = []  # reverse postorder
        seen = set()

        def dfs(b):
            stack = [(b, iter([s for s, _ in self.blocks[b].succs if s != "exit"]))]
            seen.add(b)
            while stack:
                node, it = stack[-1]
                for s in it:
                    if s not in seen:
                        seen.add(s)
                        stack.append((s, iter([t for t, _ in self.blocks[s].succs if t != "exit"])))
                        break
                else:
                    order.append(node)
                    stack.pop()
        dfs(self.entry)
        order.reverse()
        rpo = {b: k for k, b in enumerate(order)}
        preds = {b: [] for b in self.blocks}
        for b, blk in self.blocks.items():
            for s, _ in blk.succs:
                if s != "exit":
                    preds[s].append(b)
        # dominators (Cooper, Harvey, Kennedy)
        idom = {self.entry: self.entry}

        def intersect(a, b):
            while a != b:
                while rpo[a] > rpo[b]:
                    a = idom[a]
                while rpo[b] > rpo[a]:
                    b = idom[b]
            return a
        changed = True
        while changed:
            changed = False
            for b in order[1:]:
                ps = [p for p in preds[b] if p in idom]
                new = ps[0]
                for p in ps[1:]:
                    new = intersect(p, new)
                if idom.get(b) != new:
                    idom[b] = new
                    changed = True

        def dominates(a, b):
            while True:
                if a == b:
                    return True
                if b == self.entry:
                    return False
                b = idom[b]
        self.preds = preds
        self.loops: dict[int, set] = {}   # header -> body blocks
        for b in self.blocks:
            for s, _ in self.blocks[b].succs:
                if s == "exit":
                    continue
                if rpo[s] <= rpo[b]:  # a retreating edge
                    if not dominates(s, b):
                        raise Refusal(f"irreducible cycle: edge {b:#x} -> {s:#x} in {self.func.name}")
                    body = self.loops.setdefault(s, {s})
                    stack = [b]
                    while stack:
                        n = stack.pop()
                        if n not in body:
                            body.add(n)
                            stack.extend(preds[n])

    def block_of(self, addr: int):
        for b in self.blocks.values():
            if b.insns[0].addr <= addr <= b.insns[-1].addr:
                return b.start
        return None

    def _exclusive_retry(self, h: int) -> bool:
        """The loop is one block: LDREX*, STREX*, a test of the store's status and a branch back."""
        body = self.loops[h]
        if len(body) != 1:
            return False
        bases = [split_mnemonic(i.mnemonic)[0] for i in self.blocks[h].insns]
        return (len(bases) <= 5 and bases[0].startswith("ldrex") and any(b.startswith("strex") for b in bases)
                and bases[-1] in ("b", "cbnz"))

    def loop_bounds(self) -> dict[int, tuple[int, list]]:
        """Each loop's bound from the image's annotations: header -> (bound, the blocks holding
        its annotations). An annotation bounds the innermost loop holding its address."""
        found: dict[int, tuple[int, list]] = {}
        for addr, bound in self.image.bounds:
            b = self.block_of(addr)
            if b is None:
                continue
            inner = [h for h, body in self.loops.items() if b in body]
            if not inner:
                continue  # a loop the compiler unrolled completely
            h = min(inner, key=lambda h: len(self.loops[h]))
            if h in found and found[h][0] != bound:
                raise Refusal(f"loop at {self.image.where(h)} has two different bounds, {found[h][0]} and {bound}")
            found.setdefault(h, (bound, []))[1].append(b)
        for h in sorted(self.loops):
            if h not in found and self._exclusive_retry(h):
                # An LDREX/STREX retry (std::atomic's exchange): the store fails only when the
                # exclusive monitor was cleared between the two, which on a single Cortex-M3 takes
                # an exception entry or return (TRM, "Synchronization primitives"); with no
                # interrupt inside the tick (the analysis's assumption) the body runs once.
                found[h] = (1, [h])
            if h not in found:
                raise Refusal(f"loop without a bound: header {self.image.where(h)} "
                              f"(blocks {', '.join(hex(b) for b in sorted(self.loops[h]))})")
        return found


# ---- IPET -----------------------------------------------------------------------------------

def solve_ipet(cfg: Cfg, block_cost: dict, taken_cost: dict, bounds: dict, glpsol: str) -> tuple[int, dict]:
    """Longest path: maximise sum(cost * count) over the edges' counts. Returns (value, block counts)."""
    edges = []  # (src, dst, taken)
    for b, blk in cfg.blocks.items():
        for s, taken in blk.succs:
            edges.append((b, s, taken))
    name = {e: f"e{k}" for k, e in enumerate(edges)}
    # A block's cost rides on each edge out of it (a block runs as often as it is left); a taken
    # branch's pipeline refill on the taken edge only.
    lines = ["Maximize", " cost: " + " + ".join(
        f"{block_cost[src] + (taken_cost[src] if taken else 0)} {name[(src, dst, taken)]}"
        for src, dst, taken in edges), "Subject To"]

    def row(coeffs: dict, sense: str, rhs: int) -> str:
        terms = " ".join(f"{'+' if v >= 0 else '-'} {abs(v)} {k}" for k, v in coeffs.items() if v != 0)
        return f" c{len(lines)}: {terms or '0 e0'} {sense} {rhs}"

    for b in cfg.blocks:  # flow: out of a block = into it (+1 at the entry)
        coeffs: dict = {}
        for e in edges:
            if e[0] == b:
                coeffs[name[e]] = coeffs.get(name[e], 0) + 1
            if e[1] == b:
                coeffs[name[e]] = coeffs.get(name[e], 0) - 1
        lines.append(row(coeffs, "=", 1 if b == cfg.entry else 0))
    for h, body in cfg.loops.items():
        entry = [name[e] for e in edges if e[1] == h and e[0] not in body]
        outside = 0
        n, marked = bounds[h]
        if h == cfg.entry:  # the function's own entry is one more entry into the loop
            outside = n
        # Each iteration but the last takes one back edge; the annotated point runs once per
        # iteration at most (the first keeps every loop bounded, the second makes it tight).
        back = {name[e]: 1 for e in edges if e[1] == h and e[0] in body}
        for x in entry:
            back[x] = back.get(x, 0) - n
        lines.append(row(back, "<=", outside))
        for b in sorted(set(marked)):
            coeffs = {name[e]: 1 for e in edges if e[0] == b}
            for x in entry:
                coeffs[x] = coeffs.get(x, 0) - n
            lines.append(row(coeffs, "<=", outside))
    lines.append("General")
    lines.extend(f" {name[e]}" for e in edges)
    lines.append("End")
    with tempfile.TemporaryDirectory() as tmp:
        lp = os.path.join(tmp, "p.lp")
        sol = os.path.join(tmp, "p.sol")
        with open(lp, "w") as f:
            f.write("\n".join(lines) + "\n")
        # The LP relaxation first: its optimum bounds the integer one from above (sound), and
        # is the integer optimum when its solution is integral (the usual case: flow problems).
        # When it is not, the integer program itself with a time limit; if that does not
        # finish, the relaxation's value, rounded down (the costs are integers), stays a bound.
        run_glpsol(glpsol, lp, sol, cfg, "--nomip")
        with open(sol) as f:
            objective, counts, integral = _parse_solution(f.read().splitlines(), len(edges))
        if not integral:
            run_glpsol(glpsol, lp, sol, cfg, "--tmlim", str(MIP_SECONDS))
            with open(sol) as f:
                try:
                    objective, counts, _ = _parse_solution(f.read().splitlines(), len(edges))
                except Refusal:
                    objective = int(objective + 1e-6)
    flows = {b: 0 for b in cfg.blocks}
    for k, e in enumerate(edges):
        flows[e[0]] += counts[k]
    return int(objective), flows


MIP_SECONDS = 20


def run_glpsol(glpsol: str, lp: str, sol: str, cfg, *options: str) -> None:
    r = subprocess.run([glpsol, "--lp", lp, *options, "--write", sol], capture_output=True, text=True)
    if r.returncode != 0:
        raise Refusal(f"glpsol failed on {cfg.func.name}: {r.stdout[-500:]}{r.stderr[-500:]}")


def _parse_solution(lines: list, n_cols: int) -> tuple:
    """glpsol --write's raw format (GLPK 5): "s bas ROWS COLS PRIMAL DUAL OBJ" (LP) or
    "s mip ROWS COLS STATUS OBJ", then "j COL [STATUS] VALUE [DUAL]" per column."""
    obj = None
    kind = None
    cols = [0.0] * n_cols
    for line in lines:
        f = line.split()
        if len(f) >= 7 and f[0] == "s" and f[1] == "bas":
            kind = "bas"
            if f[4] != "f" or f[5] != "f":
                raise Refusal(f"the longest-path program has no optimum (primal {f[4]}, dual {f[5]}): "
                              "some cycle is unbounded")
            obj = float(f[6])
        elif len(f) >= 6 and f[0] == "s" and f[1] == "mip":
            kind = "mip"
            if f[4] != "o":
                raise Refusal(f"the integer program was not solved to optimality (status {f[4]})")
            obj = float(f[5])
        elif len(f) >= 3 and f[0] == "j":
            cols[int(f[1]) - 1] = float(f[3] if kind == "bas" else f[2])
    if obj is None:
        raise Refusal("glpsol wrote no solution")
    integral = all(abs(v - round(v)) < 1e-6 for v in cols) and abs(obj - round(obj)) < 1e-6
    if kind == "mip" or integral:
        return round(obj), [round(v) for v in cols], True
    return obj, cols, False


# ---- whole analysis ----------------------------------------------------------------------------

@dataclass
class Bound:
    instructions: int
    cycles: int
    loops: list          # (header address, bound) of this function's own loops
    callees: list        # names
    returns: bool        # some path returns (else every path ends in a halt: a trap)


class Analysis:
    def __init__(self, image: Image, wait: int, glpsol: str):
        self.image = image
        self.wait = wait
        self.glpsol = glpsol
        self.done: dict[int, Bound] = {}
        self.active: list[int] = []
        self.paths: dict[int, tuple] = {}  # function start: (cfg, block counts of its longest path in instructions)

    def bound(self, start: int) -> Bound:
        if start in self.done:
            return self.done[start]
        func = self.image.functions.get(start) or self.image.function_at(start)
        if func is None:
            raise Refusal(f"no function at {start:#x}")
        if func.start in self.active:
            chain = " -> ".join(self.image.functions[a].name for a in self.active[self.active.index(func.start):])
            raise Refusal(f"recursion: {chain} -> {func.name}")
        self.active.append(func.start)
        try:
            cfg = Cfg(self.image, func)
            bounds = cfg.loop_bounds()
            instr_cost, cycle_cost, taken_cost = {}, {}, {}
            callees = []
            laid_out = {insn.addr: k for k, insn in enumerate(func.insns)}
            for b, blk in cfg.blocks.items():
                n = len(blk.insns)
                before = written_before(func.insns, laid_out[b])
                cyc = block_cycles(blk.insns, before, self.wait, self.image.data_in_code)
                last = blk.insns[-1]
                taken_cost[b] = cycles(last, self.wait)[1]
                # A call's BL refills the pipeline (its return's refill is in the callee's bound);
                # a tail call's B refills it too, but that is its block's taken edge to the exit,
                # already charged there: not twice.
                for callee, site in zip(blk.calls, blk.call_sites):
                    cb = self.bound(self.image.function_at(callee).start)
                    n += cb.instructions
                    tail = blk.tail_call == callee and site == last.addr
                    cyc += cb.cycles + (0 if tail else PIPELINE_REFILL)
                    callees.append(self.image.function_at(callee).name)
                instr_cost[b] = n
                cycle_cost[b] = cyc
            zero = {b: 0 for b in cfg.blocks}
            instructions, counts = solve_ipet(cfg, instr_cost, zero, bounds, self.glpsol)
            self.paths[func.start] = (cfg, counts)
            cyc, _ = solve_ipet(cfg, cycle_cost, taken_cost, bounds, self.glpsol)
            returns = False
            for blk in cfg.blocks.values():
                if blk.noreturn_call is not None and self.done[self.image.function_at(blk.noreturn_call).start].returns:
                    raise Refusal(f"{func.name} runs off its end after calling "
                                  f"{self.image.function_at(blk.noreturn_call).name}, which returns")
                if blk.tail_call is not None:
                    returns = returns or self.done[self.image.function_at(blk.tail_call).start].returns
                elif blk.returns:
                    returns = True
            result = Bound(instructions, cyc, sorted((h, n) for h, (n, _) in bounds.items()), sorted(set(callees)), returns)
        finally:
            self.active.pop()
        self.done[func.start] = result
        return result

    def path(self, start: int, times: int = 1, into: dict | None = None, calls: tuple | None = None) -> dict:
        """Instructions of the longest path (in instructions) per address: each block's count on
        that path times its instructions, and each call's callee on its own longest path (the
        bound is context-insensitive, so this is the path the bound counts, not necessarily one
        a single input takes). The values add up to the bound. With `calls` (a tuple, () at the
        entry) the keys are (address, the call instructions' addresses that led there), so a
        callee's instructions can be told apart by where they were called from."""
        into = {} if into is None else into
        cfg, counts = self.paths[start]
        for b, blk in cfg.blocks.items():
            n = counts.get(b, 0) * times
            if n == 0:
                continue
            for insn in blk.insns:
                key = insn.addr if calls is None else (insn.addr, calls)
                into[key] = into.get(key, 0) + n
            for callee, site in zip(blk.calls, blk.call_sites):
                self.path(self.image.function_at(callee).start, n, into, None if calls is None else calls + (site,))
        return into


def executed(image: Image, starts: set) -> set:
    """The addresses a run executed, from the start addresses of the translation blocks QEMU
    ran (`qemu-system-arm -d exec,nochain`): a block runs straight on from its start to its
    first branch, call or return (QEMU ends a translation block there, and at nothing that
    would skip an instruction in between)."""
    ran = set()
    for f in image.functions.values():
        for i, insn in enumerate(f.insns):
            if insn.addr not in starts:
                continue
            for later in f.insns[i:]:
                if later.addr in ran:
                    break
                ran.add(later.addr)
                if _classify(later)[0] != "plain":
                    break
    return ran


def read_tb_starts(path: str) -> set:
    """Hexadecimal addresses, one a line (the `-d exec` trace's second field, deduplicated)."""
    with open(path) as f:
        return {int(line.split()[0], 16) for line in f if line.strip()}


def source_lines(image: Image, weights: dict) -> list:
    """(instructions, function, file:line) per source line of the addresses in `weights`, the
    innermost inlined function's line (addr2line), largest first."""
    addresses = sorted(weights)
    per_line: dict = {}
    for a, (fn, where) in zip(addresses, image.lines(addresses)):
        key = (short_name(fn), where)
        per_line[key] = per_line.get(key, 0) + weights[a]
    return sorted(((n, fn, where) for (fn, where), n in per_line.items()), key=lambda t: (-t[0], t[2]))


def short_name(name: str) -> str:
    """A demangled name without its template arguments and parameters, for a table."""
    out, depth = "", 0
    for ch in name:
        if ch in "<(":
            depth += 1
        elif ch in ">)":
            depth = max(0, depth - 1)
        elif depth == 0:
            out += ch
    return out.replace("toonforce::", "").strip()


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("elf")
    p.add_argument("--entry", action="append", required=True, metavar="LABEL=REGEX",
                   help="a function to bound: LABEL=REGEX on demangled names (each match is bounded)")
    p.add_argument("--wait-states", type=int, default=0)
    p.add_argument("--objdump", default="arm-none-eabi-objdump")
    p.add_argument("--glpsol", default="glpsol")
    p.add_argument("--json", help="write the bounds here as JSON")
    p.add_argument("--verbose", action="store_true", help="every function's bound and loops")
    p.add_argument("--path", action="append", default=[], metavar="LABEL",
                   help="where the bound of LABEL's functions goes: the longest path's instructions per source line")
    p.add_argument("--covered", metavar="TB_STARTS",
                   help="how many of each longest path's instructions the run that wrote TB_STARTS (QEMU's -d exec "
                        "translation-block starts, one hexadecimal address a line) never executed: a fifth column, "
                        "and with --path, per source line")
    p.add_argument("--budget", action="append", default=[], metavar="LABEL=INSTRUCTIONS[,CYCLES]",
                   help="exit 1 when a bound of LABEL's functions passes this budget")
    args = p.parse_args(argv)
    image = Image(args.elf, args.objdump)
    analysis = Analysis(image, args.wait_states, args.glpsol)
    ran = executed(image, read_tb_starts(args.covered)) if args.covered else None
    results = []
    try:
        for spec in args.entry:
            label, _, regex = spec.partition("=")
            matches = [f for f in image.functions.values() if re.search(regex, f.name)]
            if not matches:
                raise Refusal(f"no function matches {regex!r} ({label})")
            for f in sorted(matches, key=lambda f: f.name):
                b = analysis.bound(f.start)
                results.append({"label": label, "function": f.name, "address": f.start,
                                "instructions": b.instructions, "cycles": b.cycles})
                line = f"{label}\t{b.instructions}\t{b.cycles}\t{f.name}"
                if ran is not None:  # a fifth column: the longest path's instructions the run never executed
                    weights = analysis.path(f.start)
                    results[-1]["never_run"] = sum(n for a, n in weights.items() if a not in ran)
                    line += f"\t{results[-1]['never_run']}"
                print(line)
    except Refusal as e:
        print(f"wcet: {os.path.basename(args.elf)}: cannot bound: {e}", file=sys.stderr)
        return 2
    if args.verbose:
        for start, b in sorted(analysis.done.items()):
            f = image.functions[start]
            loops = ", ".join(f"{h:#x}<={n}" for h, n in b.loops)
            print(f"  {b.instructions:6d} {b.cycles:6d}  {f.name}{'  loops ' + loops if loops else ''}", file=sys.stderr)
    for label in args.path:
        for r in results:
            if r["label"] != label:
                continue
            weights = analysis.path(r["address"])
            total = sum(weights.values())
            if total != r["instructions"]:  # the path and the bound come from the same solution
                print(f"wcet: path of {r['function']}: {total} instructions against a bound of {r['instructions']}",
                      file=sys.stderr)
                return 2
            print(f"path {label} {short_name(r['function'])}: {total} instructions")
            for n, fn, where in source_lines(image, weights):
                print(f"{n:8d}  {where}  {fn}")
            if ran is not None:
                missed = {a: n for a, n in weights.items() if a not in ran}
                print(f"never run {label} {short_name(r['function'])}: {sum(missed.values())} of the path's {total} "
                      f"instructions are at addresses the run never executed")
                for n, fn, where in source_lines(image, missed):
                    print(f"{n:8d}  {where}  {fn}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"elf": args.elf, "wait_states": args.wait_states, "bounds": results}, f, indent=1)
    over = False
    for spec in args.budget:
        label, _, limits = spec.partition("=")
        instructions, _, cycles = limits.partition(",")
        for r in results:
            if r["label"] != label:
                continue
            for what, limit in (("instructions", instructions), ("cycles", cycles)):
                if limit and r[what] > int(limit):
                    over = True
                    print(f"wcet: {os.path.basename(args.elf)}: over budget: {label} {r['function']} could take "
                          f"{r[what]} {what} > {limit}", file=sys.stderr)
    return 1 if over else 0


if __name__ == "__main__":
    sys.exit(main())
