"""The signals a run records and criteria judge: what each is, in which units (degrees and
microseconds at this edge, SI otherwise, docs/design.md §3). The recorder samples every signal on one grid
in sim time; DUT-reported values (est_*) are held from the DUT's last telemetry line and are NaN before
the first one or when the DUT reports none."""

from __future__ import annotations

from dataclasses import dataclass

from rig.plant.variables import MOTORS

RECORD_PERIOD = 0.01  # s: 100 Hz, fine enough for rise times of ~0.1 s


@dataclass(frozen=True)
class Signal:
    units: str
    text: str


SIGNALS: dict[str, Signal] = {
    "roll": Signal("deg", "true roll (plant)"),
    "pitch": Signal("deg", "true pitch (plant)"),
    "yaw": Signal("deg", "true yaw (plant), -180..180"),
    "tilt": Signal("deg", "largest of |roll| and |pitch|"),
    "alt": Signal("m", "true altitude above the start point, up positive"),
    "climb": Signal("m/s", "true climb rate, up positive"),
    "speed": Signal("m/s", "true horizontal speed"),
    "p": Signal("deg/s", "true body roll rate"),
    "q": Signal("deg/s", "true body pitch rate"),
    "r": Signal("deg/s", "true body yaw rate"),
    **{f"pwm{m}": Signal("us", f"pulse width applied to motor {m} (after capture)")
       for m in range(1, MOTORS + 1)},
    "pwm_max": Signal("us", "largest of the motors' pulse widths"),
    "pwm_min": Signal("us", "smallest of the motors' pulse widths"),
    "on_ground": Signal("", "1 while the vehicle rests on the ground"),
    "roll_sp": Signal("deg", "roll stick as an angle (stick x rc.max_angle_deg)"),
    "pitch_sp": Signal("deg", "pitch stick as an angle"),
    "yaw_rate_sp": Signal("deg/s", "yaw stick as a rate (stick x rc.max_yaw_rate_dps)"),
    "roll_track_error": Signal("deg", "roll - roll_sp"),
    "pitch_track_error": Signal("deg", "pitch - pitch_sp"),
    "throttle": Signal("", "throttle stick 0..1"),
    "rc_link": Signal("", "1 while the RC emulator sends good frames"),
    "fault": Signal("", "1 while any scheduled sensor fault or the magnetic disturbance is active"),
    "wind": Signal("m/s", "wind speed magnitude (steady + turbulence + gusts)"),
    "est_roll": Signal("deg", "roll the DUT reports"),
    "est_pitch": Signal("deg", "pitch the DUT reports"),
    "est_yaw": Signal("deg", "yaw the DUT reports"),
    "est_alt": Signal("m", "altitude the DUT reports"),
    "armed": Signal("", "1 while the DUT reports armed"),
    "roll_est_error": Signal("deg", "est_roll - roll"),
    "pitch_est_error": Signal("deg", "est_pitch - pitch"),
    "yaw_est_error": Signal("deg", "est_yaw - yaw, wrapped to -180..180"),
    "alt_est_error": Signal("m", "est_alt - alt"),
    "psu_volts": Signal("V", "the bench supply's output voltage (a bench run with a supply only)"),
    "psu_amps": Signal("A", "the current the board draws from the bench supply (likewise)"),
    "battery_volts": Signal("V", "the flight pack's terminal voltage (an MCU board with a [battery] only)"),
}
#: recorded only when the run has what they measure (telemetry.csv leaves them out otherwise)
BENCH_SIGNALS = ("psu_volts", "psu_amps", "battery_volts")
