"""Korad KA3005P (and its clones sold as Tenma 72-2540, RND 320-KA3005P, Velleman PS3005D): a text
protocol over its USB serial port, 9600 baud 8N1, with no terminator on commands or answers; the
supply wants a pause between commands (docs/power.md)."""

from __future__ import annotations

import re
import time
from typing import Final

import serial

from rig.power.supply import PsuError, Reading

#: a measured or set value as the supply prints it: "12.00", "1.000"
NUMBER: Final = re.compile(rb"^\d{1,2}\.\d{2,3}$")
#: STATUS? answers one byte: bit 0 set = constant voltage, bit 6 set = output on
STATUS_CV: Final = 0x01
STATUS_OUTPUT: Final = 0x40
V_MAX: Final = 31.0
I_MAX: Final = 5.1


class KoradSupply:
    DEFAULT_BAUD: Final = 9600

    def __init__(self, port: str, baud: int = DEFAULT_BAUD, timeout: float = 0.5,
                 gap_s: float = 0.05) -> None:
        self.name = f"korad:{port}"
        self.timeout, self.gap_s = timeout, gap_s
        try:
            self._port = serial.Serial(port, baud, timeout=timeout, inter_byte_timeout=0.02)
        except (serial.SerialException, OSError) as e:
            raise PsuError(f"{self.name}: cannot open the serial port: {e}") from e
        self._last = 0.0
        try:
            self._ident = self._ask(b"*IDN?").decode("ascii", "replace").strip()
        except PsuError:
            self._port.close()
            raise
        if not self._ident:
            self._port.close()
            raise PsuError(f"{self.name}: no answer to *IDN? within {timeout:g} s")

    def _send(self, cmd: bytes) -> None:
        wait = self._last + self.gap_s - time.monotonic()
        if wait > 0:
            time.sleep(wait)  # (the supply drops a command that follows the previous too closely)
        self._port.reset_input_buffer()
        self._port.write(cmd)
        self._port.flush()
        self._last = time.monotonic()

    def _ask(self, cmd: bytes, size: int = 64) -> bytes:
        self._send(cmd)
        answer = self._port.read(size)
        self._last = time.monotonic()
        return answer

    def _number(self, cmd: bytes) -> float:
        answer = self._ask(cmd, 5)
        if not NUMBER.match(answer):
            what = f"{answer!r}" if answer else f"nothing within {self.timeout:g} s"
            raise PsuError(f"{self.name}: {cmd.decode()} answered {what}, not a number like 12.00")
        return float(answer)

    def identity(self) -> str:
        return self._ident

    def set_voltage(self, volts: float) -> None:
        if not 0 <= volts <= V_MAX:
            raise PsuError(f"{self.name}: {volts:g} V is outside 0..{V_MAX:g} V")
        self._send(f"VSET1:{volts:05.2f}".encode())

    def set_current_limit(self, amps: float) -> None:
        if not 0 <= amps <= I_MAX:
            raise PsuError(f"{self.name}: {amps:g} A is outside 0..{I_MAX:g} A")
        self._send(f"ISET1:{amps:05.3f}".encode())

    def output(self, on: bool) -> None:
        self._send(b"OUT1" if on else b"OUT0")

    def read(self) -> Reading:
        status = self._ask(b"STATUS?", 1)
        if len(status) != 1:
            raise PsuError(f"{self.name}: STATUS? answered nothing within {self.timeout:g} s")
        return Reading(volts=self._number(b"VOUT1?"), amps=self._number(b"IOUT1?"),
                       volts_set=self._number(b"VSET1?"), amps_limit=self._number(b"ISET1?"),
                       output=bool(status[0] & STATUS_OUTPUT),
                       detail="CV" if status[0] & STATUS_CV else "CC")

    def measure(self) -> tuple[float, float]:
        return self._number(b"VOUT1?"), self._number(b"IOUT1?")

    def close(self) -> None:
        self._port.close()
