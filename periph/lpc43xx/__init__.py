"""NXP LPC4337 (LPC43xx, Cortex-M4 at 204 MHz) peripherals: ADC0/1, I2C0, GPIO, USART, and the system
blocks LPCOpen start-up touches: CGU, CCU1/CCU2, SCU, CREG, RGU."""
