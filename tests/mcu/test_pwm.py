"""Motor pulses from every timer mode that can make an ESC pulse, on the 16-bit timers 1, 3, 4 and the
8-bit timers 0, 2: widths and periods exactly the datasheets' formulas (P the prescaler, TOP the mode's):
fast PWM (OCR + 1) P every (TOP + 1) P; phase correct and phase and frequency correct 2 OCR P every
2 TOP P. One firmware (regscript) writes the registers the test puts in its EEPROM."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from rig.mcu.engine import OC_PINS, PORTS, TIMERS, AvrEngine, EngineConfig, Motor
from tests.mcu.conftest import firmware

CLOCK = 16_000_000
NS_PER_CYCLE = 1e9 / CLOCK


@dataclass(frozen=True)
class Case:
    name: str
    wgm: int
    kind: str  # fast | pc | pfc
    top: int | None  # fixed TOP, else the register's value below
    top_reg: str | None = None  # "icr" | "ocra"


WIDE = [Case("fast8", 5, "fast", 0xFF), Case("fast9", 6, "fast", 0x1FF), Case("fast10", 7, "fast", 0x3FF),
        Case("fast_icr", 14, "fast", None, "icr"), Case("fast_ocra", 15, "fast", None, "ocra"),
        Case("pc8", 1, "pc", 0xFF), Case("pc9", 2, "pc", 0x1FF), Case("pc10", 3, "pc", 0x3FF),
        Case("pc_icr", 10, "pc", None, "icr"), Case("pc_ocra", 11, "pc", None, "ocra"),
        Case("pfc_icr", 8, "pfc", None, "icr"), Case("pfc_ocra", 9, "pfc", None, "ocra")]
NARROW = [Case("fast8", 3, "fast", 0xFF), Case("fast_ocra", 7, "fast", None, "ocra"),
          Case("pc8", 1, "pc", 0xFF), Case("pc_ocra", 5, "pc", None, "ocra")]


def script(writes: list[tuple[int, int]]) -> bytes:
    out = b"".join(addr.to_bytes(2, "little") + bytes([v]) for addr, v in writes)
    return out + b"\xff\xff\x00"


def setup(mcu: str, timer: int, channel: str, case: Case, ocr: int, top: int,
          cs: int) -> list[tuple[int, int]]:
    wide, tccra, tccrb, _tcnt, icr, ocra, ocrb, ocrc = TIMERS[mcu][timer]
    ch = "ABC".index(channel)
    pin = OC_PINS[mcu][(timer, channel)]
    ddr = PORTS[mcu][pin[1]] + 1
    writes = [(ddr, 1 << int(pin[2]))]

    def reg(addr: int, value: int) -> None:
        if wide:
            writes.append((addr + 1, value >> 8))
        writes.append((addr, value & 0xFF))

    if case.top_reg == "icr":
        reg(icr, top)
    elif case.top_reg == "ocra":
        reg(ocra, top)
    reg((ocra, ocrb, ocrc)[ch], ocr)
    a = (2 << (6 - 2 * ch)) | (case.wgm & 3)
    b = ((case.wgm >> 2) & (3 if wide else 1)) << 3 | cs
    writes += [(tccra, a), (tccrb, b)]
    return writes


def expected(case: Case, ocr: int, top: int, prescale: int) -> tuple[int, int]:
    t = case.top if case.top is not None else top
    if case.kind == "fast":
        cycles = ((ocr + 1) * prescale, (t + 1) * prescale)
    else:
        cycles = (2 * ocr * prescale, 2 * t * prescale)
    return round(cycles[0] * NS_PER_CYCLE), round(cycles[1] * NS_PER_CYCLE)


def run(mcu: str, timer: int, channel: str, writes: list[tuple[int, int]],
        t_ns: int) -> list[tuple[int, int, int]]:
    cfg = EngineConfig(mcu, CLOCK, firmware("regscript", mcu), motors=(Motor(OC_PINS[mcu][(timer, channel)],
                                                                               timer, channel),),
                       eeprom=script(writes), hang_ns=0)
    with AvrEngine(cfg, None) as e:
        stop = e.run_until(t_ns)
        assert stop.kind == "reached"
        return e.pulses()[0]


def check(pulses: list[tuple[int, int, int]], width: int, period: int) -> None:
    assert len(pulses) >= 4
    for _, w, p in pulses[1:]:
        assert (w, p) == (width, period)
    rises = [r for r, _, _ in pulses[1:]]
    assert {b - a for a, b in zip(rises, rises[1:], strict=False)} == {period}


@pytest.mark.parametrize("case", WIDE, ids=lambda c: c.name)
@pytest.mark.parametrize(("mcu", "timer"), [("atmega328p", 1), ("atmega2560", 3), ("atmega2560", 4)])
def test_16_bit_timer_modes(mcu: str, timer: int, case: Case) -> None:
    channel = "B"  # A is TOP in the OCRA modes
    fixed = case.top is not None
    prescale, cs = (64, 3) if fixed else (8, 2)
    top = 5000
    ocr = 100 if fixed else 2000
    pulses = run(mcu, timer, channel, setup(mcu, timer, channel, case, ocr, top, cs), 40_000_000)
    check(pulses, *expected(case, ocr, top, prescale))


@pytest.mark.parametrize("case", NARROW, ids=lambda c: c.name)
@pytest.mark.parametrize(("mcu", "timer"), [("atmega328p", 0), ("atmega328p", 2), ("atmega2560", 0),
                                            ("atmega2560", 2)])
def test_8_bit_timer_modes(mcu: str, timer: int, case: Case) -> None:
    cs = 4 if timer == 2 else 3  # 64 on both (timer 2 has the 32 step)
    pulses = run(mcu, timer, "B", setup(mcu, timer, "B", case, 100, 200, cs), 20_000_000)
    check(pulses, *expected(case, 100, 200, 64))


def test_no_pulse_from_a_pin_that_is_not_an_output() -> None:
    case = WIDE[3]
    writes = setup("atmega2560", 3, "B", case, 2000, 5000, 2)[1:]  # no DDR write
    assert run("atmega2560", 3, "B", writes, 20_000_000) == []


def test_a_compare_value_is_taken_where_the_hardware_latches_it() -> None:
    """Phase correct latches OCR at TOP: a pulse is 2 OCR P with one OCR, never half of each; phase and
    frequency correct latches at BOTTOM, inside the pulse: one pulse has the old half and the new one."""
    for case, mixed in ((WIDE[8], False), (WIDE[10], True)):  # pc_icr, pfc_icr
        writes = setup("atmega2560", 3, "B", case, 2000, 5000, 2)
        ocrb = TIMERS["atmega2560"][3][6]
        writes += [(0xFFFE, 12), (ocrb + 1, 1000 >> 8), (ocrb, 1000 & 0xFF)]
        widths = [w for _, w, _ in run("atmega2560", 3, "B", writes, 40_000_000)[1:]]
        old, new = 2 * 2000 * 500, 2 * 1000 * 500
        between = [w for w in widths if w not in (old, new)]
        assert widths[0] == old and widths[-1] == new
        assert between == ([(2000 + 1000) * 500] if mixed else [])


def test_a_motor_without_a_timer_is_measured_from_its_pin_edges() -> None:
    """Software PWM: the firmware sets and clears the pin itself (here 2 ms high every 5 ms)."""
    portb, ddrb = 0x25, 0x24
    writes = [(ddrb, 0x02)]
    for _ in range(4):
        writes += [(portb, 0x02), (0xFFFE, 2), (portb, 0x00), (0xFFFE, 3)]
    cfg = EngineConfig("atmega328p", CLOCK, firmware("regscript", "atmega328p"), motors=(Motor("PB1", None),),
                       eeprom=script(writes), hang_ns=0)
    with AvrEngine(cfg, None) as e:
        e.run_until(30_000_000)
        pulses = e.pulses()[0]
    assert len(pulses) == 4
    for i, (_, width, period) in enumerate(pulses):
        assert abs(width - 2_000_000) < 20_000  # _delay_ms and the EEPROM reads: within 1 %
        assert period == 0 if i == 0 else abs(period - 5_000_000) < 50_000
