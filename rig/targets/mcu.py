"""The MCU target: a flight controller's firmware image (an AVR ``.elf`` or ``.hex``), unmodified, under
an emulator (rig/mcu), in lockstep: the chip core answers its TWI, its timer outputs drive the plant's
motors, the sticks arrive on its RC input as its board file wires it (rig/mcu/board.py)."""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

from rig.mcu import board as boards
from rig.mcu.session import McuConfig, McuSession
from rig.session import Outcome
from rig.targets import RC_PATH, TELEMETRY_PATH, RunContext, TargetRun
from rig.targets.process import NO_SUPPLY
from scenarios.schema import Scenario


class McuRun(TargetRun):
    session: McuSession

    def __init__(self, session: McuSession) -> None:
        self.session = session

    def figures(self, outcome: Outcome) -> dict[str, object]:
        s = self.session
        f = dict(getattr(s, "figures_at_end", {}))
        f["motor_pulses"] = [m.pulses for m in s.figures.motors]
        f["rc_bytes"] = s.figures.rc_bytes
        return {"mcu": f}

    def idle(self, outcome: Outcome) -> str | None:
        if outcome.transactions == 0:
            return ("the firmware never read a sensor (no TWI transaction reached the chips): nothing it "
                    "did was a flight under test")
        if outcome.pwm_writes == 0:
            return "the firmware never drove a motor (no pulse on a motor pin): nothing was flown"
        return None


class McuTarget:
    """``board``: a board file's name or path; ``firmware``: the image. Both are checked here, before
    anything runs (BoardError, FirmwareError)."""

    mode = "mcu"
    realtime = False

    def __init__(self, board: str | Path, firmware: Path) -> None:
        from rig.mcu.image import load

        self.board = boards.load(board)
        self.firmware = Path(firmware).resolve()
        load(self.firmware, self.board.mcu.name)  # (FirmwareError: not an AVR image, or too big)
        self.firmware_sha256 = hashlib.sha256(self.firmware.read_bytes()).hexdigest()

    def describe(self, scenario: Scenario, work: Path, notes: list[str]) -> dict[str, object]:
        if scenario.bench.psu is not None:
            notes.append(NO_SUPPLY)
        if scenario.fc and not self.board.eeprom_from_fc:
            notes.append("the scenario's [fc] table configures the reference FC only; this board's "
                         "firmware keeps its own configuration")
        return {
            "dut_command": f"{self.firmware} on {self.board.name} ({self.board.mcu.name} at "
                           f"{self.board.clock_hz / 1e6:g} MHz)",
            "dut_firmware": str(self.firmware),
            "dut_firmware_sha256": self.firmware_sha256,
            "board": self.board.name,
            "board_file": str(self.board.path),
            "fc_config": dict(scenario.fc) if self.board.eeprom_from_fc else None,
            "capture": "timer outputs",
            "lockstep": True,
        }

    def world_options(self) -> dict[str, Any]:
        return {"topology": self.board.topology, "mounting": boards.mounting(self.board.mounting_yaw_deg)}

    def open(self, ctx: RunContext) -> McuRun:
        eeprom: bytes | None = None
        if self.board.eeprom_image is not None:
            eeprom = self.board.eeprom_image.read_bytes()
        elif self.board.eeprom_from_fc:
            from scenarios.eeprom import image  # the reference firmware's layout

            eeprom = image(ctx.scenario.fc)
        cfg = McuConfig(self.board, self.firmware, ctx.scenario.duration, RC_PATH, TELEMETRY_PATH, eeprom,
                        ctx.wall_timeout)
        return McuRun(McuSession(cfg, ctx.world))

    def not_run_metadata(self) -> dict[str, object]:
        return {"mode": self.mode, "board": self.board.name}
