"""The process target: a Linux program under the device-redirection shim (rig/session.py), in lockstep
virtual time (CI) or paced by the wall clock. Its motors are the sysfs PWM channels it writes, directly
or through a capture link (rig/capture.py) as the scenario's [capture] says. With no command it is the
reference FC, configured from the scenario's [fc] table."""

from __future__ import annotations

import os
import shlex
from pathlib import Path
from typing import Any

from rig import firmware
from rig.capture import CaptureLink, install_capture
from rig.scenarios.profile import Profile
from rig.scenarios.result import I2CRecord
from rig.scenarios.schema import Scenario
from rig.session import Outcome, Session, SessionConfig
from rig.targets import (
    RC_PATH,
    REFERENCE_FC,
    RunContext,
    TargetRun,
    reference_command,
    reference_config,
    telemetry_path,
)

#: a note for a run whose target has no bench supply to drive
NO_SUPPLY = "the scenario's [bench] supply powers a board behind a bridge only: not used here"


def absolute_command(command: list[str], cwd: Path) -> list[str]:
    """The command as the report records it: the program and every operand naming an existing file
    given by a relative path, made absolute (``./fc fc.conf`` says nothing once the folder is gone)."""
    out = []
    for k, a in enumerate(command):
        p = Path(a)
        named = (k == 0 and "/" in a) or (cwd / p).exists()
        if a and not a.startswith("-") and not p.is_absolute() and named:
            a = os.path.normpath(cwd / p)
        out.append(a)
    return out


def describe_command(command: list[str], scenario: Scenario, reference: bool) -> dict[str, object]:
    """result.json's words for a DUT started by command line (here and on the virtual bridge)."""
    return {
        "dut_command": shlex.join(absolute_command(command, Path.cwd())),
        **firmware.identify(command),
        "fc_config": dict(line.split(" = ", 1) for line in reference_config(scenario).splitlines())
        if reference else None,
    }


def command_for(dut: list[str] | None, scenario: Scenario, work: Path, notes: list[str],
                profile: Profile | None = None) -> list[str]:
    """The DUT's command line: ``dut`` with its profile's arguments, or the reference FC with its
    configuration written to ``work``."""
    if dut is None:
        return reference_command(scenario, work)
    if scenario.fc:
        notes.append("the scenario's [fc] table configures the reference FC only; ignored for this DUT")
    return [*dut, *(profile.config.arguments() if profile is not None else [])]


class ProcessRun(TargetRun):
    session: Session

    def __init__(self, session: Session, capture: CaptureLink | None) -> None:
        self.session = session
        self.capture = capture

    def figures(self, outcome: Outcome) -> dict[str, object]:
        return {"capture_stats": self.capture.stats()} if self.capture is not None else {}

    def transactions(self) -> list[I2CRecord] | None:
        handler = self.session.handler
        if handler is None:  # (the DUT never started)
            return []
        return handler.i2c_log  # (I2CRecords as they were made: the session is over)

    def close(self) -> None:
        if self.capture is not None:
            self.capture.close()


class ProcessTarget:
    """A Linux program (``dut``: its command line; None: the reference FC) in lockstep or real time.
    ``corrupt_every``: the capture link corrupts every Nth frame (the link's own tests). ``spin``: the
    session and the DUT on a core each, polling (rig/cores.py)."""

    def __init__(self, dut: list[str] | None = None, realtime: bool = False, corrupt_every: int = 0,
                 spin: bool = False) -> None:
        self.dut = dut
        self.realtime = realtime
        self.spin = spin
        self.mode = "real time" if realtime else "lockstep"
        self.corrupt_every = corrupt_every
        self._command: list[str] = []

    def describe(self, scenario: Scenario, work: Path, notes: list[str],
                 profile: Profile | None = None) -> dict[str, object]:
        self._command = command_for(self.dut, scenario, work, notes, profile)
        if scenario.bench.psu is not None:
            notes.append(NO_SUPPLY)
        return {**describe_command(self._command, scenario, self.dut is None),
                "capture": scenario.capture.transport, "lockstep": not self.realtime}

    def open(self, ctx: RunContext) -> ProcessRun:
        cfg = SessionConfig(
            command=self._command,
            serial=[RC_PATH, telemetry_path(ctx.profile)],
            duration=ctx.scenario.duration,
            lockstep=not self.realtime,
            spin=self.spin,
            wall_timeout=ctx.wall_timeout,
            stall_timeout=ctx.stall_timeout,
            stdout=ctx.stdout,
            stderr=ctx.stderr,
        )
        session = Session(cfg, ctx.world)
        return ProcessRun(session, install_capture(session, ctx.scenario.capture, self.corrupt_every))

    def world_options(self) -> dict[str, Any]:
        return {}

    def not_run_metadata(self) -> dict[str, object]:
        return {"mode": self.mode}


__all__ = ["REFERENCE_FC", "ProcessTarget", "absolute_command", "command_for", "describe_command"]
