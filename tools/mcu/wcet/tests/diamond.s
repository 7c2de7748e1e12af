@ Two paths. Not taken: cmp, beq, 3 adds, b, bx = 7 instructions, 1+1+3+(1+3)+(1+3) = 13 cycles.
@ Taken: cmp, beq, udiv, bx = 4 instructions, 1+(1+3)+12+(1+3) = 21 cycles. The longest path
@ in instructions is not the longest in cycles: bounds 7 and 21.
	.syntax unified
	.thumb
	.text
	.global entry
	.type entry, %function
entry:
	cmp r0, #0
	beq 1f
	adds r1, #1
	adds r1, #1
	adds r1, #1
	b 2f
1:	udiv r1, r1, r2
2:	bx lr
	.size entry, .-entry
