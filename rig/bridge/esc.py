"""The ESC protocols a bridge captures: each one's pulse limits (sent in CONFIG: outside them a pulse is a
glitch) and how its pulse maps to the plant's motor command, which is in standard-PWM microseconds
(1000 idle .. 2000 full). OneShot125 is standard PWM divided by eight (125..250 us, at up to 4 kHz)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class EscProtocol:
    name: str
    pulse_min_us: int   # a shorter pulse is a glitch
    pulse_max_us: int   # a longer one too
    period_min_us: int  # pulses starting closer than this are glitches (the fastest update rate)
    to_pwm_us: float    # pulse us times this: the plant's PWM us

    def motor_us(self, width_tenth_us: int) -> float:
        """A captured width (0.1 us, 0: no pulse) as the plant's motor command."""
        return width_tenth_us / 10.0 * self.to_pwm_us


ESC_PROTOCOLS: dict[str, EscProtocol] = {p.name: p for p in (
    EscProtocol("pwm", 500, 2500, 1000, 1.0),         # 50..490 Hz servo-style PWM, 1000..2000 us
    EscProtocol("oneshot125", 62, 313, 250, 8.0),    # 125..250 us, up to 4 kHz
)}


def esc_protocol(name: str) -> EscProtocol:
    try:
        return ESC_PROTOCOLS[name]
    except KeyError:
        raise ValueError(f"unknown ESC protocol {name!r}; known: {', '.join(ESC_PROTOCOLS)}") from None
