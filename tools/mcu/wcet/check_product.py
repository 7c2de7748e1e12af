#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""The product image's tick (product_cartoon_wall.elf, firmware/product.cpp): its bound from the
SysTick interrupt to the return, and its stack.

Cycles: wcet.py's bound of SysTick_Handler (the tick and the device's register transfers are
inlined in it) plus the exception's entry and exit. The Cortex-M3 TRM r2p1, section 5.5
"Interrupt latency", gives 12 cycles from the interrupt to the handler's first instruction with
zero wait states (the AN385's SRAM), and 6 when the exception is tail-chained to another; the
worse, 12, is taken. For the return, the unstacking of the same eight words is charged the same
12 cycles. No other exception is enabled in the image (no preemption, no late arrival), and the
model's wait states are 0: the TRM's figures are for a zero-wait-state system.

Checks (exit status 1): the most instructions the image measured for one tick inside the handler
(its "product SCENE handler_tick_max N" line) within the handler's instruction bound; the bound with
entry and exit within --budget-cycles; and the stack: the handler's static bound (stack_bound.py)
plus the exception frame (8 words, and 4 bytes of alignment: ARMv7-M ARM B1.5.6, B1.5.7) plus
the deepest stack the interrupted code can hold (run_image's bound and Reset_Handler's frame)
within the reserved stack (__stack_size).
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import stack_bound  # noqa: E402

ENTRY_CYCLES = 12  # TRM r2p1 5.5: interrupt to first handler instruction, zero wait states (tail-chain: 6)
EXIT_CYCLES = 12   # the return's unstacking of the same 8 words, charged as the stacking
EXCEPTION_FRAME_BYTES = 32 + 4  # r0-r3, r12, lr, pc, xPSR; and the 8-byte alignment's padding word


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("elf")
    p.add_argument("target", help="the image's output under QEMU")
    p.add_argument("--objects", required=True, help="the image's object directory (.su and .ci files)")
    p.add_argument("--budget-cycles", type=int, help="exit 1 when the bound with entry and exit passes this")
    args = p.parse_args(argv)
    name = os.path.basename(args.elf)
    r = subprocess.run([sys.executable, os.path.join(HERE, "wcet.py"), args.elf, "--entry", "handler=^SysTick_Handler$"],
                       capture_output=True, text=True)
    if r.returncode != 0:
        sys.stderr.write(r.stderr)
        return r.returncode
    _, instructions, cycles, _ = r.stdout.splitlines()[0].split("\t")
    instructions, cycles = int(instructions), int(cycles)
    total = cycles + ENTRY_CYCLES + EXIT_CYCLES
    failed = False
    with open(args.target) as f:
        measured = [int(m.group(1)) for m in re.finditer(r"^product \S+ handler_tick_max (\d+)$", f.read(), re.M)]
    if len(measured) != 1:
        print(f"check_product: {args.target}: no handler_tick_max line", file=sys.stderr)
        return 1
    print(f"handler\t{instructions} instructions\t{cycles} cycles\t+ entry {ENTRY_CYCLES} + exit {EXIT_CYCLES} "
          f"= {total} cycles\tmeasured tick in the handler {measured[0]} instructions")
    if measured[0] > instructions:
        print(f"check_product: {name}: a tick took {measured[0]} instructions in the handler, past its bound "
              f"{instructions}", file=sys.stderr)
        failed = True
    if args.budget_cycles is not None and total > args.budget_cycles:
        print(f"check_product: {name}: the tick from interrupt to return could take {total} cycles > "
              f"{args.budget_cycles}", file=sys.stderr)
        failed = True
    try:
        functions, absolute = stack_bound.read_image(args.elf, "arm-none-eabi-objdump")
        analysis = stack_bound.Analysis(functions, stack_bound.read_frames([args.objects]))
        by_name = {f.name: f for f in functions.values()}
        handler = analysis.depth(by_name["SysTick_Handler"]).bytes
        interrupted = analysis.depth(by_name["run_image()"]).bytes + analysis.frame(by_name["Reset_Handler"])[0]
    except stack_bound.Refusal as e:
        print(f"check_product: {name}: cannot bound the stack: {e}", file=sys.stderr)
        return 2
    stack = interrupted + EXCEPTION_FRAME_BYTES + handler
    reserved = absolute["__stack_size"]
    print(f"stack\tinterrupted code {interrupted} + exception frame {EXCEPTION_FRAME_BYTES} + handler {handler} "
          f"= {stack} bytes\treserved {reserved}")
    if stack > reserved:
        print(f"check_product: {name}: the stack could reach {stack} bytes, past the {reserved} reserved",
              file=sys.stderr)
        failed = True
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
