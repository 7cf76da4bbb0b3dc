"""A battery on an ADC pin: the pack's voltage through the divider the board file gives reaches the
MCU's ADC, so a voltage-compensating firmware sees one (before, analogRead gave 0). The datasheets'
conversion: ADC = VIN * 1024 / VREF (single-ended), VREF = AVCC = 5 V on these boards; the pin is
clamped at VCC by its protection diodes. In a session the pack sags with the motors' current (Ohm's
law through its internal resistance) and a scenario's fault on it: the firmware's readings follow."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rig.battery import Pack
from rig.emulators.faults import Fault, FaultSet
from rig.mcu import board
from rig.mcu.board import BoardError
from rig.mcu.engine import AvrEngine, config_for
from rig.mcu.session import McuConfig, McuSession
from rig.targets.mcu import McuRun
from rig.world import World
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
     ('pin = "PC0"\nvolts = -1', "battery.volts", "expected a number in 0..60"),
     ('pin = "PC0"\nvolts = 12.6\ncells = 2', "battery.volts", "6.300 V a cell for 2 cell(s)"),
     ('pin = "PC0"\nvolts = 2.0', "battery.volts", "2.000 V a cell for 1 cell(s)"),
     ('pin = "PC0"\ncells = 0', "battery.cells", "expected an integer in 1..14"),
     ('pin = "PC0"\ncapacity_mah = 0', "battery.capacity_mah", "expected a number > 0"),
     ('pin = "PC0"\ninternal_ohms = -0.1', "battery.internal_ohms", "expected a number in 0..10"),
     ('pin = "PC0"\nmotor_amps = "20"', "battery.motor_amps", "expected a finite number"),
     ('pin = "PC0"\nidle_amps = -1', "battery.idle_amps", "expected a number in 0..1000"),
     ('pin = "PC0"\namps = 1', "battery.amps", "unknown key")],
)
def test_battery_mistakes_name_the_key(tmp_path: Path, table: str, key: str, words: str) -> None:
    path = tmp_path / "b.toml"
    path.write_text(NANO + f"\n[battery]\n{table}\n")
    with pytest.raises(BoardError) as e:
        board.load(path)
    assert e.value.key == key and words in str(e.value)


def test_the_packs_defaults_keep_a_board_at_its_volts(tmp_path: Path) -> None:
    """cells from the volts (4.2 V a full cell), and no idle draw: at rest the pack holds its volts."""
    path = tmp_path / "b.toml"
    path.write_text(NANO + '\n[battery]\npin = "PC0"\nvolts = 16.8\n')
    b = board.load(path).battery
    assert b is not None and b.volts == 16.8
    assert b.pack == Pack(16.8, 4, capacity_mah=1300.0, internal_ohms=0.06, motor_amps=20.0, idle_amps=0.0)
    path.write_text(NANO + '\n[battery]\npin = "PC0"\nvolts = 7.4\ncells = 2\ncapacity_mah = 450\n'
                           "internal_ohms = 0.08\nmotor_amps = 6\nidle_amps = 0.3\n")
    b = board.load(path).battery
    assert b is not None and b.pack == Pack(7.4, 2, 450.0, 0.08, 6.0, 0.3)


#: adc_motor.c's board: the Mega with a 3S pack on PF0 through 10 k / 3.3 k; 0.1 ohm, 20 A a motor
SAG_BOARD = (BOARDS["atmega2560"] + '\n[battery]\npin = "PF0"\ndivider = [10_000, 3_300]\nvolts = 12.6\n'
             "internal_ohms = 0.1\nmotor_amps = 20\n")


def test_the_firmware_sees_the_pack_sag_under_throttle_and_a_fault(tmp_path: Path) -> None:
    """adc_motor.c reads the battery every ~11 ms, motor 1 at zero throttle for its first 25 readings,
    then full. At rest the pin is 12.6 V's; from 0.10 to 0.18 s a bias step of -1 V on the battery
    gives 11.6 V's; at full throttle 20 A through 0.1 ohm sags the pack by 2 V (the charge drawn in the
    run, 20 A for under 0.3 s, is 1.7 mAh of 1300: its open-circuit fall under 10 mV, within a count)."""
    path = tmp_path / "b.toml"
    path.write_text(SAG_BOARD)
    b = board.load(path)
    assert b.battery is not None
    faults = FaultSet()
    faults.add(Fault("bias_step", 0.10, 0.18, magnitude=-1.0))
    world = World.at_rest(seed=0, topology=b.topology, faults={"battery": faults}, battery=b.battery.pack)
    try:
        session = McuSession(McuConfig(b, firmware("adc_motor", "atmega2560"), 0.5, "/dev/ttyRC0",
                                       "/dev/ttyTEL0", listen=frozenset({0})), world)
        outcome = session.run()
    finally:
        world.close()
    assert outcome.verdict == "ok", outcome.error
    # each whole line with the step's end it came by (s)
    lines: list[tuple[float, int]] = []
    text = ""
    for t_ns, chunk in session.uart_log[0]:
        text += chunk.decode()
        *whole, text = text.split("\r\n")
        lines += [(t_ns / 1e9, int(line.split()[-1])) for line in whole]
    full_from = lines[25][0]  # (the 26th reading is taken after the pulse went to 2000 us)
    rest, fault, full = (expected(volts, 10_000, 3_300) for volts in (12.6, 11.6, 10.6))
    assert full < fault < rest
    seen = {rest: 0, fault: 0, full: 0}
    for t, got in lines:
        if t < 0.095 or 0.2 < t < full_from:
            want = rest
        elif 0.115 < t < 0.175:
            want = fault
        elif t > full_from + 0.015:
            want = full
        else:
            continue  # (a reading near a change: either)
        assert abs(got - want) <= 1, (t, got, want)
        seen[want] += 1
    assert min(seen.values()) >= 5, seen
    # the pack's volts as the run's signal has them (telemetry.csv's battery_volts): at rest, in the fault,
    # under the motor
    volts = McuRun(session).signals(np.array([0.05, 0.15, 0.49]))["battery_volts"]
    assert volts == pytest.approx([12.6, 11.6, 10.6], abs=0.01)
