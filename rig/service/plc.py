"""The test cell's PLC interface: Modbus TCP holding registers over the service's queue (docs/plc.md).

A PLC writes the scenario's position in ``rig list`` and a start command; the run it starts is an
ordinary run of the service (queued, run by a worker, kept in the history, origin ``plc``), and the
PLC polls its status, verdict, progress, run id and chosen measurements. The read-only registers are
computed from the database as each request reads them, and every write is checked there.

The server is this module's own small asyncio Modbus TCP server, not pymodbus's simulator: the
simulator answered function codes 1, 2 and 4 that the map does not have, answered a wrong unit id with
exception 4 (or a KeyError), and echoed a write of the command register with the value it reads back
(0) instead of the request, which the spec requires. Three function codes over one register block are a
few dozen lines to get exactly right; pymodbus stays the PLC side in the tests and the Riden client.
"""

from __future__ import annotations

import asyncio
import math
import struct
import sys
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
WRITABLE: Final = frozenset(r.address for r in REGISTERS if r.access != "read")
#: Modbus exception codes the server answers with
ILLEGAL_FUNCTION, ILLEGAL_ADDRESS, ILLEGAL_VALUE, DEVICE_BUSY, GATEWAY_NO_RESPONSE = 1, 2, 3, 6, 11
READ_HOLDING, WRITE_ONE, WRITE_MANY = 3, 6, 16
MAX_READ, MAX_WRITE = 125, 123  # registers per request (the spec's limits)
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
        unknown = unknown_measurements(measurements)
        if unknown:  # (a typo would read NaN forever: the PLC could not tell it from "not measured yet")
            print(f"rig serve: warning: no scenario of `rig list` has a criterion named "
                  f"{', '.join(repr(n) for n in unknown)}: its --modbus-measure registers will read NaN",
                  file=sys.stderr, flush=True)
        self.t0 = time.monotonic()
        latest = db.list(origin=PLC_ORIGIN, limit=1)  # a restart keeps the PLC's last run in view
        self.run_id: int | None = latest[0]["id"] if latest else None
        self.acknowledged = False
        # and the scenario register the position of that run's scenario (0 when there is none, or the
        # library no longer has it): a PLC that only writes start after a restart flies the same one
        last = latest[0]["scenarios"][0] if latest and latest[0].get("scenarios") else None
        self.scenario = scenarios.index(last) + 1 if last in scenarios else 0

    def size(self) -> int:
        """How many registers the map has (0..size-1 answer; beyond is ILLEGAL DATA ADDRESS)."""
        return MEASUREMENTS_AT + 2 * len(self.measurements)

    def _current(self) -> dict[str, Any] | None:
        if self.run_id is None or self.acknowledged:
            return None
        return self.db.get(self.run_id)

    def registers(self) -> dict[int, int]:
        """Every readable register's value now (address -> value)."""
        run = self._current()
        status, verdict = BY_STATUS.get(run["status"], (ERROR, VERDICT_ERROR)) if run else (IDLE, NO_VERDICT)
        run_id = self.run_id or 0
        out = {0: 0, 1: self.scenario, 2: status, 3: verdict, 4: (run_id >> 16) & 0xFFFF, 5: run_id & 0xFFFF,
               6: round(run["progress"]) if run else 0,
               7: int(time.monotonic() - self.t0) & 0xFFFF, 8: 0, 9: 0}
        values = _measured(run) if run else {}
        for k, name in enumerate(self.measurements):
            value = values.get(name)
            hi, lo = float_words(value if value is not None else math.nan)
            out[MEASUREMENTS_AT + 2 * k], out[MEASUREMENTS_AT + 2 * k + 1] = hi, lo
        return out

    def write(self, address: int, values: list[int]) -> int | None:
        """A write of ``values`` from ``address`` (FC 6 or 16): None when carried out, else the Modbus
        exception code. Nothing is changed unless every register written is writable."""
        if address < 0 or address + len(values) > self.size():
            return ILLEGAL_ADDRESS
        if any(reg not in WRITABLE for reg in range(address, address + len(values))):
            return ILLEGAL_ADDRESS
        writes = dict(zip(range(address, address + len(values)), values, strict=True))
        if 1 in writes:
            if not 1 <= writes[1] <= len(self.scenarios):
                return ILLEGAL_VALUE
            self.scenario = writes[1]
        if 0 in writes:
            refused = self.command(writes[0])
            if refused is not None:
                return {"busy": DEVICE_BUSY, "value": ILLEGAL_VALUE}[refused]
        return None

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


def answer(plc: Plc, unit: int, pdu: bytes) -> bytes | None:
    """The response PDU to one request PDU (None: no answer; the caller drops the connection)."""
    if not pdu:
        return None
    fc = pdu[0]

    def refuse(code: int) -> bytes:
        return bytes((fc | 0x80, code))

    if unit != UNIT:  # no such device behind this address: as a gateway answers (docs/plc.md)
        return refuse(GATEWAY_NO_RESPONSE)
    if fc not in (READ_HOLDING, WRITE_ONE, WRITE_MANY):
        return refuse(ILLEGAL_FUNCTION)
    if len(pdu) < 5:
        return refuse(ILLEGAL_VALUE)
    address, n = struct.unpack(">HH", pdu[1:5])
    if fc == READ_HOLDING:
        if len(pdu) != 5 or not 1 <= n <= MAX_READ:
            return refuse(ILLEGAL_VALUE)
        if address + n > plc.size():
            return refuse(ILLEGAL_ADDRESS)
        regs = plc.registers()
        return bytes((fc, 2 * n)) + struct.pack(f">{n}H", *(regs[r] for r in range(address, address + n)))
    if fc == WRITE_ONE:
        if len(pdu) != 5:
            return refuse(ILLEGAL_VALUE)
        code = plc.write(address, [n])
        return pdu if code is None else refuse(code)  # the reply echoes the request, as the spec says
    if len(pdu) < 6 or not 1 <= n <= MAX_WRITE or pdu[5] != 2 * n or len(pdu) != 6 + 2 * n:
        return refuse(ILLEGAL_VALUE)
    code = plc.write(address, list(struct.unpack(f">{n}H", pdu[6:])))
    return pdu[:5] if code is None else refuse(code)


class PlcServer:
    """The Modbus TCP server in a thread of its own (its own event loop: a slow PLC never holds up the
    HTTP API, nor the API the PLC). Requests are answered one at a time, so the Plc needs no lock."""

    def __init__(self, plc: Plc, host: str, port: int) -> None:
        self.plc, self.host, self.port = plc, host, port
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stopped: asyncio.Event | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._lock: asyncio.Lock | None = None
        self._writers: set[asyncio.StreamWriter] = set()
        self._thread = threading.Thread(target=self._main, daemon=True, name="modbus")

    def start(self, timeout: float = 10.0) -> None:
        """Returns once the server listens (RuntimeError if it cannot)."""
        self._thread.start()
        if not self._ready.wait(timeout) or self._error is not None:
            raise RuntimeError(f"Modbus TCP on {self.host}:{self.port}: {self._error or 'did not start'}")

    def _main(self) -> None:
        asyncio.run(self._serve())

    async def _serve(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._stopped, self._lock = asyncio.Event(), asyncio.Lock()
        try:
            server = await asyncio.start_server(self._client, self.host, self.port)
        except OSError as e:  # (reported by start(), in the caller's thread)
            self._error = e
            self._ready.set()
            return
        self._ready.set()
        async with server:
            await self._stopped.wait()
            for writer in list(self._writers):  # (a PLC still connected does not hold the stop up)
                writer.close()

    async def _client(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        """One PLC's connection: MBAP header (transaction, protocol 0, length, unit), then the PDU. A
        frame that is not Modbus TCP closes the connection (there is no resynchronising a stream)."""
        assert self._lock is not None
        self._writers.add(writer)
        try:
            while True:
                head = await reader.readexactly(7)
                transaction, protocol, length, unit = struct.unpack(">HHHB", head)
                if protocol != 0 or not 2 <= length <= 254:
                    break
                pdu = await reader.readexactly(length - 1)
                async with self._lock:
                    reply = answer(self.plc, unit, pdu)
                if reply is None:
                    break
                writer.write(struct.pack(">HHHB", transaction, 0, len(reply) + 1, unit) + reply)
                await writer.drain()
        except (asyncio.IncompleteReadError, ConnectionError):
            pass
        finally:
            self._writers.discard(writer)
            writer.close()

    def stop(self) -> None:
        if self._loop is not None and self._stopped is not None and self._thread.is_alive():
            self._loop.call_soon_threadsafe(self._stopped.set)
        self._thread.join(timeout=5)


def library_names() -> list[str]:
    """The scenarios in `rig list`'s order: what the scenario register's positions count."""
    from rig.run_cmd import resolve

    return [Path(p).stem for p in resolve([])]


def unknown_measurements(names: list[str]) -> list[str]:
    """The names no criterion of the library's scenarios has (what a --modbus-measure could never read)."""
    from rig.run_cmd import resolve
    from rig.scenarios.schema import ScenarioError, load

    known: set[str] = set()
    for path in resolve([]):
        try:
            known.update(c.name for c in load(path).criteria)
        except (ScenarioError, OSError):
            continue  # (rig validate reports it; the others still count)
    return [n for n in names if n not in known]
