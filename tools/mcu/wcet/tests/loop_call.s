@ A call inside a loop bounded at 4: push, movs; 4 x (bl, the leaf's adds and bx, subs, bne);
@ pop = 2 + 4 x 5 + 1 = 23 instructions. On its longest path the leaf's two lines run 4 times.
	.syntax unified
	.thumb
	.text
	.global entry
	.type entry, %function
entry:
	push {r4, lr}
	movs r4, #4
1:	bl leaf
	subs r4, r4, #1
	bne 1b
	pop {r4, pc}
	.size entry, .-entry
	.pushsection .toonforce.loop_bounds,"o",%progbits,entry
	.word 1b, 4
	.popsection
	.type leaf, %function
leaf:
	adds r0, #1
	bx lr
	.size leaf, .-leaf
