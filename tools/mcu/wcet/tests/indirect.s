@ Refused: an indirect call.
	.syntax unified
	.thumb
	.text
	.global entry
	.type entry, %function
entry:
	push {r4, lr}
	blx r3
	pop {r4, pc}
	.size entry, .-entry
