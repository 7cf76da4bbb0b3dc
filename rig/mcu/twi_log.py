"""The TWI's events (rig/mcu/engine.py TwiRecord: START, address, byte written, byte read, STOP) folded
into I2C transfers as the chips saw them (scenarios/result.py I2CRecord, run.mcap's /i2c channel).

One record per address phase, as the engine counts transactions (``twi_transactions``): a register
write then a repeated-START read is two records, the read's register being the one just written (a
bare read's is None). At most CAP records are kept (rig/handler.py's cap for the Linux DUT's), and
``cut`` counts what did not fit."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Final

from rig.mcu.engine import TwiRecord
from rig.scenarios.result import I2CRecord

CAP: Final = 1_000_000


class TwiTransfers:
    def __init__(self) -> None:
        self.records: list[I2CRecord] = []
        self.cut = 0
        self._open: tuple[int, int, bool, bool] | None = None  # (t_ns, address, read, acknowledged)
        self._wrote = bytearray()
        self._read = bytearray()
        self._register: int | None = None  # the last register written since START

    def feed(self, events: Iterable[TwiRecord]) -> None:
        for ev in events:
            if ev.kind == "A":
                self._close()
                self._open = (ev.t_ns, ev.value >> 1, bool(ev.value & 1), ev.ack)
            elif ev.kind == "W" and self._open is not None:
                self._wrote.append(ev.value)
            elif ev.kind == "R" and self._open is not None:
                self._read.append(ev.value)
            elif ev.kind in ("S", "P"):
                self._close()
                if ev.kind == "P":
                    self._register = None

    def _close(self) -> None:
        if self._open is None:
            return
        t, address, read, ok = self._open
        if read:
            register = self._register
        else:
            register = self._wrote[0] if self._wrote else None
            self._register = register
        if len(self.records) < CAP:
            self.records.append(I2CRecord(t, address, register, bytes(self._wrote), bytes(self._read), ok))
        else:
            self.cut += 1
        self._open = None
        self._wrote.clear()
        self._read.clear()

    def finish(self) -> list[I2CRecord]:
        self._close()
        return self.records
