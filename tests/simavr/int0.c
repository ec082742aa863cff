/* INT0 on a rising edge of PD2 (driven by the firmware itself: external interrupts also trigger
 * on output pins). simavr traces the PORTD store and INT0's pending flag, which rises when INTF0
 * is set and falls when the vector is taken. See tests/test_simavr_crosscheck.py. */
#include <avr/io.h>
#include <avr/sleep.h>
#include <avr/interrupt.h>
#include "avr_mcu_section.h"
AVR_MCU(16000000, "atmega328p");
AVR_MCU_VCD_FILE("int0.vcd", 1000);
const struct avr_mmcu_vcd_trace_t _traces[] _MMCU_ = {
	{ AVR_MCU_VCD_SYMBOL("PORTD"), .mask = 0xFF, .what = (void*)&PORTD, },
};
AVR_MCU_VCD_IRQ_PENDING(INT0);

volatile uint8_t hits;
ISR(INT0_vect) { hits++; }

int main(void) {
	DDRD = (1 << 2);
	EICRA = (1 << ISC01) | (1 << ISC00);    /* rising edge */
	EIMSK = (1 << INT0);
	sei();
	for (uint8_t k = 0; k < 4; k++) {
		PORTD = (1 << 2);                   /* rising edge: INTF0 */
		for (volatile uint8_t i = 0; i < 20; i++) {}
		PORTD = 0;
		for (volatile uint8_t i = 0; i < 20; i++) {}
	}
	cli();
	sleep_enable();
	sleep_cpu();
	for (;;) {}
}
