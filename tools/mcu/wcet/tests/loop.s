@ A loop bounded at 8 by its annotation (the pair TOONFORCE_LOOP_BOUND emits): 2 + 8 x 3 + 1 = 27
@ instructions; cycles 2 + 8 x 3 + 7 taken back edges x 3 + (1 + 3) = 51.
	.syntax unified
	.thumb
	.text
	.global entry
	.type entry, %function
entry:
	movs r0, #0
	movs r1, #8
1:	adds r0, r0, r1
	subs r1, r1, #1
	bne 1b
	bx lr
	.size entry, .-entry
	.pushsection .toonforce.loop_bounds,"o",%progbits,entry
	.word 1b, 8
	.popsection
