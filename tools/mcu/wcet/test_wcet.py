#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Tests of the worst-case analyser (wcet.py) on small functions for the Cortex-M3, assembled or
compiled here and linked with the images' linker script, whose longest paths are known exactly
(each file's comment derives its figures), on what it must refuse, on each rule of its strict
cycle model, and on check_bound.py's exact gate (the count's window measured from an image).

    test_wcet.py   (CTest: mcu_m3_wcet_analyser; WCET_TEST_DIR: where the test images go)
"""
import os
import subprocess
import sys
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import wcet  # noqa: E402

SOURCE_DIR = os.path.abspath(os.path.join(HERE, "..", "..", ".."))
WORK = os.environ.get("WCET_TEST_DIR", "/tmp/wcet-tests")
CXX = "arm-none-eabi-g++"
CPU = ["-mcpu=cortex-m3", "-mthumb"]


def build(name: str, *extra: str) -> str:
    os.makedirs(WORK, exist_ok=True)
    src = os.path.join(HERE, "tests", name)
    elf = os.path.join(WORK, os.path.splitext(name)[0] + ("-g" if extra else "") + ".elf")
    flags = CPU + list(extra) + ["-nostdlib", "-nostartfiles", "-Wl,-e,entry", "-Wl,--gc-sections",
                   "-T", os.path.join(SOURCE_DIR, "tools/mcu/firmware/mps2.ld"), "-o", elf]
    if name.endswith(".cpp"):
        flags += ["-std=c++20", "-O2", "-ffunction-sections", "-fdata-sections", "-fno-exceptions", "-fno-rtti",
                  "-Wall", "-Wextra", "-Wpedantic", "-Wconversion", "-Werror",
                  "-I", os.path.join(SOURCE_DIR, "effects/include")]
    subprocess.run([CXX, *flags, src], check=True)
    return elf


HEAD = "\t.syntax unified\n\t.thumb\n\t.text\n\t.global entry\n\t.type entry, %function\nentry:\n"


def build_text(name: str, body: str, tail: str = "", link: tuple = ()) -> str:
    """A function `entry` of the instructions `body` (and `tail` after it: data, other sections),
    written here and built as build() does: for the rules tried on many instructions."""
    os.makedirs(WORK, exist_ok=True)
    src = os.path.join(WORK, name + ".s")
    with open(src, "w") as f:
        f.write(HEAD + body + "\t.size entry, .-entry\n" + tail)
    elf = os.path.join(WORK, name + ".elf")
    subprocess.run([CXX, *CPU, "-nostdlib", "-nostartfiles", "-Wl,-e,entry", "-Wl,--gc-sections",
                    "-T", os.path.join(SOURCE_DIR, "tools/mcu/firmware/mps2.ld"), *link, "-o", elf, src], check=True)
    return elf


def analyse(elf: str, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, os.path.join(HERE, "wcet.py"), elf, "--entry", "t=^entry$", *extra],
                          capture_output=True, text=True)


def bound(name: str) -> tuple:
    r = analyse(build(name))
    if r.returncode != 0:
        raise AssertionError(f"{name}: exit {r.returncode}: {r.stderr}")
    label, instructions, cycles, function = r.stdout.splitlines()[0].split("\t")
    return int(instructions), int(cycles)


class Exact(unittest.TestCase):
    """Bounds equal to the longest path worked out by hand (in each file's comment)."""

    def test_straight(self):
        self.assertEqual(bound("straight.s"), (5, 8))

    def test_diamond_longest_path_differs_per_cost(self):
        self.assertEqual(bound("diamond.s"), (7, 21))

    def test_annotated_loop(self):
        self.assertEqual(bound("loop.s"), (27, 51))

    def test_nested_loops(self):
        self.assertEqual(bound("nested.s"), (38, 74))

    def test_calls(self):
        self.assertEqual(bound("call.s"), (8, 27))

    def test_exclusive_retry_runs_once(self):
        self.assertEqual(bound("exclusive.s"), (5, 10))

    def test_load_store_pairings_without_credit(self):
        # pairing.s: no -1 for a load or store after a load (22 with it).
        self.assertEqual(bound("pairing.s"), (11, 24))

    def test_a_stall_is_charged_across_a_join(self):
        self.assertEqual(bound("pairing_join.s"), (5, 12))

    def test_wait_states_add_per_fetch_and_per_word(self):
        # straight.s with 2 wait states: 5 fetches x 2 more, no data access: 8 + 10.
        r = analyse(build("straight.s"), "--wait-states", "2")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(r.stdout.split("\t")[1:3], ["5", "18"])


def text_bound(name: str, body: str, tail: str = "", link: tuple = ()) -> tuple:
    r = analyse(build_text(name, body, tail, link))
    if r.returncode != 0:
        raise AssertionError(f"{name}: exit {r.returncode}: {r.stderr}")
    return tuple(int(x) for x in r.stdout.split("\t")[1:3])


class Strict(unittest.TestCase):
    """The strict model's rules (wcet.py's docstring), each on a function that a model without
    the rule bounds differently."""

    def test_mrs_msr_cps_at_two(self):
        # TRM table 3-1: "1 or 2" each, taken at 2: 4 x 2 + bx lr (1 + 3) = 12 (8 at 1).
        self.assertEqual(text_bound("system", "\tmrs r0, APSR\n\tmsr APSR_nzcvq, r0\n\tcpsid i\n\tcpsie i\n"
                                              "\tbx lr\n"), (5, 12))

    def test_no_credit_after_a_load(self):
        # ldr 2, ldr 2 (not 1: pipelined "when possible" only), str 2 (not 1), bx 4 = 10.
        self.assertEqual(text_bound("after_load", "\tldr r0, [sp]\n\tldr r1, [sp, #4]\n\tstr r1, [sp, #8]\n"
                                                  "\tbx lr\n"), (4, 10))

    def test_a_skipped_conditional_leaves_the_stall(self):
        # moveq may not run: then the ldr follows the adds that wrote its address: + 1.
        # adds 1, it 1, moveq 1, ldr 2 + 1, bx 4 = 10 (9 when only the moveq were looked at).
        self.assertEqual(text_bound("skipped", "\tadds r3, r0, #4\n\tit eq\n\tmoveq r5, r6\n\tldr r0, [r3]\n"
                                               "\tbx lr\n"), (5, 10))

    def test_a_tail_call_refills_once(self):
        # adds 1, b leaf 1 + 3 (its taken edge; no second refill as for a BL), leaf: adds 1,
        # bx lr 1 + 3: 4 instructions, 10 cycles (13 when the B were charged as a call too).
        leaf = "\t.type leaf, %function\nleaf:\n\tadds r0, #1\n\tbx lr\n\t.size leaf, .-leaf\n"
        self.assertEqual(text_bound("tail", "\tadds r0, #1\n\tb leaf\n", leaf), (4, 10))

    # A load from a register, a PC-relative load (of the address of a word of data in SECTION,
    # which keeps the word from --gc-sections), a return.
    CODE = "\tldr r0, [r1]\n\tldr r2, 1f\n\tbx lr\n\t.align 2\n1:\t.word datum\n"

    def code_memory(self, section: str, link: tuple = ()) -> tuple:
        return text_bound("data_in" + section.replace(".", "_"), self.CODE,
                          f"\t.section {section},\"a\"\ndatum:\t.word 1\n", link)

    def test_data_in_the_code_region_charges_every_load(self):
        # A data section placed in the code region (mps2.ld itself keeps all data in RAM, and
        # refuses .rodata or the motions there): both loads contend with fetch:
        # (2 + 1) + (2 + 1) + 4 = 10.
        self.assertEqual(self.code_memory(".table", ("-Wl,--section-start=.table=0x10000",)), (3, 10))

    def test_data_in_ram_charges_pc_relative_loads_only(self):
        # .data at 0x20000000: 2 + (2 + 1) + 4 = 9.
        self.assertEqual(self.code_memory(".data"), (3, 9))

    def test_the_vector_table_is_no_data(self):
        # .vectors is read by exception entry, not by a load: as with no data, 9.
        self.assertEqual(self.code_memory(".vectors"), (3, 9))

    def test_each_refused_instruction(self):
        for insn in ("svc 0", "wfi", "wfe", "sev", "dmb sy", "dsb sy", "isb sy", "bkpt 0"):
            with self.subTest(insn=insn):
                r = analyse(build_text("refused_" + insn.split()[0], f"\tmovs r0, #0\n\t{insn}\n\tbx lr\n"))
                self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
                self.assertRegex(r.stderr, rf"cannot bound: `{insn.split()[0]}\b[^`]*`, .*, at 0x2 in entry")

    def test_udf_stays_a_halt(self):
        # A trap's end: cmp 1, bne 1, udf 1 (3 cycles); or cmp 1, bne 1 + 3, bx lr 4: 3 instructions, 9 cycles.
        self.assertEqual(text_bound("halt", "\tcmp r0, #0\n\tbne 1f\n\tudf #0\n1:\tbx lr\n"), (3, 9))

    def test_an_unknown_instruction_is_refused(self):
        r = analyse(build_text("unknown", "\tclrex\n\tbx lr\n"))
        self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
        self.assertRegex(r.stderr, r"an instruction the cycle model does not know `clrex ` at 0x0 in entry")


class Gate(unittest.TestCase):
    """check_bound.py's exact gate: measured <= bound + the count's window, the window measured
    from the image (tests/gate.s: windows 3, 1 and 2 around bounds 2, 3 and 4)."""

    def gate(self, loop: int, every: int, effects: int, calibration: str = "1 100") -> subprocess.CompletedProcess:
        elf = build("gate.s")
        counts = os.path.join(WORK, "gate-counts.txt")
        with open(counts, "w") as f:
            f.write(f"calibration {calibration}\ncount wall m 1 loop {loop} {loop} every {every} {every} "
                    f"effects {effects} {effects}\n")
        return subprocess.run([sys.executable, os.path.join(HERE, "check_bound.py"), elf, counts],
                              capture_output=True, text=True)

    def test_the_windows_are_measured(self):
        r = self.gate(5, 4, 6)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("ok:   wall loop: measured 5 <= bound 2 + window 3 instructions", r.stdout)
        self.assertIn("ok:   wall every: measured 4 <= bound 3 + window 1 instructions", r.stdout)
        self.assertIn("ok:   wall effects: measured 6 <= bound 4 + window 2 instructions", r.stdout)

    def test_an_under_count_of_one_fails(self):
        for counts in ((6, 4, 6), (5, 5, 6), (5, 4, 7)):
            with self.subTest(counts=counts):
                r = self.gate(*counts)
                self.assertEqual(r.returncode, 1, r.stdout + r.stderr)
                self.assertRegex(r.stdout, r"over: wall \w+: measured \d+ > bound")

    def test_a_calibration_the_image_does_not_show_fails(self):
        r = self.gate(5, 4, 6, "1 99")
        self.assertEqual(r.returncode, 1, r.stdout + r.stderr)
        self.assertIn("the window measure does not hold", r.stderr)


class Path(unittest.TestCase):
    """--path: where the bound goes, per source line, adding up to the bound."""

    def path(self, name: str) -> tuple:
        """--path's heading and {file:line: instructions} for tests/NAME built with line info."""
        r = analyse(build(name, "-g"), "--path", "t")
        self.assertEqual(r.returncode, 0, r.stderr)
        lines = r.stdout.splitlines()
        per_line = {}
        for line in lines[2:]:
            count, where, _ = line.split(None, 2)
            per_line[where] = int(count)
        return lines[1], per_line

    @staticmethod
    def at(name: str, counts: dict) -> dict:
        """{file:line: instructions} of tests/NAME from {line: instructions}."""
        source = os.path.relpath(os.path.join(HERE, "tests", name))
        return {f"{source}:{n}": c for n, c in counts.items()}

    def test_diamond_path_is_the_longer_arm(self):
        heading, per_line = self.path("diamond.s")
        self.assertEqual(heading, "path t entry: 7 instructions")
        # diamond.s: cmp (line 10), beq, the three adds, b, bx (17) once each; not the udiv (16).
        self.assertEqual(per_line, self.at("diamond.s", {n: 1 for n in (10, 11, 12, 13, 14, 15, 17)}))

    def test_calls_count_their_callee_path(self):
        heading, per_line = self.path("call.s")
        self.assertEqual(heading, "path t entry: 8 instructions")
        # call.s: push, bl, bl, pop (lines 9-12) once; the leaf's adds and bx (16, 17) once per call.
        self.assertEqual(per_line, self.at("call.s", {9: 1, 10: 1, 11: 1, 12: 1, 16: 2, 17: 2}))

    def test_a_callee_in_a_loop_counts_once_per_iteration(self):
        heading, per_line = self.path("loop_call.s")
        self.assertEqual(heading, "path t entry: 23 instructions")
        # loop_call.s: push, movs, pop (9, 10, 14) once; bl, subs, bne (11-13) and the leaf (21, 22) 4 times.
        self.assertEqual(per_line, self.at("loop_call.s", {9: 1, 10: 1, 11: 4, 12: 4, 13: 4, 14: 1, 21: 4, 22: 4}))


class Covered(unittest.TestCase):
    """--covered: the longest path's instructions a run never executed, from the starts of the
    translation blocks QEMU ran (each runs on to its first branch)."""

    def never_run(self, starts: list) -> int:
        elf = build("diamond.s")
        entry = wcet.Image(elf, "arm-none-eabi-objdump").by_name["entry"].start
        tbs = os.path.join(WORK, "diamond-tbs.txt")
        with open(tbs, "w") as f:
            f.writelines(f"{entry + offset:08x}\n" for offset in starts)
        r = analyse(elf, "--covered", tbs)
        self.assertEqual(r.returncode, 0, r.stderr)
        return int(r.stdout.splitlines()[0].split("\t")[4])

    def test_only_the_taken_arm_ran(self):
        # diamond.s: cmp at 0, beq at 2, adds at 4-8, b at 10, udiv at 12, bx at 16. From 0: cmp,
        # beq (a branch ends the run); from 12: udiv, bx. The path's adds and b never ran: 4.
        self.assertEqual(self.never_run([0, 12]), 4)

    def test_the_longest_arm_ran(self):
        # From 0: cmp, beq; from 4: the adds and b; from 16: bx. All of the path ran.
        self.assertEqual(self.never_run([0, 4, 16]), 0)

    def test_a_start_runs_on_to_its_branch_only(self):
        # From 4 the run ends at the b: the bx at 16 never ran.
        self.assertEqual(self.never_run([0, 4]), 1)

    def test_nothing_ran(self):
        self.assertEqual(self.never_run([]), 7)


class Budget(unittest.TestCase):
    """--budget fails (exit 1) when a bound passes it, in instructions or in cycles."""

    def test_budget(self):
        elf = build("straight.s")  # 5 instructions, 8 cycles
        self.assertEqual(analyse(elf, "--budget", "t=5,8").returncode, 0)
        over = analyse(elf, "--budget", "t=4")
        self.assertEqual(over.returncode, 1)
        self.assertRegex(over.stderr, r"over budget: t entry could take 5 instructions > 4")
        self.assertEqual(analyse(elf, "--budget", "t=5,7").returncode, 1)


class Refuses(unittest.TestCase):
    """What cannot be bounded: exit status 2 and the reason, with where."""

    def refused(self, name: str, pattern: str):
        r = analyse(build(name))
        self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
        self.assertRegex(r.stderr, pattern)

    def test_unannotated_loop(self):
        self.refused("unbounded.s", r"loop without a bound: header 0x[0-9a-f]+ in entry")

    def test_indirect_call(self):
        self.refused("indirect.s", r"indirect branch or call `blx r3` at 0x[0-9a-f]+ in entry")

    def test_recursion(self):
        self.refused("recursion.s", r"recursion: entry -> entry")

    def test_call_into_a_function(self):
        self.refused("mid_call.s", r"call to an address that starts no function at 0x[0-9a-f]+ in entry")

    def test_jump_table(self):
        self.refused("jump_table.s", r"indirect branch or call `tbb")


class Macro(unittest.TestCase):
    """TOONFORCE_LOOP_BOUND through the compiler and the images' linker script: the bounds come
    from the code's constants, and a function --gc-sections drops takes its pair with it."""

    def test_generated_bounds(self):
        elf = build("annotated.cpp")
        r = analyse(elf, "--verbose")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertRegex(r.stderr, r"sum<12u?l?>.*loops 0x[0-9a-f]+<=12\b")
        image = wcet.Image(elf, "arm-none-eabi-objdump")
        self.assertNotIn("unused", " ".join(f.name for f in image.functions.values()))
        # the dropped function's pair went with it; the two others are there
        self.assertEqual(sorted(n for _, n in image.bounds), [12, 12])


if __name__ == "__main__":
    unittest.main(verbosity=2)
