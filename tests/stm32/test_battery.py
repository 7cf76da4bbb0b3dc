"""The flight pack on the STM32 tier: tests/stm32/firmware/adc_motor.c on the shipped F405 board, whose
[battery] is a 3S pack at 12.6 V through 10 k / 1 k on PC2 with the pack's defaults (rig/mcu/board.py:
0.015 ohm a cell, 20 A a motor at full throttle), through the MCU session. At zero throttle the pin is
12.6 V's; with motor 1 at full throttle the pack sags by 20 A x 0.045 ohm = 0.9 V (the charge drawn in
the run, 20 A for under 0.15 s, is 0.8 mAh of 1300: under 2 mV of the pack's open-circuit volts, 0.2 mV
at the pin, within a count). A 12-bit code is V / 3.3 x 4095, rounded (tests/stm32/test_adc.py)."""

from __future__ import annotations

from fractions import Fraction

from rig.mcu import board as boards
from rig.mcu.session import McuConfig, McuSession
from rig.world import World
from tests.stm32.conftest import RC_PORT, TEL_PORT, engine_or_skip, firmware
from tests.stm32.test_adc import code


def pin_code(pack_volts: Fraction) -> int:
    return code(pack_volts * 1_000 / (10_000 + 1_000))


def test_the_firmware_sees_the_pack_sag_under_full_throttle() -> None:
    engine_or_skip()
    board = boards.load("stm32f405-gy86")
    world = World.at_rest(seed=0, topology=board.topology)
    try:
        session = McuSession(McuConfig(board, firmware("adc_motor"), 0.2, RC_PORT, TEL_PORT,
                                       listen=frozenset({6})), world)
        outcome = session.run()
    finally:
        world.close()
    assert outcome.verdict == "ok", outcome.error
    lines: list[tuple[float, int]] = []  # each whole line with the step's end it came by (s)
    text = ""
    for t_ns, chunk in session.uart_log[6]:
        text += chunk.decode()
        *whole, text = text.split("\n")
        lines += [(t_ns / 1e9, int(line.split()[-1])) for line in whole]
    full_from = lines[8][0]  # (the 9th reading is taken after the pulse went to 2000 us)
    rest, full = pin_code(Fraction(126, 10)), pin_code(Fraction(117, 10))
    assert (rest, full) == (1421, 1320)
    before = [got for t, got in lines if t < full_from]
    after = [got for t, got in lines if t > full_from + 0.015]
    assert len(before) >= 8 and set(before) == {rest}
    assert len(after) >= 10 and all(abs(got - full) <= 1 for got in after), after
