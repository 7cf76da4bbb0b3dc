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


def _raw(port: int, unit: int, pdu: bytes, transaction: int = 0x1234) -> bytes:
    """One Modbus TCP request as bytes on a socket; the response's PDU (after checking its header)."""
    import socket

    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        s.sendall(struct.pack(">HHHB", transaction, 0, len(pdu) + 1, unit) + pdu)
        head = b""
        while len(head) < 7:
            chunk = s.recv(7 - len(head))
            assert chunk, "the server closed the connection without an answer"
            head += chunk
        tid, protocol, length, got_unit = struct.unpack(">HHHB", head)
        assert (tid, protocol, got_unit) == (transaction, 0, unit)
        body = b""
        while len(body) < length - 1:
            chunk = s.recv(length - 1 - len(body))
            assert chunk
            body += chunk
        return body


def test_the_wire_as_the_spec_says_raw_bytes(cell: tuple[Service, Plc]) -> None:
    _, plc = cell
    port = plc.client.comm_params.port
    position = library_names().index("seed000_roll_stand") + 1
    # FC 6: the reply is the request, byte for byte, even for the command register (which reads 0)
    for request in (bytes([6, 0, 1, 0, position]), bytes([6, 0, 0, 0, 3])):
        assert _raw(port, 1, request) == request
    # FC 16: address and count
    assert _raw(port, 1, bytes([16, 0, 1, 0, 1, 2, 0, position])) == bytes([16, 0, 1, 0, 1])
    # FC 3: byte count, then the registers
    reply = _raw(port, 1, bytes([3, 0, 1, 0, 2]))
    assert reply[:2] == bytes([3, 4]) and struct.unpack(">HH", reply[2:]) == (position, 0)
    # the map has holding registers only: coils, discrete inputs, input registers are illegal functions
    for fc in (1, 2, 4, 5, 15, 23, 43):
        assert _raw(port, 1, bytes([fc, 0, 0, 0, 1])) == bytes([fc | 0x80, 1]), fc
    # another unit id: no such device behind this address, as a gateway answers (exception 11)
    for unit in (0, 2, 255):
        assert _raw(port, unit, bytes([3, 0, 0, 0, 1])) == bytes([0x83, 11]), unit
        assert _raw(port, unit, bytes([6, 0, 0, 0, 1])) == bytes([0x86, 11]), unit
    # malformed requests: a count of 0 or beyond the spec's, a byte count that disagrees
    assert _raw(port, 1, bytes([3, 0, 0, 0, 0])) == bytes([0x83, 3])
    assert _raw(port, 1, bytes([3, 0, 0, 0, 126])) == bytes([0x83, 3])
    assert _raw(port, 1, bytes([16, 0, 1, 0, 1, 4, 0, 1, 0, 0])) == bytes([0x90, 3])
    assert _raw(port, 1, bytes([16, 0, 1, 0, 2, 4, 0, 1, 0, 0])) == bytes([0x90, 2])  # 2 is read-only
    assert plc.read(0, 4)[:4] == [0, position, 0, 0]  # nothing refused changed anything


def test_the_wire_as_pymodbus_client_sees_it(cell: tuple[Service, Plc]) -> None:
    _, plc = cell
    r = plc.client.write_register(0, 3, device_id=1)  # acknowledge with nothing to acknowledge
    assert not r.isError() and (r.address, r.registers) == (0, [3])  # the echo, not the 0 it reads
    for call in (plc.client.read_coils, plc.client.read_discrete_inputs, plc.client.read_input_registers):
        r = call(0, count=1, device_id=1)
        assert r.isError() and r.exception_code == 1, call
    r = plc.client.read_holding_registers(0, count=1, device_id=7)
    assert r.isError() and r.exception_code == 11


def test_after_a_restart_the_scenario_register_reads_the_last_runs(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from rig.service.db import Db
    from rig.service.plc import Plc as Registers

    names = library_names()
    db = Db(tmp_path / "rig.sqlite")
    try:
        assert Registers(db, None, names, []).registers()[1] == 0  # type: ignore[arg-type]  # no PLC run yet
        db.submit(["seed000_roll_stand"], 0, {}, "lockstep", 0, origin="plc")
        db.submit(["step_roll"], 0, {}, "lockstep", 0, origin="api")  # (not the PLC's)
        again = Registers(db, None, names, ["overshoot after release"])  # type: ignore[arg-type]
        assert again.registers()[1] == names.index("seed000_roll_stand") + 1
        assert "warning" not in capsys.readouterr().err
        # a mistyped measurement name is told at once, not read as NaN forever in silence
        Registers(db, None, names, ["overshot after release"])  # type: ignore[arg-type]
        err = capsys.readouterr().err
        assert "warning" in err and "'overshot after release'" in err
    finally:
        db.close()
