@ A stall across a join: the block at 1: starts with a load whose address the add laid out just
@ before it computes. Reached from the add (fall-through) it stalls; reached by the taken beq it
@ does not, but the analysis cannot tell the two apart and charges the stall on both (sound).
@ Not taken: cmp 1, beq 1, adds 1, ldr 2 + 1, bx 1 + 3 = 10 cycles, 5 instructions.
@ Taken:     cmp 1, beq 1 + 3, ldr 2 + 1, bx 1 + 3 = 12 cycles, 4 instructions.
@ Bound: 5 instructions, 12 cycles.
	.syntax unified
	.thumb
	.text
	.global entry
	.type entry, %function
entry:
	cmp r0, #0
	beq 1f
	adds r3, r0, #4
1:
	ldr r0, [r3]
	bx lr
	.size entry, .-entry
