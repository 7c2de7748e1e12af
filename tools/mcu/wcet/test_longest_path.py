#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Tests of the second worst-case analyser (longest_path.py) on small Thumb-2 functions assembled
and linked here for the Cortex-M3, whose longest paths in instructions and in strict-model
cycles are worked out by hand beside each source, and on what it must refuse. Each case is there
to fail when one rule of the analyser is removed (named in its docstring).

    test_longest_path.py   (CTest: mcu_m3_wcet_longest_path; WCET_TEST_DIR: where the ELFs go)
"""
import os
import subprocess
import sys
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE_DIR = os.path.abspath(os.path.join(HERE, "..", "..", ".."))
WORK = os.path.join(os.environ.get("WCET_TEST_DIR", "/tmp/wcet-tests"), "longest_path")
LLVM_OBJDUMP = os.environ.get("TOONFORCE_LLVM_OBJDUMP", "llvm-objdump")
HEAD = "\t.syntax unified\n\t.thumb\n\t.text\n\t.global entry\n\t.type entry, %function\nentry:\n"
TAIL = "\t.size entry, .-entry\n"


def bounds_of(marks: str) -> str:
    """The loop-bound annotations of `entry`, as TOONFORCE_LOOP_BOUND emits them."""
    return f'\t.pushsection .toonforce.loop_bounds,"o",%progbits,entry\n\t.word {marks}\n\t.popsection\n'


def build(name: str, body: str, extra: str = "", link: tuple = ()) -> str:
    os.makedirs(WORK, exist_ok=True)
    src = os.path.join(WORK, name + ".s")
    elf = os.path.join(WORK, name + ".elf")
    with open(src, "w") as f:
        f.write(HEAD + body + TAIL + extra)
    subprocess.run(["arm-none-eabi-gcc", "-mcpu=cortex-m3", "-mthumb", "-nostdlib", "-nostartfiles",
                    "-Wl,-e,entry", "-T", os.path.join(SOURCE_DIR, "tools/mcu/firmware/mps2.ld"), *link, "-o", elf, src],
                   check=True)
    return elf


def analyse(elf: str, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, os.path.join(HERE, "longest_path.py"), elf, "--entry", "t=^entry$",
                           "--llvm-objdump", LLVM_OBJDUMP, *extra], capture_output=True, text=True)


def bound(name: str, body: str, extra: str = "", wait: int = 0, link: tuple = ()) -> tuple:
    r = analyse(build(name, body, extra, link), "--wait-states", str(wait))
    if r.returncode != 0:
        raise AssertionError(f"{name}: exit {r.returncode}: {r.stderr}")
    _, instructions, cycles, _ = r.stdout.splitlines()[0].split("\t")
    return int(instructions), int(cycles)


class Paths(unittest.TestCase):
    def test_straight_line(self):
        """movs, adds, mul, 1 each; bx lr 1 + P 3."""
        self.assertEqual(bound("straight", "\tmovs r0, #1\n\tadds r0, #2\n\tmuls r0, r0\n\tbx lr\n"), (4, 7))

    def test_diamond_takes_the_dearer_arm_per_cost(self):
        """Instructions: the long arm (cmp, beq, 3 movs, b, bx: 7); cycles: the short arm taken
        (cmp, beq + 3, udiv 12, bx 4 = 21) is dearer than the long one (cmp, beq, 3 movs, b + 3,
        bx 4 = 13): a longest path per cost, not one path for both."""
        body = ("\tcmp r0, #0\n\tbeq 1f\n\tmovs r1, #1\n\tmovs r1, #2\n\tmovs r1, #3\n\tb 2f\n"
                "1:\tudiv r0, r0, r1\n2:\tbx lr\n")
        self.assertEqual(bound("diamond", body), (7, 21))

    def test_annotated_loop(self):
        """Bound 8 on the body: 2 + 8 x 3 + 1 = 27 instructions; 2 + 24 + 7 back edges x 3 + 4 = 51."""
        body = "\tmovs r0, #0\n\tmovs r1, #8\n1:\tadds r0, r0, r1\n\tsubs r1, r1, #1\n\tbne 1b\n\tbx lr\n"
        self.assertEqual(bound("loop", body, bounds_of("1b, 8")), (27, 51))

    def test_annotated_header_runs_bound_times(self):
        """Rule: an annotated block runs at most bound times per entry, so with the mark in the
        header (the whole loop) 4 passes, 3 back edges: 1 + 4 x 3 + 1 = 14 instructions; cycles
        1 + 4 x 3 + 3 x 3 + 4 = 26 (without the rule: 5 passes, 17 and 32)."""
        body = "\tmovs r0, #0\n1:\tadds r0, #1\n\tcmp r0, #10\n\tbne 1b\n\tbx lr\n"
        self.assertEqual(bound("header_mark", body, bounds_of("1b, 4")), (14, 26))

    def test_mark_avoided_by_the_exit_pass(self):
        """Header H (cmp, beq: exits cheaply to a bx), M annotated 3 (adds, cmp, beq: exits to X,
        4 nops and a bx), then b back. Instructions: 2 back passes + H + M + X = 1 + 2 x 6 + 2 + 3
        + 5 = 23 beats 3 back passes + H + bx = 22 (all passes through M would be 29). Cycles:
        3 back passes (9 each) + H taken + bx = 1 + 27 + 5 + 4 = 37 beats 1 + 18 + 2 + 6 + 8 = 35."""
        body = ("\tmovs r0, #0\n1:\tcmp r0, #10\n\tbeq 3f\n2:\tadds r0, #1\n\tcmp r1, #0\n\tbeq 4f\n\tb 1b\n"
                "4:\tnop\n\tnop\n\tnop\n\tnop\n\tbx lr\n3:\tbx lr\n")
        self.assertEqual(bound("mark_exit", body, bounds_of("2b, 3")), (23, 37))

    def test_exclusive_retry_runs_once(self):
        """An LDREX/STREX retry without interrupts: once. ldrexb 2, strexb 2, cmp 1, bne 1, bx 4."""
        body = "1:\tldrexb r3, [r0]\n\tstrexb r2, r1, [r0]\n\tcmp r2, #0\n\tbne 1b\n\tbx lr\n"
        self.assertEqual(bound("exclusive", body), (5, 10))

    def test_nested_loops_collapse_innermost_first(self):
        """4 x 3: 1 + 4 + 12 x 2 + 4 x 2 + 1 = 38; cycles 1 + 4 + 24 + 8 x 3 + 8 + 3 x 3 + 4 = 74."""
        body = "\tmovs r2, #4\n1:\tmovs r3, #3\n2:\tsubs r3, #1\n\tbne 2b\n\tsubs r2, #1\n\tbne 1b\n\tbx lr\n"
        self.assertEqual(bound("nested", body, bounds_of("1b, 4, 2b, 3")), (38, 74))

    def test_calls_cost_their_callee(self):
        """push 3, 2 x (bl 1 + 3 + leaf (1 + 4)), pop with pc 1 + 2 + 3: 8 instructions, 27 cycles."""
        leaf = "\t.type leaf, %function\nleaf:\n\tadds r0, #1\n\tbx lr\n\t.size leaf, .-leaf\n"
        self.assertEqual(bound("call", "\tpush {r4, lr}\n\tbl leaf\n\tbl leaf\n\tpop {r4, pc}\n", leaf), (8, 27))

    def test_tail_call_is_one_taken_branch(self):
        """adds 1, b leaf 1 + 3 (one refill: the b's), leaf adds 1, bx 1 + 3: 4 instructions, 10."""
        leaf = "\t.type leaf, %function\nleaf:\n\tadds r0, #1\n\tbx lr\n\t.size leaf, .-leaf\n"
        self.assertEqual(bound("tail", "\tadds r0, #1\n\tb leaf\n", leaf), (4, 10))

    def test_a_halt_ends_the_path(self):
        """cmp, bne + 3 to a halt (`b .`, 1): the return path cmp, bne, movs, bx (4 / 7) against
        cmp, bne taken, b . (3 / 6)."""
        self.assertEqual(bound("halt", "\tcmp r0, #0\n\tbne 1f\n\tmovs r0, #1\n\tbx lr\n1:\tb 1b\n"), (4, 7))


class Cycles(unittest.TestCase):
    """The strict model's rules, each on the smallest function that shows it."""

    def test_mrs_msr_two(self):
        """TRM table 3-1 "1 or 2": 2 each; + bx 4."""
        self.assertEqual(bound("mrs", "\tmrs r0, apsr\n\tmsr apsr_nzcvq, r0\n\tbx lr\n"), (3, 8))

    def test_multiplies_and_divides_at_their_top(self):
        """UMULL 5, UMLAL 7, SDIV 12, MLA 2; + bx 4."""
        body = "\tumull r0, r1, r2, r3\n\tumlal r0, r1, r2, r3\n\tsdiv r0, r0, r1\n\tmla r0, r1, r2, r0\n\tbx lr\n"
        self.assertEqual(bound("mul", body), (5, 30))

    def test_no_pipelining_credit(self):
        """Two independent loads: 2 + 2 (no -1 for the second); + bx 4."""
        self.assertEqual(bound("ldr_ldr", "\tldr r1, [r0]\n\tldr r2, [r0, #4]\n\tbx lr\n"), (3, 8))

    def test_address_from_data_processing(self):
        """adds writes the load's base: + 1 (1 + 2 + 1 + 4)."""
        self.assertEqual(bound("dep", "\tadds r0, #4\n\tldr r1, [r0]\n\tbx lr\n"), (3, 8))

    def test_address_dependence_through_it_and_conditional(self):
        """adds r0; it eq; moveq r2 (may not run): the load after may follow adds: + 1.
        1 + 1 + 1 + (2 + 1) + 4 = 10."""
        body = "\tadds r0, #4\n\tit eq\n\tmoveq r2, r3\n\tldr r1, [r0]\n\tbx lr\n"
        self.assertEqual(bound("dep_it", body), (5, 10))

    def test_dependence_across_a_join_is_the_dearest(self):
        """The load's block is reached by a taken branch and by a fall-through from adds r0 (a
        stall): its first instruction is charged the dearest, so the taken path is cmp 1, beq
        1 + 3, ldr 2 + 1, bx 4 = 12 cycles (without the stall 11); instructions: the fall-through, 5."""
        body = "\tcmp r1, #0\n\tbeq 1f\n\tadds r0, #4\n1:\tldr r1, [r0]\n\tbx lr\n"
        self.assertEqual(bound("dep_join", body), (5, 12))

    def test_literal_load_contends_with_fetch(self):
        """LDR Rx,[PC,#imm]: 2 + 1; + bx 4 (the pool is in the code: no data section)."""
        self.assertEqual(bound("literal", "\tldr r0, =0x12345678\n\tbx lr\n\t.ltorg\n"), (2, 7))

    def test_loads_charged_for_code_memory_when_data_is_there(self):
        """The same load, 2 with all data at 0x20000000 (none here), 3 with a data word placed in
        the code region (mps2.ld keeps all data in RAM: the section is put there by hand)."""
        body = "\tldr r1, [r0]\n\tbx lr\n"
        self.assertEqual(bound("code_data_none", body), (2, 6))
        self.assertEqual(bound("code_data", body, '\t.section .table,"a"\n\t.word 1\n',
                               link=("-Wl,--section-start=.table=0x10000",)), (2, 7))
        # a vector table there is no data a load reads (the exception entry reads it)
        self.assertEqual(bound("code_vectors", body, '\t.section .vectors,"a"\n\t.word 1\n'), (2, 6))

    def test_wait_states_per_fetch_and_per_word(self):
        """W = 1: push {r4, lr} 3 + 3, pop {r4, pc} 3 + 3 + P 3: 15; W = 0: 9."""
        body = "\tpush {r4, lr}\n\tpop {r4, pc}\n"
        self.assertEqual(bound("wait0", body), (2, 9))
        self.assertEqual(bound("wait1", body, wait=1), (2, 15))


class Refusals(unittest.TestCase):
    def refused(self, name: str, body: str, pattern: str, extra: str = "") -> None:
        r = analyse(build(name, body, extra))
        self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
        self.assertRegex(r.stderr, pattern)

    def test_waits_barriers_and_traps(self):
        for op in ("svc #0", "wfi", "wfe", "sev", "dmb sy", "dsb sy", "isb sy", "bkpt #0"):
            with self.subTest(op=op):
                self.refused("refuse_" + op.split()[0], f"\t{op}\n\tbx lr\n", r"at 0x[0-9a-f]+ in entry")

    def test_unknown_instruction(self):
        self.refused("unknown", "\tpld [r0]\n\tbx lr\n", r"unknown instruction `pld` at 0x")

    def test_indirect(self):
        self.refused("blx", "\tpush {r4, lr}\n\tblx r3\n\tpop {r4, pc}\n", r"blx")
        self.refused("bx_reg", "\tbx r3\n", r"indirect branch `bx r3`")
        self.refused("tbb", "\ttbb [pc, r0]\n\t.byte 2, 3\n\tbx lr\n\tbx lr\n", r"tbb")

    def test_unannotated_loop(self):
        self.refused("unbounded", "1:\tsubs r0, #1\n\tbne 1b\n\tbx lr\n", r"loop without a bound")

    def test_recursion(self):
        self.refused("recursion", "\tpush {r4, lr}\n\tbl entry\n\tpop {r4, pc}\n", r"recursion: entry -> entry")

    def test_irreducible(self):
        body = "\tcmp r0, #0\n\tbeq 2f\n1:\tsubs r1, #1\n2:\tsubs r2, #1\n\tbne 1b\n\tbx lr\n"
        self.refused("irreducible", body, r"irreducible", bounds_of("1b, 4, 2b, 4"))


if __name__ == "__main__":
    unittest.main()
