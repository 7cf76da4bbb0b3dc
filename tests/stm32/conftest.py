"""The STM32 tier's tests run the rig's test firmwares (tests/stm32/firmware, built by make as the MCU
tier's are) under the engine `make stm32-engine` built (rig/mcu/stm32_engine.py; `make test` builds it
first). The engine is never built here: it takes minutes (docs/build.md); run by hand without it, a test
that needs it skips, naming the command."""

from __future__ import annotations

import functools
import re
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest

from rig.emulators import sbus
from rig.emulators.chips.board import ChipBoard
from rig.mcu import board as boards
from rig.mcu import stm32_engine
from rig.mcu.board import Board
from rig.mcu.engine import Stop, TwiRecord
from rig.mcu.session import McuConfig, McuSession
from rig.mcu.stm32_link import Stm32Config, Stm32Engine
from rig.world import World
from tests.suite_rules import NOT_BUILT

REPO = Path(__file__).resolve().parents[2]
#: the instruction count's period under -icount: 2**3 ns, 125 M instructions per virtual second
ICOUNT_SHIFT = 3
#: a safety net against a firmware that never ends (a test fails, QEMU is killed and reaped): not a
#: timing threshold, these firmwares end in well under a second
RUN_TIMEOUT_S = 60.0
#: the lockstep runs' step (run_linked)
STEP_NS = 1_000_000
REPORT_LINE = re.compile(r"([a-z0-9_]+)=0x([0-9a-f]{8})")


def engine_or_skip() -> Path:
    binary = stm32_engine.cached_binary()
    if binary is None:
        pytest.skip(f"{NOT_BUILT}the STM32 engine for the current sources: `make stm32-engine` builds it "
                    "(QEMU from source, many minutes on 2 cores; docs/build.md)")
    return binary


@functools.cache
def firmware(name: str) -> Path:
    target = f"build/stm32/test/{name}.elf"
    done = subprocess.run(["make", "-s", "--no-print-directory", "INSTALLED=1", target], cwd=REPO,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return REPO / target


def run_command(engine: Path, elf: Path, *qemu_args: str, machine: str = "rig-stm32f405") -> list[str]:
    """QEMU's command line for ``elf`` on ``machine``, in icount time, its semihosting on QEMU's standard
    output; no display, monitor or serial port."""
    return [str(engine), "-M", machine, "-nodefaults", "-display", "none",
            "-chardev", "stdio,id=semi", "-semihosting-config", "enable=on,target=native,chardev=semi",
            "-icount", f"shift={ICOUNT_SHIFT},sleep=off", *qemu_args, "-kernel", str(elf)]


def run_firmware(engine: Path, elf: Path, *qemu_args: str,
                 machine: str = "rig-stm32f405") -> subprocess.CompletedProcess[str]:
    """``elf`` run to its end (run_command)."""
    return subprocess.run(run_command(engine, elf, *qemu_args, machine=machine), stdin=subprocess.DEVNULL,
                          capture_output=True, text=True, timeout=RUN_TIMEOUT_S)


def run_to_done(name: str, *qemu_args: str,
                machine: str = "rig-stm32f405") -> subprocess.CompletedProcess[str]:
    """The test firmware ``name`` run to its end: it exits 0 with "done" last (it reported everything)."""
    done = run_firmware(engine_or_skip(), firmware(name), *qemu_args, machine=machine)
    assert done.returncode == 0, f"status {done.returncode}\n{done.stdout}\n{done.stderr}"
    assert done.stdout.endswith("done\n"), done.stdout
    return done


def run_linked(elf: Path, chips: ChipBoard | None, limit_ns: int = 50 * STEP_NS,
               settings: bytes | None = None) -> tuple[Stop, list[TwiRecord], str, int]:
    """``elf`` in lockstep on the stm32f405-gy86 board (its flash's settings image ``settings``), 1 ms
    steps, the needs served: the final stop, every I2C record, QEMU's output (the firmware's semihosting
    reports) and how many needs were served."""
    board = boards.load("stm32f405-gy86")
    engine = Stm32Engine(Stm32Config(board, elf, engine_or_skip(), settings=settings), chips)
    needs = 0
    try:
        engine.twi_log(True)
        t = 0
        while t < limit_ns:
            t += STEP_NS
            stop = engine.run_until(t)
            while stop.kind == "need":
                assert chips is not None
                needs += 1
                chips.serve(stop.need)
                stop = engine.run_until(t)
            if stop.kind != "reached":
                break
        return stop, engine.twi_take(), engine.output(), needs
    finally:
        engine.close()


def reports(stdout: str) -> dict[str, int]:
    """The NAME=0xVALUE lines a test firmware wrote."""
    return {m.group(1): int(m.group(2), 16) for m in REPORT_LINE.finditer(stdout)}


def board_with_rc(tmp_path: Path, rc: str, name: str, shipped: str = "stm32f405-gy86") -> Path:
    """The shipped board ``shipped``'s file with the body of its [rc] table replaced by ``rc`` (TOML lines),
    written as ``tmp_path``/SHIPPED-NAME.toml: the receiver tests' boards (MSP, PPM, PWM instead of SBUS)."""
    text = (boards.BOARDS / f"{shipped}.toml").read_text()
    start, end = text.index("[rc]"), text.index("[telemetry]")
    path = tmp_path / f"{shipped}-{name}.toml"
    path.write_text(text[:start] + "[rc]\n" + rc.rstrip("\n") + "\n\n" + text[end:])
    return path


#: the serial ports of the receiver tests' MCU sessions (the board's RC and telemetry USARTs)
RC_PORT, TEL_PORT = "/dev/ttyRC0", "/dev/ttyTEL0"
#: the receiver tests' frames (PPM, parallel PWM): three of 8 channels (the firmwares report three), each
#: frame's own widths in microseconds, the first starting at RC_FIRST_FRAME_NS
RC_FRAMES = [
    [1000, 1100, 1234, 1500, 1777, 1900, 2000, 1050],
    [1500, 1500, 1000, 1999, 1001, 1250, 1750, 1600],
    [2000, 1000, 1500, 1500, 1200, 1800, 1333, 1667],
]
RC_FIRST_FRAME_NS = 2_000_000
#: SBUS values as a scenario's sticks send them (172..1811; 16 channels, of which a receiver puts 8 out)
RC_SBUS_CHANNELS = [172, 992, 1811, 500, 1500, 992, 300, 1700, 992, 992, 992, 992, 992, 992, 992, 992]


def drive_rc_frames(board: Board, name: str, frame_ns: int,
                    edges: Callable[[int, list[int]], dict[str, list[tuple[int, int]]]]) -> str:
    """Firmware ``name`` on ``board`` with RC_FRAMES on its receiver's pins, one every ``frame_ns``: each
    frame's ``edges`` (pin -> (t_ns, level) from its start and widths) given to the engine in the step
    before it starts (as the MCU session does), 1 ms steps until the firmware has had the three; QEMU's
    output."""
    engine = Stm32Engine(Stm32Config(board, firmware(name), engine_or_skip()), None)
    try:
        t = 0
        for k, widths in enumerate(RC_FRAMES):
            start = RC_FIRST_FRAME_NS + k * frame_ns
            while t + STEP_NS < start:
                t += STEP_NS
                assert engine.run_until(t).kind == "reached"
            for pin, pin_edges in edges(start, widths).items():
                engine.pin_drive(pin, pin_edges)
        end = RC_FIRST_FRAME_NS + len(RC_FRAMES) * frame_ns
        while t < end:
            t += STEP_NS
            assert engine.run_until(t).kind == "reached"
        return engine.output()
    finally:
        engine.close()


def receiver_session_lines(board_file: Path, name: str, channels: list[int]) -> tuple[list[str], list[int]]:
    """Firmware ``name`` flown 0.2 s on the board through the MCU session, the scenario's RC frames
    (SBUS, as the scenarios write them) sent at 20, 40 and 60 ms: its telemetry lines, and the widths in
    microseconds a receiver maps the first 8 channels to (172 -> 1000 us, 1811 -> 2000 us, written here)."""
    board = boards.load(board_file)
    world = World.at_rest(seed=0, topology=board.topology)
    session = McuSession(McuConfig(board, firmware(name), 0.2, RC_PORT, TEL_PORT), world)
    frame = sbus.encode(channels)
    for t in (0.02, 0.04, 0.06):
        session.at(t, lambda s: s.serial_write(RC_PORT, frame))
    outcome = session.run()
    world.close()
    assert outcome.verdict == "ok", outcome.error
    want = [round(1000 + (c - 172) * (2000 - 1000) / (1811 - 172)) for c in channels[:8]]
    return session.serial_output(TEL_PORT).decode().splitlines(), want
