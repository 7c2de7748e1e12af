#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Tests of the static stack bound (stack_bound.py) on a hand-made call graph whose deepest chain
is known (tests/stack/chain.cpp and deep.s: the .su frames of two functions and a hand-written
function's 216 bytes), on a caller whose sp moves after its prologue (--fixed-callers), and on
what it must refuse (recursion, an indirect call, a dynamic frame).

    test_stack_bound.py   (CTest: mcu_m3_stack_bound_analyser; WCET_TEST_DIR: where the test images go)
"""
import os
import re
import subprocess
import sys
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE_DIR = os.path.abspath(os.path.join(HERE, "..", "..", ".."))
TESTS = os.path.join(HERE, "tests", "stack")
WORK = os.path.join(os.environ.get("WCET_TEST_DIR", "/tmp/wcet-tests"), "stack")
CXX = "arm-none-eabi-g++"
CPU = ["-mcpu=cortex-m3", "-mthumb"]


def build(name: str, *sources: str) -> tuple:
    """The image NAME.elf linked from SOURCES (compiled with -fstack-usage) and its object dir."""
    objects_dir = os.path.join(WORK, name)
    os.makedirs(objects_dir, exist_ok=True)
    for old in os.listdir(objects_dir):
        os.remove(os.path.join(objects_dir, old))
    objects = []
    for src in sources:
        obj = os.path.join(objects_dir, src + ".o")
        flags = CPU + ["-c", "-o", obj]
        if src.endswith(".cpp"):
            flags += ["-std=c++20", "-O2", "-ffunction-sections", "-fno-exceptions", "-fno-rtti", "-Wall",
                      "-Wextra", "-Werror", "-fstack-usage", "-fcallgraph-info=su"]
        subprocess.run([CXX, *flags, os.path.join(TESTS, src)], check=True)
        objects.append(obj)
    elf = os.path.join(objects_dir, name + ".elf")
    subprocess.run([CXX, *CPU, "-nostdlib", "-nostartfiles", "-Wl,-e,entry", "-Wl,--gc-sections", "-T",
                    os.path.join(SOURCE_DIR, "tools/mcu/firmware/mps2.ld"), "-o", elf, *objects, "-lgcc"],
                   check=True)
    return elf, objects_dir


def analyse(elf: str, objects_dir: str, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, os.path.join(HERE, "stack_bound.py"), elf, "--objects", objects_dir,
                           "--chain", *extra], capture_output=True, text=True)


def su_frame(objects_dir: str, source: str, name: str) -> int:
    """The frame -fstack-usage gave NAME (read here straight from the .su file)."""
    with open(os.path.join(objects_dir, source + ".su")) as su:
        for line in su:
            if re.search(rf":{re.escape(name)}\t", line):
                return int(line.split("\t")[1])
    raise AssertionError(f"no .su line for {name}")


class Chain(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.elf, cls.objects = build("chain", "chain.cpp", "deep.s")

    def bound(self, regex: str) -> tuple:
        r = analyse(self.elf, self.objects, "--entry", f"t={regex}")
        self.assertEqual(r.returncode, 0, r.stderr)
        lines = r.stdout.splitlines()
        return int(lines[0].split("\t")[1]), lines[1:]

    def test_every_frame_of_the_deepest_chain(self):
        entry = su_frame(self.objects, "chain.cpp", "int entry(int)")
        middle = su_frame(self.objects, "chain.cpp", "int middle(int)")
        self.assertGreater(entry, 0)
        self.assertGreater(middle, 0)
        total, chain = self.bound("^entry$")
        # deep.s: push of 4 registers + sub sp, #200 = 216 bytes, from the disassembly.
        self.assertEqual(total, entry + middle + 216, "\n".join(chain))
        self.assertIn("disassembly", chain[2])
        self.assertIn("deep", chain[2])

    def test_library_helpers_frames_from_their_disassembly(self):
        leaf = su_frame(self.objects, "chain.cpp", "int64_t leaf(int64_t, int64_t)")
        total, chain = self.bound(r"^leaf\(")
        # __aeabi_ldivmod (libgcc, assembly) pushes and calls __udivmoddi4 (C, no .su here): both
        # add to the leaf's own frame.
        self.assertTrue(any("__aeabi_ldivmod" in c and "disassembly" in c for c in chain), "\n".join(chain))
        self.assertTrue(any("__udivmoddi4" in c and "disassembly" in c for c in chain), "\n".join(chain))
        helpers = sum(int(c.split()[0]) for c in chain[1:])
        self.assertGreater(helpers, 0)
        self.assertEqual(total, leaf + helpers)

    def test_painted_past_the_bound_fails(self):
        total, _ = self.bound("^entry$")
        target = os.path.join(self.objects, "target.txt")
        for painted, status in ((total, 0), (total + 4, 1)):
            with open(target, "w") as f:
                f.write(f"stackfn - t {painted}\n")
            r = analyse(self.elf, self.objects, "--entry", "t=^entry$", "--painted", target)
            self.assertEqual(r.returncode, status, r.stdout + r.stderr)

    def test_past_the_reserved_stack_fails(self):
        # mps2.ld reserves __stack_size (4 KiB unless the link defines it): a 64-byte stack fails.
        r = analyse(self.elf, self.objects, "--entry", "t=^entry$", "--reserved")
        self.assertEqual(r.returncode, 0, r.stderr)
        small, objects = build("chain_small", "chain.cpp", "deep.s")
        subprocess.run([CXX, *CPU, "-nostdlib", "-nostartfiles", "-Wl,-e,entry", "-Wl,--defsym=__stack_size=64",
                        "-T", os.path.join(SOURCE_DIR, "tools/mcu/firmware/mps2.ld"), "-o", small,
                        os.path.join(objects, "chain.cpp.o"), os.path.join(objects, "deep.s.o"), "-lgcc"], check=True)
        r = analyse(small, objects, "--entry", "t=^entry$", "--reserved")
        self.assertEqual(r.returncode, 1, r.stdout + r.stderr)
        self.assertIn("reserved (__stack_size)", r.stderr)


class Callers(unittest.TestCase):
    def test_a_caller_that_moves_sp_after_its_prologue_fails(self):
        elf, objects = build("callers", "callers.s")
        r = analyse(elf, objects, "--entry", "t=^leaf$", "--fixed-callers")
        self.assertEqual(r.returncode, 1, r.stdout + r.stderr)
        self.assertIn("moving calls a bounded function", r.stderr)
        self.assertNotIn("fixed calls", r.stderr)
        r = analyse(elf, objects, "--entry", "t=^moving$", "--fixed-callers")  # entry's frame is fixed
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)


class Refused(unittest.TestCase):
    def refused(self, name: str, *sources: str) -> str:
        elf, objects = build(name, *sources)
        r = analyse(elf, objects, "--entry", "t=^entry")
        self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
        return r.stderr

    def test_recursion(self):
        self.assertIn("recursion: entry -> entry", self.refused("recursion", "recursion.s"))

    def test_indirect_call(self):
        self.assertIn("indirect call `blx r0`", self.refused("indirect", "indirect.s"))

    def test_dynamic_frame(self):
        self.assertIn("its frame is dynamic", self.refused("dynamic", "dynamic.cpp"))


if __name__ == "__main__":
    unittest.main()
