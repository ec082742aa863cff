"""Exceptions. ``McusimError`` and its subclasses are what a user sees as one clear message."""


class McusimError(Exception):
    """Bad user input or an impossible request; the CLI prints it as one line and exits non-zero."""


class ConfigError(McusimError):
    """A board file, scenario, ``--set`` key or CLI argument is wrong."""


class TimeError(McusimError):
    """A duration or frequency that cannot be parsed or converted exactly to base ticks."""


class UnsupportedConfiguration(McusimError):
    """A register configuration the model does not implement.

    The message names the peripheral, register, field and value, e.g.
    ``TIM3.SMCR.SMS = 0b0110 (trigger mode) is not modelled``.
    """

    def __init__(self, periph: str, register: str, field: str | None, value: int, why: str = "is not modelled"):
        self.periph, self.register, self.field, self.value = periph, register, field, value
        where = f"{periph}.{register}" + (f".{field}" if field else "")
        super().__init__(f"{where} = {value:#x} {why}")


class BusFault(McusimError):
    """An access to an unmapped address, or a misaligned/illegal access."""

    def __init__(self, address: int, size: int, why: str = "unmapped address"):
        self.address, self.size = address, size
        super().__init__(f"bus fault: {size * 8}-bit access to {address:#010x}: {why}")
