"""The MCU target: a flight controller's firmware image (an AVR ``.elf`` or ``.hex``), unmodified, under
an emulator (rig/mcu), in lockstep: the chip core answers its TWI, its timer outputs drive the plant's
motors, the sticks arrive on its RC input as its board file wires it (rig/mcu/board.py)."""

from __future__ import annotations

import dataclasses
import hashlib
import re
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rig.mcu import board as boards
from rig.mcu.engine import BUS_PROBLEMS
from rig.mcu.session import McuConfig, McuSession
from rig.mcu.vcd import TraceOptions
from rig.scenarios.profile import Profile
from rig.scenarios.result import I2CRecord
from rig.scenarios.schema import Scenario
from rig.session import Outcome
from rig.targets import RC_PATH, TELEMETRY_PATH, RunContext, TargetRun, telemetry_path
from rig.targets.process import NO_SUPPLY
from rig.uart_criteria import Chunks

if TYPE_CHECKING:
    from rig.world import World


class McuRun(TargetRun):
    session: McuSession

    def __init__(self, session: McuSession) -> None:
        self.session = session

    def figures(self, outcome: Outcome) -> dict[str, object]:
        s = self.session
        f = dict(getattr(s, "figures_at_end", {}))
        f["motor_pulses"] = [m.pulses for m in s.figures.motors]
        f["rc_bytes"] = s.figures.rc_bytes
        if s.cfg.trace is not None:
            f["trace"] = str(s.cfg.trace)
        problems = {name: int(f.get(key, 0)) for name, key in BUS_PROBLEMS.items()}
        out: dict[str, object] = {"mcu": f, "bus_problems": problems}
        if "motor_capture" in f:
            out["capture"] = capture_text(s.cfg.board, f["motor_capture"])
        return out

    def signals(self, t: np.ndarray) -> dict[str, np.ndarray]:
        """battery_volts, the flight pack's terminal volts on the run's grid (a board with a [battery])."""
        s = self.session
        if s.cfg.board.battery is None:
            return {}
        k = np.searchsorted(np.frombuffer(s.pack_t_ns, dtype=np.int64), np.round(t * 1e9), side="right") - 1
        return {"battery_volts": np.frombuffer(s.pack_volts)[np.clip(k, 0, None)]}

    def transactions(self) -> list[I2CRecord] | None:
        return self.session.transfers.records

    def serial_port(self, uart: int, baud: int | None) -> str | None:
        return self.session.serial_port(uart, baud)

    def uarts(self) -> dict[int, Chunks] | None:
        return dict(self.session.uart_log)

    def idle(self, outcome: Outcome) -> str | None:
        if outcome.transactions == 0:
            return ("the firmware never read a sensor (no TWI transaction reached the chips): nothing it "
                    "did was a flight under test")
        if outcome.pwm_writes == 0:
            return "the firmware never drove a motor (no pulse on a motor pin): nothing was flown"
        return None


def capture_text(board: boards.Board, counts: list[dict[str, int]] | None = None) -> str:
    """result.json's ``capture``: how each motor is measured, "m1 PE4: OC3B registers; m2 PE5: pin edges
    (OC3C disconnected)". Before a run (no ``counts``) the plan: a timer motor's compare output (its pin's
    edges while that is disconnected), else the pin's edges; after it, the ways its pulses came."""
    parts = []
    for i, m in enumerate(board.motors):
        oc = board.mcu.output_name(m.timer or 0, m.channel)
        edges = "pin edges" if m.timer is None else f"pin edges ({oc} disconnected)"
        if counts is None:
            how = "pin edges" if m.timer is None else f"{oc} registers or, disconnected, pin edges"
        else:
            ways = [f"{oc} registers"] * bool(counts[i]["timer"]) + [edges] * bool(counts[i]["edges"])
            how = " and ".join(ways) or "no pulse"
        parts.append(f"m{m.motor} {m.pin}: {how}")
    return "; ".join(parts)


def profile_board(board: boards.Board, profile: Profile | None) -> boards.Board:
    """The board as the FC of ``profile`` uses it. The firmware, not the board, chooses which pin carries
    which output and which USART talks at what speed; a board file gives them as the reference FC does.

    * ``[motors] pins``: the pin of each of the FC's outputs 1..4 (MultiWii's Mega PWM_PIN D3, D5, D6,
      D2: rear right, front right, rear left, front left); output k's pin drives plant motor
      ``order[k]``, with the timer the board file gives that pin;
    * ``[sensors] mounting_yaw_deg``: the sensor board turned as the firmware expects it (MultiWii's
      GY_86 reads the MPU-6050's X axis as the vehicle's right: the GY-86 turned 90°);
    * a telemetry port naming one of the MCU's USARTs (``usart0``): the FC's telemetry is there at the
      profile's baud (MultiWii's SERIAL0_COM_SPEED 115200 on a board whose file gives the reference
      FC's 500000), and the rig's polls reach it at that speed. A device path (a Linux DUT's) leaves
      the board's.

    BoardError: a pin that is not one of the board's motor pins, a USART the MCU lacks, or a baud its
    USARTs cannot make at the board's clock."""
    if profile is None:
        return board
    if profile.motors.pins:
        by_pin = {m.pin: m for m in board.motors}
        for pin in profile.motors.pins:
            if pin not in by_pin:
                raise boards.BoardError(str(profile.path), "motors.pins",
                                        f"{pin} is not one of the board {board.name}'s motor pins "
                                        f"({', '.join(by_pin)})")
        motors = (dataclasses.replace(by_pin[pin], motor=profile.motors.order[k])
                  for k, pin in enumerate(profile.motors.pins))
        board = dataclasses.replace(board, motors=tuple(sorted(motors, key=lambda m: m.motor)))
    if profile.mounting_yaw_deg is not None:
        board = dataclasses.replace(board, mounting_yaw_deg=profile.mounting_yaw_deg)
    if profile.telemetry.kind == "none":
        return board
    match = re.fullmatch(r"usart(\d)", profile.telemetry.port)
    if match is None:
        return board
    uart, baud = int(match.group(1)), profile.telemetry.baud
    if uart not in board.mcu.usarts:
        raise boards.BoardError(str(profile.path), "telemetry.port", f"the {board.mcu.name} has USART "
                                f"{', '.join(map(str, board.mcu.usarts))} only, not {uart}")
    if boards.baud_error(board.mcu, board.clock_hz, uart, baud) > boards.BAUD_TOLERANCE:
        raise boards.BoardError(str(profile.path), "telemetry.baud",
                                f"{baud} baud is over {boards.BAUD_TOLERANCE:.0%} off anything a USART "
                                f"makes at {board.clock_hz} Hz")
    return dataclasses.replace(board, telemetry_uart=uart, telemetry_baud=baud)


class McuTarget:
    """``board``: a board file's name or path; ``firmware``: the image. Both are checked here, before
    anything runs (BoardError, FirmwareError). ``trace``: a folder for each run's VCD trace,
    ``SCENARIO.vcd`` (rig/mcu/vcd.py). ``eeprom``: an EEPROM image preloaded instead of the board's
    (raw bytes, or Intel HEX named .eep/.hex), checked here too. Each run writes the EEPROM as the
    firmware left it as ``eeprom.bin`` in its folder, so the next run can start from it. ``hang_limit``:
    the hang check's limit (s; 0 off) instead of the board's [limits] hang_s; ``trace_options``: the
    trace's signals, window and compression (a .vcd.gz)."""

    mode = "mcu"
    realtime = False

    def __init__(self, board: str | Path, firmware: Path, trace: Path | None = None,
                 eeprom: Path | None = None, hang_limit: float | None = None,
                 trace_options: TraceOptions | None = None) -> None:
        from rig.mcu.engines import check_firmware
        from rig.mcu.image import load_eeprom

        self.board = boards.load(board)
        self.firmware = Path(firmware).resolve()
        check_firmware(self.board, self.firmware)  # (FirmwareError: not an image for this MCU, or too big)
        self.firmware_sha256 = hashlib.sha256(self.firmware.read_bytes()).hexdigest()
        self.trace = trace
        self.hang_limit = hang_limit
        self.trace_options = trace_options or TraceOptions()
        self.eeprom_file = None if eeprom is None else Path(eeprom).resolve()
        self.eeprom = None if self.eeprom_file is None else load_eeprom(self.eeprom_file, self.board.mcu.name)

    def describe(self, scenario: Scenario, work: Path, notes: list[str],
                 profile: Profile | None = None) -> dict[str, object]:
        mcu = self.board.mcu
        board = profile_board(self.board, profile)  # (BoardError before anything runs)
        for uart in sorted({s.uart for s in scenario.serial} | _listened(scenario)):
            if uart not in mcu.usarts:
                raise ValueError(f"the scenario talks to USART {uart}; the {mcu.name} has USART "
                                 f"{', '.join(map(str, mcu.usarts))} only")
        if self.board.battery is None and any(f.target == "battery" for f in scenario.faults):
            raise ValueError(f"the scenario has a fault on the battery; the board {self.board.name} measures "
                             "none (no [battery] in its file)")
        if scenario.bench.psu is not None:
            notes.append(NO_SUPPLY)
        fc_eeprom = self.board.eeprom_from_fc and self.eeprom is None
        if scenario.fc and not fc_eeprom:
            notes.append("the scenario's [fc] table configures the reference FC only; this board's "
                         "firmware keeps its own configuration" if self.eeprom is None else
                         f"the scenario's [fc] table is not used: the EEPROM is {self.eeprom_file}'s")
        eeprom = {} if self.eeprom is None else {
            "eeprom_file": str(self.eeprom_file), "eeprom_sha256": hashlib.sha256(self.eeprom).hexdigest()}
        return {
            "dut_command": f"{self.firmware} on {self.board.name} ({self.board.mcu.name} at "
                           f"{self.board.clock_hz / 1e6:g} MHz)",
            "dut_firmware": str(self.firmware),
            "dut_firmware_sha256": self.firmware_sha256,
            "board": self.board.name,
            "board_file": str(self.board.path),
            "fc_config": dict(scenario.fc) if fc_eeprom else None,
            "capture": capture_text(board),
            "lockstep": True,
            **eeprom,
        }

    def world_options(self, profile: Profile | None = None) -> dict[str, Any]:
        # (the board file, or the profile's pins, wire each motor pin to its plant motor: no output order
        # on top of it)
        board = profile_board(self.board, profile)
        return {"topology": board.topology, "mounting": boards.mounting(board.mounting_yaw_deg),
                "motor_order": (1, 2, 3, 4), "mpu_address": board.mpu_address,
                "battery": None if board.battery is None else board.battery.pack}

    def open(self, ctx: RunContext) -> McuRun:
        trace = None if self.trace is None else self.trace / f"{ctx.scenario.stem}{self.trace_options.suffix}"
        eeprom = ctx.profile.config.eeprom if ctx.profile is not None else None
        return McuRun(self.session(ctx.world, ctx.scenario.duration, ctx.scenario.fc, ctx.wall_timeout,
                                   trace, eeprom_out=ctx.work / "eeprom.bin", eeprom_image=eeprom,
                                   telemetry=telemetry_path(ctx.profile), listen=_listened(ctx.scenario),
                                   profile=ctx.profile))

    def session(self, world: World, duration: float, fc: Mapping[str, Any], wall_timeout: float,
                trace: Path | None = None, sim_timeout: float = 600.0,
                eeprom_out: Path | None = None, eeprom_image: Path | None = None,
                telemetry: str = TELEMETRY_PATH, listen: frozenset[int] = frozenset(),
                profile: Profile | None = None) -> McuSession:
        """The firmware on its board in ``world`` for ``duration`` sim seconds; ``fc``: the [fc] table
        that becomes the EEPROM on a board that says so (an empty one: the reference FC's defaults),
        unless an EEPROM image was given (``--eeprom``, else ``eeprom_image``: the FC profile's, before
        the board file's); ``eeprom_out``: where the EEPROM goes at the end; ``profile``: the FC's,
        whose telemetry USART and baud replace the board's (profile_board)."""
        eeprom: bytes | None = self.eeprom
        if eeprom is None and eeprom_image is not None:
            eeprom = eeprom_image.read_bytes()
        if eeprom is None and self.board.eeprom_image is not None:
            eeprom = self.board.eeprom_image.read_bytes()
        elif eeprom is None and self.board.eeprom_from_fc:
            from rig.scenarios.eeprom import image  # the reference firmware's layout

            eeprom = image(fc)
        board = profile_board(self.board, profile)
        cfg = McuConfig(board, self.firmware, duration, RC_PATH, telemetry, eeprom, wall_timeout, sim_timeout,
                        trace, self.trace_options, eeprom_out, listen, self.hang_limit)
        return McuSession(cfg, world)

    def not_run_metadata(self) -> dict[str, object]:
        return {"mode": self.mode, "board": self.board.name}


def _listened(scenario: Scenario) -> frozenset[int]:
    """The USARTs a scenario's criteria judge (their output is kept time-stamped)."""
    return frozenset(c.uart for c in scenario.criteria if c.uart is not None)
