/* The few STM32F746 and Cortex-M7 registers this firmware touches, laid out as the CMSIS device
 * header (stm32f746xx.h, core_cm7.h) lays them out: a struct per peripheral, one volatile 32-bit
 * field per register, so that `TIM1->CCR1 = v` is a 32-bit store to 0x40010034. */
#ifndef STM32F7_H
#define STM32F7_H

#include <stdint.h>

#define __IO volatile
#define __I  volatile const

typedef struct {
    __IO uint32_t CR1, CR2, SMCR, DIER, SR, EGR, CCMR1, CCMR2, CCER, CNT, PSC, ARR, RCR;
    __IO uint32_t CCR1, CCR2, CCR3, CCR4, BDTR, DCR, DMAR, OR, CCMR3, CCR5, CCR6;
} TIM_TypeDef;

typedef struct {
    __IO uint32_t MODER, OTYPER, OSPEEDR, PUPDR, IDR, ODR, BSRR, LCKR, AFR[2];
} GPIO_TypeDef;

typedef struct {
    __IO uint32_t CR, PLLCFGR, CFGR, CIR, AHB1RSTR, AHB2RSTR, AHB3RSTR, RESERVED0, APB1RSTR, APB2RSTR;
    uint32_t RESERVED1[2];
    __IO uint32_t AHB1ENR, AHB2ENR, AHB3ENR, RESERVED2, APB1ENR, APB2ENR;
    uint32_t RESERVED3[2];
    __IO uint32_t AHB1LPENR, AHB2LPENR, AHB3LPENR, RESERVED4, APB1LPENR, APB2LPENR;
    uint32_t RESERVED5[2];
    __IO uint32_t BDCR, CSR;
    uint32_t RESERVED6[2];
    __IO uint32_t SSCGR, PLLI2SCFGR, PLLSAICFGR, DCKCFGR1, DCKCFGR2;
} RCC_TypeDef;

typedef struct {
    __IO uint32_t CTRL, LOAD, VAL;
    __I  uint32_t CALIB;
} SysTick_Type;

typedef struct {
    __IO uint32_t ISER[8];
    uint32_t RESERVED0[24];
    __IO uint32_t ICER[8];
    uint32_t RESERVED1[24];
    __IO uint32_t ISPR[8];
    uint32_t RESERVED2[24];
    __IO uint32_t ICPR[8];
    uint32_t RESERVED3[24];
    __IO uint32_t IABR[8];
    uint32_t RESERVED4[56];
    __IO uint8_t  IP[240];       /* byte-accessible priority registers */
} NVIC_Type;

typedef struct {
    __I  uint32_t CPUID;
    __IO uint32_t ICSR, VTOR, AIRCR, SCR, CCR;
    __IO uint8_t  SHPR[12];      /* SHPR1..3 as bytes: SHPR[11] is SysTick's priority */
    __IO uint32_t SHCSR, CFSR, HFSR, DFSR, MMFAR, BFAR, AFSR, ID_PFR[2], ID_DFR, ID_AFR, ID_MFR[4];
    __IO uint32_t ID_ISAR[5];
    uint32_t RESERVED0[1];
    __I  uint32_t CLIDR, CTR, CCSIDR;
    __IO uint32_t CSSELR, CPACR;
} SCB_Type;

#define PERIPH_BASE   0x40000000UL
#define TIM2          ((TIM_TypeDef *) 0x40000000UL)
#define TIM3          ((TIM_TypeDef *) 0x40000400UL)
#define TIM4          ((TIM_TypeDef *) 0x40000800UL)
#define TIM1          ((TIM_TypeDef *) 0x40010000UL)
#define GPIOA         ((GPIO_TypeDef *) 0x40020000UL)
#define GPIOB         ((GPIO_TypeDef *) 0x40020400UL)
#define GPIOD         ((GPIO_TypeDef *) 0x40020C00UL)
#define GPIOE         ((GPIO_TypeDef *) 0x40021000UL)
#define GPIOF         ((GPIO_TypeDef *) 0x40021400UL)
#define RCC           ((RCC_TypeDef *) 0x40023800UL)
#define SysTick       ((SysTick_Type *) 0xE000E010UL)
#define NVIC          ((NVIC_Type *) 0xE000E100UL)
#define SCB           ((SCB_Type *) 0xE000ED00UL)
#define FLASH_BASE    0x08000000UL

#define IS_ADVANCED_TIM(t) ((t) == TIM1)

/* Exception and interrupt numbers (stm32f746xx.h IRQn_Type) */
#define SysTick_IRQn  (-1)
#define TIM3_IRQn     29
#define TIM4_IRQn     30
#define __NVIC_PRIO_BITS 4

/* CMSIS intrinsics used here */
static inline void __disable_irq(void) { __asm volatile ("cpsid i" ::: "memory"); }
static inline void __enable_irq(void)  { __asm volatile ("cpsie i" ::: "memory"); }
static inline void __WFI(void)         { __asm volatile ("wfi" ::: "memory"); }
static inline void __DSB(void)         { __asm volatile ("dsb 0xF" ::: "memory"); }
static inline void __ISB(void)         { __asm volatile ("isb 0xF" ::: "memory"); }

#endif
