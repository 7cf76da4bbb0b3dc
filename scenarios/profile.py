"""FC profiles: how one flight controller is flown, as data (TOML), so that a scenario can say what the
world does and what good flight is in neutral terms (arm, fly "angle", 10° of roll) and any FC can fly it.

A profile is checked like a scenario or a board file: every error names the file and the dotted key,
with a suggestion for a misspelt key or value. The shipped profiles are in scenarios/profiles/;
``--fc NAME`` finds them by name, ``--fc path/to/fc.toml`` reads any other. docs/profiles.md gives
every key.

    [profile]    name, description, source, features ("failsafe": lands on RC loss)
    [rc]         order ("AETR"...), centre_us, travel_us, min_us, max_us, sbus_us_per_step,
                 sbus_offset_us, sbus_stretch, extra (knob name -> channel), reverse (sticks)
    [arming]     method ("switch" | "sticks" | "telemetry"), channel, on_us, off_us, arm, disarm
                 (sticks -> "low" | "centre" | "high"), hold_s, detect ("telemetry" | "motors"), idle_us
    [modes]      channel, default, positions (mode -> µs), angle_deg, rate_dps, yaw_rate_dps
    [motors]     frame ("+" | "x"), order (the FC's outputs -> the plant's motors), pwm_channels, pins
                 (an MCU's: the pin of each output)
    [sensors]    mounting_yaw_deg (an MCU's: the sensor board turned as the firmware expects it),
                 baro_noise (the MS5611's datasheet noise)
    [startup]    seconds, ready ("telemetry")
    [telemetry]  kind ("none" | "text" | "msp" | "mavlink"), port, baud, poll_hz
    [config]     eeprom, params (files, relative to the profile), args ({params}, {state}), fc (the
                 reference FC's keys)
"""

from __future__ import annotations

import difflib
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

from rig.emulators.sbus import CHANNELS, KNOBS, ChannelMap
from rig.plant.toml_file import TomlFileError, read_toml
from rig.scenarios import fc_keys
from rig.scenarios.schema import ScenarioError, _Check
from rig.scenarios.terms import FEATURES, MODES

PROFILES: Final = Path(__file__).resolve().parent / "profiles"
DEFAULT: Final = "reference"
TOP: Final = {"profile", "rc", "arming", "modes", "motors", "sensors", "startup", "telemetry", "config"}
PROFILE_KEYS: Final = {"name", "description", "source", "features"}
RC_KEYS: Final = {"order", "centre_us", "travel_us", "min_us", "max_us", "sbus_us_per_step", "sbus_offset_us",
                  "sbus_stretch", "extra", "reverse"}
ARMING_KEYS: Final = {"method", "channel", "on_us", "off_us", "arm", "disarm", "hold_s", "detect", "idle_us"}
MODE_KEYS: Final = {"channel", "default", "positions", "angle_deg", "rate_dps", "yaw_rate_dps"}
MOTOR_KEYS: Final = {"frame", "order", "pwm_channels", "pins"}
STARTUP_KEYS: Final = {"seconds", "ready"}
SENSOR_KEYS: Final = {"mounting_yaw_deg", "baro_noise"}
TELEMETRY_KEYS: Final = {"kind", "port", "baud", "poll_hz"}
CONFIG_KEYS: Final = {"eeprom", "params", "args", "fc"}
#: in config.args: the folder of the FC's own files, fresh for every run
STATE: Final = "{state}"
#: modes whose sticks command rates (rate_dps per full stick), not angles
RATE_MODES: Final = ("acro", "rate")
ARMING_METHODS: Final = ("switch", "sticks", "telemetry")
TELEMETRY_KINDS: Final = ("none", "text", "msp", "mavlink")
#: the kinds the rig reads today: criteria on the FC's estimates are measured from these only
TELEMETRY_READ: Final = ("text", "msp", "mavlink")
STICK_POSITIONS: Final = ("low", "centre", "high")
GESTURE_STICKS: Final = ("roll", "pitch", "throttle", "yaw")
#: the SBUS value's µs: (raw * us_per_step + offset - 1500) * stretch + 1500
STRETCH_CENTRE_US: Final = 1500.0


class ProfileError(ScenarioError):
    """A profile that cannot be used: ``file: key: message``."""


@dataclass(frozen=True)
class Rc:
    order: str  # the letters of channels 1..4: A(ileron)=roll, E(levator)=pitch, T(hrottle), R(udder)=yaw
    centre_us: float
    travel_us: float  # full stick, each way from the centre
    min_us: float
    max_us: float
    sbus_us_per_step: float
    sbus_offset_us: float
    sbus_stretch: float
    extra: dict[str, int]  # knob -> channel (1-based)
    #: the sticks the FC reads the other way round from the rig ("pitch": its channel above the centre
    #: is nose down, where the rig's positive pitch is nose up)
    reverse: tuple[str, ...] = ()

    def raw(self, us: float) -> float:
        """The SBUS value the FC reads as ``us`` (the inverse of its mapping; not rounded)."""
        before_stretch = (us - STRETCH_CENTRE_US) / self.sbus_stretch + STRETCH_CENTRE_US
        return (before_stretch - self.sbus_offset_us) / self.sbus_us_per_step

    def us(self, raw: int) -> float:
        """What the FC makes of the SBUS value ``raw``, in µs (its mapping)."""
        return (raw * self.sbus_us_per_step + self.sbus_offset_us - STRETCH_CENTRE_US) * self.sbus_stretch \
            + STRETCH_CENTRE_US

    def channel(self, axis: str) -> int:
        """The 1-based channel of a stick axis ("roll", "pitch", "throttle", "yaw")."""
        return self.order.index({"roll": "A", "pitch": "E", "throttle": "T", "yaw": "R"}[axis]) + 1


@dataclass(frozen=True)
class Arming:
    method: str
    channel: int | None = None  # switch: its channel (1-based)
    on_us: float | None = None
    off_us: float | None = None
    arm: dict[str, str] = field(default_factory=dict)  # sticks: stick -> "low" | "centre" | "high"
    disarm: dict[str, str] = field(default_factory=dict)
    hold_s: float = 0.0
    detect: str = "motors"  # how the rig knows it armed: "telemetry" (its flag) or "motors"
    idle_us: float = 1050.0  # detect motors: a pulse above this is an armed FC's


@dataclass(frozen=True)
class Modes:
    channel: int | None
    default: str
    positions: dict[str, float]  # mode -> µs on the channel
    angle_deg: float | None  # angle per full stick in an angle mode
    rate_dps: float | None  # roll/pitch rate per full stick in a rate mode
    yaw_rate_dps: float


@dataclass(frozen=True)
class Motors:
    frame: str  # "+" | "x"
    order: tuple[int, ...]  # output k (0-based) drives plant motor order[k] (1..4)
    pwm_channels: int
    #: an MCU's: the pin of each of the FC's outputs 1..4, as its firmware drives them ("PE5"); () the
    #: board file's motor pins as they are
    pins: tuple[str, ...] = ()


@dataclass(frozen=True)
class Telemetry:
    kind: str
    port: str
    baud: int
    poll_hz: float


@dataclass(frozen=True)
class Config:
    eeprom: Path | None
    params: Path | None
    args: tuple[str, ...]
    #: the reference FC's configuration keys (dut/src/config_keys.h) this profile sets, before a
    #: scenario's own [fc] table: how the rig's own FC is made to fly as a third-party one does
    fc: tuple[tuple[str, str], ...] = ()

    @property
    def keeps_state(self) -> bool:
        """Whether the FC's arguments name a folder for its own files (``{state}``)."""
        return any(STATE in a for a in self.args)

    def arguments(self, state: Path | None = None) -> list[str]:
        """The FC's extra arguments, ``{params}`` in them replaced by the parameter file's path and
        ``{state}`` by ``state``: a folder, empty at the start of the run, for the files an FC keeps
        between boots (ArduPilot's parameter storage): without it they would land in the caller's
        folder and the next run would start from what this one saved."""
        if self.keeps_state and state is None:
            raise ValueError("the FC's arguments name {state}: a folder for its files is needed")
        return [a.replace("{params}", str(self.params or "")).replace(STATE, str(state)) for a in self.args]


@dataclass(frozen=True)
class Profile:
    path: Path
    name: str
    description: str
    source: str
    features: tuple[str, ...]
    rc: Rc
    arming: Arming
    modes: Modes
    motors: Motors
    startup_s: float
    ready: str  # "" or "telemetry": the FC says when it is ready (upper bound startup_s)
    telemetry: Telemetry
    config: Config
    sha256: str
    #: an MCU's: how the FC's firmware expects its sensor board turned (clockwise from above, from facing
    #: forward), replacing the board file's; None: the board file's
    mounting_yaw_deg: int | None = None
    #: the MS5611 reads its datasheet noise: the FC's start-up wants a barometer whose reading moves
    #: (ArduPilot: a pressure unchanged for 2 s is a stuck barometer), and a plant at rest holds one
    baro_noise: bool = False

    @property
    def mode_names(self) -> tuple[str, ...]:
        return tuple(self.modes.positions) if self.modes.positions else (self.modes.default,)

    def channel_map(self) -> ChannelMap:
        """The profile's channels as SBUS values, for the stick emulator (emulators/sbus.py)."""
        rc = self.rc
        raw = rc.raw

        def value(us: float) -> int:
            return max(0, min(2047, round(raw(us))))

        centre = raw(rc.centre_us)
        gestures: list[tuple[str, tuple[tuple[int, int], ...]]] = []
        for name, sticks in (("arm", self.arming.arm), ("disarm", self.arming.disarm)):
            if sticks:
                gestures.append((name, tuple((rc.channel(s) - 1, value(self.stick_us(pos)))
                                             for s, pos in sticks.items())))
        arm = None
        if self.arming.method == "switch" and self.arming.channel is not None:
            assert self.arming.on_us is not None and self.arming.off_us is not None
            arm = (self.arming.channel - 1, value(self.arming.on_us), value(self.arming.off_us))
        modes = tuple((m, value(us)) for m, us in self.modes.positions.items())
        default_first = tuple(sorted(modes, key=lambda mv: mv[0] != self.modes.default))
        return ChannelMap(
            roll=rc.channel("roll") - 1, pitch=rc.channel("pitch") - 1, throttle=rc.channel("throttle") - 1,
            yaw=rc.channel("yaw") - 1, centre=centre, travel=raw(rc.centre_us + rc.travel_us) - centre,
            low=value(rc.min_us), high=value(rc.max_us), rest=value(rc.centre_us), arm=arm,
            mode_channel=None if self.modes.channel is None else self.modes.channel - 1, modes=default_first,
            knobs=tuple((k, c - 1) for k, c in rc.extra.items()), gestures=tuple(gestures),
            reversed_sticks=rc.reverse,
        )

    def stick_us(self, position: str) -> float:
        """A gesture's stick position in µs: the end of its travel, or the centre."""
        return self.rc.centre_us + {"low": -1, "centre": 0, "high": 1}[position] * self.rc.travel_us

    @property
    def reads_telemetry(self) -> bool:
        """Whether the rig reads this FC's estimates (criteria on est_* are measured)."""
        return self.telemetry.kind in TELEMETRY_READ

    def not_measured_reason(self) -> str:
        """Why criteria on the FC's estimates cannot be measured under this profile ("" if they can)."""
        kind = self.telemetry.kind
        if kind in TELEMETRY_READ:
            return ""
        return f"the FC's profile {self.name!r} has no telemetry (telemetry.kind = \"{kind}\")"


def _reference_keys(c: _Check, table: object) -> tuple[tuple[str, str], ...]:
    """config.fc: the reference FC's keys, each checked against its own table as a scenario's [fc] is."""
    if not isinstance(table, dict):
        raise c.fail("config.fc", f"expected a table of the reference FC's keys, got {table!r}")
    known = fc_keys.keys()
    out: list[tuple[str, str]] = []
    for k, v in table.items():
        if k not in known:
            close = difflib.get_close_matches(k, known, n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise c.fail(f"config.fc.{k}", f"not a key of the reference FC (dut/src/config_keys.h){hint}")
        text, why = known[k].check(v)
        if why:
            raise c.fail(f"config.fc.{k}", why)
        out.append((k, text))
    return tuple(out)


# ---- finding and loading -----------------------------------------------------------------------------


def names() -> list[str]:
    """The shipped profiles' names."""
    return sorted(p.stem for p in PROFILES.glob("*.toml"))


def find(name: str | Path) -> Path:
    """A shipped profile's file by name, or the path as given."""
    p = Path(name)
    if p.suffix != ".toml" and p.parent == Path(".") and (PROFILES / f"{p.name}.toml").is_file():
        return PROFILES / f"{p.name}.toml"
    return p


def load(name: str | Path = DEFAULT) -> Profile:
    """Reads and checks a profile (a shipped profile's name, or a path); ProfileError otherwise."""
    path = find(name)
    c = _ProfileCheck(str(path))
    if not path.is_file():
        near = difflib.get_close_matches(str(name), names(), n=1)
        hint = f"; did you mean {near[0]!r}?" if near else ""
        raise c.fail("", f"no such profile file, and no shipped profile of that name{hint} (shipped: "
                         f"{', '.join(names())})")
    try:
        toml = read_toml(path)
    except TomlFileError as e:
        raise c.fail("", str(e)) from None
    return check(toml.data, path, toml.sha256)


def check(data: dict[str, Any], path: Path, sha256: str) -> Profile:
    """Checks a profile's parsed tables; every problem of the file is said at once (ProfileError)."""
    c = _ProfileCheck(str(path))
    c.table(data, "", TOP)
    t = {k: c.lenient(data.get(k, {}), k, known) for k, known in (
        ("profile", PROFILE_KEYS), ("rc", RC_KEYS), ("arming", ARMING_KEYS), ("modes", MODE_KEYS),
        ("motors", MOTOR_KEYS), ("sensors", SENSOR_KEYS), ("startup", STARTUP_KEYS),
        ("telemetry", TELEMETRY_KEYS), ("config", CONFIG_KEYS))}
    p = t["profile"]
    name, description, source = path.stem, "", ""
    features: tuple[str, ...] = ()
    with c.part():
        name = c.string(p, "name", "profile", path.stem)
        description = c.string(p, "description", "profile", "")
        source = c.string(p, "source", "profile", "")
        features = tuple(c.words(p, "features", "profile", FEATURES))
    rc = _rc(c, t["rc"])
    arming = _arming(c, t["arming"], rc)
    modes = _modes(c, t["modes"], rc)
    motors = Motors("+", (1, 2, 3, 4), 8)
    with c.part():
        m = t["motors"]
        order = m.get("order", [1, 2, 3, 4])
        if (not isinstance(order, list) or sorted(order) != [1, 2, 3, 4]
                or any(isinstance(x, bool) for x in order)):
            raise c.fail("motors.order", f"expected the plant's motors 1..4, each once, in the order of the "
                                         f"FC's outputs (e.g. [4, 1, 3, 2]), got {order!r}")
        pins = m.get("pins", [])
        if (not isinstance(pins, list) or len(pins) not in (0, 4) or len(set(map(str, pins))) != len(pins)
                or not all(isinstance(x, str) and re.fullmatch(r"P[A-L][0-7]", x) for x in pins)):
            raise c.fail("motors.pins", f"expected the four pins of the FC's outputs 1..4, each once (e.g. "
                                        f"[\"PE5\", \"PE3\", \"PH3\", \"PE4\"]), got {pins!r}")
        motors = Motors(c.string(m, "frame", "motors", "+", choices=("+", "x")), tuple(order),
                        c.integer(m, "pwm_channels", "motors", 4, 16, default=8), tuple(pins))
    mounting: int | None = None
    baro_noise = False
    with c.part():
        baro_noise = c.boolean(t["sensors"], "baro_noise", "sensors", False)
        if "mounting_yaw_deg" in t["sensors"]:
            mounting = c.integer(t["sensors"], "mounting_yaw_deg", "sensors", 0, 270)
            if mounting % 90:
                raise c.fail("sensors.mounting_yaw_deg", f"expected 0, 90, 180 or 270, got {mounting}")
    startup_s, ready = 0.0, ""
    with c.part():
        s = t["startup"]
        startup_s = c.number(s, "seconds", "startup", 0.0, low=0, high=600)
        ready = c.string(s, "ready", "startup", "", choices=("", "telemetry"))
    telemetry = Telemetry("none", "", 0, 0.0)
    with c.part():
        tel = t["telemetry"]
        kind = c.string(tel, "kind", "telemetry", "none", choices=TELEMETRY_KINDS)
        port = c.string(tel, "port", "telemetry", "/dev/ttyTEL0" if kind != "none" else "")
        telemetry = Telemetry(kind, port,
                              c.integer(tel, "baud", "telemetry", 300, 4_000_000, default=115_200),
                              c.number(tel, "poll_hz", "telemetry", 10.0, positive=True, high=1000))
        if kind == "none" and arming.detect == "telemetry":
            raise c.fail("arming.detect", "\"telemetry\" needs telemetry (telemetry.kind is \"none\"); "
                                          "expected \"motors\"")
        if ready == "telemetry" and kind in ("none", "text"):
            raise c.fail("startup.ready", f"the FC's readiness comes over MSP or MAVLink; telemetry.kind is "
                                          f"{kind!r}")
    with c.part():
        if arming.channel is not None and arming.channel == modes.channel:
            raise c.fail("modes.channel", f"channel {modes.channel} is the arm switch's (arming.channel)")
    config = Config(None, None, ())
    with c.part():
        cf = t["config"]
        args = cf.get("args", [])
        if not isinstance(args, list) or not all(isinstance(a, str) for a in args):
            raise c.fail("config.args", f"expected an array of strings (the FC's arguments), got {args!r}")
        if any("{params}" in a for a in args) and "params" not in cf:
            raise c.fail("config.args", "{params} stands for config.params, which is missing")
        config = Config(c.beside(cf, "eeprom", "config", path), c.beside(cf, "params", "config", path),
                        tuple(args), _reference_keys(c, cf.get("fc", {})))
    c.done()
    return Profile(path.resolve(), name, description, source, features, rc, arming, modes, motors, startup_s,
                   ready, telemetry, config, sha256, mounting, baro_noise)


# ---- the tables ----------------------------------------------------------------------------------


def _rc(c: _ProfileCheck, r: dict[str, Any]) -> Rc:
    rc = Rc("AETR", 1500.0, 500.0, 1000.0, 2000.0, 0.625, 880.0, 1.0, {})
    with c.part():
        order = c.string(r, "order", "rc", "AETR")
        if sorted(order) != sorted("AETR"):
            raise c.fail("rc.order", "expected the letters A, E, T, R once each in the order of channels "
                                     "1..4 "
                                     f"(AETR, TAER, ...), got {order!r}")
        centre = c.number(r, "centre_us", "rc", 1500.0, low=500, high=2500)
        travel = c.number(r, "travel_us", "rc", 500.0, positive=True, high=1000)
        lo = c.number(r, "min_us", "rc", centre - travel, low=0, high=3000)
        hi = c.number(r, "max_us", "rc", centre + travel, low=0, high=3000)
        if not lo <= centre - travel or not centre + travel <= hi:
            raise c.fail("rc.travel_us", f"a full stick ({centre - travel:g}..{centre + travel:g} us) goes "
                                         f"past min_us..max_us ({lo:g}..{hi:g})")
        extra: dict[str, int] = {}
        ex = c.table(r.get("extra", {}), "rc.extra", KNOBS)
        for k in ex:
            extra[k] = c.integer(ex, k, "rc.extra", 5, CHANNELS)
        rc = Rc(order, centre, travel, lo, hi,
                c.number(r, "sbus_us_per_step", "rc", 0.625, positive=True, high=10),
                c.number(r, "sbus_offset_us", "rc", 880.0, low=-5000, high=5000),
                c.number(r, "sbus_stretch", "rc", 1.0, positive=True, high=10), extra,
                tuple(c.words(r, "reverse", "rc", ("roll", "pitch", "yaw"))))
        for key, us in (("min_us", lo), ("max_us", hi)):
            if not 0 <= round(rc.raw(us)) <= 2047:
                raise c.fail(f"rc.{key}", f"{us:g} us is SBUS value {rc.raw(us):.0f} by this mapping: "
                                          "outside the 11 bits (0..2047) a frame carries")
    return rc


def _arming(c: _ProfileCheck, a: dict[str, Any], rc: Rc) -> Arming:
    arming = Arming("switch", None, rc.max_us, rc.min_us)  # (a bad table: no channel to clash with)
    with c.part():
        method = c.string(a, "method", "arming", "switch", choices=ARMING_METHODS)
        detect = c.string(a, "detect", "arming", "motors", choices=("telemetry", "motors"))
        idle = c.number(a, "idle_us", "arming", 1050.0, low=900, high=1500)
        hold = c.number(a, "hold_s", "arming", 0.0 if method != "sticks" else 1.0, low=0, high=30)
        channel, on, off = None, None, None
        gestures: dict[str, dict[str, str]] = {"arm": {}, "disarm": {}}
        if method == "switch":
            channel = _aux_channel(c, a, "channel", "arming", rc, 5)
            on = c.number(a, "on_us", "arming", rc.max_us, low=rc.min_us, high=rc.max_us)
            off = c.number(a, "off_us", "arming", rc.min_us, low=rc.min_us, high=rc.max_us)
        for g in ("arm", "disarm"):
            if g in a and method != "sticks":
                raise c.fail(f"arming.{g}",
                             f"a stick gesture goes with method = \"sticks\" (this is {method!r})")
            if method == "sticks":
                if g not in a:
                    raise c.fail(f"arming.{g}", "missing; expected the gesture's sticks, e.g. "
                                                "{ throttle = \"low\", yaw = \"high\" }")
                sticks = c.table(a[g], f"arming.{g}", GESTURE_STICKS)
                gestures[g] = {s: c.string(sticks, s, f"arming.{g}", choices=STICK_POSITIONS) for s in sticks}
                if not gestures[g]:
                    raise c.fail(f"arming.{g}", "expected at least one stick")
        for k in ("channel", "on_us", "off_us"):
            if k in a and method != "switch":
                raise c.fail(f"arming.{k}", f"goes with method = \"switch\" (this is {method!r})")
        arming = Arming(method, channel, on, off, gestures["arm"], gestures["disarm"], hold, detect, idle)
    return arming


def _modes(c: _ProfileCheck, m: dict[str, Any], rc: Rc) -> Modes:
    modes = Modes(None, "angle", {}, 30.0, None, 90.0)
    with c.part():
        positions: dict[str, float] = {}
        pos = c.table(m.get("positions", {}), "modes.positions", MODES)
        for k in pos:
            positions[k] = c.number(pos, k, "modes.positions", low=rc.min_us, high=rc.max_us)
        channel = _aux_channel(c, m, "channel", "modes", rc, None) if "channel" in m else None
        if positions and channel is None:
            raise c.fail("modes.channel", "missing; positions need the channel they are on")
        if channel is not None and not positions:
            raise c.fail("modes.positions", "missing; expected the µs of each mode on the channel, e.g. "
                                            "{ angle = 1000, althold = 2000 }")
        default = c.string(m, "default", "modes", next(iter(positions), "angle"), choices=MODES)
        if positions and default not in positions:
            raise c.fail("modes.default", f"expected one of the positions ({', '.join(positions)}), got "
                                          f"{default!r}")
        flown = set(positions) or {default}
        angle = c.optional(m, "angle_deg", "modes")
        rate = c.optional(m, "rate_dps", "modes")
        for key, value, needs in (("angle_deg", angle, "angle"), ("rate_dps", rate, "rate")):
            if value is not None and not 0 < value <= 2000:
                raise c.fail(f"modes.{key}", f"expected a number > 0 and at most 2000, got {value:g}")
            wants = bool(flown - set(RATE_MODES)) if needs == "angle" else bool(flown & set(RATE_MODES))
            if value is None and wants:
                raise c.fail(f"modes.{key}", f"missing; the FC flies {', '.join(sorted(flown))}: a "
                                             "scenario's "
                                             f"{'degrees' if needs == 'angle' else 'rates'} need the "
                                             f"{'angle' if needs == 'angle' else 'rate'} per full stick")
        modes = Modes(channel, default, positions, angle, rate,
                      c.number(m, "yaw_rate_dps", "modes", 90.0, positive=True, high=2000))
    return modes


def _aux_channel(c: _ProfileCheck, data: dict[str, Any], key: str, path: str, rc: Rc,
                 default: int | None) -> int:
    """A switch's channel: 5..16 (1..4 are the sticks')."""
    n = c.integer(data, key, path, 1, CHANNELS, default=default)
    if n <= 4:
        raise c.fail(f"{path}.{key}", f"channel {n} is a stick's ({rc.order[n - 1]} in {rc.order}); expected "
                                      f"5..{CHANNELS}")
    if n in rc.extra.values():
        raise c.fail(f"{path}.{key}", f"channel {n} is rc.extra's "
                                      f"{next(k for k, v in rc.extra.items() if v == n)}")
    return n


class _ProfileCheck(_Check):
    def fail(self, key: str, message: str) -> ProfileError:
        return ProfileError(self.file, key, message)

    def integer(self, data: dict[str, Any], key: str, path: str, low: int, high: int,
                default: int | None = None) -> int:
        v = self.number(data, key, path, None if default is None else float(default), low=low, high=high)
        if v != int(v):
            raise self.fail(f"{path}.{key}", f"expected an integer, got {v:g}")
        return int(v)

    def words(self, data: dict[str, Any], key: str, path: str, choices: tuple[str, ...]) -> list[str]:
        v = data.get(key, [])
        if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
            raise self.fail(f"{path}.{key}",
                            f"expected an array of strings ({', '.join(choices)}), got {v!r}")
        for x in v:
            self.string({key: x}, key, path, choices=choices)
        return list(v)

    def beside(self, data: dict[str, Any], key: str, path: str, profile: Path) -> Path | None:
        if key not in data:
            return None
        f = (profile.parent / self.string(data, key, path)).resolve()
        if not f.is_file():
            raise self.fail(f"{path}.{key}", f"no such file: {f}")
        return f


def fly_check(profile: Profile, needs: tuple[str, ...], degrees: dict[str, float]) -> str:
    """Why this FC cannot fly a scenario that needs ``needs`` (modes and features) and asks for these
    largest attitudes and rates (``roll_deg``... -> the largest |value|), or ""."""
    missing = [n for n in needs if n not in profile.mode_names and n not in profile.features
               and not (n in RATE_MODES and set(RATE_MODES) & set(profile.mode_names))]
    if missing:
        has = ", ".join([*profile.mode_names, *profile.features])
        return f"the FC's profile {profile.name!r} has no {', '.join(missing)} (it has: {has})"
    for key, value in degrees.items():
        full = stick_scale(profile, key)
        if full is not None and abs(value) > full + 1e-9:
            return (f"{key} = {value:g} is more than a full stick for the FC's profile {profile.name!r} "
                    f"({full:g} per full stick)")
    return ""


def stick_scale(profile: Profile, key: str) -> float | None:
    """The degrees (``*_deg``) or degrees per second (``*_dps``) of a full stick for a stick given in
    those units; None when the profile does not say."""
    if key == "yaw_dps":
        return profile.modes.yaw_rate_dps
    if key.endswith("_deg"):
        return profile.modes.angle_deg
    return profile.modes.rate_dps


def stick(profile: Profile, key: str, value: float) -> tuple[str, float]:
    """A stick given in degrees or degrees per second, as its axis and normalised deflection."""
    full = stick_scale(profile, key)
    assert full is not None and math.isfinite(full)  # (fly_check said no to a scenario that needs one)
    return key.rsplit("_", 1)[0], value / full
