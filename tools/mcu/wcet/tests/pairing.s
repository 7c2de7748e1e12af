@ The TRM's load/store pairings (r2p1, 3.3.1), 11 instructions; cycles:
@   add r3, sp, #0      1
@   ldr r0, [r3]        2 + 1: its address comes from the data processing just before (no forwarding)
@   ldr r1, [sp]        2: no -1 for a load after a load ("pipelined when possible": not taken)
@   str r1, [sp, #4]    2: nor for a store after a load
@   ldr r2, [r1]        2
@   ldr r0, [r2]        2: its address is the previous load's destination
@   ldr r1, .Lword      2 + 1: PC-relative (contention with the fetch), and not pipelined
@   adds r3, r0, #4     1
@   it eq               1
@   ldreq r0, [r3]      2 + 1: the IT folds, so r3 is still the add's (a stall)
@   bx lr               1 + 3
@ = 24 (no data in the code region: only the PC-relative load contends with the fetch).
	.syntax unified
	.thumb
	.text
	.global entry
	.type entry, %function
entry:
	add r3, sp, #0
	ldr r0, [r3]
	ldr r1, [sp]
	str r1, [sp, #4]
	ldr r2, [r1]
	ldr r0, [r2]
	ldr r1, .Lword
	adds r3, r0, #4
	it eq
	ldreq r0, [r3]
	bx lr
	.align 2
.Lword:
	.word 0
	.size entry, .-entry
