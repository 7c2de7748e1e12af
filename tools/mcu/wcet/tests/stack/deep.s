@ deep: no .su line (hand-written), so its frame comes from its disassembly: push of four
@ registers (16 bytes) and sub sp, #200: 216 bytes. It calls nothing.
  .syntax unified
  .thumb
  .text
  .global deep
  .type deep, %function
deep:
  push {r4, r5, r6, lr}
  sub sp, #200
  str r0, [sp, #196]
  ldr r0, [sp, #196]
  add sp, #200
  pop {r4, r5, r6, pc}
  .size deep, . - deep
