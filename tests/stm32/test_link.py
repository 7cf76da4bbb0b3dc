"""The STM32 tier in lockstep (rig/mcu/stm32_link.py, qemu/hw/rig_link.c): QEMU runs to the times the
session asks, the I2C bus's events are answered by the session's own chip core (fed by a world, its
sample needs served between steps), a HardFault ends the run naming it, and bad images are refused
before QEMU runs. Expected values: the MPU-6050's datasheet (sensitivity 16384 LSB/g at ±2 g, the
temperature formula of the register map 4.18) and the ARMv7-M Architecture Reference Manual's fault
status bits (B3.2.15, B3.2.16)."""

from __future__ import annotations

import os
import struct
import subprocess
from pathlib import Path

import pytest

from rig.emulators.chips.board import ChipBoard, build_chip_board
from rig.emulators.mpu6050 import ImuTruth
from rig.emulators.ms5611 import BaroTruth
from rig.mcu import board as boards
from rig.mcu.engine import FirmwareError
from rig.mcu.stm32_image import check_image
from rig.mcu.stm32_link import Stm32Config, Stm32Engine
from tests.stm32.conftest import STEP_NS, engine_or_skip, firmware, reports, run_linked

G = 9.80665
#: ARMv7-M ARM B3.2.15: CFSR's UsageFault UNDEFINSTR; B3.2.16: HFSR.FORCED (an escalated fault)
CFSR_UNDEFINSTR = 1 << 16
HFSR_FORCED = 1 << 30


def level_world() -> ChipBoard:
    """A board at rest and level: 1 g up on z, no rotation, 25 °C, sea-level pressure."""
    return build_chip_board(lambda t: ImuTruth((0.0, 0.0, G), (0.0, 0.0, 0.0), 25.0),
                            lambda t: (0.2, 0.0, 0.4), lambda t: BaroTruth(101325.0, 20.0))


def test_the_firmware_reads_the_session_chip_core() -> None:
    """i2c_poll's HAL transfers reach the session's chip core through the link: WHO_AM_I, and a burst of
    the accelerometer, temperature and gyro that is the level world's (needs served on the way); the
    bytes the firmware reports are the bytes the log shows the chip core answered."""
    stop, records, out, needs = run_linked(firmware("i2c_poll"), level_world())
    assert stop.kind == "exited", stop.describe()
    r = reports(out)
    assert r["who_am_i"] == 0x68
    accel_z, temp = r["burst_1"] >> 16, r["burst_1"] & 0xFFFF
    assert accel_z == 16384  # 1 g at ±2 g full scale
    assert temp == round((25.0 - 36.53) * 340) & 0xFFFF
    assert needs > 0
    # the 14-byte read in the log: the same bytes the firmware got
    reads: list[list[int]] = []
    for rec in records:
        if rec.kind == "A":
            reads.append([])
        elif rec.kind == "R":
            reads[-1].append(rec.value)
    burst = next(b for b in reads if len(b) == 14)
    reported = b"".join(r[f"burst_{k}"].to_bytes(4, "big") for k in range(3))
    reported += r["burst_3"].to_bytes(2, "big")
    assert bytes(burst) == reported


def test_two_runs_give_the_same_bytes_at_the_same_times() -> None:
    first = run_linked(firmware("i2c_poll"), level_world())
    second = run_linked(firmware("i2c_poll"), level_world())
    assert [(r.t_ns, r.kind, r.value, r.ack) for r in first[1]] == \
        [(r.t_ns, r.kind, r.value, r.ack) for r in second[1]]
    assert first[1] and first[0].cycle == second[0].cycle


def test_bytes_reach_a_usart_at_their_frame_times_and_come_back() -> None:
    """uart_echo on USART1: an SBUS frame's 25 bytes at 100000 baud 8E2 (12 bits, 120 us a byte: the SBUS
    definition) go in from 1 ms on, and the firmware's echo comes back; by each 100 us step's end no more
    bytes are back than had ended their frames."""
    frame_ns = 12 * 1_000_000_000 // 100_000
    sent = bytes([0x0F, *range(1, 23), 0x00, 0x00])
    board = boards.load("stm32f405-gy86")
    engine = Stm32Engine(Stm32Config(board, firmware("uart_echo"), engine_or_skip()), None)
    echoed = bytearray()
    try:
        t = 1_000_000
        assert engine.run_until(t).kind == "reached"
        engine.uart_send(1, sent, 100_000, "E", 2)
        while t < 1_000_000 + 30 * frame_ns:
            t += 100_000
            assert engine.run_until(t).kind == "reached"
            echoed += engine.uart_take(1)
            assert len(echoed) <= (t - 1_000_000) // frame_ns
        assert engine.uart_take(2) == b""
    finally:
        engine.close()
    assert bytes(echoed) == sent


def test_a_firmware_that_does_nothing_for_the_hang_limit_is_hung() -> None:
    """uart_echo with nothing to echo: no I2C, no pulse, no byte sent; with a 5 ms limit the run stops
    at the first step at or after 5 ms."""
    board = boards.load("stm32f405-gy86")
    cfg = Stm32Config(board, firmware("uart_echo"), engine_or_skip(), hang_ns=5 * STEP_NS)
    engine = Stm32Engine(cfg, None)
    try:
        t = 0
        while (stop := engine.run_until(t + STEP_NS)).kind == "reached":
            t += STEP_NS
    finally:
        engine.close()
    assert stop.kind == "hung" and "for 5 ms" in stop.what
    assert t + STEP_NS == 5 * STEP_NS


def test_a_hardfault_ends_the_run_naming_it() -> None:
    """fault_spin: an undefined instruction, escalated to a HardFault whose handler spins."""
    stop, _, _, _ = run_linked(firmware("fault_spin"), None, 5 * STEP_NS)
    assert stop.kind == "crashed"
    assert "HardFault" in stop.what
    assert f"CFSR 0x{CFSR_UNDEFINSTR:08x}" in stop.what and f"HFSR 0x{HFSR_FORCED:08x}" in stop.what
    assert stop.pc != 0


def test_a_lockup_ends_the_run_naming_it() -> None:
    """fault_lockup: a fault with FAULTMASK set cannot escalate; QEMU stops with the registers, pc among
    them: the undefined instruction's, main's second (CPSID is a 16-bit Thumb instruction)."""
    elf = firmware("fault_lockup")
    nm = subprocess.run(["arm-none-eabi-nm", str(elf)], capture_output=True, text=True, check=True)
    symbols = nm.stdout
    main = next(int(line.split()[0], 16) for line in symbols.splitlines() if line.endswith(" main"))
    stop, _, _, _ = run_linked(elf, None, 5 * STEP_NS)
    assert stop.kind == "crashed"
    assert "locked up (Lockup: can't escalate" in stop.what
    assert stop.pc == main + 2


def _patched(tmp_path: Path, offset: int, value: bytes) -> Path:
    data = bytearray(firmware("i2c_poll").read_bytes())
    data[offset:offset + len(value)] = value
    out = tmp_path / "patched.elf"
    out.write_bytes(bytes(data))
    return out


def test_an_avr_image_is_refused(tmp_path: Path) -> None:
    """e_machine 83 (EM_AVR, the System V ABI's registry) instead of 40 (EM_ARM)."""
    with pytest.raises(FirmwareError, match="AVR"):
        check_image(_patched(tmp_path, 18, struct.pack("<H", 83)))


def test_a_truncated_image_is_refused(tmp_path: Path) -> None:
    data = firmware("i2c_poll").read_bytes()
    cut = tmp_path / "cut.elf"
    cut.write_bytes(data[:len(data) // 3])
    with pytest.raises(FirmwareError, match="cut short"):
        check_image(cut)
    with pytest.raises(FirmwareError, match="not an ELF"):
        check_image(_patched(tmp_path, 0, b"\0\0\0\0"))


def test_a_good_image_passes() -> None:
    check_image(firmware("i2c_poll"))


@pytest.mark.parametrize("one_core", [True, False])
def test_qemu_runs_on_the_callers_core_and_the_callers_affinity_comes_back(one_core: bool) -> None:
    """In lockstep QEMU and the session take turns: with one_core (the default) QEMU's threads run on the
    one core the calling thread is pinned to for the run, and the thread's own affinity is given back at
    close(); without it, QEMU may run wherever the caller may."""
    before = os.sched_getaffinity(0)
    engine = Stm32Engine(Stm32Config(boards.load("stm32f405-gy86"), firmware("i2c_poll"), engine_or_skip(),
                                     one_core=one_core), level_world())
    try:
        assert engine.run_until(STEP_NS).kind in ("reached", "need")
        during = os.sched_getaffinity(0)
        threads = [int(tid) for tid in os.listdir(f"/proc/{engine._proc.pid}/task")]
        qemu = {frozenset(os.sched_getaffinity(tid)) for tid in threads}
    finally:
        engine.close()
    if one_core:
        assert len(during) == 1 and qemu == {frozenset(during)}
    else:
        assert during == before and qemu == {frozenset(before)}
    assert os.sched_getaffinity(0) == before
