"""Python ports of Arduino libraries for the ATmega328P (TimerOne, PJRC Encoder, PID_v1) and the core API they use."""
