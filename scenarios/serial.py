"""Talking to a firmware during a run: bytes sent to one of its USARTs at a time (``[[serial]]``), and
criteria on what comes back (``[[criteria]]`` with ``uart``): "a line matching R on USART n before t",
"an MSP reply to command c", as Renode's ``Wait For Line On Uart`` judges a firmware's console.

MSP is MultiWii's serial protocol, version 1 as MultiWii publishes it: a request is ``$M<``, the
payload's length, the command, the payload, and the XOR of length, command and payload bytes; the
firmware's reply is the same with ``$M>`` (``$M!`` for a command it refuses). A criterion's value is
the sim time the line or the reply was complete (its last byte taken from the USART), so its limit is
the window's end: found inside [start, end] passes, never found fails with the reason.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Final

from rig.scenarios.criteria import Measurement

if TYPE_CHECKING:
    from rig.scenarios.schema import CriterionSpec, _Check

SEND_KEYS: Final = {"t", "uart", "hex", "msp", "payload", "baud"}
#: a [[criteria]] table on a USART has these keys (and name, start, end), no metric or signal
SERIAL_CRITERION_KEYS: Final = {"uart", "line", "msp_reply"}
#: the MSP v1 frame's payload length is one byte
MSP_MAX_PAYLOAD: Final = 255
#: a line criterion looks at lines up to this long (a firmware that never sends a newline: its bytes)
LINE_LIMIT: Final = 4096

#: What a USART gave during a run: (sim ns the bytes were taken, the bytes), in time order
Chunks = Sequence[tuple[int, bytes]]


@dataclass(frozen=True)
class SerialSend:
    """Bytes for a firmware's USART at sim time ``t``; ``baud`` None: the board's for that USART."""

    t: float
    uart: int
    data: bytes
    baud: int | None = None


def msp_frame(command: int, payload: bytes = b"", direction: str = "<") -> bytes:
    """An MSP v1 frame: ``$M`` + direction (``<`` to the firmware, ``>`` from it), length, command,
    payload, and the XOR of length, command and payload."""
    if not 0 <= command <= 255 or len(payload) > MSP_MAX_PAYLOAD:
        raise ValueError(f"an MSP v1 command is 0..255 with at most {MSP_MAX_PAYLOAD} payload bytes")
    body = bytes([len(payload), command]) + payload
    check = 0
    for b in body:
        check ^= b
    return b"$M" + direction.encode() + body + bytes([check])


def msp_replies(data: bytes) -> list[tuple[int, int]]:
    """Every well-formed MSP v1 reply (``$M>``) in ``data``: (its command, the offset of its last byte).
    A frame with a bad checksum is not a reply."""
    found = []
    at = data.find(b"$M>")
    while at >= 0:
        if at + 5 <= len(data):
            size, command = data[at + 3], data[at + 4]
            end = at + 5 + size
            if end < len(data):
                check = 0
                for b in data[at + 3:end]:
                    check ^= b
                if check == data[end]:
                    found.append((command, end))
        at = data.find(b"$M>", at + 1)
    return found


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
        data = msp_frame(int(command), payload)
    return SerialSend(t, int(uart), data, None if baud is None else int(baud))


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


def matching_lines(chunks: Chunks, pattern: str) -> list[tuple[int, str]]:
    """The complete lines on the USART (ended by LF, a CR before it dropped) that match ``pattern``,
    each with the sim ns it was complete."""
    regex = re.compile(pattern)
    found: list[tuple[int, str]] = []
    line = bytearray()
    for t_ns, data in chunks:
        *done, rest = data.split(b"\n")
        for part in done:
            line += part
            text = bytes(line[-LINE_LIMIT:]).rstrip(b"\r").decode("latin-1")
            if regex.search(text):
                found.append((t_ns, text))
            line.clear()
        line += rest
        del line[:-LINE_LIMIT]
    return found


def replies(chunks: Chunks, command: int) -> list[int]:
    """The sim ns of every MSP reply to ``command`` on the USART (complete when its last byte came)."""
    stream = b"".join(data for _, data in chunks)
    ends: list[int] = []  # the stream offset each chunk ends at
    total = 0
    for _, data in chunks:
        total += len(data)
        ends.append(total)
    times = []
    k = 0
    for cmd, last in msp_replies(stream):
        while ends[k] <= last:
            k += 1
        if cmd == command:
            times.append(chunks[k][0])
    return times


def measure(spec: CriterionSpec, uarts: dict[int, Chunks] | None) -> Measurement:
    """A criterion on a USART: its value is the sim time (s) of the first matching line or reply inside
    the window; found by the window's end passes."""
    assert spec.uart is not None
    reason = ""
    value = math.nan
    if uarts is None:
        reason = "this DUT has no USARTs the rig reads (an MCU target's criterion)"
    else:
        chunks = uarts.get(spec.uart, ())
        if spec.metric == "uart_line":
            times = [t for t, _ in matching_lines(chunks, str(spec.expect))]
            what = f"no line matching {spec.expect!r} on USART {spec.uart}"
        else:
            times = replies(chunks, int(spec.expect or 0))
            what = f"no MSP reply to command {spec.expect} on USART {spec.uart}"
        inside = [t / 1e9 for t in times if spec.start - 1e-9 <= t / 1e9 <= spec.end + 1e-9]
        if inside:
            value = inside[0]
        else:
            reason = f"{what} in {spec.start:g}..{spec.end:g} s"
            if times:
                reason += f" (first at {times[0] / 1e9:.3f} s)"
    ok = not reason
    return Measurement(spec.name, spec.metric, spec.signal, value, "s", spec.start, spec.end,
                       spec.start, spec.end, "pass" if ok else "fail", reason)
