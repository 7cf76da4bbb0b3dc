"""Targets: the ways the runner meets a DUT, behind one small interface.

A scenario run is the same whatever the DUT is: a world (plant, sensors, chips) in sim time, sticks,
wind, faults and the recorder as events, then the DUT's telemetry and the criteria. What differs is how
the DUT is reached, and that is a target's business alone:

* ``process``: a Linux program under the device-redirection shim, in lockstep or in real time;
* ``bridge``: a board (or the reference FC on the virtual bridge) behind a bench bridge, in real time;
* ``mcu``: a firmware image of a microcontroller under an emulator, in lockstep.

A target describes its DUT for the report (``describe``) and opens one run (``open``): a ``TargetRun``
whose session offers the ``Host`` the scenario's events use, runs to an ``Outcome``, and afterwards
gives the figures and extra signals it alone knows. The runner never asks which target it drives;
adding a target adds a module here (python-can's interface registry and labgrid's drivers behind
protocols are the shape followed).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, Final, Protocol

import numpy as np

from rig.host import Host
from rig.plant.artifacts import BUILD
from rig.scenarios.result import I2CRecord

if TYPE_CHECKING:
    from rig.emulators.faults import FaultSet
    from rig.scenarios.profile import Profile
    from rig.scenarios.schema import Scenario
    from rig.session import Outcome
    from rig.uart_criteria import Chunks
    from rig.world import World

# (the build folder from a module that is never compiled: the runner may run from build/mypyc,
# rig/compiled.py, where __file__ is not the source's)
REFERENCE_FC: Final = BUILD / "dut" / "fc"
RC_PATH: Final = "/dev/ttyRC0"
TELEMETRY_PATH: Final = "/dev/ttyTEL0"


def telemetry_path(profile: Profile | None) -> str:
    """The device the FC's telemetry comes out of: its profile's port when that is a device path."""
    port = profile.telemetry.port if profile is not None and profile.telemetry.kind != "none" else ""
    return port if port.startswith("/dev/") else TELEMETRY_PATH


def reference_config(scenario: Scenario) -> str:
    """The reference FC's configuration file for a scenario: its ports and the scenario's [fc] table."""
    lines = [f"rc_path = {RC_PATH}", f"telemetry_path = {TELEMETRY_PATH}", "telemetry_every = 5"]
    lines += [f"{k} = {v}" for k, v in scenario.fc.items()]
    return "\n".join(lines) + "\n"


def reference_command(scenario: Scenario, work: Path) -> list[str]:
    """The reference FC's command line for a scenario, its configuration written into ``work``."""
    if not REFERENCE_FC.is_file():
        raise FileNotFoundError(f"reference FC not built at {REFERENCE_FC}; run `make dut`")
    conf = work / "fc.conf"
    conf.write_text(reference_config(scenario))
    return [str(REFERENCE_FC), str(conf)]


@dataclass
class RunContext:
    """What a target gets to open one run: the scenario, its world (made by the runner), the run's
    bus faults by chip, the run's folder and the DUT's output files, and the watchdogs' limits."""

    scenario: Scenario
    world: World
    faults: Mapping[str, FaultSet]
    work: Path
    stdout: IO[str]
    stderr: IO[str]
    wall_timeout: float
    stall_timeout: float
    notes: list[str] = field(default_factory=list)  # what the report should say about the run
    profile: Profile | None = None  # how the FC is flown (None: the reference FC's profile)


class TargetSession(Host, Protocol):
    """What the runner needs of a target's session besides the events' Host."""

    def run(self) -> Outcome: ...

    @property
    def dut_clock_base_s(self) -> float:
        """The DUT's own clock (as its telemetry's ``t=`` gives it) at sim time 0."""


class TargetRun:
    """One run of a target: its session, and what it says after. The defaults suit a target with
    nothing to add."""

    session: TargetSession

    def figures(self, outcome: Outcome) -> dict[str, object]:
        """result.json's metadata this target alone knows (link counters, capture statistics...)."""
        return {}

    def signals(self, t: np.ndarray) -> dict[str, np.ndarray]:
        """Extra signals on the recorder's grid ``t`` (a bench supply's volts and amps)."""
        return {}

    def serial_port(self, uart: int, baud: int | None) -> str | None:
        """The Host path that puts bytes on the DUT's USART ``uart`` (a scenario's [[serial]] sends) at
        ``baud`` (None: the one its board gives that USART), or None when this target has none."""
        return None

    def uarts(self) -> dict[int, Chunks] | None:
        """What the DUT sent on each USART, time-stamped (the criteria on a USART), or None when this
        target has no USARTs the rig reads."""
        return None

    def transactions(self) -> list[I2CRecord] | None:
        """The run's I2C transfers as the chips saw them (run.mcap's /i2c channel), the first million
        at most (rig/handler.py's I2C_LOG_CAP: a 30 s run at 1 kHz makes ~30 k); None when this target
        cannot see them (a bridge's bus is on the board, it reports counts only)."""
        return None

    def idle(self, outcome: Outcome) -> str | None:
        """Why a run that ended well still tested nothing (no sensor read, no motor driven), or None."""
        if outcome.transactions == 0:
            return ("the DUT never read a sensor (no I2C transfer reached the rig): nothing it did was a "
                    "flight under test")
        if outcome.pwm_writes == 0:
            return "the DUT never drove a motor (no sysfs PWM write reached the rig): nothing was flown"
        return None

    def close(self) -> None:
        """Frees what the run held; called once, whatever happened."""


class Target(Protocol):
    """A way to meet a DUT (a module of this package)."""

    #: result.json's ``mode``: "lockstep", "real time", "bridge", "mcu"
    mode: str
    #: paced by the wall clock (the report gives the scheduled events' lateness)
    realtime: bool

    def describe(self, scenario: Scenario, work: Path, notes: list[str],
                 profile: Profile | None = None) -> dict[str, object]:
        """The DUT as result.json names it (``dut_command``, its hashes, ``fc_config``, ``capture``);
        may write what the DUT needs into ``work`` (the reference FC's configuration) and add notes.
        ``profile``: the FC's (its arguments join a DUT's command line). Raises for a DUT that cannot be
        run at all (a missing build): the run is then not flown."""
        ...

    def world_options(self, profile: Profile | None = None) -> dict[str, Any]:
        """What the DUT's hardware makes of the world (World.at_rest's ``topology``, ``mounting``), as
        the FC of ``profile`` has it wired (an MCU's motor pins and sensor mounting)."""
        ...

    def open(self, ctx: RunContext) -> TargetRun:
        """The run's session, ready for the scenario's events and ``run()``."""
        ...

    def not_run_metadata(self) -> dict[str, object]:
        """What a result of a run that never started says of the target."""
        ...
