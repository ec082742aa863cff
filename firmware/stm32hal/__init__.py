"""A thin STM32F7 HAL written like ST's (``stm32f7xx_hal_tim.c``, ``_gpio.c``, ``_cortex.c``).

Firmware ports call these functions exactly where the C code calls the HAL; every effect is a
register access on the MCU's bus (``TIM1.CCR1 = v`` is a 32-bit store to 0x40010034), so the
peripheral models see what the chip would see. See :mod:`mcusim.fw.stm32hal.regs` for the views.
"""
