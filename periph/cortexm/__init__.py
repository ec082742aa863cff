"""Cortex-M core peripherals shared by every Arm MCU profile."""
