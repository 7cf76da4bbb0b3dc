"""The checker's parts that scenario, board and profile files share (schema.py, rig/mcu/board.py,
profile.py, serial.py): the error that names the file and the dotted key (every problem of a file at
once), and the checks of one table's keys and values, with suggestions for near misses. Apart from the
scenario format itself so that schema.py stays one concern."""

from __future__ import annotations

import difflib
import math
from collections.abc import Collection, Iterator
from contextlib import contextmanager
from typing import Any


class ScenarioError(ValueError):
    """A scenario file that cannot run: ``file: key: message``."""

    def __init__(self, file: str, key: str, message: str) -> None:
        super().__init__(f"{file}: {key}: {message}" if key else f"{file}: {message}")
        self.file, self.key = file, key
        #: every problem of the file (this one first); str() of the error says them all, a line each
        self.problems: list[ScenarioError] = [self]


def _all(problems: list[ScenarioError]) -> ScenarioError:
    """One error that says every problem of a file (the first's file and key)."""
    if len(problems) == 1:
        return problems[0]
    first = problems[0]
    err = type(first)(first.file, first.key, "")  # (a board's or a profile's error stays one)
    err.args = ("\n".join(str(p) for p in problems),)
    err.problems = list(problems)
    return err


# ---- the checker -----------------------------------------------------------------------------------


class _Check:
    """Checks one file's tables and values; every error it raises names the file and the dotted key."""

    def __init__(self, file: str) -> None:
        self.file = file
        self.problems: list[ScenarioError] = []

    def fail(self, key: str, message: str) -> ScenarioError:
        return ScenarioError(self.file, key, message)

    @contextmanager
    def part(self) -> Iterator[None]:
        """A part of the file checked on its own: a problem in it is kept and the check goes on with the
        next part, so that one run of `rig validate` names every problem (a table, an entry of an array,
        a criterion's keys: one problem each, as what follows from a bad value would only repeat it)."""
        try:
            yield
        except ScenarioError as e:
            self.problems.extend(e.problems)

    def lenient(self, data: Any, key: str, known: Collection[str]) -> dict[str, Any]:
        """``data`` as a table, an unknown key in it kept as a problem while its known keys are still
        checked (a typo beside a bad value: both are reported); {} when it is not a table."""
        with self.part():
            self.table(data, key, known)
        return data if isinstance(data, dict) else {}

    def done(self) -> None:
        """Raises every problem the parts kept, as one error."""
        if self.problems:
            raise _all(self.problems)

    def table(self, data: Any, key: str, known: Collection[str] | None) -> dict[str, Any]:
        """``data`` as a table whose keys are all ``known`` (None: any key, checked elsewhere)."""
        if not isinstance(data, dict):
            raise self.fail(key, f"expected a table, got {_kind(data)}")
        for k in data:
            if known is not None and k not in known:
                near = difflib.get_close_matches(k, list(known), n=1)
                hint = f"did you mean {near[0]!r}? " if near else ""
                raise self.fail(
                    f"{key}.{k}" if key else k,
                    f"unknown key; {hint}expected one of: {', '.join(sorted(known))}",
                )
        return data

    def number(
        self,
        data: dict[str, Any],
        key: str,
        path: str,
        default: float | None = None,
        low: float = -math.inf,
        high: float = math.inf,
        positive: bool = False,
    ) -> float:
        full = f"{path}.{key}" if path else key
        if key not in data:
            if default is None:
                raise self.fail(full, "missing; expected a number")
            return default
        v = data[key]
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise self.fail(full, f"expected a finite number, got {_kind(v)}")
        if not math.isfinite(v):
            raise self.fail(full, f"expected a finite number, got {v}")
        if (positive and not v > 0) or not low <= v <= high:
            raise self.fail(full, f"expected {_range(low, high, positive)}, got {v:g}")
        return float(v)

    def optional(self, data: dict[str, Any], key: str, path: str) -> float | None:
        return self.number(data, key, path) if key in data else None

    def string(
        self,
        data: dict[str, Any],
        key: str,
        path: str,
        default: str | None = None,
        choices: tuple[str, ...] | None = None,
    ) -> str:
        full = f"{path}.{key}" if path else key
        if key not in data:
            if default is None:
                raise self.fail(full, "missing; expected a string")
            return default
        v = data[key]
        if not isinstance(v, str):
            raise self.fail(full, f"expected a string, got {_kind(v)}")
        if choices is not None and v not in choices:
            near = difflib.get_close_matches(v, list(choices), n=1)
            hint = f"; did you mean {near[0]!r}?" if near else ""
            said = ", ".join(c or "''" for c in choices)
            raise self.fail(full, f"expected one of {said}, got {v!r}{hint}")
        return v

    def boolean(self, data: dict[str, Any], key: str, path: str, default: bool) -> bool:
        v = data.get(key, default)
        if not isinstance(v, bool):
            raise self.fail(f"{path}.{key}", f"expected true or false, got {_kind(v)}")
        return v

    def vector(self, data: dict[str, Any], key: str, path: str) -> tuple[float, float, float]:
        v = data.get(key, [0.0, 0.0, 0.0])
        if (
            not isinstance(v, list)
            or len(v) != 3
            or any(isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x) for x in v)
        ):
            raise self.fail(f"{path}.{key}", f"expected 3 finite numbers [north, east, down], got {v!r}")
        return (float(v[0]), float(v[1]), float(v[2]))

    def array(self, data: dict[str, Any], key: str) -> list[Any]:
        v = data.get(key, [])
        if not isinstance(v, list):
            raise self.fail(key, f"expected an array of tables ([[{key}]]), got {_kind(v)}")
        return v


def _range(low: float, high: float, positive: bool) -> str:
    """The numbers a key takes, in words ("a number in 0..1", "a number > 0 and at most 3600")."""
    above = "> 0" if positive and low <= 0 else (f">= {low:g}" if low > -math.inf else "")
    if high < math.inf:
        if above.startswith(">=") or (positive and low > 0):
            return f"a number in {low:g}..{high:g}"
        return f"a number {above} and at most {high:g}" if above else f"a number at most {high:g}"
    return f"a number {above}" if above else "a number"


def _kind(v: Any) -> str:
    return {
        bool: "a boolean",
        int: "an integer",
        float: "a number",
        str: "a string",
        list: "an array",
        dict: "a table",
    }.get(type(v), type(v).__name__)
