/* Timer1 CTC (mode 4), OCR1A = 99, N = 1, OC1A toggling on PB1, as in tests/test_simavr_crosscheck.py.
 * simavr traces the TCCR1B write (the timer start) and the OC1A pin; the run ends when the CPU
 * sleeps with interrupts off. */
#include <avr/io.h>
#include <avr/sleep.h>
#include <avr/interrupt.h>
#include "avr_mcu_section.h"
AVR_MCU(16000000, "atmega328p");
AVR_MCU_VCD_FILE("ctc.vcd", 1000);
const struct avr_mmcu_vcd_trace_t _traces[] _MMCU_ = {
	{ AVR_MCU_VCD_SYMBOL("TCCR1B"), .mask = 0xFF, .what = (void*)&TCCR1B, },
};
AVR_MCU_VCD_PORT_PIN('B', 1, "OC1A");

int main(void) {
	DDRB = (1 << 1);
	OCR1A = 99;
	TCCR1A = (1 << COM1A0);                 /* toggle OC1A on compare match */
	TCCR1B = (1 << WGM12) | (1 << CS10);    /* CTC, TOP = OCR1A, clk/1: the timer starts here */
	for (volatile uint16_t i = 0; i < 300; i++) {}
	cli();
	sleep_enable();
	sleep_cpu();                            /* simavr stops: sleeping with interrupts off */
	for (;;) {}
}
