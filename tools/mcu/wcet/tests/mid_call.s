@ Refused: a call into the middle of a function (its bound is from its start).
	.syntax unified
	.thumb
	.text
	.global entry
	.type entry, %function
entry:
	push {r4, lr}
	bl 1f
	pop {r4, pc}
	.size entry, .-entry
	.type leaf, %function
leaf:
	adds r0, #1
1:	adds r0, #2
	bx lr
	.size leaf, .-leaf
