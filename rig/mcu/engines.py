"""The MCU tier's engines behind one interface: the session (rig/mcu/session.py) and the target
(rig/targets/mcu.py) take the engine the board's MCU names (rig/mcu/mcus.py ``engine``): simavr for an
AVR (rig/mcu/engine.py), the rig's QEMU in lockstep for an STM32 (rig/mcu/stm32_link.py). Both run to a
sim time or stop for a sample the chip core needs, and say the same things afterwards."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

from rig.emulators.chips.board import ChipBoard
from rig.mcu.board import Board
from rig.mcu.engine import AvrEngine, Stop, TwiRecord, config_for


class Engine(Protocol):
    def run_until(self, t_ns: int) -> Stop: ...
    def pulses(self) -> list[list[tuple[int, int, int]]]: ...
    def twi_log(self, on: bool = True) -> None: ...
    def twi_take(self) -> list[TwiRecord]: ...
    def uart_take(self, uart: int) -> bytes: ...
    def uart_send(self, uart: int, data: bytes, baud: int, parity: str = "N", stop_bits: int = 1) -> None: ...
    def pin_drive(self, pin: str, schedule: list[tuple[int, int]]) -> None: ...
    def analog_input(self, channel: int, volts: float) -> None: ...
    def figures(self) -> dict[str, Any]: ...
    def poll_figures(self) -> dict[str, int]: ...
    def eeprom(self) -> bytes: ...
    def close(self) -> None: ...


def check_firmware(board: Board, firmware: Path) -> None:
    """FirmwareError unless the board's engine can run ``firmware`` (before anything runs)."""
    if board.mcu.engine == "stm32":
        from rig.mcu.stm32_image import check_image

        check_image(firmware, board.mcu)
        return
    from rig.mcu.image import load

    load(firmware, board.mcu.name)


def open_engine(board: Board, firmware: Path, chips: ChipBoard | None, eeprom: bytes | None = None,
                **limits: Any) -> Engine:
    """The board's MCU running ``firmware`` with ``chips`` on its I2C/TWI; ``limits``: the engines' error
    limits (hang_ns; the AVR's others)."""
    if board.mcu.engine == "stm32":
        from rig.mcu.stm32_link import Stm32Config, Stm32Engine

        hang_ns = int(limits.get("hang_ns", round(board.hang_s * 1e9)))
        return Stm32Engine(Stm32Config(board, firmware, hang_ns=hang_ns, settings=eeprom), chips)
    return AvrEngine(config_for(board, firmware, eeprom, **limits), chips)
