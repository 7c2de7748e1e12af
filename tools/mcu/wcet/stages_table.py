#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Where the every-stage bound goes: the instructions of each scene image's longest
path (wcet.py's bound of the every-stage tick, `full_tick`) by the stage of the servo loop they
belong to, and by the kind of work, as two tables of docs/performance/wcet.md.

An instruction belongs to the outermost stage function (STAGES) in its chain of inlined
functions (addr2line -i), the chain of the call site included when it is in a function the tick
calls (the rate limit and the clamp, `ForceSafety::limit_step`, and the 64/32 division are out of
line): the rounding inside a stage's arithmetic is that stage's. Its kind is that of the
innermost function (KINDS): the Q16.16 operators' rounding and saturation, roots and norms,
divisions and reciprocals, the rest. Each column adds up to the scene's bound, which is checked.

The tables sit between marker lines in the document. --check (CTest mcu_m3_wcet_stages_table)
fails when they are not the ones the images give, so the prose's breakdown cannot drift from the
code; --write puts them there.

    stages_table.py --doc docs/performance/wcet.md (--check | --write) SCENE.elf...
"""
from __future__ import annotations

import os
import re
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import doc_section  # noqa: E402
import wcet  # noqa: E402

BEGIN = "<!-- wcet stages: tools/mcu/wcet/stages_table.py writes the tables below -->"
END = "<!-- wcet stages: end -->"
ENTRY = r"::full_tick\("

# (stage, pattern on a frame's short name), in the tick's order; the outermost frame that
# matches decides. Anything else is the tick's own code (the shaping of the force, the fault
# bits, the status).
STAGES = [
    ("device read", r"^read$"),
    ("clock", r"^BasicLoopClock::"),
    ("supervisor", r"^Supervisor::"),
    ("velocity estimate", r"HipSensor::"),
    ("passivity: observer, the last tick's work", r"^Passivity::observe(_step)?$"),
    ("thermal model", r"^ThermalModel::"),
    ("scene force", r"^SceneStage::"),
    ("passivity: damping", r"^Passivity::damping$"),
    ("motion limits", r"MotionLimits::"),
    ("engage and soft start", r"^Engage::"),
    ("safety: rate limit and clamp", r"^ForceSafety::"),
    ("passivity: applied share", r"^Passivity::settle$"),
]
OWN = "the tick's own code"
# (kind, pattern on the innermost frame's short name), first match.
KINDS = [
    ("roots and norms", r"isqrt|inverse_root|norm_from_raw_squares|raw_squares?\b|raw_square::|raw_squares::"),
    ("divisions and reciprocals", r"div_u64|fraction_q16|reciprocal|from_ratio|countl_zero|__countl_zero"),
    ("Q16.16 rounding and saturation",
     r"saturat|from_product|rounded_product|::rounded$|::at_most$|from_wide|round_shift|^operator[-+*]|Wide::dot|times_fraction|Decay::apply"),
]
REST = "the rest"


def stage_of(chain: list) -> str:
    for frame in chain:  # outermost first
        for stage, pattern in STAGES:
            if re.search(pattern, frame):
                return stage
    return OWN


def kind_of(chain: list) -> str:
    inner = chain[-1] if chain else ""
    for kind, pattern in KINDS:
        if re.search(pattern, inner):
            return kind
    return REST


def inline_chains(image: wcet.Image, addresses: list) -> dict:
    """Each address's inlined functions, outermost first (short names), by one addr2line -i run."""
    addr2line = image.objdump.replace("objdump", "addr2line")
    r = subprocess.run([addr2line, "-a", "-i", "-f", "-C", "-e", image.elf, *[hex(a) for a in addresses]],
                       capture_output=True, text=True, timeout=60, check=True)
    chains, current, lines = {}, None, r.stdout.splitlines()
    k = 0
    while k < len(lines):
        if lines[k].startswith("0x"):
            current = int(lines[k], 16)
            chains[current] = []
            k += 1
            continue
        chains[current].insert(0, wcet.short_name(lines[k]))  # addr2line lists innermost first
        k += 2  # the name, then its file:line
    return chains


def breakdown(elf: str) -> tuple[str, int, dict, dict]:
    """(scene, bound, instructions per stage, per kind) of the image's every-stage tick."""
    image = wcet.Image(elf, "arm-none-eabi-objdump")
    analysis = wcet.Analysis(image, 0, "glpsol")
    entries = [f for f in image.functions.values() if re.search(ENTRY, f.name)]
    if len(entries) != 1:
        raise SystemExit(f"stages_table: {elf}: {len(entries)} functions match {ENTRY}")
    bound = analysis.bound(entries[0].start).instructions
    weights = analysis.path(entries[0].start, calls=())  # (address, call sites) -> instructions
    addresses = sorted({a for a, _ in weights} | {c for _, ctx in weights for c in ctx})
    chains = inline_chains(image, addresses)
    stages: dict = {}
    kinds: dict = {}
    for (a, ctx), n in weights.items():
        chain = [frame for c in ctx for frame in chains[c]] + chains[a]
        stage, kind = stage_of(chain[1:]), kind_of(chains[a])  # [1:]: not the tick itself
        stages[stage] = stages.get(stage, 0) + n
        kinds[kind] = kinds.get(kind, 0) + n
    if sum(stages.values()) != bound:
        raise SystemExit(f"stages_table: {elf}: the path adds up to {sum(stages.values())}, the bound is {bound}")
    scene = os.path.splitext(os.path.basename(elf))[0]
    return scene, bound, stages, kinds


def tables(elfs: list) -> list:
    results = [breakdown(e) for e in elfs]
    head = "| " + " | ".join(r[0] for r in results) + " |"
    rule = "| --- |" + " ---: |" * len(results)
    lines = ["| stage (every-stage loop, instructions on the bound's path) " + head, rule]
    for stage in [s for s, _ in STAGES] + [OWN]:
        lines.append(f"| {stage} | " + " | ".join(f"{r[2].get(stage, 0):,}" for r in results) + " |")
    lines.append("| **the bound** | " + " | ".join(f"**{r[1]:,}**" for r in results) + " |")
    lines += ["", "| kind (the same paths) " + head, rule]
    for kind in [k for k, _ in KINDS] + [REST]:
        lines.append(f"| {kind} | " + " | ".join(f"{r[3].get(kind, 0):,}" for r in results) + " |")
    return lines


if __name__ == "__main__":
    sys.exit(doc_section.main("stages_table", BEGIN, END, "elf", tables,
                              "breakdown of the bound is not the images' (the code changed)"))
