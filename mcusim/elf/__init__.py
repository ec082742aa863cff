"""Compiled Cortex-M firmware (ELF images) on the simulated bus: loader, memory, core, gdb server."""
