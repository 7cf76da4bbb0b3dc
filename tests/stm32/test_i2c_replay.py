"""The chip core on the STM32's I2C: every recorded client trace (emulators/traces) replayed by a firmware
(tests/stm32/firmware/i2c_replay.c, ST's HAL polling sequences on I2C1) through the link carries the
trace's messages and gives the bytes the same transfers give through the lockstep path (ChipBus.transfer_ns
at the same times, on a board of its own): the STM32 tier's I2C and the AVR tier's TWI
(tests/mcu/test_twi.py) read what lockstep reads, the same checks (tests/trace_replay.py)."""

from __future__ import annotations

import re

import pytest

from rig.emulators.trace import TRACE_DIR, load
from tests.mcu.gen_traces import TRACE_NAMES
from tests.stm32.conftest import STEP_NS, firmware, run_linked
from tests.trace_replay import board_for, check_replay

#: the firmware's report of a step: the NACK flag, the bytes read in hex
STEP_LINE = re.compile(r"^step=([01]):([0-9a-f]*)$", re.M)
#: a safety net: the longest trace (ardupilot_hmc5843) runs 0.6 s of steps
LIMIT_NS = 2000 * STEP_NS


def parse(out: str) -> list[tuple[int, bytes]]:
    """The firmware's "step=N:HEX" lines, (NACK flag, bytes read) per step; it ends with "done"."""
    assert out.endswith("done\n"), out[-500:]
    return [(int(flag), bytes.fromhex(data)) for flag, data in STEP_LINE.findall(out)]


@pytest.mark.parametrize("name", TRACE_NAMES)
def test_a_trace_through_the_i2c_reads_what_lockstep_reads(name: str) -> None:
    trace = load(TRACE_DIR / f"{name}.json")
    stop, records, out, _ = run_linked(firmware("i2c_replay"), board_for(trace), LIMIT_NS,
                                       settings=bytes([TRACE_NAMES.index(name)]))
    assert stop.kind == "exited", stop.describe()
    check_replay(trace, parse(out), records)
