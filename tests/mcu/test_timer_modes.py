"""A timer in a mode simavr 1.6 lacks (rig/mcu/timer_modes.c): Timer3 in phase correct PWM with TOP = ICR3
(WGM 10, the reference FC's motor mode), clk/8. simavr runs it with TOP 0, an overflow every 8 cycles
(TOV3 set at once); the glue stops it in simavr: TOV3 stays clear, and the motor's pulses, the cycles
and the instructions are the same as with simavr's own behaviour (the pulses are the glue's, from the
registers: the datasheet's 2 * OCR3B * 8 cycles high)."""

from __future__ import annotations

from rig.mcu.engine import TIMERS, AvrEngine, EngineConfig, Motor
from tests.mcu.conftest import firmware

CLOCK = 16_000_000
TIFR3, TOV3 = 0x38, 0x01
DDRE = 0x2D
TOP, OCR = 5000, 1000


def script() -> bytes:
    _, tccra, tccrb, tcnt, icr, _, ocrb, _ = TIMERS["atmega2560"][3]
    writes = [(DDRE, 0x10), (tccra, 0x20 | 0x02), (tccrb, 0x10), (icr + 1, TOP >> 8), (icr, TOP & 0xFF),
              (ocrb + 1, OCR >> 8), (ocrb, OCR & 0xFF), (tcnt + 1, 0), (tcnt, 0), (tccrb, 0x10 | 0x02)]
    return b"".join(a.to_bytes(2, "little") + bytes([v]) for a, v in writes) + b"\xff\xff\x00"


def fly(stock: bool) -> tuple[list[list[tuple[int, int, int]]], dict[str, object], int]:
    cfg = EngineConfig("atmega2560", CLOCK, firmware("regscript", "atmega2560"), eeprom=script(), hang_ns=0,
                       motors=(Motor("PE4", 3, "B"),))
    with AvrEngine(cfg, None) as e:
        e.stock(timer_modes=stock)
        pulses: list[list[tuple[int, int, int]]] = []
        for k in range(1, 21):
            assert e.run_until(k * 1_000_000).kind == "reached"
            pulses.append(e.pulses()[0])
        figures = {k: v for k, v in e.figures().items() if k not in ("sim_ns", "pc", "sp")}
        return pulses, figures, e.peek(TIFR3)


def test_a_timer_in_a_mode_simavr_lacks_is_stopped_in_simavr_and_pulses_alike() -> None:
    fixed, stock = fly(False), fly(True)
    assert fixed[0] == stock[0] and fixed[1] == stock[1]
    widths = {w for step in fixed[0] for _, w, _ in step}
    assert widths == {round(2 * OCR * 8 / CLOCK * 1e9)}
    assert stock[2] & TOV3 and not fixed[2] & TOV3
