@ std::atomic's exchange (its DMB left out: barriers are refused): an LDREX/STREX retry, once
@ without interrupts: 4 + 1 = 5 instructions; cycles ldrexb 2 + strexb 2 + cmp 1 + bne 1 (not
@ taken) + bx lr 4 = 10.
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
	bx lr
	.size entry, .-entry
