"""FC profiles (scenarios/profile.py): every key read as documented, every mistake refused naming the
file and the key (with a suggestion for a near miss), the shipped profiles' channels as their FCs read
them. Expected SBUS values come from each FC's published mapping, written out here."""

from __future__ import annotations

import hashlib
import struct
from pathlib import Path

import pytest

from rig.emulators.sbus import REFERENCE_MAP, Sticks
from rig.scenarios import profile as P
from rig.scenarios.profile import ProfileError

FULL = """
[profile]
name = "my-fc"
description = "an FC"
source = "its manual"
features = ["failsafe"]

[rc]
order = "TAER"
centre_us = 1500
travel_us = 500
min_us = 1000
max_us = 2000
sbus_us_per_step = 0.625
sbus_offset_us = 880
sbus_stretch = 1.0
extra = { alt_offset = 8 }
reverse = ["pitch"]

[arming]
method = "switch"
channel = 6
on_us = 1900
off_us = 1100
detect = "motors"
idle_us = 1080

[modes]
channel = 5
default = "angle"
positions = { acro = 1000, angle = 1500, althold = 2000 }
angle_deg = 45
rate_dps = 500
yaw_rate_dps = 180

[motors]
frame = "x"
order = [4, 1, 3, 2]
pwm_channels = 6
pins = ["PE5", "PE3", "PH3", "PE4"]

[sensors]
mounting_yaw_deg = 90

[startup]
seconds = 2.5

[telemetry]
kind = "text"
port = "/dev/ttyTEL0"
baud = 57600
poll_hz = 20

[config]
params = "fc.parm"
args = ["--defaults", "{params}"]
"""


def write(tmp_path: Path, text: str, name: str = "fc.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    (tmp_path / "fc.parm").write_text("X,1\n")
    return p


def test_every_key_is_read_as_written(tmp_path: Path) -> None:
    path = write(tmp_path, FULL)
    p = P.load(path)
    assert (p.name, p.description, p.source, p.features) == ("my-fc", "an FC", "its manual", ("failsafe",))
    assert p.sha256 == hashlib.sha256(path.read_bytes()).hexdigest()
    assert (p.rc.order, p.rc.centre_us, p.rc.travel_us, p.rc.min_us, p.rc.max_us) == ("TAER", 1500, 500, 1000,
                                                                                      2000)
    assert p.rc.extra == {"alt_offset": 8} and p.rc.reverse == ("pitch",)
    a = p.arming
    assert (a.method, a.channel, a.on_us, a.off_us) == ("switch", 6, 1900, 1100)
    assert (a.detect, a.idle_us) == ("motors", 1080)
    m = p.modes
    assert (m.channel, m.default, m.angle_deg, m.rate_dps, m.yaw_rate_dps) == (5, "angle", 45, 500, 180)
    assert m.positions == {"acro": 1000, "angle": 1500, "althold": 2000}
    assert (p.motors.frame, p.motors.order, p.motors.pwm_channels) == ("x", (4, 1, 3, 2), 6)
    assert p.motors.pins == ("PE5", "PE3", "PH3", "PE4") and p.mounting_yaw_deg == 90
    assert p.startup_s == 2.5
    assert (p.telemetry.kind, p.telemetry.port, p.telemetry.baud, p.telemetry.poll_hz) == (
        "text", "/dev/ttyTEL0", 57600, 20)
    assert p.config.params == (tmp_path / "fc.parm").resolve()
    assert p.config.arguments() == ["--defaults", str((tmp_path / "fc.parm").resolve())]


def test_the_channels_follow_the_order_and_the_standard_sbus_mapping(tmp_path: Path) -> None:
    # us = 880 + 0.625 * value (the usual SBUS mapping): 1000 us is 192, 1500 is 992, 2000 is 1792
    cmap = P.load(write(tmp_path, FULL)).channel_map()
    sticks = Sticks(roll=1.0, pitch=-1.0, throttle=0.0, yaw=0.5, arm=True, mode="acro", alt_offset=-1.0)
    ch = sticks.channels(cmap)
    assert ch[0] == 192  # T (TAER): throttle 0 is the bottom of its travel, 1000 us
    assert ch[1] == 1792  # A: roll full right, 2000 us
    assert ch[2] == 1792  # E: pitch full nose down, on a reversed channel (reverse = ["pitch"]): 2000 us
    assert ch[3] == round((1750 - 880) / 0.625)  # R: yaw half right, 1750 us
    assert ch[4] == 192  # channel 5: acro at 1000 us
    assert ch[5] == round((1900 - 880) / 0.625)  # channel 6: the arm switch on, 1900 us
    assert ch[7] == 192  # channel 8: the alt_offset knob at -1
    assert ch[6] == 992 and ch[8:] == [992] * 8  # the rest at the centre
    assert Sticks(mode="").channels(cmap)[4] == 992  # no mode asked: the default (angle, 1500 us)
    assert Sticks(arm=False).channels(cmap)[5] == round((1100 - 880) / 0.625)


def test_the_reference_profile_is_the_reference_fc_s_own_channels() -> None:
    p = P.load()
    assert p.name == "reference" and p.channel_map() == REFERENCE_MAP
    # the reference FC reads 172..1811 as -100..+100 % around 992
    ch = Sticks(roll=1.0, pitch=-1.0, throttle=1.0, arm=True, mode="althold").channels(p.channel_map())
    assert ch[:6] == [1811, 173, 1811, 992, 1811, 1811]  # (992 - 819 = 173: a symmetric travel)
    assert p.reads_telemetry and p.not_measured_reason() == ""


def test_multiwii_s_sbus_stretch_is_inverted() -> None:
    # MultiWii 2.4: us = (value / 2 + 988 - 1500) * 1.25 + 1500, so 1000 us is value 224, 2000 us is 1824
    p = P.load("multiwii-2.4")
    assert p.rc.raw(1000) == pytest.approx(224) and p.rc.raw(2000) == pytest.approx(1824)
    assert p.rc.us(1024) == pytest.approx(1500)
    cmap = p.channel_map()
    assert Sticks(throttle=0.0, yaw=1.0).channels(cmap)[2:4] == [224, 1824]
    # its QUADX mixer pitches nose down for a channel above 1500 us: the rig's nose up is 1000 us
    assert Sticks(roll=1.0, pitch=1.0).channels(cmap)[:2] == [1824, 224]
    # arming by sticks: throttle low + yaw right held as the gesture, whatever the sticks were
    held = Sticks(throttle=0.6, yaw=-0.2, gesture="arm").channels(cmap)
    assert held[2:4] == [224, 1824]
    assert Sticks(throttle=0.6, yaw=-0.2, gesture="disarm").channels(cmap)[2:4] == [224, 224]
    assert p.motors.frame == "x" and p.arming.method == "sticks"
    assert p.reads_telemetry and p.not_measured_reason() == ""  # MSP, polled


def test_arducopter_maps_sbus_as_ardupilot_does() -> None:
    # AP_RCProtocol_SBUS: 200..1800 -> 1000..2000 us, offset int(1000 - (0.625 * 200 + 0.5)) = 874
    p = P.load("arducopter-4")
    assert p.rc.us(200) == pytest.approx(999) and p.rc.us(1800) == pytest.approx(1999)
    assert p.modes.channel == 5 and p.telemetry.kind == "mavlink" and p.motors.pwm_channels == 14
    assert p.config.params is not None and p.config.params.name == "arducopter-4.parm"
    args = p.config.arguments(Path("/run/fc-state"))
    assert args[args.index("--defaults") + 1] == str(p.config.params)
    assert args[args.index("--storage-directory") + 1] == "/run/fc-state"  # its storage starts empty
    assert args[args.index("--serial2") + 1] == "/dev/ttyRC0"  # SBUS, SERIAL2_PROTOCOL 23
    assert p.baro_noise  # (AP_Baro: a pressure unchanged for 2 s is unhealthy)


def test_the_barometer_s_noise_is_asked_for_by_the_profile(tmp_path: Path) -> None:
    assert not P.load(write(tmp_path, FULL)).baro_noise  # the default: an exact barometer
    sensors = "mounting_yaw_deg = 90"
    on = write(tmp_path, FULL.replace(sensors, f"{sensors}\nbaro_noise = true"), "on.toml")
    assert P.load(on).baro_noise
    bad = write(tmp_path, FULL.replace(sensors, f'{sensors}\nbaro_noise = "yes"'), "bad.toml")
    with pytest.raises(P.ProfileError, match=r"sensors.baro_noise: expected true or false"):
        P.load(bad)


def test_every_shipped_profile_loads_and_a_bad_name_gets_a_suggestion() -> None:
    assert P.names() == ["arducopter-4", "multiwii-2.4", "reference", "reference-mavlink", "reference-msp",
                         "reference-sticks"]
    with pytest.raises(ProfileError, match="did you mean 'multiwii-2.4'"):
        P.load("multiwii-24")


@pytest.mark.parametrize(("change", "key", "words"), [
    (("[rc]\n", "[rc]\nordr = 1\n"), "rc.ordr", "did you mean 'order'"),
    (('order = "TAER"', 'order = "TAEA"'), "rc.order", "A, E, T, R once each"),
    (("travel_us = 500", "travel_us = 600"), "rc.travel_us", "goes past min_us..max_us"),
    (('method = "switch"', 'method = "swtich"'), "arming.method", "did you mean 'switch'"),
    (("channel = 6\non_us", "channel = 2\non_us"), "arming.channel", "a stick's"),
    (("channel = 5\ndefault", "channel = 6\ndefault"), "modes.channel", "the arm switch's"),
    (('default = "angle"', 'default = "horizon"'), "modes.default", "one of the positions"),
    (("positions = { acro", "positions = { acrobatic"), "modes.positions.acrobatic", "did you mean 'acro'"),
    (("rate_dps = 500\n", ""), "modes.rate_dps", "rate per full stick"),
    (("order = [4, 1, 3, 2]", "order = [1, 1, 3, 2]"), "motors.order", "each once"),
    (('frame = "x"', 'frame = "h"'), "motors.frame", "expected one of"),
    (("pwm_channels = 6", "pwm_channels = 40"), "motors.pwm_channels", "4..16"),
    (('pins = ["PE5", "PE3"', 'pins = ["PE5", "PE5"'), "motors.pins", "each once"),
    (('reverse = ["pitch"]', 'reverse = ["throttle"]'), "rc.reverse", "expected one of"),
    (('pins = ["PE5", "PE3"', 'pins = ["PE5", "D3"'), "motors.pins", "the four pins"),
    (("mounting_yaw_deg = 90", "mounting_yaw_deg = 45"), "sensors.mounting_yaw_deg", "0, 90, 180 or 270"),
    (('kind = "text"', 'kind = "mavlnk"'), "telemetry.kind", "did you mean 'mavlink'"),
    (('params = "fc.parm"', 'params = "gone.parm"'), "config.params", "no such file"),
    (('features = ["failsafe"]', 'features = ["failsave"]'), "profile.features", "did you mean 'failsafe'"),
    (("idle_us = 1080", "idle_us = 5"), "arming.idle_us", "900..1500"),
    (('args = [', 'fc = { telemetry_prot = 1 }\nargs = ['), "config.fc.telemetry_prot",
     "did you mean 'telemetry_proto'"),
    (('args = [', 'fc = { telemetry_proto = 3 }\nargs = ['), "config.fc.telemetry_proto", "3 is outside"),
    (('args = [', 'fc = 1\nargs = ['), "config.fc", "a table of the reference FC's keys"),
])
def test_each_mistake_is_refused_naming_the_key(tmp_path: Path, change: tuple[str, str], key: str,
                                                words: str) -> None:
    assert change[0] in FULL
    path = write(tmp_path, FULL.replace(change[0], change[1], 1))
    with pytest.raises(ProfileError) as e:
        P.load(path)
    assert any(p.key == key for p in e.value.problems), str(e.value)
    assert words in str(e.value) and str(path) in str(e.value)


def test_a_stick_gesture_needs_its_sticks_and_a_switch_its_channel(tmp_path: Path) -> None:
    text = FULL.replace('method = "switch"\nchannel = 6\non_us = 1900\noff_us = 1100\n',
                        'method = "sticks"\narm = { throttle = "low", yaw = "high" }\nhold_s = 2\n')
    with pytest.raises(ProfileError, match=r"arming\.disarm: missing"):
        P.load(write(tmp_path, text))
    ok = P.load(write(tmp_path, text.replace("hold_s = 2", 'disarm = { throttle = "low", yaw = "low" }\n'
                                                            "hold_s = 2")))
    assert ok.arming.hold_s == 2 and ok.arming.arm == {"throttle": "low", "yaw": "high"}
    with pytest.raises(ProfileError, match=r"arming\.arm\.yaw: expected one of low, centre, high"):
        P.load(write(tmp_path, text.replace('yaw = "high"', 'yaw = "right"')))


def test_detecting_arming_by_telemetry_needs_telemetry(tmp_path: Path) -> None:
    text = FULL.replace('detect = "motors"', 'detect = "telemetry"').replace('kind = "text"', 'kind = "none"')
    with pytest.raises(ProfileError, match=r"arming\.detect: \"telemetry\" needs telemetry"):
        P.load(write(tmp_path, text))


def test_what_a_profile_cannot_fly_is_said(tmp_path: Path) -> None:
    ref = P.load("reference")
    plain = P.load(write(tmp_path, FULL.replace('features = ["failsafe"]', "features = []")))
    assert P.fly_check(ref, ("angle", "althold", "failsafe"), {}) == ""
    assert "has no failsafe" in P.fly_check(plain, ("angle", "failsafe"), {})
    assert "has no acro" in P.fly_check(ref, ("acro",), {})
    assert "more than a full stick" in P.fly_check(ref, ("angle",), {"roll_deg": 31.0})
    assert P.stick(ref, "roll_deg", 10.0) == ("roll", pytest.approx(1 / 3))
    assert P.stick(ref, "yaw_dps", -45.0) == ("yaw", pytest.approx(-0.5))


def test_the_multiwii_set_up_sends_what_multiwii_2_4_reads() -> None:
    """docs/examples/multiwii-setup.toml, the set-up docs/multiwii.md runs: each MSP request has the
    payload size MultiWii 2.4's Protocol.cpp reads for it (MSP_SET_BOX: CHECKBOXITEMS u16, 5 boxes for
    QUADX + GY_86: ARM, ANGLE, HORIZON, BARO, MAG; MSP_SET_RC_TUNING: 7 bytes from rcRate8;
    MSP_SET_PID: 3 x PIDITEMS (10); MSP_ACC_CALIBRATION and MSP_EEPROM_WRITE: none), in that order, and
    the modes it sets are the profile's: ANGLE at AUX1 middle and high (bits 1, 2), BARO at high."""
    from rig.scenarios.schema import load

    sc = load(Path(__file__).resolve().parents[2] / "docs" / "examples" / "multiwii-setup.toml")
    sends = [s.msp for s in sorted(sc.serial, key=lambda s: s.t) if s.msp is not None]
    assert [(cmd, len(payload)) for cmd, payload in sends] == [
        (203, 10), (204, 7), (202, 30), (205, 0), (250, 0)]
    boxes = struct.unpack("<5H", sends[0][1])
    assert boxes == (0, 0b110, 0, 0b100, 0)
    mw = P.load("multiwii-2.4")
    assert mw.modes.positions == {"acro": 1000, "angle": 1500, "althold": 2000}
    assert sends[1][1][1] == 0  # rcExpo 0: the profile's angle_deg is linear in the stick
