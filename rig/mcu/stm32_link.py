"""The STM32 tier's engine in lockstep (docs/stm32.md): the rig's ``qemu-system-arm``
(rig/mcu/stm32_engine.py) running an ARM image on the board MCU's machine (its ``machine``: rig-stm32f405,
rig-stm32f411) with the board's crystal, linked to this process by a Unix socket (qemu/hw/rig_link.c),
with AvrEngine's interface (rig/mcu/engine.py), so the MCU session runs either.

Time is QEMU's virtual time under ``-icount shift=ICOUNT_SHIFT,sleep=off`` (each instruction 2**shift ns):
the instruction count, so the same image, world and needs served give the same bytes and pulses, run
after run. ``run_until(t)`` tells QEMU to run to t; QEMU answers "reached" with the motor outputs'
latched pulses and the CPU's exception state, then waits. A system reset is told at its instant: a
watchdog's ends the run as a crash naming the pc it came at. Meanwhile every event of the I2C bus comes
here and the session's own chip core (the world's ChipBoard, as the AVR tier's) answers it: a START
first runs the chips to its instant, and a sample the core lacks stops ``run_until`` with a ``need``,
which the session serves (ChipBoard.serve) before calling ``run_until`` again; QEMU waits for the
START's answer all the while.

Reads come ahead: a read START's answer carries the bytes the master is expected to read (as many as the
same transfer, the address and the bytes written before it, read last time), QEMU hands them to the
master at their instants and tells which it took and when (the READS message) before anything else; the
bytes it did not take are given back by taking the chip core back to its state before them and reading
again those that were (a chip's register pointer and FIFO move with each byte read). A transfer costs one
round trip, not one per byte.

Messages (qemu/hw/rig_link.c): the kind (1 byte), 3 zero bytes, the payload's length (u32), the payload;
little-endian. QEMU's bytes are checked as any input: a bad one ends the run with an error.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import socket
import struct
import subprocess
import tempfile
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

from rig.emulators import native
from rig.emulators.chips.board import ChipBoard
from rig.mcu.board import Board
from rig.mcu.engine import FirmwareError, Stop, TwiRecord, analog_inputs, format_transaction
from rig.mcu.mcus import Mcu
from rig.mcu.stm32_image import check_image, config_section, with_settings

__all__ = ["ICOUNT_SHIFT", "LINK_VERSION", "LinkError", "Stm32Engine"]

LINK_VERSION: Final = 2
#: 2**3 ns an instruction: 125 M instructions per virtual second
ICOUNT_SHIFT: Final = 3
HEADER: Final = struct.Struct("<B3xI")
MAX_PAYLOAD: Final = 1024
#: a safety net for QEMU's start and for a QEMU that stops answering (not a timing of the run)
SOCKET_TIMEOUT_S: Final = 60.0
#: the exceptions that are faults (ARMv7-M B1.5.2): IPSR while their handler runs
FAULTS: Final = {3: "HardFault", 4: "MemManage fault", 5: "BusFault", 6: "UsageFault"}
#: the SoC's USART1..USART6 (UART4, UART5 among them), each a ringbuf chardev rig-usartN in this order
UARTS: Final = 6
UART_RING_BYTES: Final = 65536
#: bytes of one UART message to QEMU (its payload's 1024 less the frame's description, 16 bytes)
UART_CHUNK: Final = 1008
#: the most an ADC input message carries (u32 microvolts; a board's battery divider is checked to 60 V)
ADC_MAX_VOLTS: Final = 60.0
#: the timer outputs rig_link.c numbers: CH1..CH4, then CH1N..CH3N
OUTPUTS: Final = ("1", "2", "3", "4", "1N", "2N", "3N")
#: pins driven at once, and edges waiting per pin (qemu/hw/rig_link.c's queues)
PIN_QUEUES: Final = 9
PIN_EDGES: Final = 1024
_EDGE = struct.Struct("<QB")
#: edges of one PIN message (its payload's 1024 less the pin's 4 bytes, 9 bytes an edge)
PIN_CHUNK: Final = (MAX_PAYLOAD - 4) // _EDGE.size
_REACHED = struct.Struct("<QIIIIB")
#: a system reset: its time, its cause, the CPU's IPSR, pc, CFSR and HFSR as it came
_RESET = struct.Struct("<QIIIII")
#: rig_link.c's reset causes (RigResetCause) that are errors of the firmware: a watchdog ran out
WATCHDOG_RESETS: Final = {1: "IWDG", 2: "WWDG"}
_PULSE = struct.Struct("<IIIQ")
#: pulses kept per motor between two takes (the oldest are dropped)
MAX_PULSES: Final = 256
#: what one recv from QEMU takes at most
RECV_BYTES: Final = 65536
#: bytes read ahead at most (an answer's payload is 1024 bytes; the MPU-6050's FIFO holds 1024)
MAX_AHEAD: Final = 512
#: the bytes written before a read that tell one transfer from another (a register address, a command)
AHEAD_KEY_BYTES: Final = 4


class LinkError(RuntimeError):
    """QEMU said something the link does not allow, or went away."""


@dataclass(frozen=True)
class Stm32Config:
    board: Board
    firmware: Path
    #: the engine binary (stm32_engine.cached_binary()); None: built or taken from the cache
    binary: Path | None = None
    #: no I2C event, USART byte sent or change of a motor's pulse for this long is a hang (0: not checked;
    #: a timer's PWM runs on without the firmware, so its pulses alone are no sign of life)
    hang_ns: int = 1_000_000_000
    #: the settings image written into the firmware's flash before it boots (stm32_image.with_settings:
    #: a scenario's [fc] table for the reference FC); None: the image as built
    settings: bytes | None = None
    #: analog inputs as AvrEngine's EngineConfig has them: (ADC channel, volts at the pin), set before the
    #: first instruction on every ADC that has that channel (the MCU's ``adc_units``); None: the board's
    #: (engine.analog_inputs: its battery through the divider)
    analog: tuple[tuple[int, float], ...] | None = None
    #: more of QEMU's command line (-global MODEL.PROPERTY=VALUE: a model's test setting)
    qemu_args: tuple[str, ...] = ()
    #: QEMU and the calling thread on one core for the run (the thread's own affinity back at close()):
    #: in lockstep only one of them runs at a time, and a round trip between two cores costs each side's
    #: core a wake-up from idle, which in a virtual machine is most of the link's cost
    #: (bench/stm32_rates.py: hover_turbulence 3.1x real time on two cores, 5.2x on one)
    one_core: bool = True


def current_cpu() -> int:
    """The CPU the calling thread runs on now (glibc's sched_getcpu), else the first it may run on."""
    with contextlib.suppress(OSError, AttributeError):
        cpu = int(ctypes.CDLL(None, use_errno=True).sched_getcpu())
        if cpu >= 0:
            return cpu
    return min(os.sched_getaffinity(0))


class Stm32Engine:
    """One QEMU running one image, in lockstep. close() ends QEMU (and reaps it)."""

    def __init__(self, cfg: Stm32Config, chips: ChipBoard | None) -> None:
        check_image(cfg.firmware, cfg.board.mcu)
        binary = cfg.binary
        if binary is None:
            from rig.mcu import stm32_engine

            # a built engine is taken without the build's lock: the service's runs see the cache read-only
            binary = stm32_engine.cached_binary() or stm32_engine.build()
        self.cfg = cfg
        self.chips = chips
        self._fast = native.fast()
        self._lib = native.chips()
        self._motors = [(m.timer or 0, OUTPUTS.index(m.channel)) for m in cfg.board.motors]
        self._now_ns = 0
        self._stop: Stop | None = None
        self._pending: tuple[int, int, bool] | None = None  # a START waiting for the chips' answer
        self._records: list[TwiRecord] = []
        self._last: list[TwiRecord] = []  # the last transaction's records
        self._log = False
        self._transactions = 0
        self._bytes = 0
        self._nacks = 0
        self._board_size = int(self._lib.rig_chip_board_size())
        self._written = bytearray()  # the bytes written since the last STOP (a read's key)
        self._in_transfer = False
        self._read_key: tuple[int, bytes] = (0, b"")
        self._read_count = 0  # bytes the master read in this read transfer
        self._read_lengths: dict[tuple[int, bytes], int] = {}  # how many the same transfer read last time
        self._ahead: list[int] = []  # the bytes QEMU holds ahead, of which the first _taken were read
        self._taken = 0
        self._before_ahead: bytes | None = None  # the chip core's state before the bytes ahead
        self._pulses: list[list[tuple[int, int, int]]] = [[] for _ in self._motors]
        self._pulse_counts = [0 for _ in self._motors]
        self._widths = [0 for _ in self._motors]
        self._active_ns = 0  # the last sign of life (hang_ns)
        self._state = (0, 0, 0, 0)  # ipsr, pc, cfsr, hfsr at the last stop
        self._resets = 0  # system resets after power-on
        self._waiting = False  # QEMU waits for a command (after a REACHED)
        self._sent: dict[int, bytearray] = {n: bytearray() for n in cfg.board.mcu.usarts}
        self._uart_counts: dict[int, list[int]] = {n: [0, 0] for n in cfg.board.mcu.usarts}  # in, out
        self._inbox = bytearray()  # bytes from QEMU not yet taken (_read), from _inbox_at on
        self._inbox_at = 0
        self._pin_edges: dict[str, list[int]] = {}  # each driven pin's edge times, those past pruned
        self._dir = tempfile.TemporaryDirectory(prefix="rig-stm32-")
        firmware = cfg.firmware
        if cfg.settings is not None:
            try:
                firmware = with_settings(cfg.firmware, cfg.settings, Path(self._dir.name) / "firmware.elf")
            except FirmwareError:
                self._dir.cleanup()
                raise
        path = str(Path(self._dir.name) / "link")
        listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        listener.bind(path)
        listener.listen(1)
        listener.settimeout(SOCKET_TIMEOUT_S)
        self._output = open(Path(self._dir.name) / "qemu.out", "w+b")  # noqa: SIM115 (closed in close())
        uarts: list[str] = []
        for n in range(1, UARTS + 1):
            chardev = f"rig-usart{n}"
            # (the machine's USARTs send into them by their ids; QEMU's own USARTs get none)
            uarts += ["-chardev", f"ringbuf,id={chardev},size={UART_RING_BYTES}"]
        # (the machine is the MCU's, its crystal the board's)
        cmd = [str(binary), "-M", cfg.board.mcu.machine,
               "-global", f"rig-stm32f4-rcc.hse-hz={cfg.board.hse_hz}", "-nodefaults",
               "-display", "none", "-monitor", "none", "-chardev", f"socket,id=rig-link,path={path}", *uarts,
               "-semihosting-config", "enable=on,target=native",
               "-icount", f"shift={ICOUNT_SHIFT},sleep=off", *cfg.qemu_args, "-kernel", str(firmware)]
        self._affinity: tuple[int, set[int]] | None = None  # the pinned thread and its own affinity
        if cfg.one_core:
            own = os.sched_getaffinity(0)
            with contextlib.suppress(OSError):  # (a machine that refuses: both run wherever they may)
                os.sched_setaffinity(0, {current_cpu()})  # (QEMU's threads inherit it)
                self._affinity = (threading.get_native_id(), own)
        self._proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=self._output,
                                      stderr=subprocess.STDOUT)
        try:
            self._sock, _ = listener.accept()
        except TimeoutError:
            self.close()
            raise LinkError(f"QEMU did not connect in {SOCKET_TIMEOUT_S:g} s: {self._tail()}") from None
        except BaseException:
            self.close()
            raise
        finally:
            listener.close()
        self._sock.settimeout(SOCKET_TIMEOUT_S)
        try:
            self._hello()
        except BaseException:
            self.close()  # (QEMU and the folder go with the engine that failed to start)
            raise

    # ---- the link ----
    def _hello(self) -> None:
        kind, payload = self._receive()
        if kind != ord("H") or len(payload) != 2:
            raise LinkError(f"QEMU's first message is not a HELLO ({kind!r}, {len(payload)} bytes)")
        (version,) = struct.unpack("<H", payload)
        if version != LINK_VERSION:
            raise LinkError(f"the engine speaks link version {version}, this rig {LINK_VERSION}: "
                            "rebuild it (make stm32-engine)")
        config = bytes([len(self._motors)]) + b"".join(bytes([t, o]) for t, o in self._motors)
        self._send(ord("C"), config)
        stop = self._until_reached()  # (the stop at time 0, before the first instruction)
        if stop.kind != "reached":
            raise FirmwareError(f"{self.cfg.firmware}: {stop.describe()}")
        analog = self.cfg.analog if self.cfg.analog is not None else analog_inputs(self.cfg.board)
        for channel, volts in analog:
            self.analog_input(channel, volts)

    def _send(self, kind: int, payload: bytes = b"") -> None:
        try:
            self._sock.sendall(HEADER.pack(kind, len(payload)) + payload)
        except OSError as e:
            raise LinkError(f"QEMU is gone ({e})") from None

    def _read(self, n: int) -> bytes:
        """``n`` bytes from QEMU: what one recv brought is kept for the next messages (a message's header
        and payload, and the messages QEMU sends without waiting, cost one system call, not one each)."""
        buf, at = self._inbox, self._inbox_at
        while len(buf) - at < n:
            chunk = self._sock.recv(RECV_BYTES)
            if not chunk:
                raise EOFError
            del buf[:at]
            at = 0
            buf += chunk
        self._inbox_at = at + n
        return bytes(buf[at:at + n])

    def _receive(self) -> tuple[int, bytes]:
        kind, length = HEADER.unpack(self._read(HEADER.size))
        if length > MAX_PAYLOAD:
            raise LinkError(f"a message of {length} bytes from QEMU (at most {MAX_PAYLOAD})")
        return kind, self._read(length) if length else b""

    def _record(self, t_ns: int, kind: str, value: int, ack: bool) -> None:
        r = TwiRecord(t_ns, kind, value, ack)
        if kind == "S":
            self._last = []
        self._last.append(r)
        if self._log:
            self._records.append(r)

    def _answer_start(self) -> Stop | None:
        """The pending START answered by the chip core once it has run to the START's instant, or a
        need stop (the START stays pending). A read START's answer carries the bytes ahead."""
        assert self._pending is not None
        t_ns, address, read = self._pending
        if self.chips is not None:
            need = self._fast.chip_advance(self.chips.addr, t_ns)
            if need is not None:
                return Stop("need", self._cycle(t_ns), need=tuple(need))
            ack = bool(self._lib.chip_start(self.chips.addr, t_ns, address, read))
        else:
            ack = False
        self._pending = None
        self._transactions += 1
        self._nacks += not ack
        self._record(t_ns, "A", address << 1 | read, ack)
        ahead = b""
        if read and ack:
            self._read_key = (address, bytes(self._written[-AHEAD_KEY_BYTES:]))
            self._read_count = 0
            ahead = self._read_ahead(self._read_lengths.get(self._read_key, 0))
        self._send(ord("a"), bytes([ack]) + ahead)
        return None

    def _read_ahead(self, n: int) -> bytes:
        """``n`` bytes of the chip core (at most MAX_AHEAD), its state before them kept to give back those
        the master will not read."""
        n = max(0, min(n, MAX_AHEAD))
        self._taken = 0
        if self.chips is None or n == 0:
            self._ahead, self._before_ahead = [0xFF] * n, None  # (no chips: the bus's pull-ups)
        else:
            self._before_ahead = ctypes.string_at(self.chips.addr, self._board_size)
            read_byte, addr = self._lib.chip_read_byte, self.chips.addr
            self._ahead = [read_byte(addr) for _ in range(n)]
        return bytes(self._ahead)

    def _take(self, t_ns: int) -> None:
        """The master read the next byte ahead at ``t_ns``."""
        if self._taken >= len(self._ahead):
            raise LinkError("QEMU read more bytes ahead than it was given")
        self._bytes += 1
        self._read_count += 1
        self._record(t_ns, "R", self._ahead[self._taken], True)
        self._taken += 1

    def _settle(self) -> None:
        """The transfer ended (a STOP, a START): the bytes ahead the master did not read given back (the
        chip core as it was before them, then those it read read again), and the transfer's length kept
        for the next time."""
        if self._read_count:
            self._read_lengths[self._read_key] = self._read_count
            self._read_count = 0
        if self._taken < len(self._ahead) and self.chips is not None and self._before_ahead is not None:
            ctypes.memmove(self.chips.addr, self._before_ahead, self._board_size)
            read_byte, addr = self._lib.chip_read_byte, self.chips.addr
            again = [read_byte(addr) for _ in range(self._taken)]
            if again != self._ahead[:self._taken]:
                raise LinkError("the chip core read other bytes the second time")
        self._ahead, self._taken, self._before_ahead = [], 0, None

    def _until_reached(self) -> Stop:
        """QEMU's messages until it reaches the time asked (or a need, or the end)."""
        chips, lib = self.chips, self._lib
        try:
            if self._pending is not None and (stop := self._answer_start()) is not None:
                return stop
            while True:
                kind, p = self._receive()
                if kind == ord("R"):
                    return self._reached(p)
                if kind == ord("T"):
                    if not p or p[0] not in self._sent:
                        raise LinkError(f"bytes from USART {p[0] if p else '?'}, which the board's MCU lacks")
                    self._sent[p[0]] += p[1:]
                    self._active_ns = self._now_ns
                    self._uart_counts[p[0]][1] += len(p) - 1
                    continue
                if kind == ord("X"):
                    if (stop := self._reset(p)) is not None:
                        return stop
                    continue
                if len(p) < 8:
                    raise LinkError(f"an I2C message ({kind!r}) without its time")
                (t_ns,) = struct.unpack_from("<Q", p)
                self._active_ns = t_ns
                if kind == ord("d") and len(p) % 8 == 0:
                    for (t,) in struct.iter_unpack("<Q", p):
                        self._take(t)
                    self._active_ns = t
                elif kind == ord("S") and len(p) == 10 and p[8] < 128 and p[9] < 2:
                    self._settle()
                    if not self._in_transfer:
                        self._written.clear()
                    self._in_transfer = True
                    self._record(t_ns, "S", 0, True)
                    self._pending = (t_ns, p[8], bool(p[9]))
                    if (stop := self._answer_start()) is not None:
                        return stop
                elif kind == ord("W") and len(p) == 9:
                    if chips is not None:
                        lib.chip_write_byte(chips.addr, p[8])
                    self._written.append(p[8])
                    self._bytes += 1
                    self._record(t_ns, "W", p[8], chips is not None)
                elif kind == ord("D") and len(p) == 8:
                    if self._taken < len(self._ahead):
                        raise LinkError("QEMU asked for a byte with bytes ahead left")
                    guess = self._read_lengths.get(self._read_key, 0) - self._read_count
                    ahead = self._read_ahead(max(guess, 1))
                    self._take(t_ns)
                    self._send(ord("b"), ahead)
                elif kind == ord("N") and len(p) == 8:
                    if self._last and self._last[-1].kind == "R":
                        self._last[-1].ack = False  # (the same record as in the log)
                elif kind == ord("P") and len(p) == 8:
                    self._settle()
                    self._in_transfer = False
                    if chips is not None:
                        lib.chip_stop(chips.addr)
                    self._record(t_ns, "P", 0, True)
                else:
                    raise LinkError(f"a malformed message from QEMU: kind {kind!r}, {len(p)} bytes")
        except (EOFError, OSError):
            return self._ended()

    def _reached(self, p: bytes) -> Stop:
        if len(p) < _REACHED.size:
            raise LinkError(f"a REACHED of {len(p)} bytes")
        self._waiting = True  # (for the next command)
        t_ns, ipsr, pc, cfsr, hfsr, n = _REACHED.unpack_from(p)
        if n != len(self._motors) or len(p) != _REACHED.size + n * _PULSE.size:
            raise LinkError(f"a REACHED with {n} motors ({len(p)} bytes); the board has {len(self._motors)}")
        for i in range(n):
            high, period, begun, last_ns = _PULSE.unpack_from(p, _REACHED.size + i * _PULSE.size)
            if high != self._widths[i]:
                self._widths[i] = high
                self._active_ns = t_ns
            if high and begun:
                # (the periods begun since the last stop, each a pulse of the width latched last: one
                # width a step, as the session takes the last pulse of a step)
                self._pulse_counts[i] += begun
                train = self._pulses[i]
                kept = min(begun, MAX_PULSES)
                train += [(last_ns - k * period, high, period) for k in range(kept - 1, -1, -1)]
                del train[:-MAX_PULSES]
        self._now_ns = t_ns
        self._state = (ipsr, pc, cfsr, hfsr)
        fault = FAULTS.get(ipsr & 0x1FF)
        if fault is not None:
            return self._final("crashed", f"{fault} (CFSR 0x{cfsr:08x}, HFSR 0x{hfsr:08x})", pc)
        hang_ns = self.cfg.hang_ns
        if hang_ns and t_ns - self._active_ns >= hang_ns:
            return self._final("hung", f"no I2C transaction, motor pulse change or USART byte sent for "
                                       f"{hang_ns / 1e6:g} ms", pc)
        return Stop("reached", self._cycle(t_ns))

    def _reset(self, p: bytes) -> Stop | None:
        """A system reset: a watchdog's ends the run naming where the firmware was; the firmware's own
        request (AIRCR.SYSRESETREQ: a reboot, after saving settings) is counted and the run goes on."""
        if len(p) != _RESET.size:
            raise LinkError(f"a RESET of {len(p)} bytes")
        t_ns, cause, ipsr, pc, cfsr, hfsr = _RESET.unpack(p)
        self._resets += 1
        self._state = (ipsr, pc, cfsr, hfsr)
        watchdog = WATCHDOG_RESETS.get(cause)
        if watchdog is None:
            return None
        self._now_ns = t_ns
        what = f"watchdog reset ({watchdog}) (CFSR 0x{cfsr:08x}, HFSR 0x{hfsr:08x})"
        return self._final("crashed", what, pc)

    def _ended(self) -> Stop:
        """QEMU is gone: a semihosting exit, a lockup (QEMU aborts), or a crash of its own."""
        with contextlib.suppress(subprocess.TimeoutExpired):
            self._proc.wait(SOCKET_TIMEOUT_S)
        text = self.output()
        lockup = next((line.strip() for line in text.splitlines() if "Lockup" in line), None)
        status = self._proc.returncode
        what = (f"locked up ({lockup.removeprefix('qemu: fatal: ')})" if lockup is not None else
                f"ended the machine (exit status {status}): {' '.join(text.split())[-300:]}")
        pc = self._state[1]
        for word in text.split():
            if word.startswith("R15="):
                with contextlib.suppress(ValueError):
                    pc = int(word[4:], 16)
        return self._final("crashed" if lockup is not None or status != 0 else "exited", what, pc)

    def _final(self, kind: str, what: str, pc: int) -> Stop:
        self._stop = Stop(kind, self._cycle(self._now_ns), pc, what, last_twi=format_transaction(self._last))
        return self._stop

    def _tail(self) -> str:
        return " ".join(self.output().split())[-2000:]

    def _cycle(self, t_ns: int) -> int:
        """The CPU's clock cycles at ``t_ns`` (the board's clock: SysTick's, DWT CYCCNT's)."""
        return t_ns * self.cfg.board.clock_hz // 1_000_000_000

    # ---- AvrEngine's interface ----
    @property
    def now_ns(self) -> int:
        return self._now_ns

    def run_until(self, t_ns: int) -> Stop:
        """Runs until sim time ``t_ns`` or an earlier stop (a need: serve it and call again)."""
        if self._stop is not None:
            return self._stop
        if self._pending is None:
            self._waiting = False
            self._send(ord("G"), struct.pack("<Q", max(t_ns, 0)))
        return self._until_reached()

    def pulses(self) -> list[list[tuple[int, int, int]]]:
        """Per motor, the pulses begun since the last call: (rise_ns, width_ns, period_ns), one a period of
        its timer, with the width latched last (the timers latch each period's pulse at its start)."""
        out, self._pulses = self._pulses, [[] for _ in self._motors]
        return out

    def twi_log(self, on: bool = True) -> None:
        self._log = on

    def twi_take(self) -> list[TwiRecord]:
        out, self._records = self._records, []
        return out

    def output(self) -> str:
        """What QEMU printed: the firmware's semihosting output, QEMU's own errors."""
        self._output.flush()
        self._output.seek(0)
        return self._output.read().decode(errors="replace")

    def last_twi(self) -> list[TwiRecord]:
        return list(self._last)

    def uart_take(self, uart: int) -> bytes:
        """What the firmware transmitted on USARTn up to the last stop, since the last take."""
        sent = self._sent.get(uart)
        if sent is None:
            return b""
        out = bytes(sent)
        sent.clear()
        return out

    def uart_send(self, uart: int, data: bytes, baud: int, parity: str = "N", stop_bits: int = 1) -> None:
        """Bytes onto USARTn's RX line from now on, one frame after another (start bit, 8 data bits, the
        parity bit, the stop bits: 8E2 at 100000 baud is 120 us a byte), after those queued before. The
        USART reads the line with its own set-up: a baud, word length or parity other than the firmware's
        gives the framing, parity and noise errors the chip would."""
        if uart not in self._sent:
            raise ValueError(f"the {self.cfg.board.mcu.name} has no USART{uart}")
        if parity not in ("N", "E", "O") or stop_bits not in (1, 2) or baud <= 0:
            raise ValueError(f"USART frame {baud} {parity}{stop_bits}: baud > 0, parity N/E/O, 1 or 2 stops")
        frame_ns = round((1 + 8 + (parity != "N") + stop_bits) * 1e9 / baud)
        for at in range(0, len(data), UART_CHUNK):
            head = struct.pack("<B3xIIBB2x", uart, frame_ns, baud, ord(parity), stop_bits)
            self._send(ord("U"), head + data[at:at + UART_CHUNK])
        self._uart_counts[uart][0] += len(data)

    def pin_drive(self, pin: str, schedule: list[tuple[int, int]]) -> None:
        """An input pin driven from outside to ``level`` at each ``(t_ns, level)`` (ascending, not before
        now), after the edges queued before: a PPM sum, a switch. QEMU's link queues them per pin and
        puts each on the pin at its virtual instant, as a receiver's wire would (the GPIO port's outside
        driver), so a timer's input capture or an EXTI line sees the edge then."""
        port, bit = _stm32_pin(self.cfg.board.mcu, pin)
        queued = [t for t in self._pin_edges.get(pin, []) if t >= self._now_ns]  # (at now: maybe not yet)
        times = [t for t, _ in schedule]
        if times != sorted(times) or (times and times[0] < max([self._now_ns, *queued[-1:]])):
            raise ValueError(f"pin {pin}: edges must ascend, from now on and after those queued: "
                             f"{schedule!r}")
        if len(queued) + len(schedule) > PIN_EDGES or (pin not in self._pin_edges and
                                                        len(self._pin_edges) == PIN_QUEUES):
            raise ValueError(f"pin {pin}: more than {PIN_EDGES} edges waiting, or more than {PIN_QUEUES} "
                             "pins driven")
        self._pin_edges[pin] = queued + times
        for at in range(0, len(schedule), PIN_CHUNK):
            edges = b"".join(_EDGE.pack(t, 1 if v else 0) for t, v in schedule[at:at + PIN_CHUNK])
            self._send(ord("I"), bytes([port, bit, 0, 0]) + edges)

    def analog_input(self, channel: int, volts: float) -> None:
        """ADC ``channel``'s pin at ``volts`` from now on, on every ADC that has it: each conversion that
        ends later reads it (against the 3.3 V reference; above it, full scale)."""
        units = self.cfg.board.mcu.adc_units.get(channel)
        if units is None or not 0 <= volts <= ADC_MAX_VOLTS:
            raise ValueError(f"the {self.cfg.board.mcu.name} has no analog input {channel}, or {volts} V is "
                             f"outside 0..{ADC_MAX_VOLTS} V")
        for unit in units:
            self._send(ord("A"), struct.pack("<BB2xI", unit, channel, round(volts * 1e6)))

    def eeprom(self) -> bytes:
        """An STM32 keeps its settings in flash: the firmware's CONFIG_SECTION as it is now (what the
        firmware programmed there), read over the link while QEMU waits at a step's end; b"" for a firmware
        without that section, or when QEMU is not waiting (gone, or running on past a watchdog's reset)."""
        section = config_section(self.cfg.firmware.read_bytes())
        if section is None or not self._waiting:
            return b""
        addr, _offset, size = section
        out = bytearray()
        for at in range(0, size, MAX_PAYLOAD):
            n = min(MAX_PAYLOAD, size - at)
            self._send(ord("M"), struct.pack("<II", addr + at, n))
            try:
                kind, p = self._receive()
            except (EOFError, OSError):
                return b""
            if kind != ord("M") or len(p) != n:
                raise LinkError(f"a reply of {kind!r}, {len(p)} bytes to a read of {n} bytes of flash")
            out += p
        return bytes(out)

    def poll_figures(self) -> dict[str, int]:
        """The AVR engine's polling-loop skip has no STM32 counterpart: QEMU's icount runs every
        instruction (a summary's ``poll_skip`` is then empty)."""
        return {}

    def figures(self) -> dict[str, Any]:
        ipsr, pc, cfsr, hfsr = self._state
        figs: dict[str, Any] = {
            "sim_ns": self._now_ns, "cycles": self._cycle(self._now_ns),
            "twi_transactions": self._transactions, "twi_bytes": self._bytes, "twi_nacks": self._nacks,
            "pc": pc, "ipsr": ipsr, "cfsr": cfsr, "hfsr": hfsr,
            "last_twi": format_transaction(self._last), "motor_periods": list(self._pulse_counts),
            "uarts": {n: {"queued": c[0], "sent": c[1]} for n, c in self._uart_counts.items()},
            "resets": self._resets,
        }
        if self._stop is not None:
            figs["stop"] = self._stop.describe()
        return figs

    def close(self) -> None:
        proc = getattr(self, "_proc", None)
        if proc is not None and proc.poll() is None:
            with contextlib.suppress(LinkError, AttributeError):  # (QEMU gone, or never connected)
                self._send(ord("Q"))
            try:
                proc.wait(SOCKET_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        if getattr(self, "_sock", None) is not None:
            self._sock.close()
        if getattr(self, "_output", None) is not None:
            self._output.close()
        if getattr(self, "_dir", None) is not None:
            self._dir.cleanup()
        pinned: tuple[int, set[int]] | None = getattr(self, "_affinity", None)
        if pinned is not None:
            tid, cpus = pinned
            with contextlib.suppress(OSError):  # (the thread gone: nothing to give back)
                os.sched_setaffinity(tid, cpus)
            self._affinity = None

    def __enter__(self) -> Stm32Engine:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _stm32_pin(mcu: Mcu, pin: str) -> tuple[int, int]:
    """A pin such as PA0 as (port 0..8 for A..I, bit 0..15), the port one the MCU has."""
    if len(pin) not in (3, 4) or pin[0] != "P" or pin[1] not in mcu.ports or not pin[2:].isdigit() or \
            int(pin[2:]) > 15:
        raise ValueError(f"pin {pin!r}: expected P, a port letter of the {mcu.name} ({mcu.ports}) and a bit "
                         "0..15")
    return ord(pin[1]) - ord("A"), int(pin[2:])
