"""The MCU session: a firmware image running under an emulator (rig/mcu/engine.py), and the world it
lives in, in lockstep.

The session owns time: the MCU's cycle counter divided by its clock is sim time. Each step goes to the
next plant tick (1 ms) or the next scheduled event, whichever is first:

1. the world advances to the step's end, the motors as the last pulses left them (a zero-order hold:
   the plant's inputs change at step boundaries, as an ESC's do at its pulses);
2. the MCU runs to the step's end; when the chip core reaches a sample instant it has no sample for,
   the engine stops there, the world's producers make exactly that sample from the plant's history,
   and the MCU resumes: the bytes on the TWI are the lockstep session's;
3. the pulses that ended become the motors' commands (an ESC that sees no pulse for ESC_TIMEOUT_S
   stops its motor, as on the bench); on a board with a [battery], the flight pack's volts at the
   step's end (rig/battery.py: its current follows these commands) reach the ADC pin through the
   divider when the pin's volts moved by PIN_STEP_V or more;
4. the scheduled events at the step's end run: sticks as SBUS bytes into the RC USART at their
   frame timing, wind, faults, the recorder.

A firmware that crashes (a bad opcode, a jump out of flash, a wild store), sleeps for ever, resets
in a loop, hangs (no TWI transaction and no pulse for a second of sim time) or talks to a bus no chip
answers ends the run with an error naming what happened, where (program counter) and when (cycle),
and the last TWI transaction: the engine says so (rig/mcu/engine.py Stop).
"""

from __future__ import annotations

import array
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final

from rig import interrupts
from rig.battery import PackState
from rig.bridge.esc import esc_protocol
from rig.emulators import sbus
from rig.mcu.board import Battery, Board, uart_baud
from rig.mcu.engines import Engine, open_engine
from rig.mcu.twi_log import TwiTransfers
from rig.mcu.vcd import McuTrace, TraceOptions
from rig.scheduler import EXIT_RIG_ERROR, EXIT_WATCHDOG, NS, Scheduler, Stop
from rig.session import Outcome
from rig.telemetry import msp
from rig.world import World

TICK_NS: Final = 1_000_000
#: an ESC that gets no pulse for this long stops its motor (BLHeli's signal-loss time is about 0.25 s;
#: a shorter one here makes a firmware that stops pulsing show at once)
ESC_TIMEOUT_S: Final = 0.1
ESC_TIMEOUT_NS: Final = round(ESC_TIMEOUT_S * NS)
#: PPM sum: frame sync gap and channel pulse (a common receiver's)
PPM_PULSE_NS: Final = 300_000
PPM_FRAME_NS: Final = 22_500_000
#: a parallel PWM receiver's frame: its channels' pulses every 20 ms (50 Hz, the servo rate)
PWM_FRAME_NS: Final = 20_000_000
#: a [[serial]] send's baud on a USART the board gives none (Arduino's usual serial speed)
DEFAULT_BAUD: Final = 115_200
#: the battery's pin volts go to the engine when they moved by this much since the last sent: an AVR's
#: ADC takes millivolts, and a message every step would cost an STM32 run a link round trip a step
PIN_STEP_V: Final = 0.001


@dataclass
class McuConfig:
    board: Board
    firmware: Path
    duration: float
    rc_path: str
    telemetry_path: str
    eeprom: bytes | None = None
    wall_timeout: float = 600.0
    sim_timeout: float = 600.0
    #: write the TWI transactions and the motor pins' edges here as VCD (rig/mcu/vcd.py)
    trace: Path | None = None
    trace_options: TraceOptions = TraceOptions()
    #: write the EEPROM as the firmware left it here, however the run ended (eeprom.bin)
    eeprom_out: Path | None = None
    #: USARTs whose output is kept time-stamped (``uart_log``: the criteria on a USART)
    listen: frozenset[int] = frozenset()
    #: the hang check's limit in seconds instead of the board's (0: off)
    hang_s: float | None = None


@dataclass
class _MotorState:
    last_pulse_ns: int = -1
    pulses: int = 0


@dataclass
class McuFigures:
    motors: list[_MotorState] = field(default_factory=list)
    rc_bytes: int = 0


class McuSession:
    """A Host for the scenario's events (rig/host.py) whose DUT is a firmware image."""

    def __init__(self, config: McuConfig, world: World) -> None:
        self.cfg = config
        self.world = world
        b = config.board
        self.sched = Scheduler(world, self, config.duration, config.sim_timeout)
        self._limits = {} if config.hang_s is None else {"hang_ns": round(config.hang_s * NS)}
        # per motor: the plant's motor (0-based) and its ESC's pulse us to the plant's PWM us
        self._motor_index = [m.motor - 1 for m in b.motors]
        self._to_us = [esc_protocol(m.protocol).to_pwm_us for m in b.motors]
        self.engine: Engine | None = None
        self._telemetry = bytearray()
        self._t_ns = 0
        self.transfers = TwiTransfers()  # what the chips saw, for run.mcap's /i2c
        self.figures = McuFigures([_MotorState() for _ in b.motors])
        self.notes: list[str] = []
        self._ppm_channels: list[int] | None = None
        self._ppm_next_ns = 0
        #: per listened USART, what the firmware sent: (the step's end in sim ns, the bytes)
        self.uart_log: dict[int, list[tuple[int, bytes]]] = {n: [] for n in config.listen}
        self._ports: dict[str, tuple[int, int]] = {}  # serial_port's paths: (USART, baud)
        #: what the polling-loop skip did (AvrEngine.poll_figures), once run: rig exec's summary has it
        self.poll_at_end: dict[str, int] = {}
        if b.battery is not None and world.battery is None:  # (a world made without the board's pack)
            world.battery = PackState(b.battery.pack)
        self._pin_sent = 0.0 if b.battery is None else b.battery.pin_volts  # (the engine's at its start)
        #: the pack's terminal volts: (step end in sim ns, volts), one entry each time they changed
        self.pack_t_ns = array.array("q", [0])
        self.pack_volts = array.array("d", [world.battery.volts if world.battery is not None else 0.0])

    # ---- the Host the scenario's events use ---------------------------------------------------

    @property
    def now_ns(self) -> int:
        event_ns = self.sched.event_ns
        return event_ns if event_ns is not None else self._t_ns

    def at(self, t: float, fn: Callable[[McuSession], None]) -> None:
        self.sched.at(t, fn)

    def serial_port(self, uart: int, baud: int | None) -> str:
        """A path for serial_write that puts bytes on USART ``uart`` at ``baud`` (None: the board's for
        that USART, else 115200), 8N1."""
        if uart not in self.cfg.board.mcu.usarts:
            raise ValueError(f"the {self.cfg.board.mcu.name} has no USART{uart} (it has "
                             f"{', '.join(map(str, self.cfg.board.mcu.usarts))})")
        baud = baud or uart_baud(self.cfg.board, uart) or DEFAULT_BAUD
        path = f"usart{uart}@{baud}"
        self._ports[path] = (uart, baud)
        return path

    def serial_write(self, path: str, data: bytes) -> None:
        """Bytes for a serial_port go into that USART; the RC port's SBUS frames go to the board's RC
        input as its protocol has them: SBUS bytes into the USART, or the same channels as a PPM sum on
        the pin or an MSP SET_RAW_RC frame. Bytes for the telemetry port (an MSP poll) go into its USART
        as they are."""
        if self.engine is None:
            return
        board = self.cfg.board
        port = self._ports.get(path)
        if port is not None:
            self.engine.uart_send(port[0], data, port[1])
            return
        if path == self.cfg.telemetry_path and board.telemetry_uart is not None:
            self.engine.uart_send(board.telemetry_uart, data, board.telemetry_baud)
            return
        if path != self.cfg.rc_path:
            return
        rc = board.rc
        if rc is None:
            return
        self.figures.rc_bytes += len(data)
        if rc.protocol == "sbus":
            assert rc.uart is not None
            self.engine.uart_send(rc.uart, data, rc.baud, "E", 2)
            return
        channels = _sbus_channels(data)
        if channels is None:
            return
        us = [round(sbus_to_us(c)) for c in channels[:8]]
        if rc.protocol == "msp":
            assert rc.uart is not None
            self.engine.uart_send(rc.uart, msp.set_raw_rc(us), rc.baud)
        else:
            self._ppm_channels = us

    def serial_silence(self, path: str) -> None:
        """A lost RC link: a PPM or PWM receiver stops its pulses too (SBUS and MSP send nothing)."""
        if path == self.cfg.rc_path:
            self._ppm_channels = None

    def serial_output(self, path: str) -> bytes:
        if path == self.cfg.telemetry_path:
            return bytes(self._telemetry)
        return b""

    @property
    def dut_clock_base_s(self) -> float:
        """A firmware's clock starts at its reset, which is sim time 0."""
        return 0.0

    # ---- running ------------------------------------------------------------------------------

    def run(self) -> Outcome:
        wall0 = time.perf_counter()
        cfg = self.cfg
        engine = open_engine(cfg.board, cfg.firmware, self.world.board, cfg.eeprom, **self._limits)
        self.engine = engine
        trace = None
        if self.cfg.trace is not None:
            trace = self._open_trace(self.cfg.trace)
        engine.twi_log(True)  # (the transfers for run.mcap, and the trace's)
        ppm = self.cfg.board.rc is not None and self.cfg.board.rc.protocol in ("ppm", "pwm")
        telemetry_uart = self.cfg.board.telemetry_uart
        battery = self.cfg.board.battery
        logs = self.uart_log
        try:
            while not self.sched.over:
                nxt = min(self._t_ns + TICK_NS - self._t_ns % TICK_NS, self.sched.limit_ns)
                ev = self.sched.next_event_ns()
                if ev is not None and self._t_ns < ev < nxt:
                    nxt = ev
                self.world.advance_to(nxt)
                if ppm:
                    self._rc_pins(nxt)
                problem = self._run_mcu(engine, nxt)
                if problem is not None:
                    self.sched.fail(EXIT_RIG_ERROR, problem)
                    break
                self._t_ns = nxt
                for n, log in logs.items():
                    sent = engine.uart_take(n)
                    if sent:
                        log.append((nxt, sent))
                        if n == telemetry_uart:
                            self._telemetry += sent
                if telemetry_uart is not None and telemetry_uart not in logs:
                    self._telemetry += engine.uart_take(telemetry_uart)
                trains = engine.pulses()
                self._motors(trains, nxt)
                if battery is not None:
                    self._battery(engine, battery, nxt)
                events = engine.twi_take()
                self.transfers.feed(events)
                if trace is not None:
                    trace.add(events, trains, nxt)
                if time.perf_counter() - wall0 > self.cfg.wall_timeout:
                    self.sched.fail(EXIT_WATCHDOG, f"wall-time watchdog: {self.cfg.wall_timeout:g} s")
                    break
                interrupts.check()
                try:
                    # (past the end: the scheduler runs what is due there, says the duration is over, stops)
                    self.sched.advance(nxt if nxt < self.sched.limit_ns else nxt + 1)
                except Stop:
                    break
        except interrupts.Interrupted as e:
            self.sched.fail(e.exit_code, str(e))
            interrupted = True
        else:
            interrupted = False
        finally:
            self.figures_at_end = engine.figures()
            self.poll_at_end = engine.poll_figures()
            if self.cfg.eeprom_out is not None:
                self.cfg.eeprom_out.write_bytes(engine.eeprom())
            events = engine.twi_take()
            self.transfers.feed(events)
            self.transfers.finish()
            if trace is not None:
                trace.add(events, [], self._t_ns)  # (the pulses: all taken, and counted)
                trace.close()
            engine.close()
        verdict, code, error = self.sched.verdict(None, self._t_ns / NS, True, True, interrupted)
        pulses = sum(m.pulses for m in self.figures.motors)
        twi = int(self.figures_at_end["twi_transactions"])
        return Outcome(verdict, code, error, None, self._t_ns / NS, self.world.time_ns / NS,
                       time.perf_counter() - wall0, twi, 0, 0, self.notes, [], self.world.outputs(), pulses)

    def _open_trace(self, path: Path) -> McuTrace:
        b = self.cfg.board
        names = [f"m{m.motor}_{m.pin}" for m in b.motors]
        path.parent.mkdir(parents=True, exist_ok=True)
        return McuTrace(path, names, b.twi_hz,
                        comment=f"{self.cfg.firmware.name} on {b.name}: TWI and motor outputs, sim time",
                        options=self.cfg.trace_options)

    def _run_mcu(self, engine: Engine, t_ns: int) -> str | None:
        """Runs the MCU to ``t_ns``, serving the chip core's needs; what went wrong, or None."""
        while True:
            stop = engine.run_until(t_ns)
            if stop.kind == "reached":
                return None
            if stop.kind == "need":
                self.world.board.serve(stop.need)
                continue
            return f"the firmware {stop.describe()}"

    def _motors(self, pulses: list[list[tuple[int, int, int]]], t_ns: int) -> None:
        """The pulses that ended become the motors' commands (the last one of each train, as an ESC
        takes the newest pulse); a motor with no pulse for ESC_TIMEOUT_S stops."""
        set_motor = self.world.set_motor
        for train, state, motor, to_us in zip(pulses, self.figures.motors, self._motor_index, self._to_us,
                                              strict=True):
            if train:
                state.last_pulse_ns = t_ns
                state.pulses += len(train)
                set_motor(motor, train[-1][1] / 1000.0 * to_us)
            elif state.last_pulse_ns >= 0 and t_ns - state.last_pulse_ns > ESC_TIMEOUT_NS:
                state.last_pulse_ns = -1
                set_motor(motor, 0.0)

    def _battery(self, engine: Engine, battery: Battery, t_ns: int) -> None:
        """The pack's volts at the step's end, the motors' commands just set; to the ADC pin when they
        moved by PIN_STEP_V there (the same volts, the same messages: run after run, the same bytes)."""
        volts = self.world.battery_volts(t_ns)
        if volts != self.pack_volts[-1]:
            self.pack_t_ns.append(t_ns)
            self.pack_volts.append(volts)
        pin = battery.pin_volts_at(volts)
        if abs(pin - self._pin_sent) >= PIN_STEP_V:
            engine.analog_input(battery.channel, pin)
            self._pin_sent = pin

    def _rc_pins(self, t_ns: int) -> None:
        """A PPM sum on the RC pin, or a parallel PWM receiver's pulses on its pins (each channel's after
        the one before, as receivers put them out): one frame every PPM_FRAME_NS or PWM_FRAME_NS while
        the link is up."""
        rc = self.cfg.board.rc
        if rc is None or self.engine is None:
            return
        period = PPM_FRAME_NS if rc.protocol == "ppm" else PWM_FRAME_NS
        while self._ppm_next_ns <= t_ns:
            start = self._ppm_next_ns
            self._ppm_next_ns += period
            if self._ppm_channels is None:
                continue
            t = start
            if rc.protocol == "pwm":
                for pin, us in zip(rc.pins, self._ppm_channels, strict=False):
                    self.engine.pin_drive(pin, [(t, 1), (t + us * 1000, 0)])
                    t += us * 1000
                continue
            assert rc.pin is not None
            self.engine.pin_drive(rc.pin, ppm_edges(t, self._ppm_channels))


def ppm_edges(start_ns: int, channels_us: list[int]) -> list[tuple[int, int]]:
    """One PPM frame from ``start_ns``: a PPM_PULSE_NS low pulse at the start of each channel and one
    after the last, so each channel's width is the time between two falling edges (the line idles high
    through the sync gap until the next frame)."""
    edges: list[tuple[int, int]] = []
    t = start_ns
    for us in channels_us:
        edges += [(t, 0), (t + PPM_PULSE_NS, 1)]
        t += us * 1000
    return edges + [(t, 0), (t + PPM_PULSE_NS, 1)]


def sbus_to_us(raw: int) -> float:
    """An SBUS channel value (172..1811, centre 992) as the PWM microseconds a receiver puts out."""
    return 1000.0 + (raw - 172) * 1000.0 / (1811 - 172)


def _sbus_channels(data: bytes) -> list[int] | None:
    if len(data) != 25:
        return None
    try:
        channels, _flags = sbus.decode(data)
    except ValueError:
        return None
    return channels
