"""Exceptions. ``McusimError`` and its subclasses are what a user sees as one clear message."""


class McusimError(Exception):
    """Bad user input or an impossible request; the CLI prints it as one line and exits non-zero."""


def key_of_message(msg: str, keys, set_too: bool = True):
    """The longest of ``keys`` that ``msg`` is about: the message starts with it (or with
    ``--set`` and it, if ``set_too``), followed by a space, ``:``, ``=`` or ``[``; else None."""
    for key in sorted(keys, key=len, reverse=True):
        for head in ((f"--set {key}", key) if set_too else (key,)):
            if msg.startswith(head) and msg[len(head):len(head) + 1] in (" ", ":", "=", "["):
                return key
    return None


def with_member(exc, member: str, keys) -> Exception:
    """``exc`` (a ConfigError about one of ``keys``, given for system member ``member``) with the key
    named as the user wrote it: ``mcm2.motor.R`` rather than ``motor.R``."""
    msg = str(exc)
    key = key_of_message(msg, keys)
    return exc if key is None else type(exc)(msg.replace(key, f"{member}.{key}", 1))


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
        self.periph, self.register, self.field, self.value, self.why = periph, register, field, value, why
        where = f"{periph}.{register}" + (f".{field}" if field else "")
        super().__init__(f"{where} = {value:#x} {why}")


class BusFault(McusimError):
    """An access to an unmapped address, or a misaligned/illegal access."""

    def __init__(self, address: int, size: int, why: str = "unmapped address"):
        self.address, self.size = address, size
        super().__init__(f"bus fault: {size * 8}-bit access to {address:#010x}: {why}")


def read_input(path, what: str, limit: int = 16 << 20) -> bytes:
    """The bytes of an input file (a profile, a scenario, a firmware image), at most ``limit``:
    OSError as the callers handle it, ConfigError for a file that is not a regular one (a device
    such as /dev/zero would be read until memory ran out) or is larger than any such file."""
    import os
    import stat
    with open(path, "rb") as f:
        mode = os.fstat(f.fileno()).st_mode
        if not (stat.S_ISREG(mode) or stat.S_ISFIFO(mode)):     # a pipe: <(...) in a shell
            raise ConfigError(f"{os.fspath(path)}: not a regular file; a {what} is a file")
        data = f.read(limit + 1)
    if len(data) > limit:
        raise ConfigError(f"{os.fspath(path)}: larger than {limit >> 20} MB; not a {what}")
    return data
