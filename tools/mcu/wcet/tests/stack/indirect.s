@ entry calls through a register: its callee is unknown (refused).
  .syntax unified
  .thumb
  .text
  .global entry
  .type entry, %function
entry:
  push {r4, lr}
  blx r0
  pop {r4, pc}
  .size entry, . - entry
