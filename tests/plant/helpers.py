"""Independent truth for the plant tests: constants from the seeds and docs/design.md, not from plant code."""

from __future__ import annotations

import math

from rig.plant import Plant

G = 9.80665
MASS, ARM, K_THRUST, K_TORQUE = 1.2, 0.2, 3.13e-5, 7.5e-7        # seed 001 Table 1
IXX, IYY, IZZ = 2.353e-3, 2.353e-3, 5.262e-2
OMEGA_MAX, ESC_MIN, ESC_MAX, MOTOR_TAU = 600.0, 1000.0, 2000.0, 0.02  # plant defaults (docs/plant.md)
OMEGA_HOVER = math.sqrt(MASS * G / (4 * K_THRUST))               # docs/design.md §3: about 306.6 rad/s
DT = 1e-3


def pwm_for_omega(omega: float) -> float:
    """Pulse width for a steady rotor speed with the default linear ESC curve."""
    return ESC_MIN + omega / OMEGA_MAX * (ESC_MAX - ESC_MIN)


HOVER_PWM = pwm_for_omega(OMEGA_HOVER)


def pwms(*values: float) -> dict[str, float]:
    return {f"pwm{i}_us": v for i, v in enumerate(values, start=1)}


def flying(pwm: tuple[float, float, float, float] = (HOVER_PWM,) * 4, **params: float) -> Plant:
    """A plant started 100 m up (far from the ground) with rotors at the speeds the pulses command."""
    return Plant(params={"pd0": -100.0, **params}, inputs=pwms(*pwm))
