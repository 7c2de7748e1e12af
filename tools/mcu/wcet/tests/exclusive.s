@ std::atomic's exchange: an LDREX/STREX retry, once without interrupts: 5 + 1 = 6 instructions;
@ cycles ldrexb 2 + strexb 2 + cmp 1 + bne 1 (not taken) + dmb 1 + bx lr 4 = 11.
	.syntax unified
	.thumb
	.text
	.global entry
	.type entry, %function
entry:
1:	ldrexb r3, [r0]
	strexb r2, r1, [r0]
	cmp r2, #0
	bne 1b
	dmb ish
	bx lr
	.size entry, .-entry
