"""HAL_GPIO_Init / WritePin / ReadPin (stm32f7xx_hal_gpio.c), one pin at a time."""

from __future__ import annotations

from dataclasses import dataclass

GPIO_MODE_INPUT, GPIO_MODE_OUTPUT_PP, GPIO_MODE_OUTPUT_OD, GPIO_MODE_AF_PP = 0x0, 0x1, 0x11, 0x2
GPIO_NOPULL, GPIO_PULLUP, GPIO_PULLDOWN = 0, 1, 2
GPIO_SPEED_FREQ_LOW, GPIO_SPEED_FREQ_HIGH, GPIO_SPEED_FREQ_VERY_HIGH = 0, 2, 3
GPIO_PIN_RESET, GPIO_PIN_SET = 0, 1


@dataclass
class GPIO_InitTypeDef:
    Pin: int  # pin number 0..15 (the C HAL takes a mask; one pin keeps the port readable)
    Mode: int = GPIO_MODE_INPUT
    Pull: int = GPIO_NOPULL
    Speed: int = GPIO_SPEED_FREQ_LOW
    Alternate: int = 0


def HAL_GPIO_Init(port, init: GPIO_InitTypeDef) -> None:
    """ST's order: OSPEEDR, OTYPER (outputs and AF), PUPDR (not analog), AFR (AF), then MODER."""
    n = init.Pin
    if init.Mode in (GPIO_MODE_OUTPUT_PP, GPIO_MODE_OUTPUT_OD, GPIO_MODE_AF_PP):
        port.OSPEEDR = (port.OSPEEDR & ~(3 << 2 * n)) | (init.Speed << 2 * n)
        port.OTYPER = (port.OTYPER & ~(1 << n)) | (((init.Mode >> 4) & 1) << n)
    port.PUPDR = (port.PUPDR & ~(3 << 2 * n)) | (init.Pull << 2 * n)
    if init.Mode == GPIO_MODE_AF_PP:
        reg = "AFR0" if n < 8 else "AFR1"
        sh = 4 * (n % 8)
        setattr(port, reg, (getattr(port, reg) & ~(0xF << sh)) | (init.Alternate << sh))
    port.MODER = (port.MODER & ~(3 << 2 * n)) | ((init.Mode & 3) << 2 * n)


def HAL_GPIO_WritePin(port, pin: int, state: int) -> None:
    port.BSRR = (1 << pin) if state else (1 << (pin + 16))


def HAL_GPIO_ReadPin(port, pin: int) -> int:
    return (port.IDR >> pin) & 1
