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

A trace a person keeps (``TraceOptions``): only the signals chosen (``twi``, ``motors``, ``twi.scl``,
``m2``, ...), only the changes inside a time window (the values at the window's start written there),
and gzip-compressed (``.vcd.gz``, which GTKWave opens as it is): the reference FC's 3.6 MB per sim second
of VCD compresses about tenfold.

Nothing in the file depends on the wall clock or the machine (no ``$date``, a gzip header with no time
or name): two runs of the same firmware, scenario and seed give the same bytes.
"""

from __future__ import annotations

import gzip
import heapq
import io
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO, Final, TextIO

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


class VcdWriter:
    """A VCD written as a run goes: ``change`` (time, variable index, value) in any order, ``flush``
    writes those before a time in time order (stable: of two changes of one variable at one time the
    later given wins; a change to the value a variable has is left out), ``close`` the rest. A change
    earlier than what is written already is an error (the caller holds its changes back far enough)."""

    def __init__(self, out: TextIO, variables: Sequence[Var], timescale: str = "1 ns", comment: str = "",
                 window: tuple[int, int] | None = None):
        for v in variables:
            if not v.name or any(c.isspace() for c in v.name + v.scope) or v.width < 1:
                raise ValueError(f"VCD variable {v.scope}.{v.name!r} (width {v.width}): a name without "
                                 "spaces")
        self._out, self._vars = out, list(variables)
        self._idents = [_ident(i) for i in range(len(variables))]
        self._current: list[int | None] = [v.initial for v in variables]
        self._pending: dict[int, dict[int, int]] = {}
        self._times: list[int] = []  #: the pending times, a heap
        self._written = 0  #: changes before this time are written
        #: only the changes in [start, end] are written, the values at start written there
        self._window = window
        self._shown = list(self._current)  #: the values the file gives now
        self._opened = window is None or window[0] <= 0
        if comment:
            out.write(f"$comment\n  {comment}\n$end\n")
        out.write(f"$timescale {timescale} $end\n")
        scopes: dict[str, list[int]] = {}
        for i, v in enumerate(variables):
            scopes.setdefault(v.scope, []).append(i)
        for scope, members in scopes.items():
            out.write(f"$scope module {scope} $end\n")
            for i in members:
                v, kind = variables[i], "wire" if variables[i].width == 1 else "reg"
                out.write(f"$var {kind} {v.width} {self._idents[i]} {v.name} $end\n")
            out.write("$upscope $end\n")
        out.write("$enddefinitions $end\n#0\n$dumpvars\n")
        for i, v in enumerate(variables):
            out.write(_value(v, self._idents[i], v.initial) + "\n")
        out.write("$end\n")

    def change(self, t: int, index: int, value: int) -> None:
        if t < self._written:
            raise ValueError(f"VCD change at {t}, before {self._written}, which is written already")
        at = self._pending.get(t)
        if at is None:
            at = self._pending[t] = {}
            heapq.heappush(self._times, t)
        else:
            at.pop(index, None)  # (keeps the order of the last change of each variable)
        at[index] = value

    @property
    def written(self) -> int:
        """Changes from this time on can still be given."""
        return self._written

    def flush(self, before: int | None = None) -> None:
        """Writes the changes before ``before`` (None: all)."""
        times, heap = [], self._times
        while heap and (before is None or heap[0] < before):
            times.append(heapq.heappop(heap))
        chunks = []
        start, end = self._window or (0, None)
        for t in times:
            changes = self._pending.pop(t)
            if end is not None and t > end:
                continue  # (after the window)
            if not self._opened:
                if t < start:  # (before the window: kept, to write the values at its start)
                    self._current = [changes.get(i, v) for i, v in enumerate(self._current)]
                    continue
                chunks.append(self._open_window())
            lines = []
            for i, value in changes.items():
                if self._current[i] != value:
                    self._current[i] = value
                    lines.append(_value(self._vars[i], self._idents[i], value))
            if lines:
                chunks.append(f"#{t}\n" + "\n".join(lines) + "\n")
        if not self._opened and (before is None or before > start):
            chunks.append(self._open_window())
        self._out.write("".join(chunks))
        if times:
            self._written = times[-1] + 1
        if before is not None:
            self._written = max(self._written, before)


    def _open_window(self) -> str:
        """The values at the window's start, where they differ from those the file gives."""
        assert self._window is not None
        self._opened = True
        lines = [_value(v, self._idents[i], self._current[i]) for i, v in enumerate(self._vars)
                 if self._current[i] != self._shown[i]]
        return f"#{self._window[0]}\n" + "".join(line + "\n" for line in lines)


def write_vcd(out: TextIO, variables: Sequence[Var], changes: Iterable[tuple[int, int, int]],
              timescale: str = "1 ns", comment: str = "") -> None:
    """A whole VCD at once: ``changes`` are (time, variable index, value) in any order (VcdWriter)."""
    w = VcdWriter(out, variables, timescale, comment)
    for t, i, value in changes:
        if t < 0:
            raise ValueError(f"VCD change at a negative time {t}")
        w.change(t, i, value)
    w.flush()


# ---- a firmware run's trace ------------------------------------------------------------------------

SCL, SDA, BYTE, ACK, BUSY = range(5)
TWI_SIGNALS: Final = ("scl", "sda", "byte", "ack", "busy")


@dataclass(frozen=True)
class TraceOptions:
    """What a trace keeps: ``signals`` ("twi", "motors", "twi.scl", "m2", ...; empty: all), the sim time
    ``window_ns`` [start, end] (None: the whole run), and ``gzip`` (a .vcd.gz)."""

    signals: tuple[str, ...] = ()
    window_ns: tuple[int, int] | None = None
    gzip: bool = False

    @property
    def suffix(self) -> str:
        return ".vcd.gz" if self.gzip else ".vcd"


def signal_problem(signals: Iterable[str], motors: int = 4) -> str | None:
    """Why a trace's signal names are not ones it has (None: they are)."""
    known = {"twi", "motors", *(f"twi.{s}" for s in TWI_SIGNALS), *(f"m{k}" for k in range(1, motors + 1))}
    for s in signals:
        if s not in known:
            return f"no trace signal {s!r}; the signals: {', '.join(sorted(known))}"
    return None


def _chosen(var: Var, signals: Sequence[str]) -> bool:
    if not signals:
        return True
    short = var.name.split("_")[0] if var.scope == "motors" else var.name
    return any(s in (var.scope, f"{var.scope}.{var.name}", short) for s in signals)


class TwiDrawing:
    """The TWI records as changes of the five twi.* variables (indices SCL..BUSY), record after record
    (the bus's state carries over from one batch to the next)."""

    def __init__(self, bit_ns: int) -> None:
        self.bit_ns = bit_ns
        self.prev = 0  #: the time the bus was last drawn to
        self.busy = False

    def draw(self, records: Iterable[TwiRecord]) -> list[tuple[int, int, int]]:
        out: list[tuple[int, int, int]] = []
        bit_ns = self.bit_ns
        batch = list(records)
        for i, r in enumerate(batch):
            t = max(r.t_ns, self.prev)
            after = batch[i + 1] if i + 1 < len(batch) else None
            if r.kind == "S" and after is not None and after.kind == "A" and after.t_ns == r.t_ns:
                # an engine that has the START when the address byte ended (the STM32 link: QEMU's slaves
                # see a START with its address): the START drawn that byte's nine clocks and one before
                t = max(r.t_ns - 10 * bit_ns, self.prev)
            room = t - self.prev
            if r.kind == "S" and not self.busy:  # from an idle bus (both lines high): SDA falls
                out += [(t, SDA, 0), (t, BUSY, 1)]
            elif r.kind == "S":  # a repeated START: the lines go high first, then SDA falls
                half = max(min(bit_ns // 2, room // 3), 0)
                out += [(t - 2 * half, SCL, 0), (t - 2 * half, SDA, 1), (t - half, SCL, 1), (t, SDA, 0)]
            elif r.kind == "P":  # SDA low, SCL high, then SDA rises
                half = max(min(bit_ns // 2, room // 3), 0)
                out += [(t - 2 * half, SCL, 0), (t - 2 * half, SDA, 0), (t - half, SCL, 1), (t, SDA, 1),
                        (t, BUSY, 0)]
                self.busy = False
            else:  # A, W, R: eight data bits MSB first and the acknowledge, the ninth clock ending at t
                bit = max(min(bit_ns, room // 10), 0)
                start = t - 9 * bit
                bits = [(r.value >> (7 - k)) & 1 for k in range(8)] + [0 if r.ack else 1]
                for k, level in enumerate(bits):
                    b0 = start + k * bit
                    out += [(b0, SCL, 0), (b0 + bit // 4, SDA, level), (b0 + bit // 2, SCL, 1)]
                out += [(t, SCL, 0), (t, BYTE, r.value), (t, ACK, 1 if r.ack else 0)]
            self.busy = self.busy or r.kind == "S"
            self.prev = t
        return out


class McuTrace:
    """A run's trace written as it goes (a long run's records are not held): ``add`` each step's TWI
    records (engine.twi_take) and motor pulses (engine.pulses: rise_ns, width_ns, period_ns) with the
    step's end. A pulse is reported when it ends and a byte's bits are drawn before its record's time,
    so the changes of the last HOLD_NS (or twice the longest pulse seen) are held back; one that still
    comes too late (a pin held high longer than that) is written at the earliest time still open."""

    HOLD_NS: Final = 100_000_000

    def __init__(self, path: Path, motor_names: Sequence[str], twi_hz: int, comment: str = "",
                 options: TraceOptions = TraceOptions()) -> None:
        variables = [Var("twi", "scl", 1, 1), Var("twi", "sda", 1, 1), Var("twi", "byte", 8),
                     Var("twi", "ack", 1), Var("twi", "busy", 1, 0)]
        variables += [Var("motors", name, 1, 0) for name in motor_names]
        kept = [v for v in variables if _chosen(v, options.signals)]
        #: a variable's index among all -> among those written (None: not written)
        self._index = [kept.index(v) if v in kept else None for v in variables]
        self._twi = TwiDrawing(max(1, round(1e9 / twi_hz)))
        self._file: TextIO
        self._gzipped: BinaryIO | None = None  # (GzipFile leaves the file it writes to open)
        if options.gzip:  # (no name and no time in the header: the same run, the same bytes)
            self._gzipped = open(path, "wb")  # noqa: SIM115 (closed by close())
            raw = gzip.GzipFile(filename="", mode="wb", fileobj=self._gzipped, mtime=0)
            self._file = io.TextIOWrapper(raw, encoding="ascii", newline="\n")
        else:
            self._file = open(path, "w", encoding="ascii", newline="\n")  # noqa: SIM115 (closed by close())
        self._vcd = VcdWriter(self._file, kept, comment=comment, window=options.window_ns)
        self._hold_ns = max(self.HOLD_NS, 20 * self._twi.bit_ns)

    def add(self, records: Iterable[TwiRecord], pulses: Sequence[Iterable[tuple[int, int, int]]],
            now_ns: int) -> None:
        vcd = self._vcd
        changes = self._twi.draw(records)
        for k, train in enumerate(pulses):
            index = BUSY + 1 + k
            for rise, width, _period in train:
                changes += [(rise, index, 1), (rise + width, index, 0)]
                self._hold_ns = max(self._hold_ns, 2 * width)
        open_ns, kept = vcd.written, self._index
        for t, i, value in changes:
            written = kept[i]
            if written is not None:
                vcd.change(max(t, open_ns), written, value)
        vcd.flush(now_ns - self._hold_ns)

    def close(self) -> None:
        if not self._file.closed:
            self._vcd.flush()
            self._file.close()
            if self._gzipped is not None:
                self._gzipped.close()


def mcu_trace(path: Path, records: Sequence[TwiRecord], pulses: Sequence[Iterable[tuple[int, int, int]]],
              motor_names: Sequence[str], twi_hz: int, comment: str = "") -> None:
    """A run's whole trace at once (McuTrace with one step)."""
    trace = McuTrace(path, motor_names, twi_hz, comment)
    try:
        trace.add(records, pulses, 0)
    finally:
        trace.close()
