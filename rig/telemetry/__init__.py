"""The DUT's telemetry lines read into columns after a run: ``T t=… key=value …``, the reference FC's
format (dut/linux/main.c, dut/avr/telemetry.c), any other keys passed over.

What is read (the DUT's bytes are not trusted): the text as ASCII, a byte above 0x7f standing for a
character that is in no key and no number. Lines starting with ``#`` are the DUT's messages, passed
over. A ``T `` line is items separated by whitespace, each ``key=value`` (split at its first ``=``);
a key given twice counts its last; a line without ``t``, with an item that is not ``key=value``, with
a value read that ``float()`` refuses, or whose ``t`` is not finite after the clock's base is taken
off, is counted and skipped, as is any other line that is not blank. A value the DUT gives as NaN or
infinite is kept as NaN (the rest of its line stands) and its key's first such time is reported. A
last line without its line end is one the run's end cut while its bytes were still on the wire (a
USART's frames take their time): it is not read.

Why C (lines.c, the extension module ``build/_rigtelemetry*.so``, built on first use as the other
extensions are): the same reading as Python string methods cost 27 k instructions a line, 5 k per FC
cycle of a lockstep flight at the reference FC's 50 lines a second; in C about 6 k a line (a callgrind
profile of the flight: the scan of its 150-odd bytes and the six numbers' conversions). The
tests hold it to a plain Python reading of the paragraph above over odd lines and random edits.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType
from typing import Final

import numpy as np

from rig.plant.artifacts import BUILD
from rig.plant.native_build import EXTENSION_SUFFIX, built_extension, compile_extension

SOURCE: Final = Path(__file__).resolve().with_name("lines.c")
LIB: Final = BUILD / f"_rigtelemetry{EXTENSION_SUFFIX}"


@functools.cache
def native() -> ModuleType:
    """The C side (lines.c), built on first use and again when its source is newer."""
    what = "the telemetry's reader (rig/telemetry/lines.c)"
    return built_extension("_rigtelemetry", LIB, [SOURCE], lambda: compile_extension([SOURCE], LIB, what))


def read_columns(text: bytes | bytearray | memoryview, clock_base_s: float, keys: Sequence[str]
                 ) -> tuple[dict[str, np.ndarray], int, dict[str, float]]:
    """The lines of ``text`` as columns: ``t`` (sim seconds: the DUT's clock minus ``clock_base_s``)
    and each of ``keys`` (NaN where a line lacks it), one row per line read; the count of lines
    skipped; and per key, the sim time it was first not finite."""
    data = bytes(text)
    data = data[:data.rfind(b"\n") + 1]  # (a last line cut by the run's end is not read)
    t, columns, bad, nonfinite = native().parse(data, clock_base_s, ("t", *keys))
    out = {"t": np.frombuffer(t, dtype=float)}
    for k, col in zip(keys, columns, strict=True):
        out[k] = np.frombuffer(col, dtype=float)
    return out, int(bad), dict(nonfinite)
