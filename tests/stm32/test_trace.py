"""The STM32 tier's `--trace` (rig/mcu/vcd.py, as the AVR tier's): `rig exec --mcu stm32f405-gy86` with
the reference FC writes a VCD whose SCL and SDA, read back by an independent reader (vcdvcd) and decoded
by tests/mcu/test_trace.py's I2C decoder, carry as many STARTs with an address and bytes as the run's
figures count (the link has a START when its address byte ended: the trace draws it that byte's time
before), each motor output as many rising edges as pulses counted, and two runs of a seed give
byte-identical files."""

from __future__ import annotations

import json
from pathlib import Path

from rig.mcu import board as boards
from tests.mcu.test_trace import check_trace_against_figures, read, rig_exec
from tests.stm32.conftest import REPO, engine_or_skip

BOARD = "stm32f405-gy86"


def test_exec_traces_what_its_figures_count_and_the_same_bytes_twice(tmp_path: Path) -> None:
    engine_or_skip()
    fc = REPO / "build" / "stm32" / "fc.elf"
    runs = []
    for k in "ab":
        done = rig_exec("--mcu", BOARD, "--firmware", fc, "--duration", "1.2", "--seed", 1,
                        "--summary", tmp_path / f"{k}.json", "--trace", tmp_path / k)
        assert done.returncode == 0, done.stderr
        runs.append(json.loads((tmp_path / f"{k}.json").read_text()))
    assert (tmp_path / "a" / "fc.vcd").read_bytes() == (tmp_path / "b" / "fc.vcd").read_bytes()
    mcu = runs[0]["mcu"]
    assert runs[0]["verdict"] == "ok" and mcu["twi_nacks"] == 0
    motors = [f"m{motor.motor}_{motor.pin}" for motor in boards.load(BOARD).motors]
    check_trace_against_figures(read(tmp_path / "a" / "fc.vcd"), mcu, motors)
