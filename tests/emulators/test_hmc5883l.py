"""HMC5883L against docs/sensors.md §4."""

from __future__ import annotations

import pytest

from rig.emulators.hmc5883l import GAINS
from rig.emulators.i2c_bus import I2CNack, read, write
from tests.emulators.boards import Script, board, s16

A = 0x1E


def direct(script=None):
    script = script or Script()
    return script, board(script, topology="direct").bus


def xyz(bus, t):
    d = bus.transfer([write(A, 0x03), read(A, 6)], t)[0]
    x, z, y = s16(d[0], d[1]), s16(d[2], d[3]), s16(d[4], d[5])
    return x, y, z


def test_identity_and_defaults():
    _, bus = direct()
    assert bus.transfer([write(A, 0x0A), read(A, 3)], 0.0)[0] == b"H43"
    assert bus.transfer([write(A, 0x00), read(A, 3)], 0.0)[0] == bytes([0x10, 0x20, 0x01])


@pytest.mark.parametrize("gn", range(8))
def test_gain_table_and_register_order(gn):
    script, bus = direct()
    script.field = (0.4, -0.3, 0.2)
    bus.transfer([write(A, 0x01, gn << 5), write(A, 0x02, 0x00)], 0.0)  # gain, continuous 15 Hz
    x, y, z = xyz(bus, 1.0)  # many measurements later: the new gain is in effect
    g = GAINS[gn]
    expect = [round(v * g) for v in script.field]
    expect = [v if -2048 <= v <= 2047 else -4096 for v in expect]
    assert (x, y, z) == tuple(expect)


def test_overflow_reads_minus_4096_per_axis():
    script, bus = direct()
    script.field = (2.5, 0.1, -0.2)
    bus.transfer([write(A, 0x02, 0x00)], 0.0)
    x, y, z = xyz(bus, 1.0)
    assert x == -4096 and y == round(0.1 * 1090) and z == round(-0.2 * 1090)


def test_pointer_returns_to_3_after_8_and_to_0_after_12():
    _, bus = direct()
    bus.transfer([write(A, 0x02, 0x00)], 0.0)
    first = bus.transfer([write(A, 0x03), read(A, 6)], 1.0)[0]
    again = bus.transfer([read(A, 6)], 1.0)[0]  # no pointer write: X MSB again
    assert again == first
    bus.transfer([write(A, 0x0A), read(A, 3)], 1.0)
    assert bus.transfer([read(A, 1)], 1.0)[0] == bytes([0x10])  # back at CRA


def test_single_measurement_takes_6_ms_then_goes_idle():
    script, bus = direct()
    bus.transfer([write(A, 0x02, 0x01)], 1.0)
    status = bus.transfer([write(A, 0x09), read(A, 1)], 1.005)[0][0]
    assert status & 1 == 0
    status = bus.transfer([write(A, 0x09), read(A, 1)], 1.0061)[0][0]
    assert status & 1 == 1
    assert bus.transfer([write(A, 0x02), read(A, 1)], 1.007)[0][0] == 0x03  # idle after single
    xyz(bus, 1.008)
    assert bus.transfer([write(A, 0x09), read(A, 1)], 1.009)[0][0] & 1 == 0  # read clears RDY


def test_continuous_first_result_after_two_periods_then_every_period():
    script, bus = direct()
    bus.transfer([write(A, 0x00, 0x18), write(A, 0x02, 0x00)], 0.0)  # 75 Hz
    assert bus.transfer([write(A, 0x09), read(A, 1)], 2 / 75 - 1e-4)[0][0] & 1 == 0
    assert bus.transfer([write(A, 0x09), read(A, 1)], 2 / 75 + 1e-4)[0][0] & 1 == 1


def test_lock_holds_new_results_until_all_six_bytes_are_read():
    script, bus = direct()
    bus.transfer([write(A, 0x00, 0x18), write(A, 0x02, 0x00)], 0.0)
    old = xyz(bus, 0.1)
    bus.transfer([write(A, 0x03), read(A, 2)], 0.11)           # X only: LOCK
    assert bus.transfer([write(A, 0x09), read(A, 1)], 0.11)[0][0] & 2
    script.field = (0.1, 0.1, 0.1)
    rest = bus.transfer([write(A, 0x05), read(A, 4)], 0.2)[0]  # still the old sample's Z, Y
    assert (s16(rest[2], rest[3]), s16(rest[0], rest[1])) == (old[1], old[2])
    assert xyz(bus, 0.2) == (109, 109, 109)                    # the held result, placed after


def test_gain_change_counts_from_the_second_measurement():
    script, bus = direct()
    script.field = (0.5, 0.0, 0.0)
    bus.transfer([write(A, 0x01, 0xE0)], 0.07)  # gain 230, after the power-on measurement (56 ms)
    bus.transfer([write(A, 0x02, 0x01)], 0.1)   # single: still the old gain
    assert xyz(bus, 0.11)[0] == round(0.5 * 1090)
    bus.transfer([write(A, 0x02, 0x01)], 0.2)   # the next one: new gain
    assert xyz(bus, 0.21)[0] == round(0.5 * 230)


@pytest.mark.parametrize(("ms", "sign"), [(0x01, 1), (0x02, -1)])
def test_bias_self_test_gives_the_strap_field(ms, sign):
    script, bus = direct()
    bus.transfer([write(A, 0x01, 0xA0), write(A, 0x00, 0x10 | ms)], 0.0)  # gain 390
    bus.transfer([write(A, 0x02, 0x01)], 0.1)
    bus.transfer([write(A, 0x02, 0x01)], 0.2)
    x, y, z = xyz(bus, 0.21)
    assert (x, y, z) == (sign * round(1.16 * 390), sign * round(1.16 * 390), sign * round(1.08 * 390))
    assert 243 <= abs(x) <= 575  # MultiWii's acceptance window


def test_gy86_hides_the_magnetometer_until_bypass():
    script = Script()
    bus = board(script).bus
    with pytest.raises(I2CNack):
        bus.transfer([write(A, 0x0A), read(A, 3)], 0.0)
    bus.transfer([write(0x68, 0x6B, 0x00), write(0x68, 0x37, 0x02)], 0.0)
    assert bus.transfer([write(A, 0x0A), read(A, 3)], 0.0)[0] == b"H43"
    bus.transfer([write(0x68, 0x6A, 0x20)], 0.0)  # aux master on: bypass no longer effective
    with pytest.raises(I2CNack):
        bus.transfer([write(A, 0x0A), read(A, 3)], 0.0)


@pytest.mark.parametrize(("wraps", "after_status"), [(False, 0x48), (True, 0x01)])
def test_pointer_after_status_register_is_an_option(wraps, after_status):
    # Default 9 -> 10 (ID_A 'H'); with status_wraps_to_data, 9 -> 3 (X MSB: 0.25 G * 1090 = 0x0111).
    script = Script()
    b = board(script, topology="direct")
    b.hmc.status_wraps_to_data = wraps
    b.bus.transfer([write(A, 0x02, 0x00)], 0.0)
    b.bus.transfer([write(A, 0x09), read(A, 1)], 1.0)
    assert b.bus.transfer([read(A, 1)], 1.0)[0][0] == after_status
