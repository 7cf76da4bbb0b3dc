"""Simulated bench supplies on ptys, written here from the supplies' documented wire formats (not from
the drivers): a Riden RD6006 as a Modbus RTU server (framed and CRC'd by hand, a second
implementation against pymodbus's client) and a Korad KA3005P's text protocol. Each keeps a log of
what it was told, in order, and can go silent or corrupt its answers."""

from __future__ import annotations

import os
import re
import select
import struct
import threading
import tty
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass


def crc16_modbus(data: bytes) -> int:
    """CRC-16/MODBUS: reflected polynomial 0xA001, initial 0xFFFF (sent low byte first)."""
    crc = 0xFFFF
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc


@dataclass
class Load:
    """The board on the supply's output: it draws ``amps`` while powered (capped by the limit)."""

    amps: float = 0.35


class _PtySim:
    def __init__(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.log: list[tuple[str, object]] = []
        self.mode = "ok"  # "silent": reads and says nothing; "bad_crc": every answer's CRC broken
        self._stop_r, self._stop_w = os.pipe()
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._buf = b""

    def _loop(self) -> None:
        while True:
            ready, _, _ = select.select([self.master, self._stop_r], [], [])
            if self._stop_r in ready:
                return
            try:
                data = os.read(self.master, 4096)
            except OSError:
                return
            self._buf += data
            self._buf = self.consume(self._buf)

    def consume(self, buf: bytes) -> bytes:
        raise NotImplementedError

    def answer(self, data: bytes) -> None:
        if self.mode != "silent":
            os.write(self.master, data)

    def close(self) -> None:
        os.write(self._stop_w, b"x")
        self._thread.join(timeout=5)
        for fd in (self.master, self.slave, self._stop_r, self._stop_w):
            os.close(fd)


class SimRiden(_PtySim):
    """An RD6006 (model register 60062): V ÷100, I ÷1000; unit 1."""

    def __init__(self, model_id: int = 60062, v_scale: int = 100, i_scale: int = 1000) -> None:
        super().__init__()
        self.load = Load()
        self.v_scale, self.i_scale = v_scale, i_scale
        self.regs = [0] * 40
        self.regs[0] = model_id
        self.regs[8], self.regs[9] = 12 * v_scale, 2 * i_scale  # set 12.00 V, 2.000 A
        self._thread.start()

    def _refresh(self) -> None:
        on = self.regs[18] == 1
        limit = self.regs[9] / self.i_scale
        amps = min(self.load.amps, limit) if on else 0.0
        self.regs[10] = self.regs[8] if on else 0
        self.regs[11] = round(amps * self.i_scale)
        self.regs[17] = int(on and self.load.amps >= limit)

    def _reply(self, body: bytes) -> None:
        crc = crc16_modbus(body)
        if self.mode == "bad_crc":
            crc ^= 0x5A5A
        self.answer(body + struct.pack("<H", crc))

    def consume(self, buf: bytes) -> bytes:
        while len(buf) >= 8:
            fc = buf[1]
            size = 9 + buf[6] if fc == 16 and len(buf) >= 7 else 8
            if len(buf) < size:
                break
            frame, buf = buf[:size], buf[size:]
            if crc16_modbus(frame[:-2]) != struct.unpack("<H", frame[-2:])[0] or frame[0] != 1:
                self.log.append(("bad frame", frame.hex()))
                continue
            self._refresh()
            if fc == 3:
                addr, count = struct.unpack(">HH", frame[2:6])
                if addr + count > len(self.regs) or count == 0:
                    self._reply(bytes([1, 0x83, 2]))
                    continue
                self.log.append(("read", (addr, count)))
                values = self.regs[addr:addr + count]
                self._reply(bytes([1, 3, 2 * count]) + struct.pack(f">{count}H", *values))
            elif fc == 6:
                addr, value = struct.unpack(">HH", frame[2:6])
                if addr >= len(self.regs):
                    self._reply(bytes([1, 0x86, 2]))
                    continue
                self.regs[addr] = value
                self.log.append(("write", (addr, value)))
                self._reply(frame[:6])
            else:
                self._reply(bytes([1, 0x80 | fc, 1]))  # ILLEGAL FUNCTION
        return buf

    def writes(self) -> list[tuple[int, int]]:
        return [v for k, v in self.log if k == "write"]  # type: ignore[misc]


KORAD_COMMAND = re.compile(rb"^(\*IDN\?|STATUS\?|[VI](SET|OUT)1\?|VSET1:\d\d\.\d\d|ISET1:\d\.\d\d\d|OUT[01])")


class SimKorad(_PtySim):
    """A KA3005P: no terminators; answers with no newline."""

    IDN = b"KORAD KA3005P V5.8 SN:03379314"

    def __init__(self) -> None:
        super().__init__()
        self.load = Load()
        self.v_set, self.i_set, self.on = 12.0, 2.0, False
        self.garble = False  # VOUT1? answers "1x.0y"
        self._thread.start()

    def consume(self, buf: bytes) -> bytes:
        while buf:
            m = KORAD_COMMAND.match(buf)
            if m is None:
                if len(buf) > 16:  # nothing it knows: drop a byte (the real one ignores junk)
                    buf = buf[1:]
                    continue
                break
            cmd, buf = m.group(0).decode(), buf[m.end():]
            self.log.append(("cmd", cmd))
            amps = min(self.load.amps, self.i_set) if self.on else 0.0
            if cmd == "*IDN?":
                self.answer(self.IDN)
            elif cmd == "STATUS?":
                cv = not (self.on and self.load.amps >= self.i_set)
                self.answer(bytes([(0x40 if self.on else 0) | int(cv)]))
            elif cmd == "VOUT1?":
                self.answer(b"1x.0y" if self.garble else f"{self.v_set if self.on else 0:05.2f}".encode())
            elif cmd == "IOUT1?":
                self.answer(f"{amps:05.3f}".encode())
            elif cmd == "VSET1?":
                self.answer(f"{self.v_set:05.2f}".encode())
            elif cmd == "ISET1?":
                self.answer(f"{self.i_set:05.3f}".encode())
            elif cmd.startswith("VSET1:"):
                self.v_set = float(cmd[6:])
            elif cmd.startswith("ISET1:"):
                self.i_set = float(cmd[6:])
            elif cmd in ("OUT0", "OUT1"):
                self.on = cmd == "OUT1"
        return buf

    def commands(self) -> list[str]:
        return [str(v) for _, v in self.log]


@contextmanager
def sim(kind: type[_PtySim]) -> Iterator[_PtySim]:
    s = kind()
    try:
        yield s
    finally:
        s.close()

