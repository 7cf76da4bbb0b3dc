"""Transaction traces: a client's exact bus sequence as data (bytes out, bytes expected back, sim time
between), replayed against a bus. Another implementation of the same devices can be checked against the
same files (``emulators/traces/*.json``).

Format: ``{"name", "source", "topology", "truth": {...}, "steps": [{"dt": s, "msgs": [...],
"expect": [hex | null, ...], "nack": bool}]}``; a message is ``"w 68 6b 00"`` (address, then bytes,
hex) or ``"r 68 14"`` (address hex, length decimal); ``expect`` lists each read's bytes as hex, null to
skip the check; ``dt`` is the sim time since the previous step.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from rig.emulators.i2c_bus import I2CBus, I2CNack, Msg

TRACE_DIR = Path(__file__).resolve().parent / "traces"


class TraceError(ValueError):
    """A trace file is malformed; the message names the file and the step."""


@dataclass
class Mismatch:
    step: int
    t: float
    msgs: list[str]
    expected: str
    got: str


def parse_msg(text: str) -> Msg:
    parts = text.split()
    if len(parts) < 2 or parts[0] not in ("w", "r"):
        raise TraceError(f"message {text!r}: expected 'w ADDR [BYTES...]' or 'r ADDR LEN'")
    addr = int(parts[1], 16)
    if parts[0] == "r":
        if len(parts) != 3:
            raise TraceError(f"message {text!r}: a read has an address and a length")
        return Msg(addr, True, b"", int(parts[2]))
    return Msg(addr, False, bytes(int(b, 16) for b in parts[2:]))


def load(path: Path) -> dict:
    try:
        trace = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise TraceError(f"{path}: not JSON ({exc})") from exc
    for key in ("name", "topology", "truth", "steps"):
        if key not in trace:
            raise TraceError(f"{path}: missing key {key!r}")
    return trace


def replay(trace: dict, bus: I2CBus) -> list[Mismatch]:
    """Runs every step at its sim time; returns the mismatches (empty when the devices agree)."""
    t = 0.0
    problems: list[Mismatch] = []
    for i, step in enumerate(trace["steps"]):
        t += float(step.get("dt", 0.0))
        msgs = [parse_msg(m) for m in step["msgs"]]
        try:
            got = bus.transfer(msgs, t)
        except I2CNack as exc:
            if not step.get("nack"):
                problems.append(Mismatch(i, t, step["msgs"], "ACK", str(exc)))
            continue
        if step.get("nack"):
            problems.append(Mismatch(i, t, step["msgs"], "NACK", "ACK"))
            continue
        for want, data in zip(step.get("expect", []), got, strict=False):
            if want is not None and data.hex() != want.replace(" ", "").lower():
                problems.append(Mismatch(i, t, step["msgs"], want, data.hex()))
    return problems
