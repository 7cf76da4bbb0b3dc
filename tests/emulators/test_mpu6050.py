"""MPU-6050 against docs/sensors.md §3."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rig.emulators.i2c_bus import read, write
from rig.emulators.mpu6050 import ACCEL_LSB_PER_G, GYRO_LSB_PER_DPS, ST_ACCEL_G, ST_GYRO_DPS, ImuTruth
from tests.emulators.boards import Script, board, s16

M, G0 = 0x68, 9.80665


def awake(script=None, dlpf=False):
    script = script or Script()
    b = board(script, dlpf=dlpf)
    b.bus.transfer([write(M, 0x6B, 0x00)], 0.0)
    return script, b


def burst(bus, t):
    d = bus.transfer([write(M, 0x3B), read(M, 14)], t)[0]
    v = [s16(d[i], d[i + 1]) for i in range(0, 14, 2)]
    return v[0:3], v[3], v[4:7]


def test_power_on_is_asleep_and_reads_zeros():
    b = board(Script())
    assert b.bus.transfer([write(M, 0x6B), read(M, 1)], 0.0)[0] == b"\x40"
    assert b.bus.transfer([write(M, 0x75), read(M, 1)], 0.0)[0] == b"\x68"
    assert b.bus.transfer([write(M, 0x3B), read(M, 14)], 1.0)[0] == bytes(14)


def test_worked_bytes_of_specs_3_4():
    script, b = awake()
    assert b.bus.transfer([write(M, 0x3F), read(M, 2)], 0.01)[0] == b"\x40\x00"  # +1 g at 2 g
    script.accel = (0, 0, -G0)
    assert b.bus.transfer([write(M, 0x3F), read(M, 2)], 0.02)[0] == b"\xc0\x00"
    b.bus.transfer([write(M, 0x1C, 0x18), write(M, 0x1B, 0x18)], 0.02)
    script.accel, script.gyro = (0, 0, G0), (0, 0, math.radians(100))
    assert b.bus.transfer([write(M, 0x3F), read(M, 2)], 0.03)[0] == b"\x08\x00"
    assert b.bus.transfer([write(M, 0x47), read(M, 2)], 0.03)[0] == b"\x06\x68"
    script.temperature = 25.0
    assert b.bus.transfer([write(M, 0x41), read(M, 2)], 0.04)[0] == b"\xf0\xb0"  # -3920


@settings(max_examples=100, deadline=None)
@given(fs=st.integers(0, 3), a=st.floats(-1.0, 1.0), w=st.floats(-1.0, 1.0))
def test_every_full_scale_encodes_a_value_back_within_one_lsb(fs, a, w):
    script, b = awake()
    b.bus.transfer([write(M, 0x1C, fs << 3), write(M, 0x1B, fs << 3)], 0.0)
    a_ms2 = a * (2 << fs) * G0 * 0.999            # inside the range
    w_rad = math.radians(w * (250 << fs) * 0.999)
    script.accel, script.gyro = (a_ms2, -a_ms2, 0.0), (w_rad, 0.0, -w_rad)
    acc, _, gyro = burst(b.bus, 0.01)
    assert abs(acc[0] / ACCEL_LSB_PER_G[fs] * G0 - a_ms2) <= G0 / ACCEL_LSB_PER_G[fs]
    assert abs(acc[1] + acc[0]) <= 1
    assert abs(math.radians(gyro[0] / GYRO_LSB_PER_DPS[fs]) - w_rad) <= math.radians(1 / GYRO_LSB_PER_DPS[fs])


def test_out_of_range_values_saturate():
    script, b = awake()
    script.accel = (100 * G0, -100 * G0, 0)
    acc, _, _ = burst(b.bus, 0.01)
    assert acc[:2] == [32767, -32768]


def test_burst_reads_never_mix_two_samples():
    script, b = awake()
    for k in range(50):
        script.accel = (k * 0.01, k * 0.01, G0)  # every sample differs
        script.gyro = (k * 0.001,) * 3
        acc, _, gyro = burst(b.bus, 0.0005 + k * 0.00037)
        # Within one burst, x and y and all gyro axes come from the same instant.
        assert acc[0] == acc[1] and gyro[0] == gyro[1] == gyro[2]


def test_sample_rate_divider_and_dlpf_set_the_clock():
    script, b = awake()
    mpu = b.mpu
    for div, cfg, rate in ((0, 0, 8000), (0, 1, 1000), (1, 2, 500), (19, 4, 50)):
        b.bus.transfer([write(M, 0x19, div), write(M, 0x1A, cfg)], 0.0)
        assert mpu.sample_rate() == rate
    start = mpu.samples
    b.bus.transfer([write(M, 0x75), read(M, 1)], 1.0)  # 50 Hz for one second (last 64 kept)
    assert mpu.samples - start <= 64


def test_dlpf_responds_with_its_bandwidth():
    script, b = awake(dlpf=True)
    b.bus.transfer([write(M, 0x1A, 0x04)], 0.0)  # 20 Hz gyro, 1 kHz
    b.bus.transfer([write(M, 0x75), read(M, 1)], 0.0)  # one sample at rest (t = 0)
    script.gyro = (math.radians(100), 0, 0)            # step from the sample at 1 ms on
    _, _, during_delay = burst(b.bus, 0.0081)           # table delay 8.3 ms: nothing yet
    _, _, one_tau = burst(b.bus, 0.0163)                # delay + 1/(2 pi 20 Hz) = 16.3 ms
    _, _, settled = burst(b.bus, 0.2)
    assert during_delay[0] == 0
    assert settled[0] == round(100 * 131)
    assert one_tau[0] / settled[0] == pytest.approx(1 - math.exp(-1), abs=0.05)


def test_int_status_sets_each_sample_and_clears_on_read():
    script, b = awake()
    assert b.bus.transfer([write(M, 0x3A), read(M, 1)], 0.01)[0][0] & 1
    assert b.bus.transfer([write(M, 0x3A), read(M, 1)], 0.01)[0][0] == 0  # cleared by that read
    b.bus.transfer([write(M, 0x37, 0x10)], 0.01)  # INT_RD_CLEAR: any read clears
    b.bus.transfer([write(M, 0x75), read(M, 1)], 0.02)
    assert b.bus.transfer([write(M, 0x3A), read(M, 1)], 0.02)[0][0] == 0
    burst(b.bus, 0.03)  # a data burst is a read too
    assert b.bus.transfer([write(M, 0x3A), read(M, 1)], 0.03)[0][0] == 0
    b.bus.transfer([write(M, 0x37, 0x00)], 0.03)
    burst(b.bus, 0.04)  # without INT_RD_CLEAR it is not
    assert b.bus.transfer([write(M, 0x3A), read(M, 1)], 0.04)[0][0] & 1


def test_fifo_records_latched_count_overflow_and_empty_repeat():
    script, b = awake()
    bus = b.bus
    bus.transfer([write(M, 0x19, 7), write(M, 0x23, 0xF8), write(M, 0x6A, 0x04), write(M, 0x6A, 0x40)], 0.0)
    d = bus.transfer([write(M, 0x72), read(M, 2)], 0.0105)[0]  # 1 kHz: samples at 0, 1, ... 10 ms
    count = (d[0] << 8) | d[1]
    assert count == 14 * 11
    rec = bus.transfer([write(M, 0x74), read(M, 14)], 0.0105)[0]
    assert s16(rec[4], rec[5]) == 16384  # accel Z first (ascending registers), then temp, gyro
    bus.transfer([write(M, 0x74), read(M, count - 14)], 0.0105)
    last = bus.transfer([write(M, 0x74), read(M, 2)], 0.0105)[0]
    assert last[0] == last[1]  # empty: the last byte again
    bus.transfer([write(M, 0x3A), read(M, 1)], 0.0105)
    status = bus.transfer([write(M, 0x3A), read(M, 1)], 0.2)[0][0]
    assert status & 0x10  # 190 records of 14 bytes > 1024: overflow
    d = bus.transfer([write(M, 0x72), read(M, 2)], 0.2)[0]
    assert (d[0] << 8) | d[1] == 1024


def test_aux_master_reads_the_magnetometer_into_ext_sens_data():
    script, b = awake()
    bus = b.bus
    bus.transfer([write(M, 0x37, 0x02), write(0x1E, 0x02, 0x00)], 0.0)  # HMC continuous via bypass
    # MultiWii's GY-86 sequence (docs/sensors.md §7.8).
    bus.transfer([write(M, 0x6A, 0x20), write(M, 0x37, 0x00), write(M, 0x24, 0x0D),
                  write(M, 0x25, 0x9E), write(M, 0x26, 0x03), write(M, 0x27, 0x86)], 0.0)
    d = bus.transfer([write(M, 0x49), read(M, 6)], 0.5)[0]
    x, z, y = s16(d[0], d[1]), s16(d[2], d[3]), s16(d[4], d[5])
    # 0.25 G * 1090 = 272.5: docs/sensors.md §2 rounds half away from zero (Python's round() would give 272).
    assert (x, y, z) == (273, 0, round(0.433 * 1090))


def test_device_reset_restores_defaults_and_bypass_off():
    script, b = awake()
    bus = b.bus
    bus.transfer([write(M, 0x37, 0x02), write(M, 0x1B, 0x18)], 0.0)
    bus.transfer([write(M, 0x6B, 0x80)], 0.1)
    assert bus.transfer([write(M, 0x6B), read(M, 1)], 0.1)[0] == b"\x40"  # bit 7 already clear
    assert bus.transfer([write(M, 0x1B), read(M, 1)], 0.1)[0] == b"\x00"
    assert not b.mpu.bypass


def test_sleep_freezes_the_data_registers():
    script, b = awake()
    before, _, _ = burst(b.bus, 0.01)
    b.bus.transfer([write(M, 0x6B, 0x40)], 0.01)
    script.accel = (G0, 0, 0)
    after, _, _ = burst(b.bus, 0.5)
    assert after == before


def test_self_test_response_matches_factory_trim():
    script, b = awake()
    b.bus.transfer([write(M, 0x1B, 0x00), write(M, 0x1C, 0x10)], 0.0)  # 250 dps, 8 g
    off_a, _, off_g = burst(b.bus, 0.01)
    b.bus.transfer([write(M, 0x1B, 0xE0), write(M, 0x1C, 0xF0)], 0.01)
    on_a, _, on_g = burst(b.bus, 0.02)
    codes = b.bus.transfer([write(M, 0x0D), read(M, 4)], 0.02)[0]
    xg = codes[0] & 0x1F
    xa = ((codes[0] >> 5) << 2) | ((codes[3] >> 4) & 3)
    ft_g = 25 * 131 * 1.046 ** (xg - 1)                      # register-map formulas (docs/sensors.md §3.10)
    ft_a = 4096 * 0.34 * (0.92 / 0.34) ** ((xa - 1) / 30)
    assert on_g[0] - off_g[0] == pytest.approx(ft_g, abs=1)
    assert on_g[1] - off_g[1] == pytest.approx(-ft_g, abs=1)
    assert on_a[2] - off_a[2] == pytest.approx(ft_a, abs=1)
    assert 10 <= ST_GYRO_DPS <= 105 and 0.30 <= ST_ACCEL_G <= 0.95  # Crazyflie's limits


def test_fifo_slave_data_sits_where_the_aux_master_put_it():
    # SLV0 writes (takes no EXT_SENS_DATA bytes), SLV1 reads the HMC's 6 data bytes: the FIFO's slave
    # part must be the bytes the master stored at EXT_SENS_DATA_00.
    script, b = awake()
    bus = b.bus
    bus.transfer([write(M, 0x37, 0x02), write(0x1E, 0x02, 0x00)], 0.0)
    bus.transfer([write(M, 0x6A, 0x20), write(M, 0x37, 0x00),
                  write(M, 0x25, 0x1E), write(M, 0x26, 0x02), write(M, 0x63, 0x00), write(M, 0x27, 0x83),
                  write(M, 0x28, 0x9E), write(M, 0x29, 0x03), write(M, 0x2A, 0x86)], 0.2)
    bus.transfer([write(M, 0x23, 0x02), write(M, 0x6A, 0x24), write(M, 0x6A, 0x60)], 0.3)
    ext = bus.transfer([write(M, 0x49), read(M, 6)], 0.3021)[0]
    record = bus.transfer([write(M, 0x74), read(M, 6)], 0.3021)[0]
    assert ext == bytes.fromhex("011101d80000") and record == ext


def test_standby_axes_and_temp_dis_hold_their_last_value():
    # docs/sensors.md §3.6: TEMP_DIS=1 stops temperature sampling, a STBY_* axis holds its last value
    script, b = awake()
    script.accel, script.gyro, script.temperature = (1.0, 2.0, 3.0), (0.1, 0.2, 0.3), 30.0
    acc0, temp0, gyro0 = burst(b.bus, 0.01)
    b.bus.transfer([write(M, 0x6C, 0x20 | 0x01), write(M, 0x6B, 0x08)], 0.01)  # STBY_XA, STBY_ZG; TEMP_DIS
    script.accel, script.gyro, script.temperature = (-1.0, -2.0, -3.0), (-0.1, -0.2, -0.3), 40.0
    acc1, temp1, gyro1 = burst(b.bus, 0.02)
    assert acc1[0] == acc0[0] and gyro1[2] == gyro0[2] and temp1 == temp0
    assert acc1[1:] == [-a for a in acc0[1:]] and gyro1[:2] == [-g for g in gyro0[:2]]


def test_a_non_finite_input_saturates_or_reads_zero_and_the_device_runs_on():
    # a plant that blew up must not take the emulator down: +-inf saturates as a huge value does, NaN
    # (no value at all) reads 0
    script, b = awake()
    script.accel, script.gyro = (math.inf, -math.inf, math.nan), (math.nan, 0.0, 0.0)
    acc, _, gyro = burst(b.bus, 0.01)
    assert acc == [32767, -32768, 0] and gyro[0] == 0
    script.accel, script.gyro = (0.0, 0.0, G0), (0.0, 0.0, 0.0)
    acc, _, _ = burst(b.bus, 0.02)
    assert acc == [0, 0, 16384]


def test_fifo_over_many_blocks_is_what_sample_by_sample_reading_gives():
    # a long wait with the FIFO on keeps every sample, taken in blocks of at most 64: the bytes must be
    # those of reading the device every millisecond, one sample at a time
    class Moving(Script):
        def imu(self, t):
            return ImuTruth((math.sin(40 * t), 0.0, G0), (0.0, 0.0, 0.0), 25.0)

    def fifo_bytes(reads_at):
        _, b = awake(Moving(), dlpf=True)
        b.bus.transfer([write(M, 0x1A, 0x03), write(M, 0x23, 0x08), write(M, 0x6A, 0x40)], 0.0)  # accel
        for t in reads_at:
            b.bus.transfer([write(M, 0x75), read(M, 1)], t)
        count = b.bus.transfer([write(M, 0x72), read(M, 2)], 0.1695)[0]
        return b.bus.transfer([write(M, 0x74), read(M, (count[0] << 8) | count[1])], 0.1695)[0]

    one_wait = fifo_bytes([0.1695])                               # samples at 0..169 ms: 170
    assert len(one_wait) == 170 * 6 and len(set(one_wait[i:i + 2] for i in range(0, 1020, 6))) > 100
    assert one_wait == fifo_bytes([k * 0.001 for k in range(170)])
