"""Talking to a firmware during a run: bytes sent to one of its USARTs at a time (``[[serial]]``), and
criteria on what comes back (``[[criteria]]`` with ``uart``): "a line matching R on USART n before t",
"an MSP reply to command c", as Renode's ``Wait For Line On Uart`` judges a firmware's console.

MSP is MultiWii's serial protocol, version 1 as MultiWii publishes it: a request is ``$M<``, the
payload's length, the command, the payload, and the XOR of length, command and payload bytes; the
firmware's reply is the same with ``$M>`` (``$M!`` for a command it refuses). This module reads and
checks the tables; the runner frames the requests and judges the criteria (rig/uart_criteria.py, with
rig/telemetry/msp.py), a layer above.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Final

if TYPE_CHECKING:
    from rig.scenarios.schema import _Check

SEND_KEYS: Final = {"t", "uart", "hex", "msp", "payload", "baud"}
#: a [[criteria]] table on a USART has these keys (and name, start, end), no metric or signal
SERIAL_CRITERION_KEYS: Final = {"uart", "line", "msp_reply"}
#: the MSP v1 frame's payload length is one byte
MSP_MAX_PAYLOAD: Final = 255

@dataclass(frozen=True)
class SerialSend:
    """Bytes for a firmware's USART at sim time ``t``: ``data`` as they are, or an MSP v1 request for
    ``msp`` (command, payload; the runner frames it, rig/telemetry/msp.py); ``baud`` None: the board's
    for that USART."""

    t: float
    uart: int
    data: bytes = b""
    msp: tuple[int, bytes] | None = None
    baud: int | None = None


def parse_bytes(c: _Check, text: str, key: str) -> bytes:
    """A hex string as bytes ("24 4d 3c 00 cd cd", spaces and colons allowed)."""
    try:
        return bytes.fromhex(text.replace(":", " "))
    except ValueError:
        raise c.fail(key, f"expected bytes in hex (\"24 4d 3c\"), got {text!r}") from None


def parse_send(c: _Check, raw: Any, key: str, duration: float) -> SerialSend:
    """One [[serial]] table: t, uart, and either hex, or msp (a command number) with its payload (hex)."""
    s = c.table(raw, key, SEND_KEYS)
    t = c.number(s, "t", key, low=0, high=duration)
    uart = c.number(s, "uart", key, low=0, high=7)
    if uart != int(uart):
        raise c.fail(f"{key}.uart", f"expected a USART number 0..7, got {uart:g}")
    baud = c.number(s, "baud", key, low=300, high=2_000_000) if "baud" in s else None
    if ("hex" in s) == ("msp" in s):
        raise c.fail(key, "expected either hex (raw bytes) or msp (a command number), one of them")
    if "hex" in s:
        if "payload" in s:
            raise c.fail(f"{key}.payload", "goes with msp; hex is the whole message")
        data = parse_bytes(c, c.string(s, "hex", key), f"{key}.hex")
        if not data:
            raise c.fail(f"{key}.hex", "expected at least one byte")
    else:
        command = c.number(s, "msp", key, low=0, high=255)
        payload = parse_bytes(c, c.string(s, "payload", key, ""), f"{key}.payload")
        if command != int(command) or len(payload) > MSP_MAX_PAYLOAD:
            raise c.fail(f"{key}.msp", f"expected a command 0..255 with at most {MSP_MAX_PAYLOAD} payload "
                                       "bytes")
        return SerialSend(t, int(uart), msp=(int(command), payload), baud=None if baud is None else int(baud))
    return SerialSend(t, int(uart), data, baud=None if baud is None else int(baud))


def parse_expect(c: _Check, cr: dict[str, Any], key: str) -> tuple[str, str, str | int]:
    """A [[criteria]] table on a USART: (metric, signal, what): ``line`` (a regular expression a whole
    line must match, Python's ``re.search``) or ``msp_reply`` (a command number)."""
    for wrong in ("metric", "signal", "target", "band", "min", "max", "baseline_at"):
        if wrong in cr:
            raise c.fail(f"{key}.{wrong}", "a criterion on a USART (uart = …) takes line or msp_reply, "
                                           "a window (start, end: found by end passes), and no metric or "
                                           "limits")
    uart = c.number(cr, "uart", key, low=0, high=7)
    if uart != int(uart):
        raise c.fail(f"{key}.uart", f"expected a USART number 0..7, got {uart:g}")
    signal = f"usart{int(uart)}"
    if ("line" in cr) == ("msp_reply" in cr):
        raise c.fail(key, "expected either line (a regular expression) or msp_reply (a command number)")
    if "line" in cr:
        pattern = c.string(cr, "line", key)
        try:
            re.compile(pattern)
        except re.error as e:
            raise c.fail(f"{key}.line", f"not a regular expression: {e}") from None
        return "uart_line", signal, pattern
    command = c.number(cr, "msp_reply", key, low=0, high=255)
    if command != int(command):
        raise c.fail(f"{key}.msp_reply", f"expected a command number 0..255, got {command:g}")
    return "msp_reply", signal, int(command)
