"""A firmware run's bus and motor traffic as a VCD file (IEEE 1364 §18), for GTKWave or PulseView.

Why a writer of our own: the format is a few lines of text, and what we need of it is narrow (wires
and small vectors, a nanosecond timescale, changes in time order); a dependency for that would be more
code to trust than this. Why a VCD at all: it is what logic analysers' software opens, so a user looks
at the firmware's TWI and ESC outputs as they would look at a capture from the bench.

What the file holds (``mcu_trace``):

* ``twi.scl``, ``twi.sda``: the TWI drawn as wires, so PulseView's I2C decoder reads START, the
  address and R/W, each byte, ACK/NACK and STOP. Each byte's nine bits end at the byte's sim time (when
  the MCU's TWI finished it); inside a byte the bits are drawn at the board's ``twi_hz``, closer
  together when the bytes followed each other faster than that (the engine records when a byte ended,
  not its clock);
* ``twi.byte`` (8 bits) and ``twi.ack``: each address or data byte and its acknowledge at its sim time,
  for a viewer without a decoder; ``twi.busy``: 1 from a START to its STOP;
* ``motors.mN_PIN``: each motor's output pin, rising and falling at its pulses' edges.

Nothing in the file depends on the wall clock or the machine (no ``$date``): two runs of the same
firmware, scenario and seed give the same bytes.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO

from rig.mcu.engine import TwiRecord


@dataclass(frozen=True)
class Var:
    scope: str
    name: str
    width: int = 1
    initial: int | None = None  #: None: unknown ("x") until its first change


def _ident(n: int) -> str:
    """The n-th short identifier: printable ASCII 33..126, as many characters as needed."""
    chars = []
    while True:
        chars.append(chr(33 + n % 94))
        n //= 94
        if n == 0:
            return "".join(chars)
        n -= 1


def _value(var: Var, ident: str, value: int | None) -> str:
    if var.width == 1:
        return f"{'x' if value is None else value & 1}{ident}"
    bits = "x" if value is None else format(value & ((1 << var.width) - 1), "b")
    return f"b{bits} {ident}"


def write_vcd(out: TextIO, variables: Sequence[Var], changes: Iterable[tuple[int, int, int]],
              timescale: str = "1 ns", comment: str = "") -> None:
    """Writes a VCD: ``changes`` are (time, variable index, value), in any order; they are put in time
    order (stable: of two changes of one variable at one time the later given wins), and a change to
    the value a variable already has is left out."""
    for v in variables:
        if not v.name or any(c.isspace() for c in v.name + v.scope) or v.width < 1:
            raise ValueError(f"VCD variable {v.scope}.{v.name!r} (width {v.width}): a name without spaces")
    idents = [_ident(i) for i in range(len(variables))]
    if comment:
        out.write(f"$comment\n  {comment}\n$end\n")
    out.write(f"$timescale {timescale} $end\n")
    scopes: dict[str, list[int]] = {}
    for i, v in enumerate(variables):
        scopes.setdefault(v.scope, []).append(i)
    for scope, members in scopes.items():
        out.write(f"$scope module {scope} $end\n")
        for i in members:
            v = variables[i]
            kind = "wire" if v.width == 1 else "reg"
            out.write(f"$var {kind} {v.width} {idents[i]} {v.name} $end\n")
        out.write("$upscope $end\n")
    out.write("$enddefinitions $end\n")
    current: list[int | None] = [v.initial for v in variables]
    out.write("#0\n$dumpvars\n")
    for i, v in enumerate(variables):
        out.write(_value(v, idents[i], v.initial) + "\n")
    out.write("$end\n")
    by_time: dict[int, dict[int, int]] = {}
    for t, i, value in changes:
        if t < 0:
            raise ValueError(f"VCD change at a negative time {t}")
        at = by_time.setdefault(t, {})
        at.pop(i, None)  # (keeps the order of the last change of each variable)
        at[i] = value
    for t in sorted(by_time):
        lines = []
        for i, value in by_time[t].items():
            if current[i] != value:
                current[i] = value
                lines.append(_value(variables[i], idents[i], value))
        if lines:
            out.write(f"#{t}\n" + "\n".join(lines) + "\n")


# ---- a firmware run's trace ------------------------------------------------------------------------

SCL, SDA, BYTE, ACK, BUSY = range(5)


def twi_changes(records: Sequence[TwiRecord], bit_ns: int) -> list[tuple[int, int, int]]:
    """The TWI records as changes of the five twi.* variables (indices SCL..BUSY)."""
    out: list[tuple[int, int, int]] = []
    prev = 0  # the time the bus was last drawn to
    busy = False
    for r in records:
        t = max(r.t_ns, prev)
        room = t - prev
        if r.kind == "S" and not busy:  # from an idle bus (both lines high): SDA falls
            out += [(t, SDA, 0), (t, BUSY, 1)]
        elif r.kind == "S":  # a repeated START: the lines go high first, then SDA falls
            half = max(min(bit_ns // 2, room // 3), 0)
            out += [(t - 2 * half, SCL, 0), (t - 2 * half, SDA, 1), (t - half, SCL, 1), (t, SDA, 0)]
        elif r.kind == "P":  # SDA low, SCL high, then SDA rises
            half = max(min(bit_ns // 2, room // 3), 0)
            out += [(t - 2 * half, SCL, 0), (t - 2 * half, SDA, 0), (t - half, SCL, 1), (t, SDA, 1),
                    (t, BUSY, 0)]
            busy = False
        else:  # A, W, R: eight data bits MSB first and the acknowledge, the ninth clock ending at t
            bit = max(min(bit_ns, room // 10), 0)
            start = t - 9 * bit
            bits = [(r.value >> (7 - k)) & 1 for k in range(8)] + [0 if r.ack else 1]
            for k, level in enumerate(bits):
                b0 = start + k * bit
                out += [(b0, SCL, 0), (b0 + bit // 4, SDA, level), (b0 + bit // 2, SCL, 1)]
            out += [(t, SCL, 0), (t, BYTE, r.value), (t, ACK, 1 if r.ack else 0)]
        busy = busy or r.kind == "S"
        prev = t
    return out


def mcu_trace(path: Path, records: Sequence[TwiRecord], pulses: Sequence[Iterable[tuple[int, int, int]]],
              motor_names: Sequence[str], twi_hz: int, comment: str = "") -> None:
    """Writes a run's trace: the TWI records (engine.twi_take) and each motor's pulses (engine.pulses:
    rise_ns, width_ns, period_ns), one name per motor (``m1_PE4``)."""
    variables = [Var("twi", "scl", 1, 1), Var("twi", "sda", 1, 1), Var("twi", "byte", 8),
                 Var("twi", "ack", 1), Var("twi", "busy", 1, 0)]
    variables += [Var("motors", name, 1, 0) for name in motor_names]
    changes = twi_changes(records, max(1, round(1e9 / twi_hz)))
    for k, train in enumerate(pulses):
        index = BUSY + 1 + k
        for rise, width, _period in train:
            changes += [(rise, index, 1), (rise + width, index, 0)]
    with open(path, "w", encoding="ascii", newline="\n") as out:
        write_vcd(out, variables, changes, comment=comment)

