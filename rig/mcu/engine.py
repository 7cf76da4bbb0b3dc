"""The MCU tier's engine (docs/mcu.md): an AVR image run by simavr 1.6 (Debian's libsimavr) in this
process, with the rig's glue in C (rig/mcu/*.c, build/librigmcu.so, compiled on first use like the
emulators' library): the chip core on the TWI in demand mode, motor pulses as the pins show them, bytes
into the USARTs at frame timing, pin schedules, and every way a firmware fails named.

Time is the MCU's cycle counter divided by its clock. ``run_until`` runs to a sim time or an earlier stop;
a ``need`` stop is the chip core asking for a sample: the session serves it (ChipBoard.serve) and calls
``run_until`` again, the MCU resuming exactly where it was. Same image, inputs and needs served → same
bytes and pulses, run after run (nothing here reads a clock or a random source).

In-process rather than a harness process: the chip core's board and its producers live in this
process, and a 1 ms step costs a C call, not a round trip. A hostile image cannot take the process down:
simavr's wild pointers land in oversized buffers, its crash path stops the core instead of exiting, its
invalid-opcode log becomes a stop (glue.c).
"""

from __future__ import annotations

import ctypes
import functools
import os
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

from rig.emulators import native
from rig.emulators.chips.board import ChipBoard
from rig.mcu.board import Board
from rig.mcu.doing import polling
from rig.mcu.image import EEPROM, FLASH, FirmwareError, load
from rig.mcu.mcus import MCUS
from rig.plant.artifacts import BUILD
from rig.plant.native_build import compile_shared, is_stale

__all__ = ["AvrEngine", "EngineConfig", "FirmwareError", "Motor", "Stop", "config_for"]

HERE: Final = Path(__file__).resolve().parent
SOURCES: Final = tuple(HERE / f for f in ("glue.c", "twi.c", "pwm.c", "serial.c", "timer_modes.c",
                                          "polling.c", "loop_eval.c", "loop_values.c"))
HEADERS: Final = (HERE / "glue.h", HERE / "polling.h", native.CHIPS_DIR / "chip_core.h")
LIB: Final = BUILD / "librigmcu.so"

#: mcu_run's results (glue.h MCU_*)
STOPS: Final = ("reached", "need", "crashed", "sleeping", "watchdog", "hung", "unanswered")
#: each error stop in words that follow "the firmware " (Stop.describe)
HEADLINES: Final = {"crashed": "crashed", "sleeping": "fell asleep for good", "hung": "hung",
                    "watchdog": "was reset by its watchdog in a loop",
                    "unanswered": "talks to a bus no chip answers"}
#: mcu_figure's counters, by index
FIGURES: Final = ("cycles", "instructions", "twi_transactions", "twi_bytes", "twi_nacks", "twi_collisions",
                  "resets", "watchdog_resets", "pc", "sp", "twi_data_nacks", "twi_ignored", "twi_abandoned",
                  "twi_bus_errors", "twi_arbitration_lost")
#: what the firmware saw go wrong on its TWI (result.json's ``bus_problems``), from figures()' names
BUS_PROBLEMS: Final = {"address_nacks": "twi_nacks", "data_nacks": "twi_data_nacks",
                       "ignored_requests": "twi_ignored", "abandoned_waits": "twi_abandoned",
                       "write_collisions": "twi_collisions", "bus_errors": "twi_bus_errors",
                       "arbitration_lost": "twi_arbitration_lost"}

#: per MCU: timer n -> (16-bit, TCCRnA, TCCRnB, TCNTn, ICRn, OCRnA, OCRnB, OCRnC) data-space addresses
_T16_2560: Final = {3: 0x90, 4: 0xA0, 5: 0x120}
TIMERS: Final[dict[str, dict[int, tuple[bool, int, int, int, int, int, int, int]]]] = {
    "atmega328p": {0: (False, 0x44, 0x45, 0x46, 0, 0x47, 0x48, 0),
                   1: (True, 0x80, 0x81, 0x84, 0x86, 0x88, 0x8A, 0),
                   2: (False, 0xB0, 0xB1, 0xB2, 0, 0xB3, 0xB4, 0)},
    "atmega2560": {0: (False, 0x44, 0x45, 0x46, 0, 0x47, 0x48, 0),
                   1: (True, 0x80, 0x81, 0x84, 0x86, 0x88, 0x8A, 0x8C),
                   2: (False, 0xB0, 0xB1, 0xB2, 0, 0xB3, 0xB4, 0),
                   **{n: (True, b, b + 1, b + 4, b + 6, b + 8, b + 10, b + 12)
                      for n, b in _T16_2560.items()}},
}
#: the compare output pins: (timer, channel) -> pin (rig/mcu/mcus.py, the datasheets')
OC_PINS: Final = {name: m.oc_pins for name, m in MCUS.items()}
#: PINx addresses (DDRx follows)
PORTS: Final = {
    "atmega328p": {"B": 0x23, "C": 0x26, "D": 0x29},
    "atmega2560": {"A": 0x20, "B": 0x23, "C": 0x26, "D": 0x29, "E": 0x2C, "F": 0x2F, "G": 0x32, "H": 0x100,
                   "J": 0x103, "K": 0x106, "L": 0x109},
}
#: USARTn -> UCSRnA's address
UARTS: Final = {"atmega328p": {0: 0xC0}, "atmega2560": {0: 0xC0, 1: 0xC8, 2: 0xD0, 3: 0x130}}


class _Need(ctypes.Structure):  # chip_core.h chip_need
    _fields_ = [("chip", ctypes.c_uint8), ("keeps_all", ctypes.c_uint8), ("anchor_mpu", ctypes.c_uint8),
                ("osr", ctypes.c_uint8), ("t_thirds", ctypes.c_uint8), ("hmc_start", ctypes.c_uint8),
                ("count", ctypes.c_uint32), ("anchor", ctypes.c_uint32), ("epoch", ctypes.c_uint32),
                ("t_ns", ctypes.c_uint64), ("period_ns", ctypes.c_uint64), ("anchor_ns", ctypes.c_uint64),
                ("target_ns", ctypes.c_uint64)]


#: a _Need's fields in order, from its bytes (the C struct's layout: native sizes and alignment)
_NEED: Final = struct.Struct("@6B3I4Q")


class _Record(ctypes.Structure):  # glue.h mcu_twi_record
    _fields_ = [("t_ns", ctypes.c_uint64), ("kind", ctypes.c_uint8), ("value", ctypes.c_uint8),
                ("ack", ctypes.c_uint8), ("pad", ctypes.c_uint8 * 5)]


#: a _Record's bytes (the C struct's: native order, standard sizes, no padding but its own)
_RECORD: Final = struct.Struct("=QBBB5x")


class _Calls(ctypes.Structure):  # glue.h mcu_chip_calls
    _fields_ = [(n, ctypes.c_void_p) for n in ("advance", "start", "write_byte", "read_byte", "stop")]


_P, _U8, _U16, _U32, _U64 = ctypes.c_void_p, ctypes.c_uint8, ctypes.c_uint16, ctypes.c_uint32, ctypes.c_uint64
_API: Final[dict[str, tuple[Any, list[Any]]]] = {
    "mcu_engine_size": (ctypes.c_size_t, []),
    "mcu_open": (ctypes.c_int, [_P, ctypes.c_char_p, _U32, ctypes.c_char_p, _U32, ctypes.c_char_p, _U32,
                                ctypes.c_char_p, ctypes.c_size_t]),
    "mcu_close": (None, [_P]),
    "mcu_run": (ctypes.c_int, [_P, _U64]),
    "mcu_cycle_at": (_U64, [_P, _U64]),
    "mcu_ns_at": (_U64, [_P, _U64]),
    "mcu_cycle": (_U64, [_P]),
    "mcu_what": (ctypes.c_char_p, [_P]),
    "mcu_stop_pc": (_U32, [_P]),
    "mcu_stop_cycle": (_U64, [_P]),
    "mcu_need": (None, [_P, ctypes.POINTER(_Need)]),
    "mcu_limits": (None, [_P, _U32, _U64, _U64]),
    "mcu_attach_chips": (None, [_P, _P, ctypes.POINTER(_Calls)]),
    "mcu_figure": (_U64, [_P, ctypes.c_int]),
    "mcu_peek": (_U8, [_P, _U16]),
    "mcu_eeprom_read": (_U32, [_P, ctypes.POINTER(_U8), _U32]),
    "mcu_stock": (None, [_P, ctypes.c_int]),
    "mcu_poll_enable": (None, [_P, ctypes.c_bool]),
    "mcu_poll_figure": (_U64, [_P, ctypes.c_int]),
    "mcu_fuses": (None, [_P, ctypes.c_bool]),
    "mcu_twi_last": (_U32, [_P, ctypes.POINTER(_Record)]),
    "mcu_twi_log": (None, [_P, ctypes.c_bool]),
    "mcu_twi_take": (_U32, [_P, ctypes.POINTER(_Record), _U32]),
    "mcu_timer_define": (None, [_P, _U8, ctypes.c_bool, _U16, _U16, _U16, _U16, _U16, _U16, _U16]),
    "mcu_motor_add": (ctypes.c_bool, [_P, ctypes.c_int8, _U8, ctypes.c_char, _U8, _U16]),
    "mcu_pulses": (_U32, [_P, _U8, ctypes.POINTER(_U64), _U32]),
    "mcu_pulses_all": (_U32, [_P, ctypes.POINTER(_U64), _U32, ctypes.POINTER(_U32)]),
    "mcu_motor_source": (_U32, [_P, _U8, ctypes.c_int]),
    "mcu_uart_define": (ctypes.c_bool, [_P, _U8, _U16]),
    "mcu_watch_port": (ctypes.c_bool, [_P, ctypes.c_char, _U16]),
    "mcu_adc_set": (ctypes.c_bool, [_P, _U8, _U32]),
    "mcu_uart_send": (ctypes.c_bool, [_P, _U8, ctypes.c_char_p, _U32, _U32, ctypes.c_char, _U8]),
    "mcu_uart_take": (_U32, [_P, _U8, ctypes.POINTER(_U8), _U32]),
    "mcu_uart_count": (_U32, [_P, _U8, ctypes.c_int]),
    "mcu_pin_drive": (ctypes.c_bool, [_P, ctypes.c_char, _U8, ctypes.POINTER(_U64), ctypes.POINTER(_U8),
                                      _U32]),
}


def build() -> Path:
    return compile_shared(SOURCES, LIB, "the MCU engine's glue (needs libsimavr-dev: make avr-toolchain)",
                          libs=["-lsimavr"], flags=[f"-I{native.CHIPS_DIR}"])


@functools.cache
def lib() -> ctypes.CDLL:
    """The glue through ctypes, built first when missing or older than a source."""
    if is_stale(LIB, (*SOURCES, *HEADERS)):
        build()
    so = ctypes.CDLL(str(LIB))
    for name, (restype, argtypes) in _API.items():
        fn = getattr(so, name)
        fn.restype, fn.argtypes = restype, argtypes
    return so


@dataclass(frozen=True)
class Motor:
    """One ESC output: a compare output pin of a timer (``timer`` None: measured from the pin's edges,
    software PWM)."""

    pin: str  #: "PE4": port letter and bit
    timer: int | None  #: 0..5
    channel: str = "A"  #: "A" | "B" | "C" (OCnX)


@dataclass(frozen=True)
class EngineConfig:
    mcu: str  #: "atmega2560" | "atmega328p"
    clock_hz: int  #: 16_000_000
    firmware: Path  #: .elf or .hex
    motors: tuple[Motor, ...] = ()
    eeprom: bytes | None = None  #: preloaded EEPROM image (else the ELF's .eeprom section, if any)
    twi: bool = True  #: the chip core on the TWI (else no chip answers)
    #: the firmware's errors: this many watchdog resets; no TWI transaction and no motor pulse for
    #: hang_ns; addresses NACKed with none acknowledged for unanswered_ns (0: not checked)
    watchdog_resets: int = 3
    hang_ns: int = 1_000_000_000
    unanswered_ns: int = 1_000_000_000
    #: the WDTON fuse programmed: the watchdog always on in system reset mode (a board's [fuses])
    watchdog_always_on: bool = False
    #: analog inputs: (ADC channel, volts at the pin), e.g. a battery through its divider
    analog: tuple[tuple[int, float], ...] = ()
    #: the polling-loop skip (rig/mcu/polling.c): None follows RIG_MCU_POLL_SKIP (on unless "0")
    poll_skip: bool | None = None


#: the environment variable that turns the polling-loop skip off ("0") for a whole process: the rig's
#: commands and sessions build their engines from board files, so a comparison of runs with it on and
#: off needs no option threaded through them
POLL_SKIP_ENV: Final = "RIG_MCU_POLL_SKIP"
#: mcu_poll_figure's counters, by index
POLL_FIGURES: Final = ("skipped_cycles", "skips", "refused", "mismatches")


def poll_skip_on(cfg: EngineConfig) -> bool:
    """Whether an engine of ``cfg`` skips polling loops: its own setting, else the environment's."""
    if cfg.poll_skip is not None:
        return cfg.poll_skip
    return os.environ.get(POLL_SKIP_ENV, "1") != "0"


def config_for(board: Board, firmware: Path, eeprom: bytes | None = None, **limits: Any) -> EngineConfig:
    """The engine's configuration for a board file (rig/mcu/board.py): its MCU, clock, motors in the
    plant's order (1..4), fuses; ``limits``: EngineConfig's error limits (hang_ns, ...)."""
    motors = tuple(Motor(m.pin, m.timer, m.channel or "A")
                   for m in sorted(board.motors, key=lambda m: m.motor))
    limits.setdefault("hang_ns", round(board.hang_s * 1e9))
    return EngineConfig(board.mcu.name, board.clock_hz, firmware, motors, eeprom=eeprom,
                        watchdog_always_on=board.watchdog_always_on, analog=analog_inputs(board), **limits)


def analog_inputs(board: Board) -> tuple[tuple[int, float], ...]:
    """The board's analog inputs as both engines take them: (ADC channel, volts at the pin), its battery
    through the divider."""
    return () if board.battery is None else ((board.battery.channel, board.battery.pin_volts),)


@dataclass(frozen=True)
class Stop:
    """Why run_until returned. kind: "reached" (the time asked), "need" (the chip core lacks a sample:
    ``need`` for ChipBoard.serve), or the firmware's error, final: "crashed" (invalid opcode, jump outside
    the program or flash, bad data address), "sleeping" (asleep with interrupts off), "watchdog" (reset by
    it in a loop), "hung" (no TWI, pulses, USART bytes sent or output pin changes), "unanswered"
    (a bus no chip answers)."""

    kind: str
    cycle: int
    pc: int = 0
    what: str = ""
    need: tuple[int, ...] | None = None
    last_twi: str = ""

    @property
    def error(self) -> bool:
        return self.kind not in ("reached", "need")

    def describe(self) -> str:
        """One line: what happened, where and when (the last TWI transaction when there was one), to
        follow "the firmware ": "hung: no TWI transaction, motor pulse, USART byte sent or output pin
        change for 1000 ms; it was polling UCSR0A ... (pc ...)"."""
        text = f"{HEADLINES.get(self.kind, self.kind)}: {self.what} (pc 0x{self.pc:05x}, cycle {self.cycle})"
        return f"{text}; last TWI transaction: {self.last_twi}" if self.last_twi else text


@dataclass
class TwiRecord:
    t_ns: int
    kind: str  #: S start, A address, W written, R read, P stop
    value: int
    ack: bool


def format_transaction(records: list[TwiRecord]) -> str:
    """``S 68W+ 3B+ S 69R+ 00+ 12- P`` style: + acknowledged, - not."""
    parts = [f"t={records[0].t_ns / 1e6:.3f} ms"] if records else []
    for r in records:
        mark = "+" if r.ack else "-"
        if r.kind == "A":
            parts.append(f"{'S' if not parts or parts[-1] != 'S' else ''}{r.value >> 1:02x}"
                         f"{'R' if r.value & 1 else 'W'}{mark}")
        elif r.kind in "WR":
            parts.append(f"{r.value:02x}{mark}")
        elif r.kind == "S":
            parts.append("S")
        else:
            parts.append("P")
    return " ".join(p for p in parts)


@dataclass
class _Uart:
    sent: int = 0


class AvrEngine:
    """One MCU running one image. Not thread-safe; close() frees simavr's memory."""

    def __init__(self, cfg: EngineConfig, chips: ChipBoard | None) -> None:
        if cfg.mcu not in FLASH:
            raise FirmwareError(f"unknown MCU {cfg.mcu!r}; choose one of {', '.join(FLASH)}")
        if cfg.clock_hz <= 0 or cfg.clock_hz > 50_000_000:
            raise ValueError(f"clock {cfg.clock_hz} Hz: an AVR runs at 1..50 MHz")
        image = load(Path(cfg.firmware), cfg.mcu)
        self._flash = image.flash  # (a hang's words: the loop it was in)
        self.cfg = cfg
        self._lib = lib()
        self._mem = ctypes.create_string_buffer(self._lib.mcu_engine_size())
        self._addr = ctypes.addressof(self._mem)
        self._open = False
        err = ctypes.create_string_buffer(256)
        eeprom = cfg.eeprom if cfg.eeprom is not None else image.eeprom
        if self._lib.mcu_open(self._addr, cfg.mcu.encode(), cfg.clock_hz, image.flash, len(image.flash),
                              eeprom, len(eeprom or b""), err, len(err)) != 0:
            raise FirmwareError(f"{cfg.firmware}: {err.value.decode()}")
        self._open = True
        self._lib.mcu_limits(self._e, cfg.watchdog_resets, cfg.hang_ns, cfg.unanswered_ns)
        self._lib.mcu_fuses(self._e, cfg.watchdog_always_on)
        self._lib.mcu_poll_enable(self._e, poll_skip_on(cfg))
        self.chips = chips if cfg.twi else None
        if self.chips is not None:
            so = native.chips()
            calls = _Calls(*(ctypes.cast(getattr(so, f"chip_{n}"), ctypes.c_void_p).value
                             for n in ("advance", "start", "write_byte", "read_byte", "stop")))
            self._lib.mcu_attach_chips(self._e, self.chips.addr, ctypes.byref(calls))
        self.motors = cfg.motors
        for i, m in enumerate(cfg.motors):
            self._add_motor(i, m)
        self._uarts: dict[int, _Uart] = {}
        for n, base in UARTS[cfg.mcu].items():
            if self._lib.mcu_uart_define(self._e, n, base):
                self._uarts[n] = _Uart()
        for channel, volts in cfg.analog:
            self.analog_input(channel, volts)
        for port, pin_addr in PORTS[cfg.mcu].items():
            if not self._lib.mcu_watch_port(self._e, port.encode(), pin_addr + 1):
                raise ValueError(f"the {cfg.mcu}'s port {port} cannot be watched")
        self._pulse_buf = (_U64 * (3 * 64))()
        self._pulse_counts = (_U32 * len(cfg.motors))()
        self._uart_buf = (_U8 * 4096)()
        self._need = _Need()
        self._need_ref = ctypes.byref(self._need)
        self._stop: Stop | None = None
        self._twi_buf = (_Record * 1024)()  # (twi_take's, made once: it runs every plant tick)

    @property
    def _e(self) -> int:
        """The glue's engine (a closed engine's memory is gone: using it is an error, not a crash)."""
        if not self._open:
            raise RuntimeError("the engine is closed")
        return self._addr

    def _add_motor(self, i: int, m: Motor) -> None:
        mcu = self.cfg.mcu
        port, bit = _pin(mcu, m.pin)
        if m.timer is not None:
            timers = TIMERS[mcu]
            if m.timer not in timers or m.channel not in ("A", "B", "C"):
                raise ValueError(f"motor {i + 1}: the {mcu} has no OC{m.timer}{m.channel}")
            want = OC_PINS[mcu].get((m.timer, m.channel))
            if want != m.pin:
                raise ValueError(f"motor {i + 1}: OC{m.timer}{m.channel} is pin {want}, not {m.pin}")
            self._lib.mcu_timer_define(self._e, m.timer, *timers[m.timer])
        ok = self._lib.mcu_motor_add(self._e, -1 if m.timer is None else m.timer, "ABC".index(m.channel),
                                     port.encode(), bit, PORTS[mcu][port] + 1)
        if not ok:
            raise ValueError(f"motor {i + 1}: no room (8 motors at most) or no pin {m.pin}")

    # ---- time ----
    @property
    def cycle(self) -> int:
        return int(self._lib.mcu_cycle(self._e))

    @property
    def now_ns(self) -> int:
        return int(self._lib.mcu_ns_at(self._e, self.cycle))

    def run_until(self, t_ns: int) -> Stop:
        """Runs until sim time ``t_ns`` (its first cycle at or after it) or an earlier stop."""
        if self._stop is not None:
            return self._stop
        e, c = self._e, self._lib
        r = c.mcu_run(e, c.mcu_cycle_at(e, max(t_ns, 0)))
        kind = STOPS[r]
        if kind == "reached":
            return Stop("reached", c.mcu_cycle(e))
        if kind == "need":
            n = self._need
            c.mcu_need(e, self._need_ref)
            return Stop("need", c.mcu_cycle(e), need=_NEED.unpack_from(n))
        pc = int(c.mcu_stop_pc(e))
        what = c.mcu_what(e).decode(errors="replace")
        if kind == "hung":  # (what it was waiting on: a receiver, the EEPROM, ...)
            doing = polling(self._flash, pc, self.cfg.mcu)
            what += f"; {doing}" if doing else ""
        self._stop = Stop(kind, int(c.mcu_stop_cycle(e)), pc, what,
                          last_twi=format_transaction(self.last_twi()))
        return self._stop

    def run_served(self, t_ns: int) -> Stop:
        """run_until, serving the chip core's needs from the ChipBoard until another stop."""
        while True:
            stop = self.run_until(t_ns)
            if stop.kind != "need" or self.chips is None:
                return stop
            self.chips.serve(stop.need)

    # ---- I/O ----
    def uart_send(self, uart: int, data: bytes, baud: int, parity: str = "N", stop_bits: int = 1) -> None:
        """Bytes into USARTn's receiver from now on, one frame apart (8E2 at 100000 baud: 120 us a byte).
        A receiver set to another baud or parity counts them as frame errors and gets nothing."""
        if uart not in self._uarts:
            raise ValueError(f"the {self.cfg.mcu} has no USART{uart}")
        if parity not in ("N", "E", "O") or stop_bits not in (1, 2) or baud <= 0:
            raise ValueError(f"USART frame {baud} {parity}{stop_bits}: baud > 0, parity N/E/O, 1 or 2 stops")
        if not self._lib.mcu_uart_send(self._e, uart, data, len(data), baud, parity.encode(), stop_bits):
            raise ValueError(f"USART{uart}: more than 4096 bytes waiting")

    def uart_take(self, uart: int) -> bytes:
        """What the firmware transmitted on USARTn since the last take."""
        buf = self._uart_buf
        n = self._lib.mcu_uart_take(self._e, uart, buf, len(buf))
        return ctypes.string_at(buf, n) if n else b""

    def uart_counts(self, uart: int) -> dict[str, int]:
        names = ("delivered", "frame_errors", "waiting", "tx_dropped", "receiver_off")
        return {k: int(self._lib.mcu_uart_count(self._e, uart, i)) for i, k in enumerate(names)}

    def analog_input(self, channel: int, volts: float) -> None:
        """ADC ``channel``'s pin at ``volts`` (to the millivolt, as simavr takes it) from now on: each
        conversion that starts later reads it (against AVCC; above it, full scale)."""
        if volts < 0 or not self._lib.mcu_adc_set(self._e, channel, round(volts * 1000)):
            raise ValueError(f"the {self.cfg.mcu} has no ADC{channel}, or {volts} V is below 0")

    def pin_drive(self, pin: str, schedule: list[tuple[int, int]]) -> None:
        """An input pin driven to ``level`` at each ``(t_ns, level)`` (ascending, not before now): a PPM
        sum, a switch. Edges on an INTx or PCINT pin interrupt as on the hardware."""
        port, bit = _pin(self.cfg.mcu, pin)
        n = len(schedule)
        cycles = (_U64 * n)(*(self._lib.mcu_cycle_at(self._e, t) for t, _ in schedule))
        levels = (_U8 * n)(*(1 if v else 0 for _, v in schedule))
        if not self._lib.mcu_pin_drive(self._e, port.encode(), bit, cycles, levels, n):
            raise ValueError(f"pin {pin}: more than 4096 edges waiting, or more than 9 pins driven")

    def pulses(self) -> list[list[tuple[int, int, int]]]:
        """Per motor, the pulses ended since the last call: (rise_ns, width_ns, period_ns)."""
        out: list[list[tuple[int, int, int]]] = [[] for _ in self.motors]
        buf, counts, take, e = self._pulse_buf, self._pulse_counts, self._lib.mcu_pulses_all, self._e
        while True:  # (one call into C a plant tick: a tick holds a few pulses, the buffer 64)
            total = take(e, buf, 64, counts)
            if total:
                flat = buf[:3 * total]
                k = 0
                for got, n in zip(out, counts, strict=False):
                    if n:
                        part = flat[3 * k:3 * (k + n)]
                        got += zip(part[0::3], part[1::3], part[2::3], strict=True)
                        k += n
            if total < 64:
                return out

    def capture(self) -> list[dict[str, int]]:
        """Per motor, how its pulses so far were measured: ``timer`` from the compare registers (the
        compare output driving the pin), ``edges`` from the pin's edges (no timer, or the compare output
        disconnected: the pin follows PORTx)."""
        return [{"timer": int(self._lib.mcu_motor_source(self._e, i, 0)),
                 "edges": int(self._lib.mcu_motor_source(self._e, i, 1))} for i in range(len(self.motors))]

    # ---- looking in ----
    def last_twi(self) -> list[TwiRecord]:
        buf = (_Record * 96)()
        n = self._lib.mcu_twi_last(self._e, buf)
        return [TwiRecord(r.t_ns, chr(r.kind), r.value, bool(r.ack)) for r in buf[:n]]

    def twi_log(self, on: bool = True) -> None:
        """Keeps every TWI record from now on, for twi_take (the replayer test)."""
        self._lib.mcu_twi_log(self._e, on)

    def twi_take(self) -> list[TwiRecord]:
        """The TWI records since the last take (twi_log), read from the buffer's bytes: a record's
        fields one by one through ctypes cost more than the rest of a plant tick's Python."""
        out: list[TwiRecord] = []
        buf, take, e = self._twi_buf, self._lib.mcu_twi_take, self._e
        while True:
            n = take(e, buf, 1024)
            if n:
                raw = ctypes.string_at(buf, n * _RECORD.size)
                out += [TwiRecord(t, chr(k), v, a != 0) for t, k, v, a in _RECORD.iter_unpack(raw)]
            if n < 1024:
                return out

    def stock(self, extint_poll: bool = False, uart_poll_sleep: bool = False,
              timer_modes: bool = False) -> None:
        """simavr 1.6's own behaviour back, for bench/mcu_rates.py to measure what the glue's fixes save:
        the per-cycle poll of an INTx pin held low, a usleep(1) per poll of an idle USART, a timer in a
        mode simavr lacks overflowing every prescaler period (rig/mcu/timer_modes.c)."""
        self._lib.mcu_stock(self._e, (1 if extint_poll else 0) | (2 if uart_poll_sleep else 0)
                            | (4 if timer_modes else 0))

    def poll_figures(self) -> dict[str, int]:
        """What the polling-loop skip did: the cycles it jumped over, in how many jumps, the loops it
        tried and could not prove, and its predictions simavr did not confirm (0: any is a defect, and
        that loop is then run). Not part of figures(): result.json is the same with it on and off."""
        return {name: int(self._lib.mcu_poll_figure(self._e, i)) for i, name in enumerate(POLL_FIGURES)}

    def peek(self, addr: int) -> int:
        """A byte of the data space (registers, I/O, SRAM) as it is; SREG (0x5F) as its flags are."""
        return int(self._lib.mcu_peek(self._e, addr))

    def eeprom(self) -> bytes:
        """The EEPROM as the firmware has left it, all of it (what the chip would keep at power-off)."""
        buf = (_U8 * EEPROM[self.cfg.mcu])()
        n = self._lib.mcu_eeprom_read(self._e, buf, len(buf))
        if n != len(buf):
            raise RuntimeError(f"simavr gave {n} bytes of the {self.cfg.mcu}'s {len(buf)}-byte EEPROM")
        return ctypes.string_at(buf, n)

    def figures(self) -> dict[str, Any]:
        figs: dict[str, Any] = {name: int(self._lib.mcu_figure(self._e, i))
                                   for i, name in enumerate(FIGURES)}
        figs["sim_ns"] = self.now_ns
        figs["last_twi"] = format_transaction(self.last_twi())
        figs["uarts"] = {n: self.uart_counts(n) for n in self._uarts}
        figs["motor_capture"] = self.capture()
        if self._stop is not None:
            figs["stop"] = self._stop.describe()
        return figs

    def close(self) -> None:
        if getattr(self, "_open", False):
            self._lib.mcu_close(self._addr)
            self._open = False

    def __enter__(self) -> AvrEngine:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        self.close()


def _pin(mcu: str, pin: str) -> tuple[str, int]:
    if len(pin) != 3 or pin[0] != "P" or pin[1] not in PORTS[mcu] or not pin[2].isdigit() or int(pin[2]) > 7:
        raise ValueError(f"pin {pin!r}: expected P, a port letter of the {mcu} "
                         f"({''.join(PORTS[mcu])}) and a bit 0..7")
    return pin[1], int(pin[2])


