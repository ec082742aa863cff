"""The general MOSFET leg model of docs/plants.md §2.1, shared by the L6206 and BTS7960 bridges.

Each leg is H (high side on), L (low side on) or Z (both off: the body diodes conduct). For a
current j flowing out of the leg, its voltage is ``c − r·j`` with (c, r) from :meth:`_leg`; the
motor sees v_m = v_A − v_B. A bridge using :class:`MosfetBridge` provides ``params`` (Vs, R_HS,
R_LS, V_D, r_D), a ``legs`` property giving the (A, B) leg states now, and ``_drive_cache = {}``.
"""

from __future__ import annotations


class MosfetBridge:
    def _leg(self, kind, sign):
        """(c, r) with leg voltage c − r·j for current j out of the leg with sign ``sign``."""
        p = self.params
        if kind == "H":
            return p.Vs, p.R_HS
        if kind == "L":
            return 0.0, p.R_LS
        return (-p.V_D, p.r_D) if sign > 0 else (p.Vs + p.V_D, p.r_D)

    def drive_state(self):
        """(V⁺, V⁻, R_br, has_diode): v_m = V± − R_br·i in the i > 0 / i < 0 domain (DcMotor's contract)."""
        legs = self.legs
        self._legs_seen = legs
        return self.drive_for(legs)

    def drive_for(self, legs):
        """:meth:`drive_state` for the leg states ``legs``."""
        d = self._drive_cache.get(legs)
        if d is None:
            a, b = legs
            ca_p, ra = self._leg(a, +1)
            cb_n, rb = self._leg(b, -1)     # i > 0 flows into leg B: j_B = −i < 0
            ca_n, _ = self._leg(a, -1)
            cb_p, _ = self._leg(b, +1)
            d = self._drive_cache[legs] = (ca_p - cb_n, ca_n - cb_p, ra + rb, "Z" in legs)
        return d


def input_shape(nets):
    """What a bridge's drive schedule depends on (fast engine): per input net its waveform's shape
    (phase within the period, period, width; not where its owner already knows it ends: the owner
    publishes again there) or its level (None for an input that is not wired). A waveform
    republished with the same shape (a compare value waiting in a preload register ends it at the
    next update) leaves the schedule the motor follows as it is."""
    return tuple(None if n is None else ((w.rise % w.period, w.period, w.width) if (w := n.wave) is not None
                                         else n.level) for n in nets)


def leg_pieces(waves, legs_at):
    """Fast engine: the leg states of one period of input waveforms that share a period.

    ``legs_at(t)`` gives the legs at tick t. Returns ``(anchor, period, [(offset, legs), ...])``
    with a new piece at each offset where the legs change (the first piece starts at ``anchor``),
    or None when the waveforms do not share a period or the legs never change."""
    P = waves[0].period
    if any(w.period != P for w in waves):
        return None
    anchor = waves[0].rise
    offs = sorted({0} | {(w.rise - anchor) % P for w in waves}
                  | {(w.rise + w.width - anchor) % P for w in waves})
    pieces = []
    for o in offs:
        legs = legs_at(anchor + o)
        if not pieces or pieces[-1][1] != legs:
            pieces.append((o, legs))
    if len(pieces) > 1 and pieces[0][1] == pieces[-1][1]:   # the first piece began in the last
        shift = pieces[-1][0]
        anchor += shift
        pieces = sorted([(0, pieces[-1][1])] + [(o - shift + P, lg) for o, lg in pieces[1:-1]])
    return None if len(pieces) == 1 else (anchor, P, pieces)
