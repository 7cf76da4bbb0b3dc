"""run.mcap's /i2c, /sensors, /attitude and /motors messages, written by string formatting
(reports/mcap.py), against the standard library's ``json.dumps`` of the same message built as a dict,
and the sensors' words decoded here a second way, from the datasheets' layouts (MPU-6050 register
map: ACCEL_XOUT_H at 0x3B, seven big-endian signed words, accel x y z, temperature, gyro x y z;
HMC5883L: data output X, Z, Y from 0x03; MS5611: a 24-bit ADC result after command 0x00), byte by
byte with ``int.from_bytes``."""

from __future__ import annotations

import json
import math
import random
from typing import Any

import numpy as np
import pytest

from rig.reports import mcap
from rig.scenarios.result import I2CRecord

MPU = ("ax", "ay", "az", "temp", "gx", "gy", "gz")
HMC = ("x", "z", "y")


def _words(data: bytes, start: int, names: tuple[str, ...]) -> dict[str, int] | None:
    if len(data) < start + 2 * len(names):
        return None
    words = (data[start + 2 * i:start + 2 * i + 2] for i in range(len(names)))
    return {n: int.from_bytes(w, "big", signed=True) for n, w in zip(names, words, strict=True)}


def _expected_sensor(rec: I2CRecord) -> dict[str, Any] | None:
    if not rec.ok or rec.register is None or not rec.read:
        return None
    if rec.address in (0x76, 0x77) and rec.register == 0 and len(rec.read) == 3:
        adc = int.from_bytes(rec.read, "big")
        return {"chip": "MS5611", "address": rec.address, "register": 0, "values": {"adc": adc}}
    windows = (((0x68, 0x69), 0x3B, "MPU-6050", MPU), ((0x1E,), 0x03, "HMC5883L", HMC))
    for addresses, first, chip, names in windows:
        if rec.address in addresses and rec.register <= first:
            values = _words(rec.read, first - rec.register, names)
            if values is not None:
                return {"chip": chip, "address": rec.address, "register": first, "values": values}
    return None


def _compact(msg: dict[str, Any]) -> bytes:
    return json.dumps(msg, separators=(",", ":"), allow_nan=False).encode()


def _records(n: int) -> list[I2CRecord]:
    rng = random.Random(7)
    out = []
    for _ in range(n):
        address = rng.choice([0x68, 0x69, 0x1E, 0x76, 0x77, 0x0C, 0x00, 0x7F])
        register = rng.choice([None, 0x00, 0x02, 0x03, 0x3A, 0x3B, 0x3C, 0x75, 0xFF])
        read = bytes(rng.randrange(256) for _ in range(rng.choice([0, 1, 2, 3, 6, 7, 13, 14, 15, 20])))
        more = bytes(rng.randrange(256) for _ in range(rng.randrange(3)))
        wrote = b"" if register is None else bytes([register]) + more
        t_ns = rng.choice([0, -5, 1, 2**63 - 1, rng.randrange(10**10)])
        out.append(I2CRecord(t_ns, address, register, wrote, read, rng.random() < 0.8))
    return out


RECORDS = _records(3000)


def test_the_formatted_i2c_message_is_json_dumps_of_its_fields() -> None:
    for rec in RECORDS:
        want = _compact({"t_ns": rec.t_ns, "address": rec.address, "register": rec.register,
                         "wrote": rec.wrote.hex(), "read": rec.read.hex(), "ok": rec.ok})
        assert mcap._i2c_json(rec) == want, rec


def test_the_formatted_sensor_message_is_the_datasheet_decoding() -> None:
    decoded = 0
    for rec in RECORDS:
        want = _expected_sensor(rec)
        got = mcap._sensor_json(rec)
        assert got == (None if want is None else _compact(want)), rec
        decoded += want is not None
    assert decoded > 50  # (the draw reaches every chip's window, not only the None cases)
    chips = {json.loads(m)["chip"] for m in map(mcap._sensor_json, RECORDS) if m is not None}
    assert chips == {"MPU-6050", "HMC5883L", "MS5611"}


@pytest.mark.parametrize("read", [bytes(range(15)), bytes([0xFF] * 16)])
def test_an_mpu_burst_from_int_status_is_decoded_from_the_next_byte(read: bytes) -> None:
    rec = I2CRecord(1, 0x68, 0x3A, b"\x3a", read, True)
    values = json.loads(mcap._sensor_json(rec) or b"null")["values"]
    assert values["ax"] == int.from_bytes(read[1:3], "big", signed=True)
    assert values["gz"] == int.from_bytes(read[13:15], "big", signed=True)
    assert list(values) == list(MPU)
    assert mcap._sensor_json(rec._replace(read=read[:14])) is None  # (one byte short of gz)


def _signals(rng: np.random.Generator, n: int, names: tuple[str, ...]) -> dict[str, np.ndarray]:
    """Recorder columns as odd as a run's can be: every float's magnitude, -0.0, NaN here and there, a
    column NaN throughout, one shorter than the time (left out)."""
    signals = {"t": np.arange(n) * 0.01}
    for k, name in enumerate(names):
        col = rng.standard_normal(n) * 10.0 ** rng.integers(-30, 30, n)
        col[rng.random(n) < 0.05] = -0.0
        if k % 5 == 1:
            col[rng.random(n) < 0.1] = np.nan
        if k % 5 == 2:
            col[:] = np.nan
        if k % 7 == 3:
            col = col[:-1]
        signals[name] = col
    return signals


@pytest.mark.parametrize("group", [mcap.ATTITUDE, mcap.MOTORS_GROUP + mcap.BENCH])
def test_the_formatted_rows_are_json_dumps_of_the_rows(group: tuple[str, ...]) -> None:
    signals = _signals(np.random.default_rng(3), 400, group)
    got = list(mcap._rows(signals, group))
    assert len(got) == 400
    for k, (t_ns, data) in enumerate(got):
        want = {"t": signals["t"][k].item()}
        for name in group:
            if name in signals and len(signals[name]) == 400:
                v = signals[name][k].item()
                want[name] = None if math.isnan(v) else v
        assert t_ns == round(want["t"] * 1e9) and data == _compact(want), (k, data)
    assert any(b"null" in d for _, d in got) and any(b"e-" in d for _, d in got)


def test_an_infinite_row_is_refused_as_the_json_encoder_refuses_it() -> None:
    signals = _signals(np.random.default_rng(4), 10, mcap.ATTITUDE)
    signals[mcap.ATTITUDE[0]][7] = np.inf
    with pytest.raises(ValueError, match="not JSON compliant"):
        list(mcap._rows(signals, mcap.ATTITUDE))
    assert list(mcap._rows({"t": np.zeros(0)}, mcap.ATTITUDE)) == []
