"""The process target: a Linux program under the device-redirection shim (rig/session.py), in lockstep
virtual time (CI) or paced by the wall clock. Its motors are the sysfs PWM channels it writes, directly
or through a capture link (rig/capture.py) as the scenario's [capture] says. With no command it is the
reference FC, configured from the scenario's [fc] table."""

from __future__ import annotations

import os
import shlex
import shutil
from pathlib import Path
from typing import Any

from rig import firmware
from rig.capture import CaptureLink, install_capture
from rig.emulators.topology import TOPOLOGIES
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

#: channels pwmchip0 can have (rig/shim/protocol.h RIG_PWM_MAX)
PWM_CHANNELS_MAX = 16


def hardware_problems(pwm_channels: int | None, topology: str | None) -> list[str]:
    """What is wrong with a Linux DUT's hardware as asked for (None: the default, 8 channels on a
    GY-86), in words naming the option; the CLI, the API, the pytest plugin and the service say the
    same."""
    problems = []
    if pwm_channels is not None and not 1 <= pwm_channels <= PWM_CHANNELS_MAX:
        problems.append(f"--pwm-channels must be between 1 and {PWM_CHANNELS_MAX}, got {pwm_channels}")
    if topology is not None and topology not in TOPOLOGIES:
        problems.append(f"--topology must be one of {', '.join(TOPOLOGIES)}, got {topology!r}")
    return problems


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
    if profile is None:
        return dut
    return [*dut, *profile.config.arguments(fresh_state(work) if profile.config.keeps_state else None)]


def fresh_state(work: Path) -> Path:
    """The run's folder for the FC's own files (``{state}`` in its profile's arguments), emptied: a run
    starts from the profile's parameters, never from what an earlier run into the same folder saved."""
    state = work / "fc-state"
    shutil.rmtree(state, ignore_errors=True)
    state.mkdir(parents=True)
    return state


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
    session and the DUT on a core each, polling (rig/cores.py). ``pwm_channels`` (1..16) and
    ``topology`` ("gy86", "direct"): the board the DUT sees (None: 8 channels on a GY-86); a stack that
    opens 14 channels, or never sets the MPU-6050's bypass, needs them. Raises ValueError for others."""

    def __init__(self, dut: list[str] | None = None, realtime: bool = False, corrupt_every: int = 0,
                 spin: bool = False, pwm_channels: int | None = None, topology: str | None = None) -> None:
        problems = hardware_problems(pwm_channels, topology)
        if problems:
            raise ValueError("; ".join(problems))
        self.hardware = {k: v for k, v in (("pwm_channels", pwm_channels), ("topology", topology))
                         if v is not None}
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
                "capture": scenario.capture.transport, "lockstep": not self.realtime, **self.hardware}

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

    def world_options(self, profile: Profile | None = None) -> dict[str, Any]:
        return dict(self.hardware)

    def not_run_metadata(self) -> dict[str, object]:
        return {"mode": self.mode}


__all__ = ["PWM_CHANNELS_MAX", "REFERENCE_FC", "ProcessTarget", "absolute_command", "command_for",
           "describe_command", "hardware_problems"]
