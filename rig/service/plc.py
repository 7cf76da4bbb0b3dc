"""The test cell's PLC interface: Modbus TCP holding registers over the service's queue (docs/plc.md).

A PLC writes the scenario's position in ``rig list`` and a start command; the run it starts is an
ordinary run of the service (queued, run by a worker, kept in the history, origin ``plc``), and the
PLC polls its status, verdict, progress, run id and chosen measurements. The server is pymodbus's
(``pymodbus.simulator``: a SimDevice passed straight to ModbusTcpServer) in a thread with its own event
loop; the action hook sees every access, so the read-only registers are computed from the database
as each request reads them, and every write is checked there: pymodbus itself refuses writes to the
read-only registers (ILLEGAL DATA ADDRESS) before the hook runs.
"""

from __future__ import annotations

import asyncio
import math
import struct
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

from rig.service.db import Db
from rig.service.worker import Workers


@dataclass(frozen=True)
class Register:
    address: int
    name: str
    access: str  # "write", "read/write", "read"
    words: int
    text: str


#: the map (docs/plc.md is written from it, and tests/service/test_plc.py reads it)
REGISTERS: Final = (
    Register(0, "command", "write", 1, "1 start, 2 abort, 3 acknowledge (returns status to idle); reads 0"),
    Register(1, "scenario", "read/write", 1, "the scenario to run: its 1-based position in `rig list`"),
    Register(2, "status", "read", 1, "0 idle, 1 queued, 2 running, 3 done, 4 error"),
    Register(3, "verdict", "read", 1, "0 none, 1 pass, 2 fail, 3 error"),
    Register(4, "run_id", "read", 2, "the run's id in the service's history (UINT32, big-endian word order)"),
    Register(6, "progress", "read", 1, "%"),
    Register(7, "heartbeat", "read", 1, "+1 each second (wraps at 65536): the service is alive"),
    Register(8, "reserved", "read", 2, "0"),
)
MEASUREMENTS_AT: Final = 10
MAX_MEASUREMENTS: Final = 16
CMD_START, CMD_ABORT, CMD_ACK = 1, 2, 3
IDLE, QUEUED, RUNNING, DONE, ERROR = 0, 1, 2, 3, 4
NO_VERDICT, PASS, FAIL, VERDICT_ERROR = 0, 1, 2, 3
#: the service's run status -> (status register, verdict register)
BY_STATUS: Final = {
    "queued": (QUEUED, NO_VERDICT),
    "running": (RUNNING, NO_VERDICT),
    "passed": (DONE, PASS),
    "failed": (DONE, FAIL),
    "error": (ERROR, VERDICT_ERROR),
    "interrupted": (ERROR, VERDICT_ERROR),
    "cancelled": (ERROR, NO_VERDICT),  # aborted: no verdict
}
UNIT: Final = 1
PLC_ORIGIN: Final = "plc"


def float_words(value: float) -> tuple[int, int]:
    """FLOAT32 as two registers, high word first (as pymodbus's DataType.FLOAT32 and most PLCs)."""
    hi, lo = struct.unpack(">HH", struct.pack(">f", value))
    return hi, lo


class Plc:
    """The registers' meaning over the service's database and workers."""

    def __init__(self, db: Db, workers: Workers, scenarios: list[str], measurements: list[str],
                 mode: str = "lockstep") -> None:
        if len(measurements) > MAX_MEASUREMENTS:
            raise ValueError(f"at most {MAX_MEASUREMENTS} measurements on the PLC's registers")
        self.db, self.workers, self.scenarios, self.measurements, self.mode = \
            db, workers, scenarios, measurements, mode
        self.t0 = time.monotonic()
        latest = db.list(origin=PLC_ORIGIN, limit=1)  # a restart keeps the PLC's last run in view
        self.run_id: int | None = latest[0]["id"] if latest else None
        self.acknowledged = False
        self.scenario = 0

    def device(self) -> Any:
        from pymodbus.simulator import DataType, SimData, SimDevice

        n = 2 * len(self.measurements)
        data = [SimData(0, count=2, values=0, datatype=DataType.REGISTERS),
                SimData(2, count=8, values=0, datatype=DataType.REGISTERS, readonly=True)]
        if n:
            data.append(SimData(MEASUREMENTS_AT, count=n, values=0, datatype=DataType.REGISTERS,
                                readonly=True))
        return SimDevice(UNIT, simdata=data, action=self.action)

    def _current(self) -> dict[str, Any] | None:
        if self.run_id is None or self.acknowledged:
            return None
        return self.db.get(self.run_id)

    def registers(self) -> dict[int, int]:
        """Every readable register's value now (address -> value)."""
        run = self._current()
        status, verdict = BY_STATUS.get(run["status"], (ERROR, VERDICT_ERROR)) if run else (IDLE, NO_VERDICT)
        run_id = self.run_id or 0
        out = {0: 0, 1: self.scenario, 2: status, 3: verdict, 4: run_id >> 16, 5: run_id & 0xFFFF,
               6: round(run["progress"]) if run else 0,
               7: int(time.monotonic() - self.t0) & 0xFFFF, 8: 0, 9: 0}
        values = _measured(run) if run else {}
        for k, name in enumerate(self.measurements):
            value = values.get(name)
            hi, lo = float_words(value if value is not None else math.nan)
            out[MEASUREMENTS_AT + 2 * k], out[MEASUREMENTS_AT + 2 * k + 1] = hi, lo
        return out

    async def action(self, function_code: int, start_address: int, address: int, count: int,
                     current: list[int], set_values: list[int] | list[bool] | None) -> Any:
        from pymodbus.constants import ExcCodes

        if set_values is None:  # a read: the registers as they stand now
            for reg, value in self.registers().items():
                if 0 <= reg - start_address < len(current):
                    current[reg - start_address] = value
            return None
        writes = dict(zip(range(address, address + count), (int(v) for v in set_values), strict=False))
        if 1 in writes:
            if not 1 <= writes[1] <= len(self.scenarios):
                return ExcCodes.ILLEGAL_VALUE
            self.scenario = writes[1]
        if 0 in writes:
            refused = self.command(writes[0])
            if refused is not None:
                return {"busy": ExcCodes.DEVICE_BUSY, "value": ExcCodes.ILLEGAL_VALUE}[refused]
        return None  # (the answer echoes the write, as a Modbus device's must; a read of 0 gives 0)

    def command(self, cmd: int) -> str | None:
        """Carries out a command; None, or why it is refused ("busy", "value")."""
        run = self._current()
        active = run is not None and run["status"] in ("queued", "running")
        if cmd == CMD_START:
            if active:
                return "busy"
            if not 1 <= self.scenario <= len(self.scenarios):
                return "value"  # no scenario chosen yet
            name = self.scenarios[self.scenario - 1]
            sha = self.workers.store.pin(name)  # (the library's version now is the one it flies)
            self.run_id = self.db.submit([name], 0, {}, self.mode, 0, origin=PLC_ORIGIN,
                                         versions={name: sha} if sha is not None else {})
            self.acknowledged = False
            self.workers.wake()
        elif cmd == CMD_ABORT:
            if active and run is not None:
                self.workers.abort(run["id"])
        elif cmd == CMD_ACK:
            if active:
                return "busy"
            self.acknowledged = True
        else:
            return "value"
        return None


def _measured(run: dict[str, Any]) -> dict[str, float]:
    out: dict[str, float] = {}
    for result in run.get("results") or []:
        for m in result.get("measurements", []):
            if isinstance(m.get("value"), int | float) and m.get("name") not in out:
                out[m["name"]] = float(m["value"])
    return out


class PlcServer:
    """The Modbus TCP server in a thread of its own (its own event loop: a slow PLC never holds up the
    HTTP API, nor the API the PLC)."""

    def __init__(self, plc: Plc, host: str, port: int) -> None:
        self.plc, self.host, self.port = plc, host, port
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server: Any = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._main, daemon=True, name="modbus")

    def start(self, timeout: float = 10.0) -> None:
        """Returns once the server listens (RuntimeError if it cannot)."""
        self._thread.start()
        if not self._ready.wait(timeout) or self._error is not None:
            raise RuntimeError(f"Modbus TCP on {self.host}:{self.port}: {self._error or 'did not start'}")

    def _main(self) -> None:
        asyncio.run(self._serve())

    async def _serve(self) -> None:
        from pymodbus.server import ModbusTcpServer

        self._loop = asyncio.get_running_loop()
        try:
            self._server = ModbusTcpServer(self.plc.device(), address=(self.host, self.port))
            await self._server.serve_forever(background=True)
        except BaseException as e:  # (reported by start(), in the caller's thread)
            self._error = e
            self._ready.set()
            return
        self._ready.set()
        await self._server.serving

    def stop(self) -> None:
        if self._loop is not None and self._server is not None and self._thread.is_alive():
            asyncio.run_coroutine_threadsafe(self._server.shutdown(), self._loop).result(timeout=5)
        self._thread.join(timeout=5)


def library_names() -> list[str]:
    """The scenarios in `rig list`'s order: what the scenario register's positions count."""
    from rig.run_cmd import resolve

    return [Path(p).stem for p in resolve([])]
