"""The criteria on a USART, judged after a run from what the firmware sent (time-stamped chunks): "a line
matching R on USART n before t", "an MSP reply to command c" (rig/scenarios/serial.py reads them from a
scenario; rig/telemetry/msp.py reads MSP replies). A criterion's value is the sim time the line or the
reply was complete (its last byte taken from the USART, to the session's step), so its limit is the
window's end: found inside [start, end] passes, never found fails with the reason."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from typing import Final

from rig.scenarios.criteria import Measurement
from rig.scenarios.schema import CriterionSpec
from rig.telemetry import msp

#: a line criterion looks at lines up to this long (a firmware that never sends a newline: its bytes)
LINE_LIMIT: Final = 4096

#: What a USART gave during a run: (sim ns the bytes were taken, the bytes), in time order
Chunks = Sequence[tuple[int, bytes]]


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
    """The sim ns of every MSP reply to ``command`` on the USART (complete when its last byte came; a
    ``$M!`` refusal is not a reply)."""
    reader = msp.ReplyReader()
    return [t for t, data in chunks for r in reader.feed(data) if r.command == command and not r.error]


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
