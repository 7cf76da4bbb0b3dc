"""The bridge core (bridge/core: bridge.c, pwm_capture.c, sbus_out.c) through its test harness
(bridge/tests/bridge_tool.c: a HAL whose clock the script sets): ESC pulse capture with counter wrap,
glitches and its frames over CAN, SBUS frames byte for byte against emulators/sbus.py, every down
message's dispatch, the version rule, host silence, register images that never tear a burst, and
fuzzed frames that are rejected, counted and never acted on.

Every test runs twice: on the host, and on a Cortex-M4 (the STM32G431's core, cross-built with
arm-none-eabi-gcc for the hard-float ABI) under QEMU's mps2-an386 with semihosting, where each script's
output must also equal the host build's byte for byte (word size, alignment, float and endianness
cannot differ silently)."""

from __future__ import annotations

import random
import struct
from dataclasses import dataclass

import pytest

from rig.bridge.esc import ESC_PROTOCOLS
from rig.bridge.link import Decoded, Receiver, encode
from rig.bridge.messages import HOST_SILENT_US, MESSAGES, PROTOCOL_VERSION
from rig.emulators import pwm_capture, sbus
from tests.bridge.tools import Tool, bridge_tools

G = 9.80665


@pytest.fixture(scope="module", params=["host", "cortex-m4"])
def tool(request: pytest.FixtureRequest) -> Tool:
    return bridge_tools(request.param)


@dataclass
class Run:
    lines: list[str]

    def up(self) -> list[Decoded]:
        rx = Receiver("up")
        out = [m for line in self.lines if line.startswith("up ") for m in rx.feed(bytes.fromhex(line[3:]))]
        assert rx.bad == 0
        return out

    def named(self, name: str) -> list[dict[str, object]]:
        return [m.values for m in self.up() if m.name == name]

    def tagged(self, tag: str) -> list[str]:
        return [line[len(tag) + 1:] for line in self.lines if line.startswith(tag + " ")]

    def status(self) -> dict[str, int]:
        """The last `status` line as numbers."""
        words = self.tagged("status")[-1].split()
        out = {"underruns": 0}
        out.update({"imu_underruns": int(words[1]), "mag_underruns": int(words[2]),
                    "baro_underruns": int(words[3])})
        it = iter(words[4:])
        out.update({k: int(v) for k, v in zip(it, it, strict=True)})
        return out


def run(tool: Tool, script: list[str]) -> Run:
    return Run(tool.run("\n".join(script) + "\n").splitlines())


class Script:
    """Host frames and board transactions, in order, with the clock."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self.seq = 0

    def t(self, us: int) -> Script:
        self.lines.append(f"t {us}")
        return self

    def send(self, name: str, **values: object) -> Script:
        self.lines.append("rx " + encode(name, self.seq, **values).hex())
        self.seq += 1
        return self

    def queue(self, name: str, **values: object) -> Script:
        """As send, but the frames up it causes stay queued until a later command (rxq)."""
        self.lines.append("rxq " + encode(name, self.seq, **values).hex())
        self.seq += 1
        return self

    def raw(self, wire: bytes) -> Script:
        self.lines.append("rx " + wire.hex())
        return self

    def hello(self, version: int = PROTOCOL_VERSION) -> Script:
        return self.send("HELLO", version=version, nonce=0xC0FFEE)

    def xfer(self, t_ns: int, addr: int, write: bytes, nread: int) -> Script:
        self.lines.append(f"xfer {t_ns} {addr:x} {write.hex() or '-'} {nread}")
        return self

    def cmd(self, *lines: str) -> Script:
        self.lines += lines
        return self


def accel_bytes(accel: tuple[float, float, float], temp_c: float, gyro: tuple[float, float, float]) -> bytes:
    """ACCEL_XOUT_H..GYRO_ZOUT_L at ±2 g and ±250 °/s (the power-on ranges)."""
    a = [round(x / G * 16384) for x in accel]
    g = [round(x * 57.29578 * 131) for x in gyro]
    return struct.pack(">7h", *a, round((temp_c - 36.53) * 340), *g)


WAKE = bytes([0x6B, 0x00])
SAMPLE = {"accel": [0.5, -0.25, -G], "gyro": [0.1, -0.2, 0.05], "temp_c": 30.0}


# ---------------------------------------------------------------- pulse capture


def pwm(tool: Tool, init: str, edges: list[tuple[int, int, int, int]],
        widths_at: int) -> tuple[list[int], list[int]]:
    r = run(tool, [f"pwm_init {init}", *[f"pwm_edge {c} {lv} {n} {t}" for c, lv, n, t in edges],
                   f"pwm_widths {widths_at}"])
    pulses = [int(x) for x in r.tagged("pulse")]
    return pulses, [int(x) for x in r.tagged("widths")[-1].split()]


def test_pulse_widths_in_tenths_of_a_microsecond(tool: Tool) -> None:
    # 10 MHz counter: 1500.3 us is 15003 ticks; four channels, each its own width
    edges = []
    for ch, w in enumerate((15003, 10000, 20000, 12345)):
        edges += [(ch, 1, 1000, 100), (ch, 0, 1000 + w, 100 + w // 10)]
    pulses, widths = pwm(tool, "32 10000000 500 2500 1000 100000", edges, 3000)
    assert pulses == [0, 1] * 4 and widths == [15003, 10000, 20000, 12345]


@pytest.mark.parametrize("bits", [16, 32])
def test_a_counter_that_wraps_inside_a_pulse_still_gives_its_width(tool: Tool, bits: int) -> None:
    top = (1 << bits) - 1
    rise = top - 4999  # 5000 ticks to the wrap (at 0), 10000 after it
    edges = [(0, 1, rise, 1000), (0, 0, 10000, 2500)]
    pulses, widths = pwm(tool, f"{bits} 10000000 500 2500 1000 100000", edges, 2600)
    assert pulses == [0, 1] and widths[0] == 15000


def test_glitches_are_filtered_and_counted(tool: Tool) -> None:
    init = "32 1000000 500 2500 1000 100000"  # 1 MHz: ticks are microseconds
    edges = [
        (0, 1, 0, 0), (0, 0, 1500, 1500),             # good: 1500 us
        (0, 1, 3000, 3000), (0, 0, 3300, 3300),       # too short (300 us): glitch
        (0, 1, 5000, 5000), (0, 0, 6000, 6000),       # good: 1000 us, 5000 us after the last good start
        (0, 1, 6500, 6500), (0, 1, 7000, 7000),       # a rise while high (a fall was lost): glitch
        (0, 0, 7400, 7400),                           # its width counts from the second rise: 400, glitch
        (0, 0, 7600, 7600),                           # a fall with no rise: glitch
        (0, 1, 9000, 9000), (0, 0, 12000, 12000),     # too long (3000 us): glitch
        (0, 1, 13000, 13000), (0, 0, 13600, 13600),   # good: 600 us
        (0, 1, 13800, 13800), (0, 0, 15000, 15000),   # 800 us after the last good start: glitch
    ]
    r = run(tool, [f"pwm_init {init}", *[f"pwm_edge {c} {lv} {n} {t}" for c, lv, n, t in edges],
                   "pwm_widths 15100", "pwm_widths 200000"])
    assert [int(x) for x in r.tagged("pulse")] == [0, 1, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0]
    assert r.tagged("pwm")[-1] == "3 6"  # 3 good pulses, 6 glitches
    assert r.tagged("widths") == ["6000 0 0 0", "0 0 0 0"]  # the last good one; stale 100 ms later


def test_can_capture_frames_agree_byte_for_byte_with_the_dbc_codec(tool: Tool) -> None:
    """With a CAN port the core sends the DBC's two capture frames with each PULSES (the firmware's
    capture-only mode is only that): each equal to what emulators/pwm_capture.py's CanCodec encodes from
    the same widths and the frame's sequence, which counts up one per pair."""
    rng = random.Random(19)
    s = Script().t(0).hello().cmd("poll")
    for k in range(40):  # 400 Hz, 10 MHz counter, widths 1000..2000 us to the 0.1 us
        t0 = 2500 * k + 10
        for ch in range(4):
            w = rng.randrange(10000, 20001)
            s.cmd(f"edge {ch} 1 {t0 * 10} {t0}", f"edge {ch} 0 {t0 * 10 + w} {t0 + w // 10}")
        s.t(t0 + 2300).cmd("poll")
    r = run(tool, s.lines)
    pulses = [list(m["width_tenth_us"]) for m in r.named("PULSES")]  # type: ignore[call-overload]
    can = [tuple(line.split()) for line in r.tagged("can")]
    codec = pwm_capture.CanCodec()
    assert len(can) == 2 * len(pulses) and len(pulses) > 30
    want = [(f"{fid:03x}", data.hex()) for seq, w in enumerate(pulses)
            for fid, data in codec.encode(seq % 256, [x * pwm_capture.UNIT_US for x in w])]
    assert can == want
    assert codec.decode(0x211, bytes.fromhex(can[-1][1]))[1] == (len(pulses) - 1) % 256


# ---------------------------------------------------------------- SBUS


def test_sbus_frames_agree_byte_for_byte_with_the_python_encoder(tool: Tool) -> None:
    rng = random.Random(5)
    cases = [([rng.randrange(2048) for _ in range(16)], rng.choice([0, 4, 8, 12])) for _ in range(200)]
    cases += [([0] * 16, 0), ([2047] * 16, 12), (sbus.Sticks(throttle=0.5, arm=True).channels(), 0)]
    r = run(tool, [f"sbus_encode {' '.join(map(str, ch))} {fl}" for ch, fl in cases])
    want = [sbus.encode(ch, bool(fl & 4), bool(fl & 8)).hex() for ch, fl in cases]
    assert r.tagged("frame") == want


def test_sbus_goes_out_at_its_period_and_a_full_uart_drops_counted_bytes(tool: Tool) -> None:
    ch = sbus.Sticks(roll=0.3, throttle=0.6, arm=True).channels()
    s = Script().t(1000).hello().send("CONFIG", topology=0, mpu_addr=0x68, hmc_addr=0x1E, baro_addr=0x77,
                                      sbus_period_ms=7, capture_channels=4)
    s.send("SBUS", channels=ch, flags=0)
    for t in range(1000, 1000 + 7000 * 5, 1000):  # polled every ms for 35 ms: frames at 0, 7, .. 28 ms
        s.t(t).cmd("poll")
    s.cmd("sbus_limit 20").t(36000).cmd("poll", "status")
    r = run(tool, s.lines)
    frames = r.tagged("sbus")
    assert frames[:5] == [sbus.encode(ch).hex()] * 5 and frames[5] == sbus.encode(ch).hex()[:40]
    assert r.status()["sbus_dropped"] == 5


def test_sbus_frames_say_frame_lost_then_failsafe_while_the_host_is_silent(tool: Tool) -> None:
    ch = sbus.Sticks(throttle=0.5).channels()
    s = Script().t(0).hello().send("SBUS", channels=ch, flags=0).cmd("poll")
    s.t(HOST_SILENT_US + 14_000).cmd("poll").t(1_000_000 + 28_000).cmd("poll")
    s.t(1_000_000 + 42_000).send("HEARTBEAT").cmd("poll")
    r = run(tool, s.lines)
    assert r.tagged("sbus") == [sbus.encode(ch).hex(), sbus.encode(ch, frame_lost=True).hex(),
                                sbus.encode(ch, frame_lost=True, failsafe=True).hex(), sbus.encode(ch).hex()]


# ---------------------------------------------------------------- dispatch


def test_hello_is_answered_and_another_version_is_refused_with_nothing_applied(tool: Tool) -> None:
    s = Script().t(10).hello(version=PROTOCOL_VERSION + 1)
    s.send("IMU_SAMPLE", valid_us=0, **SAMPLE).xfer(20_000, 0x68, WAKE, 0).t(30).cmd("poll", "status")
    s.xfer(3_000_000, 0x68, b"\x3b", 14)  # the sample was not applied: no sample yet, all quantities 0
    s.t(40).hello().send("IMU_SAMPLE", valid_us=3000, **SAMPLE).cmd("status")
    s.xfer(4_000_000, 0x68, b"\x3b", 14)
    r = run(tool, s.lines)
    replies = r.named("HELLO_REPLY")
    assert [m["version"] for m in replies] == [PROTOCOL_VERSION, PROTOCOL_VERSION]
    name = replies[0]["bridge_id"]
    assert isinstance(name, list) and bytes(name).rstrip(b"\0") == b"bridge_tool"
    assert replies[0]["nonce"] == 0xC0FFEE
    first, second = r.tagged("status")
    assert "refused 1 " in first and "agreed 0" in first  # the sample, refused
    assert "refused 0 " in second and "agreed 1" in second and "ok 2 " in second  # counters start again
    applied = accel_bytes((0.5, -0.25, -G), 30.0, (0.1, -0.2, 0.05)).hex()
    # awake with nothing pushed, the chip holds the zero sample: 0 m/s², 0 rad/s and a 0 °C die (TEMP_OUT
    # is not 0: docs/sensors.md §3.4's offset); the data registers read all zeros only while asleep (§3.6)
    assert r.tagged("xfer ok")[1:] == [accel_bytes((0, 0, 0), 0.0, (0, 0, 0)).hex(), applied]


def test_imu_samples_become_register_bytes_at_their_valid_time(tool: Tool) -> None:
    s = Script().t(0).hello().xfer(1000, 0x68, WAKE, 0)
    s.send("IMU_SAMPLE", valid_us=1000, **SAMPLE)
    s.send("IMU_SAMPLE", valid_us=2000, accel=[1.0, 2.0, 3.0], gyro=[0, 0, 0], temp_c=25.0)
    s.xfer(1_500_000, 0x68, b"\x3b", 14).xfer(2_500_000, 0x68, b"\x3b", 14).xfer(2_600_000, 0x68, b"\x75", 1)
    r = run(tool, s.lines)
    assert r.tagged("xfer ok") == ["", accel_bytes((0.5, -0.25, -G), 30.0, (0.1, -0.2, 0.05)).hex(),
                                   accel_bytes((1.0, 2.0, 3.0), 25.0, (0, 0, 0)).hex(), "68"]


def test_a_sample_encoded_ahead_is_encoded_again_when_the_range_changed(tool: Tool) -> None:
    """The tool encodes each sample ahead as it arrives (bridge_idle, as the firmware's main loop), under
    the ranges of that moment; the board then sets ±8 g and ±1000 °/s before the sample's instant, and
    the bytes it reads are the new ranges' (the copy made ahead is not used)."""
    s = Script().t(0).hello().xfer(1000, 0x68, WAKE, 0).xfer(2000, 0x68, bytes([0x1A, 0x01]), 0)
    s.send("IMU_SAMPLE", valid_us=5000, **SAMPLE)  # encoded ahead at ±2 g, ±250 °/s
    s.xfer(3_000_000, 0x68, bytes([0x1B, 0x10, 0x10]), 0)  # GYRO_CONFIG ±1000 °/s, ACCEL_CONFIG ±8 g
    s.xfer(6_000_000, 0x68, b"\x3b", 14)
    r = run(tool, s.lines)
    a = [round(x / G * 4096) for x in SAMPLE["accel"]]  # type: ignore[attr-defined]
    g = [round(x * 57.29578 * 32.8) for x in SAMPLE["gyro"]]  # type: ignore[attr-defined]
    assert r.tagged("xfer ok")[-1] == struct.pack(">7h", *a, round((30.0 - 36.53) * 340), *g).hex()


def test_a_held_sample_is_encoded_again_under_a_new_range(tool: Tool) -> None:
    """With no new sample the chip holds the last one (its bytes kept once encoded, so an instant copies
    them): a range changed since gives the held sample under the new range, not the kept bytes."""
    s = Script().t(0).hello().xfer(1000, 0x68, WAKE, 0).send("IMU_SAMPLE", valid_us=0, **SAMPLE)
    s.xfer(1_000_000, 0x68, b"\x3b", 14).xfer(2_000_000, 0x68, b"\x3b", 14)  # held: the kept bytes
    s.xfer(3_000_000, 0x68, bytes([0x1B, 0x10, 0x10]), 0).xfer(4_000_000, 0x68, b"\x3b", 14).cmd("status")
    r = run(tool, s.lines)
    a = [round(x / G * 4096) for x in SAMPLE["accel"]]  # type: ignore[attr-defined]
    g = [round(x * 57.29578 * 32.8) for x in SAMPLE["gyro"]]  # type: ignore[attr-defined]
    first, held, ranged = r.tagged("xfer ok")[1], r.tagged("xfer ok")[2], r.tagged("xfer ok")[4]
    assert first == held == accel_bytes((0.5, -0.25, -G), 30.0, (0.1, -0.2, 0.05)).hex()
    assert ranged == struct.pack(">7h", *a, round((30.0 - 36.53) * 340), *g).hex()
    assert r.status()["imu_underruns"] > 0


def test_a_burst_read_never_mixes_two_samples(tool: Tool) -> None:
    """Sample B becomes valid in the middle of a 14-byte burst: the burst reads A whole, the next B."""
    s = Script().t(0).hello().xfer(1000, 0x68, WAKE, 0)
    s.send("IMU_SAMPLE", valid_us=1000, accel=[1, 1, 1], gyro=[0, 0, 0], temp_c=20)
    s.send("IMU_SAMPLE", valid_us=2000, accel=[-3, -3, -3], gyro=[1, 1, 1], temp_c=40)
    # the read starts at 1.9975 ms: its 14 bytes at 400 kHz take 0.32 ms, across 2.0 ms
    s.xfer(1_950_000, 0x68, b"\x3b", 14).xfer(2_400_000, 0x68, b"\x3b", 14)
    r = run(tool, s.lines)
    a = accel_bytes((1, 1, 1), 20, (0, 0, 0)).hex()
    b = accel_bytes((-3, -3, -3), 40, (1, 1, 1)).hex()
    assert r.tagged("xfer ok")[1:] == [a, b]


def test_register_writes_go_up_so_the_host_follows_the_configuration(tool: Tool) -> None:
    s = Script().t(0).hello()
    s.xfer(1000, 0x68, bytes([0x1A, 0x03, 0x18, 0x08]), 0)  # CONFIG=3, GYRO_CONFIG=0x18, ACCEL_CONFIG=8
    s.xfer(2_000_000, 0x77, bytes([0x48]), 0)  # MS5611: convert D1 at OSR 4096
    s.xfer(3_000_000, 0x42, bytes([0x01, 0x02]), 0)  # nobody there: nothing goes up
    r = run(tool, s.lines)
    writes = [(m["addr"], m["reg"], m["value"]) for m in r.named("REG_WRITE")]
    assert writes == [(0x68, 0x1A, 0x03), (0x68, 0x1B, 0x18), (0x68, 0x1C, 0x08), (0x77, 0x48, 0)]
    assert r.lines.count("xfer nack") == 1


def test_bypass_enables_the_magnetometer_and_its_samples_are_read(tool: Tool) -> None:
    s = Script().t(0).hello().xfer(1000, 0x1E, b"\x0a", 3)  # behind the MPU: absent
    s.xfer(2000, 0x68, bytes([0x6B, 0x00]), 0).xfer(100_000, 0x68, bytes([0x37, 0x02]), 0)
    s.send("MAG_SAMPLE", valid_us=0, field=[0.3, -0.1, 0.4]).t(200).cmd("poll")
    # the power-on single measurement completes 56 ms after power-up (docs/sensors.md §4.6): read after it
    s.xfer(60_000_000, 0x1E, b"\x0a", 3).xfer(61_000_000, 0x1E, b"\x03", 6)
    r = run(tool, s.lines)
    assert r.lines.count("xfer nack") == 1 and "addr 1e 1" in r.lines
    x, y, z = (round(v * 1090) for v in (0.3, -0.1, 0.4))  # CRB default: gain 1090 LSB/G
    assert r.tagged("xfer ok")[-2:] == ["483433", struct.pack(">3h", x, z, y).hex()]


def test_a_field_encoded_ahead_is_encoded_again_at_a_new_gain(tool: Tool) -> None:
    """The field is encoded ahead as it arrives (bridge_idle) at the effective gain, 1090 LSB/G. The board
    sets CRB to 390 LSB/G: the next single measurement still uses 1090 (a new gain counts from the one
    after, datasheet), the one after that 390, from the same sample (its copy made ahead not used)."""
    s = Script().t(0).hello().xfer(2000, 0x68, WAKE, 0).xfer(100_000, 0x68, bytes([0x37, 0x02]), 0)
    s.send("MAG_SAMPLE", valid_us=0, field=[0.3, -0.1, 0.4])
    s.xfer(61_000_000, 0x1E, bytes([0x01, 0xA0]), 0)  # CRB: gain 5, 390 LSB/G
    s.xfer(62_000_000, 0x1E, bytes([0x02, 0x01]), 0).xfer(72_000_000, 0x1E, b"\x03", 6)  # single, read
    s.xfer(73_000_000, 0x1E, bytes([0x02, 0x01]), 0).xfer(83_000_000, 0x1E, b"\x03", 6)  # single, read
    r = run(tool, s.lines)

    def xzy(gain: int) -> str:
        x, y, z = (round(v * gain) for v in (0.3, -0.1, 0.4))
        return struct.pack(">3h", x, z, y).hex()

    assert r.tagged("xfer ok")[-3::2] == [xzy(1090), xzy(390)]


def test_barometer_words_are_given_by_the_conversion_the_board_started(tool: Tool) -> None:
    s = Script().t(0).hello().send("BARO_SAMPLE", valid_us=0, d1=0x812345, d2=0x7A0B0C)
    s.xfer(1_000_000, 0x77, b"\x48", 0).xfer(20_000_000, 0x77, b"\x00", 3)  # D1 at OSR 4096
    s.xfer(21_000_000, 0x77, b"\x52", 0).xfer(40_000_000, 0x77, b"\x00", 3)  # D2 at OSR 512
    s.xfer(41_000_000, 0x77, b"\xa2", 0).xfer(42_000_000, 0x77, b"", 2)  # PROM word 1
    r = run(tool, s.lines)
    assert r.tagged("xfer ok")[1::2] == ["812345", "7a0b0c", f"{40127:04x}"]


def test_time_sync_is_answered_with_the_bridge_times(tool: Tool) -> None:
    r = run(tool, Script().t(5).hello().t(123_456).send("TIME_SYNC", id=77, host_ns=999).lines)
    assert r.named("TIME_SYNC_REPLY") == [{"id": 77, "rx_us": 123_456, "tx_us": 123_456}]


def test_a_time_sync_reply_is_stamped_when_it_leaves_not_when_it_was_queued(tool: Tool) -> None:
    """The reply is framed by the main loop after the frame was taken in: tx_us is that moment (the host's
    offset estimate assumes the reply left at tx_us)."""
    r = run(tool, Script().t(5).hello().t(100).queue("TIME_SYNC", id=3, host_ns=1).t(250).cmd("idle").lines)
    assert r.named("TIME_SYNC_REPLY") == [{"id": 3, "rx_us": 100, "tx_us": 250}]


def test_frames_are_framed_with_the_lock_released_and_every_lock_is_undone(tool: Tool) -> None:
    """On the STM32 the lock masks the I2C interrupt: framing (CRC, COBS) under it would hold a byte of the
    board's bus up. The tool's HAL prints "lock error" for a frame given to the link under the lock and
    for a call that returns with it held; every kind of message and bus event goes through here."""
    s = Script().t(0).hello().send("CONFIG", topology=0, mpu_addr=0x68, hmc_addr=0x1E, baro_addr=0x77,
                                   sbus_period_ms=7, capture_channels=4, trace=1)
    s.send("IMU_SAMPLE", valid_us=1000, **SAMPLE).send("MAG_SAMPLE", valid_us=1000, field=[0.2, 0.0, 0.4])
    s.send("BARO_SAMPLE", valid_us=1000, d1=9_000_000, d2=8_000_000).send("TIME_SYNC", id=1, host_ns=2)
    s.send("FAULT", target=6, kind=6, start_us=50_000, end_us=60_000).send("HEARTBEAT")
    s.send("SBUS", channels=[992] * 16).xfer(1000, 0x68, WAKE + b"\x00", 0)
    s.xfer(1_500_000, 0x68, bytes([0x37, 0x02]), 0).xfer(2_000_000, 0x68, b"\x3b", 14)  # bypass on
    s.xfer(2_500_000, 0x1E, bytes([0x02, 0x00]), 0).xfer(3_000_000, 0x77, b"\x48", 0)
    s.cmd("edge 0 1 100 10", "edge 0 0 15100 11", "start 3500000 68 1", "rd 3500100", "unread",
          "stop 3500200").t(5000).queue("TIME_SYNC", id=2, host_ns=3).cmd("poll", "status", "locks")
    r = run(tool, s.lines)
    assert [line for line in r.lines if "lock error" in line] == []
    assert int(r.tagged("locks")[0]) >= 20
    names = {m.name for m in r.up()}
    assert {"HELLO_REPLY", "TIME_SYNC_REPLY", "REG_WRITE", "TRACE", "PULSES", "STATUS"} <= names


def test_a_full_outbox_drops_whole_messages_and_the_host_sees_the_gap(tool: Tool) -> None:
    """40 register writes in one burst, with no main loop between them, meet the 32 places of the
    outbox: 32 go up whole, 8 are dropped, and their sequence numbers are spent, so the host counts
    the gap."""
    s = Script().t(0).hello().xfer(1000, 0x68, b"\x0d" + bytes(40), 0).cmd("poll")
    r = run(tool, s.lines)
    rx = Receiver("up")
    got = [m for line in r.tagged("up") for m in rx.feed(bytes.fromhex(line))]
    writes = [m for m in got if m.name == "REG_WRITE"]
    assert [m.values["reg"] for m in writes] == list(range(0x0D, 0x0D + 32))
    status = [m for m in got if m.name == "STATUS"]
    assert status[0].seq == writes[-1].seq + 9 and rx.seq_gaps == 1 and rx.bad == 0


def test_a_bus_fault_nacks_its_chip_in_its_window_and_counts(tool: Tool) -> None:
    s = Script().t(0).hello()
    s.send("FAULT", target=4, kind=6, start_us=1000, end_us=2000)  # mpu off 1..2 ms
    s.send("FAULT", target=0, kind=6, start_us=1000, end_us=2000)  # accel: a signal fault, not the bridge's
    s.send("FAULT", target=4, kind=7, start_us=2000, end_us=1000)  # ends before it starts
    for t in (500, 1500, 1900, 2500):
        s.xfer(t * 1000, 0x68, b"\x75", 1)
    s.cmd("status")
    r = run(tool, s.lines)
    assert r.tagged("xfer ok") == ["68", "68"] and r.lines.count("xfer nack") == 2
    st = r.status()
    assert st["i2c_errors"] == 2 and st["refused"] == 2


def test_a_fifo_burst_read_one_byte_ahead_gives_that_byte_back(tool: Tool) -> None:
    """The tool reads like the STM32's target: one byte more than the master takes, given back at its
    NACK (bridge_i2c_unread). Six FIFO bytes read as 5 + 1 are the sample's accelerometer, in order,
    and FIFO_COUNT goes down by exactly six."""
    s = Script().t(0).hello().xfer(1000, 0x68, WAKE, 0).send("IMU_SAMPLE", valid_us=0, **SAMPLE)
    s.xfer(2000, 0x68, bytes([0x1A, 0x01]), 0)  # DLPF 1: 1 kHz samples
    s.xfer(3000, 0x68, bytes([0x6A, 0x40]), 0).xfer(4000, 0x68, bytes([0x23, 0x08]), 0)  # FIFO on: accel
    s.xfer(10_500_000, 0x68, b"\x72", 2).xfer(10_600_000, 0x68, b"\x74", 5)
    s.xfer(10_700_000, 0x68, b"\x74", 1).xfer(10_800_000, 0x68, b"\x72", 2)
    r = run(tool, s.lines)
    before, five, one, after = (bytes.fromhex(x) for x in r.tagged("xfer ok")[-4:])
    assert int.from_bytes(before, "big") >= 12 and int.from_bytes(before, "big") % 6 == 0
    assert int.from_bytes(after, "big") == int.from_bytes(before, "big") - 6
    assert five + one == accel_bytes(tuple(SAMPLE["accel"]), 30.0, (0, 0, 0))[:6]  # type: ignore[arg-type]


# ---- a target that does not stretch SCL (hal.h i2c_preload): each read's first byte held before its address


def mixed_traffic(s: Script) -> Script:
    """Reads of every kind from all three chips: repeated START and STOP-separated, bursts, FIFO, the
    magnetometer through the MPU's bypass, the barometer's PROM and conversions, with samples."""
    s.t(0).hello().send("IMU_SAMPLE", valid_us=1000, **SAMPLE)
    s.send("IMU_SAMPLE", valid_us=2000, accel=[1.0, 2.0, 3.0], gyro=[0, 0, 0], temp_c=25.0)
    s.send("MAG_SAMPLE", valid_us=0, field=[0.2, -0.1, 0.4]).send("BARO_SAMPLE", valid_us=0, d1=0x812345,
                                                                   d2=0x7A0B0C)
    s.xfer(500_000, 0x68, WAKE, 0).xfer(600_000, 0x68, b"\x75", 1).xfer(700_000, 0x68, bytes([0x37, 0x02]), 0)
    s.xfer(1_500_000, 0x68, b"\x3b", 14).xfer(1_600_000, 0x68, b"\x43", 0).xfer(1_700_000, 0x68, b"", 6)
    s.t(2000).cmd("poll").xfer(2_500_000, 0x68, b"\x3b", 14)
    s.xfer(3_000_000, 0x1E, bytes([0x02, 0x00]), 0).t(10_000).cmd("poll").xfer(10_000_000, 0x1E, b"\x03", 6)
    s.xfer(10_100_000, 0x1E, b"\x0a", 3).xfer(11_000_000, 0x77, b"\x48", 0).t(30_000).cmd("poll")
    s.xfer(30_000_000, 0x77, b"\x00", 0).xfer(30_100_000, 0x77, b"", 3).xfer(31_000_000, 0x77, b"\xa2", 2)
    return s.cmd("status")


def test_without_stretching_every_read_gives_the_bytes_it_gives_with(tool: Tool) -> None:
    """The same traffic with the first bytes preloaded (as the STM32 in NOSTRETCH mode must: it sends a
    read's first byte as it acknowledges the address) gives the same bytes, with no miss."""
    plain = run(tool, mixed_traffic(Script()).lines)
    preloaded = run(tool, mixed_traffic(Script().cmd("nostretch")).lines)
    assert len(plain.tagged("xfer ok")) == 14 and plain.lines.count("xfer nack") == 0
    assert preloaded.tagged("xfer ok") == plain.tagged("xfer ok")
    assert preloaded.status()["preload_misses"] == 0 and len(preloaded.tagged("pre")) > 20
    assert plain.status()["i2c_errors"] == preloaded.status()["i2c_errors"] == 0


def burst_across_an_instant(stop_between: bool) -> Script:
    """Sample A valid at 1 ms, B at 2 ms (the MPU samples every 125 us from its wake-up at about 0.1 ms:
    B is taken at 2.1 ms); the board sets the pointer at 1.95 ms and reads 14 bytes at 2.2 ms, after a
    poll at 2.15 ms, with a repeated START or a STOP between."""
    s = Script().t(0).cmd("nostretch").hello().xfer(100_000, 0x68, WAKE, 0)
    s.send("IMU_SAMPLE", valid_us=1000, accel=[1, 1, 1], gyro=[0, 0, 0], temp_c=20)
    s.send("IMU_SAMPLE", valid_us=2000, accel=[-3, -3, -3], gyro=[1, 1, 1], temp_c=40)
    s.t(1950).cmd("poll", "start 1950000 68 0", "wr 1952500 3b", *(["stop 1955000"] if stop_between else []))
    s.t(2150).cmd("poll", "start 2200000 68 1", *(f"rd {2202500 + 22500 * i}" for i in range(13)), "unread",
                  "stop 2500000", "status")
    return s


def test_a_read_after_a_repeated_start_is_the_instant_its_first_byte_was_taken(tool: Tool) -> None:
    """The transaction is open from its first START: the poll holds the chips' time (the MPU-6050 holds
    its data registers while its serial interface is busy), so the preloaded first byte and the 13
    after it are sample A's, though B's instant passed before the repeated START."""
    r = run(tool, burst_across_an_instant(stop_between=False).lines)
    assert bytes(int(x, 16) for x in r.tagged("rd")) == accel_bytes((1, 1, 1), 20, (0, 0, 0))
    assert r.status()["preload_misses"] == 0


def test_a_read_after_a_stop_is_preloaded_again_when_time_moves(tool: Tool) -> None:
    """With a STOP between, the poll after B's instant advances the chips and preloads again: the read is
    B's whole."""
    r = run(tool, burst_across_an_instant(stop_between=True).lines)
    assert bytes(int(x, 16) for x in r.tagged("rd")) == accel_bytes((-3, -3, -3), 40, (1, 1, 1))
    assert r.status()["preload_misses"] == 0


def test_a_read_from_the_address_not_expected_is_a_counted_miss(tool: Tool) -> None:
    """Port 0 answers the MPU-6050 and the MS5611 and expects a read from the one it answered last: a
    PROM read from the MS5611 straight after an MPU transaction gets the MPU's byte first (counted),
    then the MS5611's second byte, and the next read from it is right. A port that could not take
    its byte (busy) makes the same kind of miss, counted as well."""
    s = Script().t(0).cmd("nostretch").hello().xfer(100_000, 0x77, b"\xa2", 0).xfer(200_000, 0x68, b"\x75", 1)
    s.xfer(300_000, 0x77, b"", 2).xfer(400_000, 0x77, b"\xa2", 0).xfer(500_000, 0x77, b"", 2)
    s.cmd("busy 0 1").xfer(600_000, 0x68, b"\x75", 0).xfer(700_000, 0x68, b"", 1).cmd("busy 0 0", "status")
    r = run(tool, s.lines)
    # the MPU's pointer wraps from WHO_AM_I to 0x00, which reads 0; PROM word 1 is 40127 (0x9cbf); the
    # busy port still holds the MS5611's byte after its PROM word (0), not WHO_AM_I's 0x68
    assert r.tagged("xfer ok") == ["", "68", "00bf", "", f"{40127:04x}", "", "00"]
    assert r.status()["preload_misses"] == 2


def test_a_bus_fault_turns_the_targets_address_off_for_its_window(tool: Tool) -> None:
    """The STM32's target ACKs its own addresses in hardware: the core turns a silent chip's address
    off at the poll (and on again after), so the board sees a NACK as from the real chip."""
    s = Script().t(0).hello().cmd("poll")
    s.send("FAULT", target=4, kind=6, start_us=1000, end_us=2000)  # mpu off 1..2 ms
    # the barometer silent for the first 20 us of each 50 us, from 3 to 3.1 ms
    s.send("FAULT", target=6, kind=7, start_us=3000, end_us=3100, period_s=50e-6, duty=0.4)
    s.t(1500).cmd("poll").t(2500).cmd("poll")
    s.t(3010).cmd("poll").t(3030).cmd("poll").t(3500).cmd("poll")
    r = run(tool, s.lines)
    addr = [line for line in r.lines if line.startswith("addr")]
    assert addr == ["addr 68 1", "addr 77 1",  # at start
                    "addr 68 0", "addr 68 1", "addr 77 0", "addr 77 1"]


def test_out_of_range_values_are_refused_whole(tool: Tool) -> None:
    s = Script().t(0).hello()
    s.send("CONFIG", topology=2, mpu_addr=0x68, hmc_addr=0x1E, baro_addr=0x77, sbus_period_ms=14)
    s.send("IMU_SAMPLE", valid_us=0, accel=[float("nan"), 0, 0], gyro=[0, 0, 0], temp_c=20)
    s.send("SBUS", channels=[2048] + [992] * 15).send("SBUS", channels=[992] * 16, flags=0x10)
    s.send("BARO_SAMPLE", valid_us=0, d1=1 << 24).cmd("poll", "status")
    s.xfer(1000, 0x68, WAKE, 0).xfer(2_000_000, 0x68, b"\x3b", 6)
    r = run(tool, s.lines)
    assert r.status()["refused"] == 5 and r.tagged("sbus") == []
    assert r.tagged("xfer ok")[-1] == bytes(6).hex()
    assert not any(line.startswith("addr") for line in r.lines[3:])  # CONFIG did not reset the addresses


def test_config_direct_topology_puts_the_magnetometer_on_the_bus(tool: Tool) -> None:
    s = Script().t(0).hello().send("CONFIG", topology=1, mpu_addr=0x69, hmc_addr=0x1E, baro_addr=0x76,
                                   sbus_period_ms=14, capture_channels=4)
    s.xfer(1000, 0x1E, b"\x0a", 3).xfer(2_000_000, 0x69, b"\x75", 1).xfer(3_000_000, 0x68, b"\x75", 1)
    r = run(tool, s.lines)
    assert {"addr 69 1", "addr 76 1", "addr 1e 1"} <= set(r.lines)
    assert r.tagged("xfer ok") == ["483433", "68"] and r.lines.count("xfer nack") == 1


def test_late_samples_are_counted(tool: Tool) -> None:
    s = Script().t(5000).hello().send("IMU_SAMPLE", valid_us=4000, **SAMPLE)
    s.send("IMU_SAMPLE", valid_us=6000, **SAMPLE).send("MAG_SAMPLE", valid_us=10, field=[0, 0, 0])
    s.cmd("status")
    assert run(tool, s.lines).status()["late"] == 2


def test_a_silent_host_is_flagged_the_samples_held_and_the_board_answered(tool: Tool) -> None:
    s = Script().t(0).hello().xfer(0, 0x68, bytes([0x1A, 0x01]), 0).xfer(0, 0x68, WAKE, 0)  # DLPF 1: 1 kHz
    for k in range(50):  # 50 ms of 1 kHz samples, streamed 2 ms ahead
        s.t(max(0, 1000 * k - 2000)).send("IMU_SAMPLE", valid_us=1000 * k, accel=[0, 0, -G], gyro=[0, 0, 0],
                                          temp_c=25 + k * 0.1).cmd("poll")
    s.t(49_000).send("HEARTBEAT").cmd("poll", "status")
    s.t(49_000 + HOST_SILENT_US - 1000).cmd("poll", "status")
    s.t(49_000 + HOST_SILENT_US + 1000).cmd("poll", "status").xfer(150_000_000, 0x68, b"\x3b", 14)
    s.t(200_000).send("HEARTBEAT").cmd("poll", "status")
    r = run(tool, s.lines)
    st = r.tagged("status")
    assert [" silent 1 " in x for x in st] == [False, False, True, False]
    # the sample instants run at 1 kHz from the first sample (the chip core sets their phase): every
    # instant after the last sample's (49 ms) held it and counted an underrun: 50 .. 148 ms, .. 150, .. 200
    held = [int(x.split()[1]) for x in st]
    assert held[0] == 0 and held[1] in (98, 99) and held[2] - held[1] == 2 and held[3] - held[2] == 50
    assert r.tagged("xfer ok")[-1] == accel_bytes((0, 0, -G), 25 + 49 * 0.1, (0, 0, 0)).hex()
    statuses = r.named("STATUS")
    assert any(m["host_silent"] == 1 for m in statuses) and statuses[-1]["host_silent"] == 0


def test_pulses_go_up_with_their_widths(tool: Tool) -> None:
    s = Script().t(0).hello().cmd("poll")
    for k in range(3):  # 400 Hz, 10 MHz counter: channel widths 1100, 1200, 1300, 1400 us
        t0 = 2500 * k + 10
        for ch in range(4):
            t1 = t0 + 1100 + 100 * ch
            s.cmd(f"edge {ch} 1 {t0 * 10} {t0}", f"edge {ch} 0 {t1 * 10} {t1}")
        s.t(t0 + 2000).cmd("poll")
    r = run(tool, s.lines)
    pulses = r.named("PULSES")
    assert pulses[-1]["width_tenth_us"] == [11000, 12000, 13000, 14000]
    assert pulses[-1]["t_us"] == 5010 + 1400


def oneshot_pulses(limits: dict[str, int]) -> list[str]:
    """Three OneShot125 rounds at 2 kHz (125..245 us on the four inputs) after CONFIG with ``limits``."""
    s = Script().t(0).hello().send("CONFIG", topology=0, mpu_addr=0x68, hmc_addr=0x1E, baro_addr=0x77,
                                   sbus_period_ms=14, capture_channels=4, **limits).cmd("poll")
    for k in range(3):
        t0 = 500 * k + 10
        for ch in range(4):
            t1 = t0 + 125 + 40 * ch
            s.cmd(f"edge {ch} 1 {t0 * 10} {t0}", f"edge {ch} 0 {t1 * 10 + 3} {t1}")
        s.t(t0 + 400).cmd("poll")
    return s.lines + ["status"]


def test_oneshot125_pulses_are_captured_once_config_gives_their_limits(tool: Tool) -> None:
    esc = ESC_PROTOCOLS["oneshot125"]
    oneshot = {"pulse_min_us": esc.pulse_min_us, "pulse_max_us": esc.pulse_max_us,
               "period_min_us": esc.period_min_us}
    r = run(tool, oneshot_pulses(oneshot))
    assert r.named("PULSES")[-1]["width_tenth_us"] == [1253, 1653, 2053, 2453]
    assert r.status()["refused"] == 0 and r.status()["glitches"] == 0
    r = run(tool, oneshot_pulses({}))  # the defaults (standard PWM, 500..2500 us): each one a glitch
    assert all(p["width_tenth_us"] == [0, 0, 0, 0] for p in r.named("PULSES"))
    assert r.status()["glitches"] == 12
    for bad in ({"pulse_min_us": 300, "pulse_max_us": 200, "period_min_us": 1000},
                {"pulse_min_us": 0, "pulse_max_us": 200, "period_min_us": 1000},
                {"pulse_min_us": 100, "pulse_max_us": 200, "period_min_us": 0}):
        assert run(tool, oneshot_pulses(bad)).status()["refused"] == 1, bad


# ---------------------------------------------------------------- fuzz


def plausible(name: str, rng: random.Random) -> dict[str, object]:
    """Values a host might send, now and then out of range."""
    if name == "HELLO":
        version = PROTOCOL_VERSION if rng.random() < 0.9 else rng.randrange(65536)
        return {"version": version, "nonce": rng.randrange(9)}
    if name == "CONFIG":
        return {"topology": rng.choice([0, 0, 1, 2]), "mpu_addr": rng.choice([0x68, 0x69]), "hmc_addr": 0x1E,
                "baro_addr": rng.choice([0x77, 0x76, 0x10]), "sbus_period_ms": rng.choice([7, 14, 200]),
                "capture_channels": rng.randrange(6), "trace": rng.randrange(2)}
    if name == "IMU_SAMPLE":
        return {"valid_us": rng.randrange(0, 400_000), "accel": [rng.uniform(-20, 20) for _ in range(3)],
                "gyro": [rng.uniform(-5, 5) for _ in range(3)], "temp_c": rng.uniform(0, 40)}
    if name == "MAG_SAMPLE":
        return {"valid_us": rng.randrange(0, 400_000), "field": [rng.uniform(-1, 1) for _ in range(3)]}
    if name == "BARO_SAMPLE":
        return {"valid_us": rng.randrange(400_000), "d1": rng.randrange(1 << 24),
                "d2": rng.randrange(1 << 25)}
    if name == "SBUS":
        return {"channels": [rng.randrange(2100) for _ in range(16)], "flags": rng.choice([0, 4, 8, 16])}
    if name == "TIME_SYNC":
        return {"id": rng.randrange(1 << 32), "host_ns": rng.randrange(1 << 40)}
    if name == "FAULT":
        start = rng.randrange(400_000)
        return {"target": rng.randrange(8), "kind": rng.randrange(10), "start_us": start,
                "end_us": start + rng.randrange(-1000, 50_000), "period_s": rng.uniform(-0.01, 0.02),
                "duty": rng.uniform(-0.2, 1.2)}
    return {}


def observable(r: Run) -> list[object]:
    """What the board and the host see, less the link's own counters (which differ: one run saw the bad
    frames)."""
    out: list[object] = []
    for line in r.lines:
        if line.startswith(("up ", "status ")):
            continue
        out.append(line)
    for m in r.up():
        v = dict(m.values)
        if m.name == "STATUS":
            for k in ("frames_ok", "frames_bad", "seq_gaps"):
                v.pop(k)
        out.append((m.name, v))
    return out


def test_fuzzed_frames_are_rejected_counted_and_nothing_of_them_is_applied(tool: Tool) -> None:
    """The same session twice: once as a bad cable delivers it (bits flipped, bytes lost, frames cut,
    noise), once with only the frames the host's decoder accepts from that wire, sent clean. Everything
    the board and the host observe (bytes read, SBUS, address changes, replies, STATUS but for the link
    counters) is the same: no damaged frame was acted on, and the bridge counted the damage."""
    from tests.bridge.test_link import mutate

    rng = random.Random(18)
    down = [m.name for m in MESSAGES if m.direction == "down"]
    dirty = Script().t(0).hello()
    clean = Script().t(0).hello()
    host = Receiver("down")
    host.feed(encode("HELLO", 0, version=PROTOCOL_VERSION, nonce=0xC0FFEE))
    seq = 1
    for step in range(150):
        t = 1000 + step * 2500
        frames = []
        for _ in range(rng.randrange(1, 8)):
            name = rng.choice(down if step < 100 else [n for n in down if n != "HELLO"])
            frames.append(encode(name, seq, **plausible(name, rng)))
            seq += 1
        wire = mutate(frames, rng) if rng.random() < 0.7 else b"".join(frames)
        if rng.random() < 0.1:
            wire += rng.randbytes(rng.randrange(1, 200))
        dirty.t(t).raw(wire)
        accepted = host.feed(wire)
        clean.t(t)
        for m in accepted:
            clean.raw(encode(m.name, m.seq, **m.values))
        board = [f"xfer {t * 1000 + 100_000} 68 3b 14", f"xfer {t * 1000 + 500_000} 77 00 3",
                 f"xfer {t * 1000 + 900_000} 1e 03 6", "poll"]
        dirty.cmd(*board)
        clean.cmd(*board)
    dirty.cmd("status")
    clean.cmd("status")
    a, b = run(tool, dirty.lines), run(tool, clean.lines)
    assert observable(a) == observable(b)
    sa, sb = a.status(), b.status()
    # (an agreed HELLO starts the bridge's counts again: the last 50 steps have none)
    assert sa["bad"] > 10 and sb["bad"] == 0 and host.bad > 50
    assert sa["ok"] == sb["ok"] and sa["refused"] == sb["refused"] > 10
    assert len(a.named("TIME_SYNC_REPLY")) > 5 and len(a.tagged("sbus")) > 5

