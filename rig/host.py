"""What a scenario's events see of the session that runs them: the lockstep or real-time Session
(rig/session.py) and the bench's BenchSession (rig/bridge/session.py) both offer it, so the runner's
sticks, wind, recorder and timeline run unchanged against either."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from rig.world import World


class Host(Protocol):
    world: World

    @property
    def now_ns(self) -> int: ...

    def at(self, t: float, fn: Callable[[Host], None]) -> None:
        """Runs ``fn(host)`` at sim time ``t`` seconds."""

    def serial_write(self, path: str, data: bytes) -> None:
        """Bytes to the DUT on a serial path (the RC port's SBUS frames, on a bench the bridge's)."""

    def serial_silence(self, path: str) -> None:
        """Nothing on that path for now (a receiver that stopped its output)."""

    def serial_output(self, path: str) -> bytes:
        """What the DUT has written on a serial path so far."""
