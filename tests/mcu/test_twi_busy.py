"""TWCR written while the TWI is busy, as the datasheet allows (ATmega640/1280/1281/2560/2561 datasheet
2549Q, "2-wire Serial Interface"; the ATmega328P's TWI is the same): the twi_busy firmware writes each
case and reports the statuses it saw. The expected codes are the datasheet's (avr-libc's util/twi.h
spells them: TW_START 0x08, TW_REP_START 0x10, TW_MT_SLA_ACK 0x18, TW_MT_DATA_ACK 0x28, TW_MR_SLA_ACK
0x40, TW_MR_DATA_ACK 0x50, TW_MR_DATA_NACK 0x58); the MPU-6050's WHO_AM_I (register 0x75) reads 0x68
(its register map, 4.32)."""

from __future__ import annotations

import pytest

from rig.emulators.chips.board import ChipBoard, build_chip_board
from rig.emulators.mpu6050 import ImuTruth
from rig.emulators.ms5611 import BaroTruth
from rig.mcu.engine import AvrEngine, EngineConfig, TwiRecord
from tests.mcu.conftest import MCUS, firmware

CLOCK = 16_000_000
ROUNDS = 100  # twi_busy.c
TW_START, TW_REP_START, TW_MT_SLA_ACK, TW_MT_DATA_ACK = 0x08, 0x10, 0x18, 0x28
TW_MR_SLA_ACK, TW_MR_DATA_ACK, TW_MR_DATA_NACK = 0x40, 0x50, 0x58
WHO_AM_I = 0x68
TWSTO, TWINT = 0x10, 0x80


def board() -> ChipBoard:
    return build_chip_board(lambda t: ImuTruth((0.0, 0.0, 9.81), (0.0, 0.0, 0.0), 25.0),
                            lambda t: (0.2, 0.0, 0.4), lambda t: BaroTruth(101325.0, 25.0))


def run_case(case: int, mcu: str) -> tuple[bytes, list[TwiRecord], dict[str, object]]:
    """What the firmware reported (without its end mark), the TWI's records, the engine's figures."""
    cfg = EngineConfig(mcu, CLOCK, firmware("twi_busy", mcu), eeprom=bytes([case]), hang_ns=0)
    out = b""
    with AvrEngine(cfg, board()) as e:
        e.twi_log()
        t = 0
        while not out.endswith(b"\x5a\x5a") and t < 200_000_000:
            t += 1_000_000
            assert e.run_served(t).kind == "reached"
            out += e.uart_take(0)
        records = e.twi_take()
        figures = e.figures()
    assert out.endswith(b"\x5a\x5a"), out.hex()
    return out[:-2], records, figures


@pytest.mark.parametrize("mcu", MCUS)
@pytest.mark.parametrize("together", [False, True], ids=["stop-then-start", "stop-and-start"])
def test_a_start_asked_during_a_stop_follows_it(mcu: str, together: bool) -> None:
    """TWSTA: "if the bus is not free, the TWI waits until a STOP condition is detected, and then
    generates a new START condition"; TWCR = TWINT|TWSTA|TWSTO after a status: "STOP condition followed
    by a START condition will be transmitted and TWSTO Flag will be reset" (Table 24-3). Written as two
    writes (STOP, then START at once: MultiWii's i2c_stop(); i2c_rep_start();) or one, each of the 100
    STARTs sets TWINT with 0x08, a START on a free bus, and no wait is given up."""
    out, records, figures = run_case(1 if together else 0, mcu)
    starts, reads = out[:ROUNDS], out[ROUNDS:]
    assert list(starts) == [TW_START] * ROUNDS
    assert list(reads) == [WHO_AM_I] * ROUNDS
    assert figures["twi_abandoned"] == figures["twi_ignored"] == 0
    # on the bus: each round a transfer of its own, STOP then START
    assert "".join(r.kind for r in records) == "S" + "AWSARPS" * ROUNDS + "P"


@pytest.mark.parametrize("mcu", MCUS)
def test_twea_changed_while_a_byte_is_received_decides_its_ack(mcu: str) -> None:
    """TWEA: "the ACK pulse is generated on the TWI bus if ... A data byte has been received in Master
    Receiver ... mode": the bit as it is when the byte has been received, whatever it was when TWINT was
    cleared."""
    out, records, _ = run_case(2, mcu)
    assert list(out) == [TW_MR_SLA_ACK, TW_MR_DATA_ACK, TW_MR_DATA_NACK]
    assert [r.ack for r in records if r.kind == "R"] == [True, False]


@pytest.mark.parametrize("mcu", MCUS)
def test_a_stop_asked_during_a_stop_is_one_stop(mcu: str) -> None:
    """TWSTO: "When the STOP condition is executed on the bus, the TWSTO bit is cleared automatically";
    "TWINT is NOT set after a STOP condition has been sent" (Using the TWI). The second request joins the
    STOP under way: one STOP on the bus, and the next START is a START on a free bus."""
    out, records, _ = run_case(3, mcu)
    assert list(out) == [0, 0, TW_START]
    assert "".join(r.kind for r in records) == "SAPSP"


@pytest.mark.parametrize("mcu", MCUS)
def test_a_start_asked_while_a_byte_is_on_the_bus_is_ignored(mcu: str) -> None:
    """TWINT: "Writing a one to TWINT clears the flag. The TWI will then commence executing whatever
    operation was specified": while the address byte is on the bus the flag is already clear, so a
    second write starts nothing; the byte ends with its own status. The rig counts the request."""
    out, records, figures = run_case(4, mcu)
    assert list(out) == [TW_MT_SLA_ACK, TW_MT_DATA_ACK]
    assert "".join(r.kind for r in records) == "SAWP"
    assert figures["twi_ignored"] == 1 and figures["twi_abandoned"] == 0


@pytest.mark.parametrize("mcu", MCUS)
def test_a_start_given_up_before_twint_is_counted_and_the_bus_recovers(mcu: str) -> None:
    """TWEN: "If this bit is written to zero, the TWI is switched off and all TWI transmissions are
    terminated, regardless of any ongoing operation": a START then TWCR = 0 before TWINT is a wait the
    firmware gave up on, counted; the next START is a START on a free bus."""
    out, _, figures = run_case(5, mcu)
    assert list(out) == [TW_START]
    assert figures["twi_abandoned"] == 1 and figures["twi_ignored"] == 0
