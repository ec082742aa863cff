"""Board-profile adapters for the rover's plant parts: the ``[[part]]`` kinds battery, divider,
rover-body and estop, built as ``kind(kernel, name=..., <references>, <terminals>, **params)``.

They connect what a profile names (``loads = ["mcm1.ibt2", ...]``, ``source = "battery"``) and
add the summary entries of a rover run (``battery_v``, ``pose``)."""

from __future__ import annotations

from ..errors import ConfigError
from ..signals import Net
from .battery import LeadAcidBank, VoltageDivider
from .estop import EStop
from .rover import RoverBody


class BatteryPart(LeadAcidBank):
    def __init__(self, kernel, name="battery", loads=(), **params):
        super().__init__(kernel, name=name, **params)
        for bridge in ([loads] if not isinstance(loads, (list, tuple)) else loads):
            if not hasattr(bridge, "set_supply"):
                raise ConfigError(f"part {name}: load {getattr(bridge, 'name', bridge)!r} is not a bridge")
            self.connect(bridge)

    def summary_entries(self) -> dict:
        return {"battery_v": self.voltage(), "battery_soc": self.soc, "battery_min_v": self.min_voltage}


class DividerPart(VoltageDivider):
    """A resistor divider from a part's voltage (``source``) to an ADC input."""

    def __init__(self, kernel, name="divider", source=None, r_top=None, r_bottom=None):
        if source is None or not hasattr(source, "voltage"):
            raise ConfigError(f"part {name}: source = must name a part with a voltage (a battery)")
        if r_top is None or r_bottom is None:
            raise ConfigError(f"part {name}: r_top and r_bottom (ohms) are required")
        super().__init__(source.voltage, float(r_top), float(r_bottom))
        self.name = name


class RoverBodyPart(RoverBody):
    READERS = ("pose_at_now",)     # (x, y, yaw) now, a value a scenario expectation may read
    def __init__(self, kernel, name="body", motors=(), **params):
        super().__init__(kernel, name=name, motors=list(motors), **params)

    def summary_entries(self) -> dict:
        x, y, yaw = self.pose_at_now()
        return {"pose": {"x": x, "y": y, "yaw": yaw}}


class EStopPart(EStop):
    """The E-stop; without a wired ``enable_out`` (the board alone) it drives a net of its own."""

    def __init__(self, kernel, name="estop", enable_in=None, enable_out=None, sense=None):
        if enable_in is None:
            raise ConfigError(f"part {name}: terminal ENABLE_IN is not wired")
        enable_out = enable_out if enable_out is not None else Net(f"{name}.ENABLE_OUT", pull=0)
        super().__init__(kernel, name=name, enable_in=enable_in, enable_out=enable_out, sense=sense)
