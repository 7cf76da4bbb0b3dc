"""The reference FC's configuration keys, read from the FC's own table (``dut/src/config_keys.h``, which
its parser compiles), so a scenario's ``[fc]`` table is checked by ``rig validate`` exactly as the FC
would check it: an unknown key, a value of the wrong kind or out of range fails before anything flies.
Rules relating two keys (``ctrl_rate_hz`` at most ``est_rate_hz``) are left to the FC, which says so in
its own words when a run starts."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from functools import cache

from rig.plant.artifacts import tree_file

TABLE = tree_file("dut/src/config_keys.h")


@dataclass(frozen=True)
class FcKey:
    name: str
    kind: str  # "D" numbers, "I" an integer, "S" a path or word
    count: int
    low: float
    high: float

    def check(self, value: object) -> tuple[str, str | None]:
        """The value as the config file line gets it, and what is wrong with it (None: nothing)."""
        if self.kind == "S":
            ok = isinstance(value, str) and 0 < len(value) < 64 and not any(c.isspace() for c in value)
            return str(value), None if ok else "expected a path or word without spaces (under 64 characters)"
        if isinstance(value, list) and self.count > 1:
            items: list[object] = value
        elif isinstance(value, str):
            items = [x for x in re.split(r"[\s,]+", value.strip()) if x]
        else:
            items = [value]
        numbers: list[float] = []
        for x in items:
            if isinstance(x, bool):
                return str(value), f"expected {self._what()}, got a boolean"
            if isinstance(x, str):
                try:
                    x = int(x, 0) if self.kind == "I" else float(x)
                except ValueError:
                    return str(value), f"expected {self._what()}, got {value!r}"
            if not isinstance(x, int | float) or not math.isfinite(x):
                return str(value), f"expected {self._what()}"
            if self.kind == "I" and x != int(x):
                return str(value), f"expected {self._what()}, got {x}"
            numbers.append(float(x))
        text = ", ".join(f"{int(x)}" if self.kind == "I" else repr(x) for x in numbers)
        if len(numbers) != self.count:
            return text, f"expected {self._what()}, got {len(numbers)}"
        bad = [x for x in numbers if not self.low <= x <= self.high]
        if bad:
            return text, f"{bad[0]:g} is outside {self._range()}"
        return text, None

    def _what(self) -> str:
        if self.kind == "I":
            return "an integer"
        return "a number" if self.count == 1 else f"{self.count} numbers (an array or 'a, b, …')"

    def _range(self) -> str:
        if self.high == math.inf:
            return f">= {self.low:g}"
        if self.low == -math.inf:
            return f"<= {self.high:g}"
        return f"{self.low:g}..{self.high:g}"


@cache
def keys() -> dict[str, FcKey]:
    text = TABLE.read_text()
    out: dict[str, FcKey] = {}
    for m in re.finditer(r"FC_KEY\((\w+),\s*([DIS]),\s*(\d+),\s*(\S+?),\s*(\S+?)\)", text):
        name, kind, count, low, high = m.groups()
        lo = -math.inf if low == "ANY" else float(low)
        hi = math.inf if high == "ANY" else float(high)
        out[name] = FcKey(name, kind, int(count), lo, hi)
    return out


@cache
def profiles() -> tuple[str, ...]:
    m = re.search(r"#define FC_PROFILES\(PROFILE\)(.*)", TABLE.read_text())
    return tuple(re.findall(r"PROFILE\((\w+)\)", m.group(1))) if m else ()
