/* Timer1 fast PWM mode 14: ICR1 = 799 (TOP), OCR1A = 200, COM1A = 10, N = 1. See tests/test_simavr_crosscheck.py. */
#include <avr/io.h>
#include <avr/sleep.h>
#include <avr/interrupt.h>
#include "avr_mcu_section.h"
AVR_MCU(16000000, "atmega328p");
AVR_MCU_VCD_FILE("mode14.vcd", 1000);
const struct avr_mmcu_vcd_trace_t _traces[] _MMCU_ = {
	{ AVR_MCU_VCD_SYMBOL("TCCR1B"), .mask = 0xFF, .what = (void*)&TCCR1B, },
};
AVR_MCU_VCD_PORT_PIN('B', 1, "OC1A");
int main(void) {
	DDRB = (1 << 1);
	ICR1 = 799; OCR1A = 200;
	TCCR1A = (1 << COM1A1) | (1 << WGM11);
	TCCR1B = (1 << WGM13) | (1 << WGM12) | (1 << CS10);
	for (volatile uint16_t i = 0; i < 800; i++) {}
	cli(); sleep_enable(); sleep_cpu(); for (;;) {}
}
