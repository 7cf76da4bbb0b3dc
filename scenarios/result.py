"""What one scenario run produced, as plain data: the verdict, every measurement, the recorded signals
and the run's metadata. The runner (rig/runner.py) makes it; the reports (reports/) render it."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple, Protocol

import numpy as np

from rig.scenarios.criteria import Measurement
from rig.scenarios.schema import Scenario


class ScenarioInfo(Protocol):
    """What a report needs of a scenario: a loaded Scenario, or a ScenarioRecord read back from a
    result.json whose scenario file may be gone."""

    @property
    def path(self) -> Path: ...
    @property
    def name(self) -> str: ...
    @property
    def description(self) -> str: ...
    @property
    def sha256(self) -> str: ...
    @property
    def stem(self) -> str: ...


@dataclass(frozen=True)
class ScenarioRecord:
    path: Path
    name: str
    description: str
    sha256: str

    @property
    def stem(self) -> str:
        return self.path.stem


_: type[ScenarioInfo] = Scenario  # (both kinds are ScenarioInfo: mypy checks it here)
__: type[ScenarioInfo] = ScenarioRecord


class I2CRecord(NamedTuple):
    """One I2C transfer as the chips saw it (run.mcap's /i2c channel): its sim time, the address of its
    first message, the register (the first byte written; None for a bare read), the bytes written and
    read, and whether it completed (False: NACK or protocol error).

    A named tuple, not a frozen dataclass: a run makes about 500 a second of sim time, and a frozen
    dataclass's ``__init__`` (Python, one ``object.__setattr__`` per field) cost the session about 3 k
    instructions per record; ``tuple.__new__(I2CRecord, fields)`` builds one with no Python frame."""

    t_ns: int
    address: int
    register: int | None
    wrote: bytes
    read: bytes
    ok: bool


class RcFrame(NamedTuple):
    """One RC frame sent to the DUT (run.mcap's /rc channel): its sim time, its 16 channels' SBUS
    values and its failsafe flag (a named tuple, as I2CRecord, for the same reason: about 70 a second)."""

    t_ns: int
    channels: tuple[int, ...]
    failsafe: bool


#: a run's verdicts: "skipped" is a scenario the FC cannot fly (its profile says why), not a failure
VERDICTS = ("pass", "fail", "error", "interrupted", "skipped")


@dataclass
class RunResult:
    scenario: ScenarioInfo
    verdict: str  # VERDICTS: "interrupted" when a signal stopped the rig mid-run
    error: str | None
    measurements: list[Measurement]
    signals: dict[str, np.ndarray]
    metadata: dict[str, Any]  # JSON-like: result.json's "metadata"
    exit_code: int | None = None  # the session's (rig exec's) exit status; 128 + N for signal N
    stderr: str = ""
    notes: list[str] = field(default_factory=list)
    #: for run.mcap: the bus transfers (None: the target cannot say) and the RC frames sent (None: not
    #: known, as for a run read back from its folder)
    i2c: list[I2CRecord] | None = None
    rc_frames: list[RcFrame] | None = None
