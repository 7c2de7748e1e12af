@ Two calls of a leaf (2 instructions, 1 + (1 + 3) = 5 cycles): 2 + 2 x 2 + ... = 8 instructions;
@ cycles push (1 + 2) + 2 x (bl 1 + 3 + leaf 5) + pop with pc (1 + 2 + 3) = 27.
	.syntax unified
	.thumb
	.text
	.global entry
	.type entry, %function
entry:
	push {r4, lr}
	bl leaf
	bl leaf
	pop {r4, pc}
	.size entry, .-entry
	.type leaf, %function
leaf:
	adds r0, #1
	bx lr
	.size leaf, .-leaf
