"""mcusim: a tick-accurate simulator of microcontroller peripherals, firmware and plants."""

from .errors import BusFault, ConfigError, McusimError, UnsupportedConfiguration
from .sim import Simulation, load

__all__ = ["BusFault", "ConfigError", "McusimError", "Simulation", "UnsupportedConfiguration", "load"]
__version__ = "0.1.0"
