"""ATmega328P peripheral models (registers at their data-space addresses)."""
