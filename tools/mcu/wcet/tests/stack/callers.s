@ Two callers of leaf: fixed keeps its sp from its prologue on (a depth painted below that sp is
@ leaf's alone); moving pushes after its first call, so its sp at the second call is lower.
  .syntax unified
  .thumb
  .text
  .global entry
  .type entry, %function
entry:
  push {r4, lr}
  bl fixed
  bl moving
  pop {r4, pc}
  .size entry, . - entry

  .type fixed, %function
fixed:
  push {r4, lr}
  sub sp, #8
  bl leaf
  bl leaf
  add sp, #8
  pop {r4, pc}
  .size fixed, . - fixed

  .type moving, %function
moving:
  push {r4, lr}
  bl leaf
  sub sp, #8
  bl leaf
  add sp, #8
  pop {r4, pc}
  .size moving, . - moving

  .type leaf, %function
leaf:
  push {r4, lr}
  pop {r4, pc}
  .size leaf, . - leaf
