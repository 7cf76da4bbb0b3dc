"""An emulated I2C bus: transfers as lists of messages, devices addressed by 7-bit address.

A transfer is what Linux's ``I2C_RDWR`` carries: messages joined by repeated STARTs, one STOP at the
end. Devices see ``start``/``write``/``read``/``stop`` calls in wire order and are told the sim time
before every transfer (devices never read the wall clock). The bus only moves bytes; physics reaches
devices through their sources.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Final, Protocol


class I2CNack(Exception):
    """No device acknowledged the address (the kernel reports ENXIO/EREMOTEIO)."""

    def __init__(self, addr: int) -> None:
        super().__init__(f"no ACK from address 0x{addr:02x}")
        self.addr = addr


class I2CProtocolError(Exception):
    """An SMBus block read whose count byte is 0 or above 32 (the kernel reports EPROTO)."""


SMBUS_BLOCK_MAX: Final = 32


class I2CDevice(Protocol):
    """What the bus needs from a device; the emulators implement it."""

    def advance_to(self, t: float) -> None: ...
    def start(self, read: bool) -> None: ...
    def write(self, data: bytes) -> None: ...
    def read(self, n: int) -> bytes: ...
    def stop(self) -> None: ...


class Msg:
    """One message of a transfer: a write of ``data`` or a read of ``length`` bytes. A ``recv_len``
    read is SMBus's block read (``I2C_M_RECV_LEN``): the first byte read is the count of the rest.
    (A checked plain class rather than a NamedTuple or a frozen dataclass: the session builds one per
    message the DUT sends, and compiled (rig/compiled.py) a plain class is a native one, built several
    times faster than either.)"""

    __slots__ = ("addr", "read", "data", "length", "recv_len")

    def __init__(self, addr: int, read: bool = False, data: bytes = b"", length: int = 0,
                 recv_len: bool = False) -> None:
        if not 0 <= addr <= 0x7F:
            raise ValueError(f"I2C address 0x{addr:x} is not a 7-bit address")
        if read and (length < 0 or data):
            raise ValueError("a read message has a length and no data")
        if recv_len and not read:
            raise ValueError("only a read message can take its length from the first byte")
        self.addr, self.read, self.data, self.length, self.recv_len = addr, read, data, length, recv_len

    def _fields(self) -> tuple[int, bool, bytes, int, bool]:
        return self.addr, self.read, self.data, self.length, self.recv_len

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Msg) and self._fields() == other._fields()

    def __hash__(self) -> int:
        return hash(self._fields())

    def __repr__(self) -> str:
        return "Msg(addr=0x{:02x}, read={}, data={!r}, length={}, recv_len={})".format(*self._fields())


def write(addr: int, *data: int) -> Msg:
    return Msg(addr, False, bytes(data))


def read(addr: int, length: int) -> Msg:
    return Msg(addr, True, b"", length)


Resolver = Callable[[int], I2CDevice | None]


@dataclass
class I2CBus:
    """A bus of devices at fixed addresses, plus resolvers for devices that appear conditionally
    (the HMC5883L behind the MPU-6050's bypass switch)."""

    devices: dict[int, I2CDevice] = field(default_factory=dict)
    resolvers: list[Resolver] = field(default_factory=list)
    #: devices that keep sim time without a fixed address (reached through resolvers or another device)
    hidden: list[I2CDevice] = field(default_factory=list)
    _refusers: dict[type, bool] = field(default_factory=dict, init=False, repr=False, compare=False)

    def attach(self, addr: int, device: I2CDevice) -> None:
        if addr in self.devices:
            raise ValueError(f"address 0x{addr:02x} is already taken")
        self.devices[addr] = device

    def device_at(self, addr: int, t: float | None = None) -> I2CDevice | None:
        """The device that acknowledges ``addr`` now: fixed ones first, then resolvers; a device
        with a bus fault (``acks(t)`` false) does not answer."""
        dev = self.devices.get(addr)
        if dev is None:
            for resolve in self.resolvers:  # (a loop: mypyc turns a nested generator into a list)
                dev = resolve(addr)
                if dev is not None:
                    break
        if dev is not None and t is not None and self._can_refuse(dev):
            if not dev.acks(t):  # type: ignore[attr-defined]
                return None
        return dev

    def _can_refuse(self, dev: I2CDevice) -> bool:
        """Whether ``dev`` has ``acks`` (a FaultyDevice does), by its class, once: asking each device
        object raised and caught an AttributeError per transfer."""
        kind = type(dev)
        known = self._refusers.get(kind)
        if known is None:
            known = self._refusers[kind] = callable(getattr(kind, "acks", None))
        return known

    def advance_to(self, t: float) -> None:
        for dev in self.devices.values():  # (two loops, not a chaining generator: this runs per transfer)
            dev.advance_to(t)
        for dev in self.hidden:
            dev.advance_to(t)

    def transfer(self, msgs: Sequence[Msg], t: float) -> list[bytes]:
        """Runs one transfer at sim time ``t``; returns the bytes of each read message in order.

        Raises I2CNack when a message's address is not acknowledged, and I2CProtocolError when a
        block read announces an impossible count; messages before it have taken effect (as on a real
        bus), and the device that was addressed sees its STOP.
        """
        self.advance_to(t)
        results: list[bytes] = []
        current: I2CDevice | None = None
        try:
            for msg in msgs:
                dev = self.device_at(msg.addr, t)
                if dev is None:
                    raise I2CNack(msg.addr)
                if current is not None and current is not dev:
                    current.stop()
                current = dev
                dev.start(msg.read)
                if msg.recv_len:
                    count = dev.read(1)
                    if not 1 <= count[0] <= SMBUS_BLOCK_MAX:
                        raise I2CProtocolError(f"block read from 0x{msg.addr:02x} announced {count[0]} bytes")
                    results.append(count + dev.read(count[0]))
                elif msg.read:
                    data = dev.read(msg.length)
                    if len(data) != msg.length:
                        raise AssertionError(f"device at 0x{msg.addr:02x} returned {len(data)} bytes")
                    results.append(data)
                else:
                    dev.write(msg.data)
        finally:
            if current is not None:
                current.stop()
        return results
