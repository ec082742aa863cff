set pagination off
target extended-remote :3391
info registers pc sp xpsr msp control
break SysTick_Handler
continue
info registers pc lr xpsr ipsr
bt
print ticks
x/wx 0xE000E018
x/wx 0xE000ED04
stepi
info registers pc
delete
watch ticks
continue
print ticks
delete
detach
