@ Straight line: 5 instructions; cycles 4 x 1 + bx lr (1 + P = 4) = 8.
	.syntax unified
	.thumb
	.text
	.global entry
	.type entry, %function
entry:
	movs r0, #1
	movs r1, #2
	adds r0, r0, r1
	movs r2, #3
	bx lr
	.size entry, .-entry
