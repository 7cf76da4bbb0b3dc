"""Bad firmware ends its run with an error that names what happened, and the rig (this process) lives on:
a bus no chip answers (with the last TWI transaction), a store far outside SRAM. (Hangs, watchdog loops,
wild jumps, invalid opcodes and sleeping for ever: tests/mcu/test_engine.py.)"""

from __future__ import annotations

import pytest

from rig.emulators.chips.board import ChipBoard, build_chip_board
from rig.emulators.mpu6050 import ImuTruth
from rig.emulators.ms5611 import BaroTruth
from rig.mcu.engine import AvrEngine, EngineConfig
from tests.mcu.conftest import MCUS, firmware

CLOCK = 16_000_000


def board() -> ChipBoard:
    return build_chip_board(lambda t: ImuTruth((0.0, 0.0, 9.81), (0.0, 0.0, 0.0), 25.0),
                            lambda t: (0.2, 0.0, 0.4), lambda t: BaroTruth(101325.0, 25.0))


@pytest.mark.parametrize("mcu", MCUS)
def test_a_bus_no_chip_answers_ends_the_run_naming_the_transaction(mcu: str) -> None:
    cfg = EngineConfig(mcu, CLOCK, firmware("twi_ghost", mcu), unanswered_ns=30_000_000)
    with AvrEngine(cfg, board()) as e:
        stop = e.run_served(1_000_000_000)
        figures = e.figures()
    assert stop.kind == "unanswered" and "addresses in a row not acknowledged" in stop.what
    assert stop.describe().startswith("talks to a bus no chip answers: ")
    assert 30_000_000 <= stop.cycle * 10**9 // CLOCK < 32_000_000
    assert "50W-" in stop.last_twi and stop.last_twi.endswith("P")  # 0x50, write, not acknowledged
    assert "last TWI transaction" in stop.describe()
    assert figures["twi_nacks"] == figures["twi_transactions"] >= 25


def test_without_the_check_the_nacks_are_counted_only() -> None:
    cfg = EngineConfig("atmega328p", CLOCK, firmware("twi_ghost", "atmega328p"), unanswered_ns=0)
    with AvrEngine(cfg, board()) as e:
        assert e.run_served(20_000_000).kind == "reached"
        assert e.figures()["twi_nacks"] >= 15


@pytest.mark.parametrize("mcu", MCUS)
def test_a_store_far_outside_sram_is_a_crash_and_the_process_lives(mcu: str) -> None:
    with AvrEngine(EngineConfig(mcu, CLOCK, firmware("wild_write", mcu)), None) as e:
        stop = e.run_until(5_000_000)
    assert stop.kind == "crashed" and "fff0" in stop.what.lower() and stop.cycle < 200
    with AvrEngine(EngineConfig(mcu, CLOCK, firmware("busy", mcu), hang_ns=0), None) as e:
        assert e.run_until(1_000_000).kind == "reached"  # the next run is unharmed
