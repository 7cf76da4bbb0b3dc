"""The words a scenario and an FC profile share: flight modes, features, and how a stick may be given.
A scenario asks for them; a profile (scenarios/profile.py) says whether and how its FC does them."""

from __future__ import annotations

from rig.emulators.sbus import KNOBS

#: flight modes a scenario may ask for and a profile may name
MODES = ("angle", "horizon", "acro", "rate", "althold", "poshold", "loiter", "land", "rth")
#: what an FC does beyond its modes, which a scenario may need
FEATURES = ("failsafe",)
#: sticks: normalised (-1..1; throttle 0..1), the knobs, or in the FC's terms through its profile
#: (degrees in an angle mode, degrees per second in a rate mode or for yaw)
STICK_UNITS = ("roll", "pitch", "yaw", "throttle")
STICK_TERMS = ("roll_deg", "pitch_deg", "roll_dps", "pitch_dps", "yaw_dps")
#: the older switch keys of a timeline's sticks, read as the actions they are (arm, mode)
STICK_SWITCHES = ("arm", "alt_hold")
STICKS = (*STICK_UNITS, *KNOBS, *STICK_TERMS, *STICK_SWITCHES)
