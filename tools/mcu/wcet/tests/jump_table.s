@ Refused: a jump table (TBB).
	.syntax unified
	.thumb
	.text
	.global entry
	.type entry, %function
entry:
	tbb [pc, r0]
	.byte 2, 3
	bx lr
	nop
	bx lr
	.size entry, .-entry
