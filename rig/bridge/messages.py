"""The bridge link's messages, written once (docs/design.md §8 "Link").

This table is the protocol: the host's codec (rig/bridge/link.py) reads it, and the bridge's C side is
generated from it (``python -m rig.bridge.gen`` writes ``build/gen/bridge_messages.h``: ids, structs,
encoders and decoders), as plant/variables.py does for the FMU. A message is a type byte, a sequence
byte, its fields little-endian in table order (floats as IEEE 754 binary32), then a CRC-16/CCITT-FALSE
(big-endian) over all of that, COBS-encoded and ended by 0x00. Changing a layout means a new
PROTOCOL_VERSION: the hello says which one each side speaks.

Down is host to bridge, up is bridge to host. Times on the link are the bridge's microsecond clock; the
host maps its own time onto it (TIME_SYNC).
"""

from __future__ import annotations

import functools
import struct
from dataclasses import dataclass
from typing import Literal

#: 2: CONFIG carries the ESC pulse limits (OneShot125); 3: STATUS counts i2c_preload_misses
PROTOCOL_VERSION = 3

Direction = Literal["down", "up"]
#: field type -> (struct code, C type)
TYPES: dict[str, tuple[str, str]] = {
    "u8": ("B", "uint8_t"), "u16": ("H", "uint16_t"), "u32": ("I", "uint32_t"), "u64": ("Q", "uint64_t"),
    "i16": ("h", "int16_t"), "i32": ("i", "int32_t"), "f32": ("f", "float"),
}


@dataclass(frozen=True)
class Field:
    name: str
    type: str
    count: int = 1  # an array of this many
    doc: str = ""


@dataclass(frozen=True)
class Message:
    name: str
    id: int
    direction: Direction
    fields: tuple[Field, ...]
    doc: str

    @functools.cached_property
    def field_names(self) -> frozenset[str]:
        return frozenset(f.name for f in self.fields)

    @functools.cached_property
    def layout(self) -> struct.Struct:
        """The body's bytes (after type and seq, before the CRC). Kept: every frame packs through it."""
        codes = (f"{f.count}{TYPES[f.type][0]}" if f.count > 1 else TYPES[f.type][0] for f in self.fields)
        return struct.Struct("<" + "".join(codes))


def _f(name: str, type: str, count: int = 1, doc: str = "") -> Field:
    return Field(name, type, count, doc)


MESSAGES: tuple[Message, ...] = (
    # ---- down: host -> bridge --------------------------------------------------------------------
    Message("HELLO", 0x01, "down", (_f("version", "u16", doc="PROTOCOL_VERSION the host speaks"),
                                    _f("nonce", "u32", doc="echoed in HELLO_REPLY")),
            "the host starts a session; the bridge answers HELLO_REPLY and resets its link counters"),
    Message("CONFIG", 0x02, "down", (_f("topology", "u8", doc="0 GY-86 (HMC behind the MPU), 1 direct"),
                                     _f("mpu_addr", "u8"), _f("hmc_addr", "u8"), _f("baro_addr", "u8"),
                                     _f("sbus_period_ms", "u8", doc="14 normal, 7 high speed; 0: no SBUS"),
                                     _f("capture_channels", "u8", doc="ESC inputs to capture (0: none)"),
                                     _f("trace", "u8", doc="1: a TRACE up per I2C transaction"),
                                     _f("pulse_min_us", "u16", doc="a shorter pulse: a glitch (0: 500)"),
                                     _f("pulse_max_us", "u16", doc="a longer one is a glitch (0: 2500)"),
                                     _f("period_min_us", "u16",
                                        doc="pulses starting closer than this are glitches (0: 1000)")),
            "what the bridge emulates and captures; the chips reset to their power-on state"),
    Message("IMU_SAMPLE", 0x10, "down", (_f("valid_us", "u64", doc="bridge time from which it holds"),
                                         _f("accel", "f32", 3, doc="m/s^2, sensor frame, after the DLPF"),
                                         _f("gyro", "f32", 3, doc="rad/s, sensor frame, after the DLPF"),
                                         _f("temp_c", "f32")),
            "the MPU-6050's next sample, streamed a lead ahead of its valid time"),
    Message("MAG_SAMPLE", 0x11, "down", (_f("valid_us", "u64"),
                                         _f("field", "f32", 3, doc="gauss, sensor frame")),
            "the HMC5883L's field"),
    Message("BARO_SAMPLE", 0x12, "down", (_f("valid_us", "u64"),
                                          _f("d1", "u32", doc="raw pressure word (24 bits)"),
                                          _f("d2", "u32", doc="raw temperature word (24 bits)")),
            "the MS5611's conversion results, encoded on the host with the chip's PROM (the host follows "
            "the board's commands, REG_WRITE, for the OSR's noise): a conversion ending at or after the "
            "valid time gives the word of its kind"),
    Message("SBUS", 0x13, "down", (_f("channels", "u16", 16, doc="11-bit values"),
                                   _f("flags", "u8", doc="bit 2 frame lost, bit 3 failsafe; bit 7 "
                                      "(SBUS_OUT_OFF): no frames at all until the next SBUS")),
            "sticks: the bridge sends them to the board as SBUS frames at the configured period"),
    Message("TIME_SYNC", 0x20, "down", (_f("id", "u32"), _f("host_ns", "u64", doc="host clock at sending")),
            "a time-sync probe; the bridge answers TIME_SYNC_REPLY"),
    Message("FAULT", 0x21, "down", (_f("target", "u8", doc="index in emulators.faults.TARGETS"),
                                    _f("kind", "u8", doc="index in emulators.faults.KINDS"),
                                    _f("start_us", "u64"), _f("end_us", "u64"), _f("magnitude", "f32"),
                                    _f("period_s", "f32"), _f("duty", "f32")),
            "a bus-level fault scheduled on the bridge's clock (signal faults stay on the host)"),
    Message("HEARTBEAT", 0x22, "down", (), "nothing to send: the host is alive"),
    # ---- up: bridge -> host ----------------------------------------------------------------------
    Message("HELLO_REPLY", 0x81, "up", (_f("version", "u16", doc="PROTOCOL_VERSION the bridge speaks"),
                                        _f("nonce", "u32"), _f("core_version", "u16"),
                                        _f("bridge_id", "u8", 16, doc="its name, NUL-padded ASCII"),
                                        _f("firmware_sha256", "u8", 8, doc="first 8 bytes"),
                                        _f("clock_hz", "u32", doc="its core clock")),
            "who the bridge is"),
    Message("REG_WRITE", 0x90, "up", (_f("t_us", "u64"), _f("addr", "u8"),
                                      _f("reg", "u8", doc="the register (MS5611: the command byte)"),
                                      _f("value", "u8", doc="the byte written (MS5611: 0)")),
            "the board wrote a chip register, acknowledged (the host follows rates, ranges, DLPF); the "
            "register is the pointer the board set plus the byte's place in the burst"),
    Message("PULSES", 0x91, "up", (_f("t_us", "u64", doc="capture time of the last edge"),
                                   _f("width_tenth_us", "u16", 4, doc="0.1 us; 0: no pulse")),
            "the ESC pulse widths the bridge captured"),
    Message("STATUS", 0x92, "up", (_f("t_us", "u64"), _f("underruns", "u32", 3, doc="IMU, mag, baro"),
                                   _f("late_samples", "u32"), _f("i2c_errors", "u32"),
                                   _f("i2c_acked", "u32", doc="STARTs our chips acknowledged: the board "
                                      "used them"),
                                   _f("frames_ok", "u32"),
                                   _f("frames_bad", "u32"), _f("seq_gaps", "u32"),
                                   _f("refused", "u32", doc="good frames not acted on: version not agreed, "
                                      "a value out of range, a message the bridge cannot act on"),
                                   _f("pulse_glitches", "u32", doc="captured pulses filtered out"),
                                   _f("sbus_dropped", "u32", doc="SBUS bytes the UART could not take"),
                                   _f("i2c_preload_misses", "u32", doc="reads whose first byte, loaded "
                                      "before the address (a target that does not stretch SCL), was not "
                                      "the chip's"),
                                   _f("host_silent", "u8", doc="1 while no frame came for HOST_SILENT_US")),
            "the bridge's counters, a few times a second"),
    Message("TIME_SYNC_REPLY", 0xA0, "up", (_f("id", "u32"), _f("rx_us", "u64"), _f("tx_us", "u64")),
            "when the probe arrived and when this left, in bridge time"),
    Message("TRACE", 0xA1, "up", (_f("t_us", "u64"), _f("addr", "u8"), _f("read", "u8"), _f("len", "u8"),
                                  _f("data", "u8", 16, doc="the first 16 bytes")),
            "one I2C transaction of the board (when tracing is on)"),
)

BY_NAME = {m.name: m for m in MESSAGES}
BY_ID = {m.id: m for m in MESSAGES}
#: The bridge says the host is silent after this long without a frame; it holds its last samples
HOST_SILENT_US = 100_000
MAX_FRAME = 128  # the longest message's bytes before COBS, with type, seq and CRC
