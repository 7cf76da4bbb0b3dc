"""The rig's STM32F405 I2C controller (qemu/hw/rig_stm32_i2c.c) against RM0090 section 27, with the chip
core's GY-86 on I2C1 (qemu/hw/rig_gy86.c): two test firmwares make the same transfers, one by polling
with ST's HAL sequences (tests/stm32/firmware/i2c_poll.c), one from the event and error interrupts
(i2c_irq.c), and the polling one again with I2C1 on PB8/PB9 (i2c_poll_pb8.elf). Expected values are
the sensors' datasheets' (docs/sensors.md), RM0090's status bits and the MS5611 application note's
CRC-4, written here."""

from __future__ import annotations

import functools

import pytest

from tests.stm32.conftest import engine_or_skip, firmware, reports, run_firmware, run_to_done

FIRMWARES = ("i2c_poll", "i2c_irq", "i2c_poll_pb8")
#: MS5611 datasheet's example coefficients C1..C6 (docs/sensors.md §5.4), the chip core's default PROM
MS5611_C = (40127, 36924, 23317, 23282, 33464, 28312)
#: RM0090 27.6.6/27.6.7
SR1_SB, SR1_ADDR, SR1_TXE, SR1_AF = 1 << 0, 1 << 1, 1 << 7, 1 << 10
SR2_MSL, SR2_BUSY, SR2_TRA = 1 << 0, 1 << 1, 1 << 2
NACKED = 0xFFFF_FFFF  # the firmwares' -1


def crc4(prom: list[int]) -> int:
    """AN520 (MEAS, 'C-code example for MS56xx'): CRC-4 over the PROM, its own nibble taken as 0."""
    words = [*prom[:7], prom[7] & 0xFF00]
    rem = 0
    for n in range(16):
        word = words[n >> 1]
        rem ^= word & 0xFF if n & 1 else word >> 8
        for _ in range(8):
            rem = ((rem << 1) ^ 0x3000) if rem & 0x8000 else rem << 1
            rem &= 0xFFFF
    return (rem >> 12) & 0xF


def mpu_temp_out(celsius: float) -> int:
    """MPU-6050 register map 4.18: T = TEMP_OUT / 340 + 36.53, as 16-bit two's complement."""
    return round((celsius - 36.53) * 340) & 0xFFFF


@functools.cache
def reported(name: str) -> dict[str, int]:
    done = run_to_done(name)
    return reports(done.stdout)


@pytest.fixture(params=FIRMWARES)
def r(request: pytest.FixtureRequest) -> dict[str, int]:
    return reported(request.param)


def test_who_am_i_reads_0x68(r: dict[str, int]) -> None:
    """One-byte reads (ACK cleared before ADDR is): WHO_AM_I and PWR_MGMT_1's reset value (asleep)."""
    assert r["who_am_i"] == 0x68
    assert r["pwr_mgmt_1_reset"] == 0x40


def test_writes_reach_the_mpu(r: dict[str, int]) -> None:
    assert r["pwr_mgmt_1_awake"] == 0x00
    assert r["int_pin_cfg"] == 0x02  # I2C_BYPASS_EN


def test_the_magnetometer_answers_only_behind_the_bypass(r: dict[str, int]) -> None:
    """GY-86: the HMC5883L hangs off the MPU's auxiliary bus; 0x1E NACKs until the bypass is on. Its
    identification registers A, B, C (a three-byte read: the last three bytes taken at BTF) read 'H43'."""
    assert r["hmc_before_bypass"] == NACKED
    assert r["hmc_after_bypass"] == 0
    assert r["hmc_id"].to_bytes(3, "big") == b"H43"


def test_the_ms5611_prom_reads_with_a_valid_crc(r: dict[str, int]) -> None:
    """Two-byte reads (HAL's POS sequence): the eight PROM words, big-endian."""
    prom = [r[f"prom{k}"] for k in range(8)]
    assert tuple(prom[1:7]) == MS5611_C
    assert crc4(prom) == prom[7] & 0xF
    assert r["prom_crc4"] == crc4(prom)  # the firmware's own AN520 check agrees


def test_a_14_byte_burst_reads_the_sample_at_rest(r: dict[str, int]) -> None:
    """ACCEL_XOUT_H..GYRO_ZOUT_L in one read (N bytes: RXNE, then the last three at BTF). Nothing pushed
    samples: the chip core holds its power-on sample, all zeros (0 m/s², 0 rad/s, a 0 °C die)."""
    assert r["burst_result"] == 0
    burst = b"".join(r[f"burst_{i}"].to_bytes(4, "big") for i in range(3)) + r["burst_3"].to_bytes(2, "big")
    accel, temp, gyro = burst[0:6], int.from_bytes(burst[6:8], "big"), burst[8:14]
    assert accel == bytes(6) and gyro == bytes(6)
    assert temp == mpu_temp_out(0.0) == 0xCF7C


def test_an_absent_address_sets_af_and_the_bus_goes_on(r: dict[str, int]) -> None:
    """27.6.6: AF after an address nobody acknowledges; after STOP the bus works again, idle at the end."""
    assert r["absent_result"] == NACKED
    assert r["absent_sr1"] == SR1_AF
    assert r["who_am_i_after_nack"] == 0x68
    assert r["nacks"] == 2  # the HMC before the bypass, and 0x50
    assert r["sr2_end"] == 0  # neither MSL nor BUSY


def test_status_registers_at_each_event() -> None:
    """RM0090 27.3.3 (figures 243 and 244): EV5 (SB), EV6 in each direction (ADDR, with TXE for the
    transmitter, whose SR2 says TRA), as the polling firmware saw them first."""
    r = reported("i2c_poll")
    assert r["sr1_start"] == SR1_SB
    assert r["sr1_addr_write"] == SR1_ADDR | SR1_TXE
    assert r["sr2_addr_write"] == SR2_MSL | SR2_BUSY | SR2_TRA
    assert r["sr1_addr_read"] == SR1_ADDR
    assert r["sr2_addr_read"] == SR2_MSL | SR2_BUSY


def test_the_error_interrupt_comes_once_per_nack() -> None:
    r = reported("i2c_irq")
    assert r["er_interrupts"] == r["nacks"] == 2
    assert r["ev_interrupts"] > 0


def test_polling_and_interrupts_read_the_same_bytes() -> None:
    seen = [reported(name) for name in FIRMWARES]
    shared = sorted(set(seen[0]) & set(seen[1]))
    assert len(shared) >= 20
    assert {k: seen[0][k] for k in shared} == {k: seen[1][k] for k in shared}


@pytest.mark.parametrize("name", FIRMWARES)
def test_two_runs_are_byte_identical(name: str) -> None:
    engine = engine_or_skip()
    first, second = (run_firmware(engine, firmware(name)) for _ in range(2))
    assert first.returncode == second.returncode == 0
    assert first.stdout == second.stdout


def test_an_abandoned_read_holds_the_bus_until_the_unstick() -> None:
    """A controller reset in the middle of a read leaves the slave holding SDA low: SR2.BUSY stays set
    (27.6.7: set while SDA or SCL is low), as the F4's stuck-bus erratum describes, and PB7's IDR reads
    0. INAV's unstick by GPIO frees it: nine SCL pulses clock the byte out and SDA is released, and a STOP
    made by hand (SDA rising while SCL is high) clears BUSY; then the bus works again."""
    check_unstick(reported("i2c_poll"), scl_pin=6)


def test_on_pb8_pb9_the_unstick_by_gpio_reaches_the_bus() -> None:
    """The F405 datasheet's table 9: I2C1_SCL and I2C1_SDA are AF4 on PB8 and PB9 too (the Black Pill's
    pins). i2c_poll.c built for them reads the same registers, and its unstick by GPIO on PB8/PB9 frees
    the bus the abandoned read left held."""
    check_unstick(reported("i2c_poll_pb8"), scl_pin=8)


def check_unstick(r: dict[str, int], scl_pin: int) -> None:
    scl, sda = 1 << scl_pin, 1 << (scl_pin + 1)
    assert r["abandoned_bytes"] == 0  # ACCEL_XOUT_H/L of the sample at rest
    # 27.6.1: under SWRST the registers hold their reset values (27.6.9: TRISE resets to 2)
    assert (r["cr1_in_reset"], r["cr2_in_reset"], r["trise_in_reset"]) == (1 << 15, 0, 0x0002)
    assert r["sr2_after_reset"] == SR2_BUSY
    assert r["sr2_stuck"] == SR2_BUSY
    assert r["idr_stuck"] == scl
    assert r["idr_after_pulses"] == scl | sda
    assert r["sr2_sda_low"] == SR2_BUSY
    assert r["sr2_after_stop"] == 0
    assert r["who_am_i_after_unstick"] == 0x68


def test_pb8_pb9_carry_the_same_transfers_as_pb6_pb7() -> None:
    """Every register the polling firmware reports reads the same on either pair, but the pins' IDR."""
    on_pb6, on_pb8 = reported("i2c_poll"), reported("i2c_poll_pb8")
    assert set(on_pb6) == set(on_pb8)
    same = [k for k in on_pb6 if not k.startswith("idr_")]
    assert len(same) >= 30
    assert {k: on_pb6[k] for k in same} == {k: on_pb8[k] for k in same}
