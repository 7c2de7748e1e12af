@ Refused: a loop without annotation.
	.syntax unified
	.thumb
	.text
	.global entry
	.type entry, %function
entry:
	movs r1, #8
1:	subs r1, r1, #1
	bne 1b
	bx lr
	.size entry, .-entry
