"""Named motor parameter sets (docs/plants.md §0, §1.3, §1.4).

A preset is a plain dict of :class:`mcusim.plant.dcmotor.MotorParams` names -> values, all on the
motor shaft except ``gear_ratio`` / ``load_inertia`` / ``load_torque`` (output shaft). Use it as
``DcMotor(kernel, "m", preset="openrover-100w-50")`` (board files: ``preset = "..."`` in the
part table); explicit parameters given next to the preset override it.

Provenance marks are those of docs/plants.md: [V] read in a primary source, [S] secondary source,
[I] inference / estimate (a placeholder until measured).

This module deliberately imports nothing from :mod:`mcusim.plant.dcmotor` (which imports it).
"""

from __future__ import annotations

from ..errors import ConfigError

__all__ = ["MOTOR_PRESETS", "motor_preset"]

MOTOR_PRESETS: dict[str, dict[str, float]] = {
    # docs/plants.md §0 / §1.3: Pololu 37D 12 V, 30:1, 64 CPR. Identical to the
    # MotorParams defaults (a test checks that they stay identical).
    "pololu-37d-12v-30": {
        "R": 2.18,            # Ω            [I from V: 12 V / 5.5 A stall]
        "L": 1.5e-3,          # H            [I] (0.8–3 mH)
        "K": 0.0110,          # V·s/rad      [I from V: no-load 10,000 rpm @ 12 V]
        "J": 5e-6,            # kg·m²        [I] (3e-6–8e-6)
        "tau_c": 1.54e-3,     # N·m          [I] (1.5 mN·m rounded)
        "b": 6.3e-7,          # N·m·s/rad    [I]
        "tau_s": 5.0e-3,      # N·m          [I from V: "≤ 5 mN·m"]
        "gear_ratio": 30.0,   #              [I: the 30:1 catalogue variant; the one fitted is not stated]
        "efficiency": 0.78,   #              [I: η₂ of §1.3 for 30:1]
        "load_inertia": 0.0,  # kg·m² output [none]
        "load_torque": 0.0,   # N·m output
    },
    # docs/plants.md §0 / §1.4: 100 W, 12 V, 2000 rpm, 0.45 N·m motor, 1:50 gearbox,
    # 0.39 m wheels, recommended row η_r = 0.78, I_0 = 1.0 A. Loop resistance of the bridge is
    # NOT included in R (the BTS7960 model adds R_ON(HS) + R_ON(LS) in the drive states).
    "openrover-100w-50": {
        "R": 0.160,           # Ω            [I] (0.13–0.20); stall ≈ 75 A @ 12 V
        "L": 0.30e-3,         # H            [I] (0.15–0.6 mH); τe ≈ 1.9 ms
        "K": 0.0496,          # V·s/rad      [I] (0.047–0.051); no-load ≈ 2,279 rpm @ 12 V
        "J": 1.2e-4,          # kg·m²        [I] (0.8e-4–3e-4), ~45 mm × 50 mm iron rotor
        "tau_c": 0.035,       # N·m          [I] (70 % of τf0 = K·I_0 ≈ 0.050 N·m)
        "b": 6.2e-5,          # N·m·s/rad    [I] (30 % of τf0 at ω_0)
        "tau_s": 0.0613,      # N·m          [I] usual 1.5–2 × τc; 1.75 × τc chosen here
        "gear_ratio": 50.0,   #              [given: 1:50]
        "efficiency": 0.80,   #              [I] η_g = 0.8 used at the rated point in §1.4
                              #              (spur/planetary 0.7–0.9; worm 0.4–0.7, gearbox type unknown)
        # Loaded rover, §1.4 "Vehicle" table [I: 50 kg rover, equal share per wheel, 2 kg solid
        # disc wheels, r = 0.195 m], on the OUTPUT shaft: 12.5 kg·0.195² + ½·2 kg·0.195²
        # = 0.4753 + 0.0380 = 0.5133 kg·m² (→ 2.05e-4 kg·m² at the motor, J_eq = 3.25e-4 kg·m²).
        "load_inertia": 0.5133,
        # Rolling resistance (≈20 mN·m per motor at the motor shaft, Crr 0.03) always opposes the
        # motion, which MotorParams.load_torque (fixed direction) cannot express: left at 0 [I].
        "load_torque": 0.0,
    },
}


def motor_preset(name: str) -> dict[str, float]:
    """A copy of the named parameter set; unknown names raise :class:`ConfigError` listing them."""
    try:
        return dict(MOTOR_PRESETS[name])
    except (KeyError, TypeError):
        raise ConfigError(f"unknown motor preset {name!r} (presets: {', '.join(sorted(MOTOR_PRESETS))})") from None
