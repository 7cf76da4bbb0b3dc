"""MS5611 against datasheet truth (docs/sensors.md §5): worked example, CRC-4 vectors, the inverse
table, exact round trips for any pressure and temperature, and the command state machine."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rig.emulators.i2c_bus import I2CBus, read, write
from rig.emulators.ms5611 import DEFAULT_PROM, MS5611, BaroTruth, crc4, encode
from tests.emulators import boards
from tests.emulators.boards import Script, make_board

C = DEFAULT_PROM


def datasheet_forward(d1: int, d2: int, prom=C) -> tuple[int, int]:
    """The datasheet's integer flow, written out again here (C-style 64-bit products, floor shifts)."""
    c1, c2, c3, c4, c5, c6 = prom[1:7]
    dT = d2 - c5 * 256
    TEMP = 2000 + dT * c6 // 2**23
    OFF = c2 * 2**16 + c4 * dT // 2**7
    SENS = c1 * 2**15 + c3 * dT // 2**8
    T2 = OFF2 = SENS2 = 0
    if TEMP < 2000:
        T2 = dT * dT // 2**31
        OFF2 = 5 * (TEMP - 2000) ** 2 // 2
        SENS2 = 5 * (TEMP - 2000) ** 2 // 4
        if TEMP < -1500:
            OFF2 = OFF2 + 7 * (TEMP + 1500) ** 2
            SENS2 = SENS2 + 11 * (TEMP + 1500) ** 2 // 2
    TEMP, OFF, SENS = TEMP - T2, OFF - OFF2, SENS - SENS2
    return TEMP, (d1 * SENS // 2**21 - OFF) // 2**15


def test_datasheet_worked_example():
    assert datasheet_forward(9085466, 8569150) == (2007, 100009)


def test_crc4_vectors():
    assert crc4([0x3132, 0x3334, 0x3536, 0x3738, 0x3940, 0x4142, 0x4344, 0x4500]) == 0xB
    assert crc4((0x0000, *C[1:7], 0x0000)) == 0x0
    assert crc4((0x0001, *C[1:7], 0x0008)) == 0x8
    assert crc4(C) == 0x3 == C[7] & 0xF  # default PROM: valid and non-zero (Linux rejects 0)


@pytest.mark.parametrize(("p", "t", "d2", "d1"), [
    (101325, 25.00, 8715078, 9104564), (101325, 15.00, 8421453, 9206742),
    (100009, 20.07, 8569006, 9085537), (89875, 8.50, 8240715, 8662882),
    (70000, -10.00, 7766352, 7739453), (120000, -40.00, 7089918, 11075836),
    (1000, 85.00, 10492827, 3944310)])
def test_inverse_table_of_specs_5_10(p, t, d2, d1):
    assert encode(C, p, t) == (d1, d2)
    assert datasheet_forward(d1, d2) == (round(t * 100), p)


UNREACHABLE = {-3932, -717}  # docs/sensors.md §5.10: no D2 decodes to these with the example PROM


@settings(max_examples=300, deadline=None)
@given(p=st.integers(1000, 120000), t=st.integers(-4000, 8500))
def test_every_pascal_and_centidegree_decodes_back_exactly(p, t):
    d1, d2 = encode(C, p, t / 100)
    assert 0 < d1 < 0xFFFFFF and 0 < d2 < 0xFFFFFF
    temp, pressure = datasheet_forward(d1, d2)
    assert pressure == p
    assert temp == t or (t in UNREACHABLE and abs(temp - t) == 1)


def float_forward(d1: int, d2: int) -> tuple[float, float]:
    c1, c2, c3, c4, c5, c6 = C[1:7]
    dT = d2 - c5 * 256.0
    TEMP = 2000 + dT * c6 / 2**23
    OFF = c2 * 2**16 + c4 * dT / 2**7
    SENS = c1 * 2**15 + c3 * dT / 2**8
    return TEMP / 100, (d1 * SENS / 2**21 - OFF) / 2**15 / 1.0


@settings(max_examples=200, deadline=None)
@given(p=st.floats(1000, 120000), t=st.floats(20, 85))
def test_float_encoding_is_close_for_float_clients(p, t):
    temp, pressure = float_forward(*encode(C, p, t, mode="float"))
    assert pressure == pytest.approx(p, abs=0.05)
    assert temp == pytest.approx(t, abs=0.005)


# ---- the device on a bus ------------------------------------------------------------------------

class Truth:
    pressure, temperature = 101325.0, 25.0

    def __call__(self, t):
        return BaroTruth(self.pressure, self.temperature)


def baro_bus(truth, **options):
    """A bus with the barometer on it: the Python MS5611 alone, or the chip core's board."""
    if boards.IMPL == "core":
        return make_board(Script().imu, Script().mag, truth, "direct", **options).bus
    b = I2CBus()
    b.attach(0x77, MS5611(truth, **options))
    return b


@pytest.fixture
def bus():
    return baro_bus(Truth())


def adc(bus, t):
    return int.from_bytes(bus.transfer([write(0x77, 0x00), read(0x77, 3)], t)[0], "big")


def test_prom_reads_without_reset_and_checks(bus):
    words = [int.from_bytes(bus.transfer([write(0x77, 0xA0 + 2 * k), read(0x77, 2)], 0.0)[0], "big")
             for k in range(8)]
    assert tuple(words) == C and crc4(words) == words[7] & 0xF


@pytest.mark.parametrize(("osr_index", "t_conv"), [(0, 0.54e-3), (2, 2.08e-3), (4, 8.22e-3)])
def test_conversion_is_timed_per_osr_and_reads_zero_idle_early_and_twice(bus, osr_index, t_conv):
    assert adc(bus, 0.0) == 0                           # idle
    bus.transfer([write(0x77, 0x58)], 0.0)              # D2 at OSR 4096, then D1 at the chosen OSR
    assert adc(bus, 0.01) == encode(C, 101325, 25.0)[1]
    bus.transfer([write(0x77, 0x40 + 2 * osr_index)], 1.0)
    assert adc(bus, 1.0 + t_conv + 1e-6) == encode(C, 101325, 25.0)[0]
    assert adc(bus, 1.1) == 0                           # a second read without a conversion
    bus.transfer([write(0x77, 0x40 + 2 * osr_index)], 2.0)
    assert adc(bus, 2.0 + t_conv * 0.9) == 0            # too early: 0, and the result is corrupt
    assert adc(bus, 2.1) not in (0, encode(C, 101325, 25.0)[0])


def test_quick_write_and_two_byte_reset_are_harmless(bus):
    bus.transfer([write(0x77, 0x48)], 0.0)
    bus.transfer([write(0x77)], 0.001)                  # i2cdetect's probe: not a command
    assert adc(bus, 0.01) == encode(C, 101325, 25.0)[0]
    bus.transfer([write(0x77, 0x48)], 0.02)
    bus.transfer([write(0x77, 0x1E, 0x00)], 0.021)      # MultiWii's reset aborts the conversion
    assert adc(bus, 0.05) == 0


def test_out_of_range_truth_is_clamped_to_the_sensor_range():
    b = baro_bus(lambda t: BaroTruth(500.0, 120.0))
    b.transfer([write(0x77, 0x48)], 0.0)
    d1 = adc(b, 0.01)
    b.transfer([write(0x77, 0x58)], 0.02)
    d2 = adc(b, 0.03)
    assert datasheet_forward(d1, d2) == (8500, 1000)


def test_max_timing_option_uses_the_datasheet_maximum():
    b = baro_bus(Truth(), timing="max")
    b.transfer([write(0x77, 0x48)], 0.0)
    assert adc(b, 0.00823) == 0          # past the typical 8.22 ms, before the maximum 9.04 ms
    b.transfer([write(0x77, 0x48)], 0.1)
    assert adc(b, 0.1 + 0.00905) == encode(C, 101325, 25.0)[0]


def test_osr_noise_option_varies_readings_repeatably():
    def readings(seed):
        b = baro_bus(Truth(), osr_noise=True, seed=seed)
        out = []
        for k in range(20):
            b.transfer([write(0x77, 0x40)], k * 0.01)  # OSR 256: 6.5 Pa RMS
            out.append(adc(b, k * 0.01 + 0.001))
        return out
    first = readings(1)
    assert len(set(first)) > 10 and first == readings(1) and first != readings(2)
    d2 = encode(C, 101325, 25.0)[1]
    pressures = [datasheet_forward(d1, d2)[1] for d1 in first]
    assert all(abs(p - 101325) < 40 for p in pressures)  # about 6 sigma
