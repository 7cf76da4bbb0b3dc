"""A battery on an ADC pin: the pack's voltage through the divider the board file gives reaches the
MCU's ADC, so a voltage-compensating firmware sees one (before, analogRead gave 0). The datasheets'
conversion: ADC = VIN * 1024 / VREF (single-ended), VREF = AVCC = 5 V on these boards; the pin is
clamped at VCC by its protection diodes."""

from __future__ import annotations

from pathlib import Path

import pytest

from rig.mcu import board
from rig.mcu.board import BoardError
from rig.mcu.engine import AvrEngine, config_for
from tests.mcu.conftest import firmware

NANO = board.find("nano328-gy521").read_text()
BOARDS = {"atmega328p": NANO, "atmega2560": board.find("mega2560-gy86").read_text()}


def readings(path: Path, mcu: str) -> set[int]:
    b = board.load(path)
    with AvrEngine(config_for(b, firmware("adc_batt", mcu), twi=False, hang_ns=0), None) as e:
        assert e.run_until(100_000_000).kind == "reached"
        lines = e.uart_take(0).decode().split("\r\n")[:-1]  # (whole lines: the last may be cut)
    return {int(line.split()[-1]) for line in lines if line.startswith("# adc ")}


def expected(volts: float, top: float, bottom: float) -> int:
    return min(1023, int(volts * bottom / (top + bottom) * 1024 / 5.0))


@pytest.mark.parametrize(("mcu", "pin"), [("atmega328p", "PC0"), ("atmega2560", "PF0")])
@pytest.mark.parametrize(("volts", "divider"), [(12.6, (10_000, 3_300)), (16.8, (20_000, 4_700)),
                                                (12.6, (0, 1))])
def test_the_battery_reaches_the_adc_through_its_divider(tmp_path: Path, mcu: str, pin: str, volts: float,
                                                         divider: tuple[int, int]) -> None:
    path = tmp_path / "b.toml"
    path.write_text(BOARDS[mcu] +
                    f'\n[battery]\npin = "{pin}"\ndivider = [{divider[0]}, {divider[1]}]\nvolts = {volts}\n')
    got = readings(path, mcu)
    want = expected(volts, *divider)
    # (simavr scales by 1023, not the datasheet's 1024: within 1 LSB)
    assert len(got) == 1 and abs(got.pop() - want) <= 1, (got, want)


def test_without_a_battery_the_adc_reads_0(tmp_path: Path) -> None:
    path = tmp_path / "b.toml"
    path.write_text(NANO)
    assert readings(path, "atmega328p") == {0}


@pytest.mark.parametrize(
    ("table", "key", "words"),
    [('pin = "PD0"', "battery.pin", "analog inputs are PC0, PC1"),
     ('pin = "PC0"\ndivider = [10000, 0]', "battery.divider", "the second > 0"),
     ('pin = "PC0"\nvolts = -1', "battery.volts", "expected a number in 0..60")],
)
def test_battery_mistakes_name_the_key(tmp_path: Path, table: str, key: str, words: str) -> None:
    path = tmp_path / "b.toml"
    path.write_text(NANO + f"\n[battery]\n{table}\n")
    with pytest.raises(BoardError) as e:
        board.load(path)
    assert e.value.key == key and words in str(e.value)
