"""The scheduler's events as a heap in C (queue.c, the extension module ``build/_rigevents*.so``): events
in order of time, ties in the order they were scheduled, as heapq's (t_ns, seq, fn) tuples kept them.

Why: a flight schedules about one event per FC cycle (the recorder, the wind, the sticks' frames, each
scheduling its next tick); heapq's tuples cost about 2 k instructions a push and pop, this about a
tenth (queue.c says where it went). The lockstep fast path reads the first event's time straight from
the queue's struct (queue.h). Built on first use, and again when a source is newer, as the other
extensions are; ``make native`` builds it explicitly.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any, Final, Protocol

from rig.plant.artifacts import BUILD
from rig.plant.native_build import EXTENSION_SUFFIX, built_extension, compile_extension

HERE: Final = Path(__file__).resolve().parent
SOURCES: Final = (HERE / "queue.c", HERE / "queue.h")
LIB: Final = BUILD / f"_rigevents{EXTENSION_SUFFIX}"


class EventQueue(Protocol):
    def push(self, t_ns: int, fn: Callable[[Any], None], /) -> None:
        """``fn`` scheduled at ``t_ns`` (ties run in the order pushed)."""

    def pop(self) -> tuple[int, Callable[[Any], None]]:
        """The first event, taken off (IndexError when there is none)."""

    def first_ns(self) -> int | None:
        """The first event's time, or None."""

    def __len__(self) -> int: ...


def build() -> Path:
    return compile_extension(SOURCES[:1], LIB, "the scheduler's event queue (rig/event_queue/queue.c)")


@functools.cache
def native() -> ModuleType:
    return built_extension("_rigevents", LIB, SOURCES, build)


def new_queue() -> EventQueue:
    """An empty queue."""
    q: EventQueue = native().EventQueue()
    return q
