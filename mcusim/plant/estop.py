"""Emergency-stop mushroom button of the rover (latching, twist to release).

Two contacts [I: the usual E-stop wiring; the rover's actual wiring is not documented]:

- an NC contact in series with the motor-enable line, from the controller's enable output
  (``enable_in``) to the bridges' enable inputs (``enable_out``: the IBT-2 R_EN/L_EN = BTS7960 INH
  pins). Released, the contact is closed and ``enable_out`` follows ``enable_in``; pressed, it is
  open and the IBT-2's pull-downs on its inputs (74HC244 buffer with pull-downs, docs/plants.md §2.3) pull
  the line low: the button model drives 0 on ``enable_out`` as driver ``name`` for them. So the
  motors lose drive (INH low: both switches off, coast) even if the firmware keeps enable high.
- a second (NO) contact from the controller's ``sense`` input to ground. The board's pull-up holds
  ``sense`` at 1 (give the Net ``pull=1``, or a board ``[pull]``); pressed, the button drives it 0
  as driver ``name``; released, it lets go (the pull-up returns it to 1). Active low, as the
  EDU-CIAA buttons (board schematic).

Contact bounce and the contacts' switching order are not modelled: both change at the tick of
:meth:`EStop.press` / :meth:`EStop.release`.
"""

from __future__ import annotations

from ..errors import ConfigError
from ..signals import Net

__all__ = ["EStop"]


class EStop:
    """``EStop(kernel, name="estop", *, enable_in, enable_out, sense=None, pressed=False)``.

    ``press()`` latches the button down, ``release()`` releases it; ``pressed``; ``presses`` (count);
    ``log`` ((tick, "press"|"release") of every change).
    """

    def __init__(self, kernel, name: str = "estop", *, enable_in: Net, enable_out: Net,
                 sense: Net | None = None, pressed: bool = False):
        if enable_in is None or enable_out is None:
            raise ConfigError(f"estop {name}: enable_in and enable_out must both be wired")
        if enable_in is enable_out:
            raise ConfigError(f"estop {name}: enable_in and enable_out must be different nets")
        self.kernel, self.name = kernel, name
        self.enable_in, self.enable_out, self.sense = enable_in, enable_out, sense
        self._pressed = bool(pressed)
        self.presses = 0
        self.log = []
        enable_in.listen(self._on_enable_in)
        self._update()

    @property
    def pressed(self) -> bool:
        return self._pressed

    def press(self) -> None:
        """Push the mushroom: it latches; the motor enable is cut and ``sense`` goes low."""
        if not self._pressed:
            self._pressed = True
            self.presses += 1
            self.log.append((self.kernel.now, "press"))
            self._update()

    def release(self) -> None:
        """Twist to release: the enable line follows the controller again, ``sense`` is released."""
        if self._pressed:
            self._pressed = False
            self.log.append((self.kernel.now, "release"))
            self._update()

    def _on_enable_in(self, net):
        if not self._pressed:
            self.enable_out.set(self.name, net.level)

    def _update(self):
        if self._pressed:
            self.enable_out.set(self.name, 0)           # NC contact open: the pull-downs win
            if self.sense is not None:
                self.sense.set(self.name, 0)            # NO contact closed to ground
        else:
            self.enable_out.set(self.name, self.enable_in.level)
            if self.sense is not None:
                self.sense.set(self.name, None)         # the board's pull-up takes over

    def __repr__(self):
        return f"EStop({self.name}: {'PRESSED' if self._pressed else 'released'})"
