/* HAL_GPIO_Init / HAL_GPIO_WritePin (stm32f7xx_hal_gpio.c). */
#include "stm32f7xx_hal.h"

/* ST's order for each pin of the mask: OSPEEDR and OTYPER (outputs and AF), PUPDR (not analog),
 * AFR (AF), then MODER. */
void HAL_GPIO_Init(GPIO_TypeDef *port, const GPIO_InitTypeDef *init)
{
    for (uint32_t n = 0; n < 16U; n++) {
        if (!(init->Pin & (1U << n)))
            continue;
        uint32_t mode = init->Mode & 3U;
        if (mode == 1U || mode == 2U) {
            port->OSPEEDR = (port->OSPEEDR & ~(3U << 2 * n)) | (init->Speed << 2 * n);
            port->OTYPER = (port->OTYPER & ~(1U << n)) | (((init->Mode >> 4) & 1U) << n);
        }
        if (mode != 3U)
            port->PUPDR = (port->PUPDR & ~(3U << 2 * n)) | (init->Pull << 2 * n);
        if (mode == 2U) {
            uint32_t sh = 4U * (n & 7U);
            port->AFR[n >> 3] = (port->AFR[n >> 3] & ~(0xFU << sh)) | (init->Alternate << sh);
        }
        port->MODER = (port->MODER & ~(3U << 2 * n)) | (mode << 2 * n);
    }
}

void HAL_GPIO_WritePin(GPIO_TypeDef *port, uint16_t pin, GPIO_PinState state)
{
    if (state != GPIO_PIN_RESET)
        port->BSRR = pin;
    else
        port->BSRR = (uint32_t)pin << 16;
}
