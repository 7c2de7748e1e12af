@ Loops 4 x 3: blocks run 1, 4, 12, 4, 1 times: 1 + 4 + 12 x 2 + 4 x 2 + 1 = 38 instructions;
@ cycles 1 + 4 + (24 + 8 inner back edges x 3) + (8 + 3 outer back edges x 3) + 4 = 74.
	.syntax unified
	.thumb
	.text
	.global entry
	.type entry, %function
entry:
	movs r2, #4
1:	movs r3, #3
2:	subs r3, #1
	bne 2b
	subs r2, #1
	bne 1b
	bx lr
	.size entry, .-entry
	.pushsection .toonforce.loop_bounds,"o",%progbits,entry
	.word 1b, 4, 2b, 3
	.popsection
