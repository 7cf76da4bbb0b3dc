"""The test cell's PLC over Modbus TCP, as a PLC meets it: `rig serve --modbus` (a real uvicorn and a real
pymodbus server on 127.0.0.1) spoken to by pymodbus's own TCP client. A PLC's run is an ordinary run of
the service: what the registers say equals what the HTTP API says of the same run."""

from __future__ import annotations

import math
import struct
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from rig.service.plc import REGISTERS, library_names
from tests.service.test_api import Service, blocked_dut, free_port, start, stop
from tests.waits import read_pid, wait_gone

pymodbus_client = pytest.importorskip("pymodbus.client")
ILLEGAL_ADDRESS, ILLEGAL_VALUE, DEVICE_BUSY = 2, 3, 6
MEASURED = ("overshoot after release", "level at the end")


class Plc:
    def __init__(self, port: int) -> None:
        self.client = pymodbus_client.ModbusTcpClient("127.0.0.1", port=port, timeout=10)
        assert self.client.connect()

    def read(self, address: int = 0, count: int = 14) -> list[int]:
        r = self.client.read_holding_registers(address, count=count, device_id=1)
        assert not r.isError(), r
        return list(r.registers)

    def write(self, address: int, value: int) -> int | None:
        """None when accepted; else the exception code."""
        r = self.client.write_register(address, value, device_id=1)
        return r.exception_code if r.isError() else None

    def state(self) -> dict[str, Any]:
        r = self.read()
        floats = [struct.unpack(">f", struct.pack(">HH", r[k], r[k + 1]))[0] for k in (10, 12)]
        return {"status": r[2], "verdict": r[3], "run_id": r[4] << 16 | r[5], "progress": r[6],
                "heartbeat": r[7], "measured": floats}


@pytest.fixture
def cell(tmp_path: Path) -> Iterator[tuple[Service, Plc]]:
    port = free_port()
    extra = ["--slots", "1", "--modbus", str(port)]
    for name in MEASURED:
        extra += ["--modbus-measure", name]
    svc = start(tmp_path / "data", *extra)
    plc = Plc(port)
    yield svc, plc
    plc.client.close()
    stop(svc)


def test_the_map_in_the_docs_is_the_map_served() -> None:
    doc = (Path(__file__).resolve().parents[2] / "docs" / "plc.md").read_text()
    for reg in REGISTERS:
        span = str(reg.address) if reg.words == 1 else f"{reg.address}–{reg.address + reg.words - 1}"
        assert f"| {span} | `{reg.name}` | {reg.access} |" in doc, reg


def test_a_plc_sequence_then_busy_abort_illegal_address_and_bad_value(cell: tuple[Service, Plc],
                                                                      tmp_path: Path) -> None:
    svc, plc = cell
    t0, first = time.monotonic(), plc.state()
    assert first["status"] == 0 and first["verdict"] == 0 and first["run_id"] == 0
    assert all(math.isnan(v) for v in first["measured"])  # nothing measured yet
    # read-only registers refuse writes; outside the map nothing answers
    for reg in (2, 3, 4, 5, 6, 7, 10):
        assert plc.write(reg, 1) == ILLEGAL_ADDRESS, reg
    r = plc.client.read_holding_registers(200, count=1, device_id=1)
    assert r.isError() and r.exception_code == ILLEGAL_ADDRESS
    # bad values: a position outside `rig list`, an unknown command, a start with no scenario chosen
    assert plc.write(1, 0) == ILLEGAL_VALUE and plc.write(1, len(library_names()) + 1) == ILLEGAL_VALUE
    assert plc.write(0, 1) == ILLEGAL_VALUE and plc.write(0, 9) == ILLEGAL_VALUE
    position = library_names().index("seed000_roll_stand") + 1
    assert plc.write(1, position) is None and plc.read(1, 1) == [position]

    # the only lockstep slot busy with an HTTP client's run: the PLC's run waits in the queue
    command, fifo = blocked_dut(tmp_path)
    _, blocker = svc.call("POST", "/api/runs", {"scenarios": ["step_roll"], "dut": {"command": command}})
    blocker_pid = read_pid(fifo)
    assert plc.write(0, 1) is None
    queued = plc.state()
    assert queued["status"] == 1 and queued["run_id"] > blocker["id"]
    _, run = svc.call("GET", f"/api/runs/{queued['run_id']}")
    assert run["status"] == "queued" and run["origin"] == "plc" and run["scenarios"] == ["seed000_roll_stand"]
    assert plc.write(0, 1) == DEVICE_BUSY  # start while its run is queued
    assert plc.write(0, 3) == DEVICE_BUSY  # acknowledge while queued
    assert plc.write(0, 2) is None  # abort
    aborted = plc.state()
    assert (aborted["status"], aborted["verdict"]) == (4, 0)
    assert svc.call("GET", f"/api/runs/{queued['run_id']}")[1]["status"] == "cancelled"
    assert plc.write(0, 3) is None and plc.state()["status"] == 0  # acknowledged: idle
    assert svc.call("DELETE", f"/api/runs/{blocker['id']}")[0] == 200
    assert wait_gone(blocker_pid)

    # the sequence: scenario, start -> poll -> done -> verdict -> acknowledge
    assert plc.write(0, 1) is None
    run_id = plc.state()["run_id"]
    assert run_id > queued["run_id"] and plc.state()["status"] in (1, 2, 3)
    assert plc.write(0, 1) == DEVICE_BUSY or plc.state()["status"] == 3
    done = svc.follow(run_id)  # (the HTTP API's long poll instead of a sleep)
    end = plc.state()
    assert done["status"] == "passed" and done["origin"] == "plc"
    assert (end["status"], end["verdict"], end["run_id"], end["progress"]) == (3, 1, run_id, 100)
    values = {m["name"]: m["value"] for m in done["results"][0]["measurements"]}
    for name, got in zip(MEASURED, end["measured"], strict=True):
        assert got == pytest.approx(values[name], rel=1e-6), name  # FLOAT32 of the API's value
    assert plc.write(0, 3) is None
    idle = plc.state()
    assert (idle["status"], idle["verdict"], idle["run_id"]) == (0, 0, run_id)
    assert all(math.isnan(v) for v in idle["measured"])
    # the heartbeat counts the service's seconds
    elapsed = time.monotonic() - t0
    assert math.floor(elapsed) - 1 <= idle["heartbeat"] - first["heartbeat"] <= math.ceil(elapsed) + 1


def test_modbus_beyond_loopback_needs_an_explicit_yes(tmp_path: Path) -> None:
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "rig.cli", "serve", "--host", "0.0.0.0", "--token", "t",
                        "--modbus", str(free_port()), "--data", str(tmp_path)],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "Modbus TCP has no authentication" in r.stderr
