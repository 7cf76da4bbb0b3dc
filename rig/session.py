"""A session: one DUT process under device redirection, and the world it lives in.

The session owns time. In lockstep the DUT's clock is a shared page the shim reads (and nudges by a
quantum per read); the DUT waits by asking the session, which runs the world (plant, devices,
scheduled events) up to the wake-up time and then answers. Nothing moves while the DUT computes, so
a run is a function of the DUT, the seed and the scenario, and runs as fast as the CPU allows. In
real time the session follows the wall clock and the shim leaves the clocks alone.

The session is a single-threaded select loop over the shim connections, the ptys and the status pipe
of the DUT's keeper (its parent process, which ends everything the DUT started).
It never trusts what arrives: a malformed message costs only the connection it came on, a DUT that
crashes, hangs or never shows up ends the run with an error verdict, and watchdogs on sim time, wall
time and wall time without progress bound every run.
"""

from __future__ import annotations

import array
import errno
import fcntl
import heapq
import itertools
import mmap
import os
import selectors
import shutil
import signal
import socket
import struct
import subprocess
import tempfile
import termios
import time
import tty
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Final

from emulators.i2c_bus import I2CNack, I2CProtocolError, Msg
from rig import interrupts
from rig import protocol as P
from rig.world import PwmChannel, World

NS: Final = 1_000_000_000
FOREVER_SLICE_NS: Final = 10_000_000  # a wait with no deadline lets 10 ms pass, then the DUT looks again
EPOCH_NS: Final = 1_767_225_600 * NS  # CLOCK_REALTIME at sim time 0: 2026-01-01T00:00:00Z
MONO_BASE_NS: Final = 1_000 * NS  # CLOCK_MONOTONIC at sim time 0, as if the board had been up 1000 s
KILL_GRACE_S: Final = 2.0

EXIT_WATCHDOG: Final = 124  # as timeout(1)
EXIT_RIG_ERROR: Final = 125  # the run could not be judged: the DUT never came, left early, ...
EXIT_NOT_EXECUTABLE: Final = 126
EXIT_NOT_FOUND: Final = 127
LATE_NS: Final = 1_000_000  # real time: an event run more than 1 ms after its due time counts as late
#: What a serial port holds for a DUT that has not read it: the tty's read buffer (N_TTY_BUF_SIZE - 1)
RX_BUFFER: Final = 4095


@dataclass
class SessionConfig:
    command: list[str]
    lockstep: bool = True
    i2c_bus: int = 1
    serial: list[str] = field(default_factory=list)   # device paths the DUT opens, served by ptys
    i2c_clock_hz: int = 0             # 0: transfers take no sim time; 100_000 or 400_000: bus time
    quantum_ns: int = 1000            # sim time a clock read costs
    duration: float | None = None     # sim seconds; then the DUT is stopped and the run is over
    sim_timeout: float = 600.0
    wall_timeout: float = 600.0
    stall_timeout: float = 30.0       # lockstep: wall seconds with no request and no clock read
    pin: bool | None = None           # DUT and session on one CPU core; None: in lockstep only
    log_path: Path | None = None
    allow_no_devices: bool = False
    env: dict[str, str] | None = None
    shim_path: Path | None = None
    stdout: IO[str] | int | None = None   # the DUT's stdout/stderr (None: inherited)
    stderr: IO[str] | int | None = None


@dataclass
class Outcome:
    """How a run ended. ``exit_code`` is what ``rig exec`` exits with (the DUT's own status when the
    DUT ended the run itself)."""

    verdict: str                      # "ok" | "failed" (the DUT said so) | "error" (the rig says so)
    #                                   | "interrupted" (a signal stopped the rig: rig.interrupts)
    exit_code: int
    error: str | None
    dut_returncode: int | None
    sim_time: float
    plant_time: float
    wall_time: float
    transactions: int
    waits: int
    connections: int
    notes: list[str]
    malformed: list[str]
    plant: dict[str, float]
    #: real time only: scheduled events run, how many ran over 1 ms late, the worst and the 99th
    #: percentile lateness (s). Measured and reported, never hidden (DESIGN.md §1)
    pwm_writes: int = 0               # sysfs PWM writes the DUT made (export, period, duty, enable …)
    events_run: int = 0
    events_late: int = 0
    max_lateness_s: float = 0.0
    p99_lateness_s: float = 0.0


@dataclass
class _Conn:
    sock: socket.socket
    index: int
    buf: bytearray = field(default_factory=bytearray)
    hello: bool = False
    pid: int = 0


@dataclass
class _Pty:
    path: str
    master: int
    slave: int
    pending: bytearray = field(default_factory=bytearray)   # DUT output not yet stamped
    received: bytearray = field(default_factory=bytearray)  # everything the DUT wrote
    dropped: int = 0                  # bytes to the DUT that did not fit its receive buffer
    first_drop_ns: int = 0

    @property
    def slave_name(self) -> str:
        return os.ttyname(self.slave)


class _Stop(Exception):
    """The run is over (limit reached or watchdog); no further replies."""


class Session:
    def __init__(self, config: SessionConfig, world: World) -> None:
        """``world`` is the DUT's world (plant, sensors, board: World.at_rest); the session steps it."""
        self.cfg = config
        self.world = world
        if len(self.world.pwm) > P.PWM_MAX:
            raise ValueError(f"at most {P.PWM_MAX} PWM channels")
        self._events: list[tuple[int, int, Callable[[Session], None]]] = []
        self._seq = itertools.count()
        self._ptys: dict[str, _Pty] = {}
        self._event_output = False
        self._in_flight: dict[int, int] = {}  # pty slave fd -> bytes readable once delivered
        self.transactions = self.waits = self.pwm_writes = 0
        self.notes: list[str] = []
        self.malformed: list[str] = []
        self._log: IO[str] | None = None
        self._error: tuple[int, str] | None = None
        self._ended_by_duration = False
        self._conns: list[_Conn] = []
        self._n_conns = 0
        self._rt_t0 = 0.0
        self._running = False
        self._event_ns: int | None = None
        self._lateness_ns: list[int] = []  # real time: wall clock minus due time, per event
        self.interrupted: int | None = None  # the signal that stopped the rig mid-run (rig.interrupts)

    # ---- the API scenarios use ------------------------------------------------------------------

    def at(self, t: float, fn: Callable[[Session], None]) -> None:
        """Runs ``fn(session)`` at sim time ``t`` seconds (before any DUT request at or after it)."""
        heapq.heappush(self._events, (round(t * NS), next(self._seq), fn))

    def serial_write(self, path: str, data: bytes) -> None:
        """Sends bytes to the DUT on a serial path; in lockstep they are readable by the DUT before
        it runs again, and a DUT polling that port wakes at this instant. Like a UART, the line does
        not wait for its reader: what does not fit the DUT's receive buffer (RX_BUFFER bytes unread)
        is dropped and counted, and the run's notes say so."""
        pty = self._ptys[path]
        before = self._in_flight.get(pty.slave)
        if before is None:
            before = _pending_input(pty.slave)
        room = max(0, RX_BUFFER - before)
        if len(data) > room:
            self._overflow(pty, len(data) - room)
            data = data[:room]
        view = memoryview(data)
        while view:
            try:
                k = os.write(pty.master, view)
            except BlockingIOError:  # (real time: the kernel's own buffers are full too)
                self._overflow(pty, len(view))
                data = data[:len(data) - len(view)]
                break
            view = view[k:]
        if self.cfg.lockstep:  # delivered before the DUT next runs (see _deliver_serial)
            self._in_flight[pty.slave] = before + len(data)
        self._event_output = True
        if self._log:  # (the message is not even formatted otherwise: this runs per request)
            self._write_log(self.now_ns, f"tty {path} > {data.hex()}")

    def _overflow(self, pty: _Pty, n: int) -> None:
        if not pty.dropped:
            pty.first_drop_ns = self.now_ns
        pty.dropped += n

    def _deliver_serial(self) -> None:
        """Waits until the bytes written to the DUT's serial ports are readable on its side. The pty
        hands them over asynchronously (a kernel worker), so this waits for the count, not a fixed
        time; it runs just before the DUT is let run again, so the handover overlaps the session's
        own work instead of stalling each write."""
        deadline = time.monotonic() + 1.0
        for slave, target in self._in_flight.items():
            while _pending_input(slave) < target and time.monotonic() < deadline:
                time.sleep(0)
        self._in_flight.clear()

    def serial_output(self, path: str) -> bytes:
        """Everything the DUT has written to ``path`` so far."""
        if self._running:
            self._collect_serial(self.now_ns)
        return bytes(self._ptys[path].received)

    @property
    def now_ns(self) -> int:
        """Sim time now; inside an event, the event's own time (the DUT's clock may still lag it)."""
        if self._event_ns is not None:
            return self._event_ns
        if self.cfg.lockstep:
            return self._shm_now()
        return int((time.perf_counter() - self._rt_t0) * NS)

    @property
    def dut_clock_base_s(self) -> float:
        """The DUT's CLOCK_MONOTONIC at sim time 0: the shim's fixed base in lockstep; in real time the
        shim leaves the clock alone and sim time 0 is the session's start (perf_counter is
        CLOCK_MONOTONIC on Linux)."""
        return MONO_BASE_NS / NS if self.cfg.lockstep else self._rt_t0

    # ---- running ------------------------------------------------------------------------------

    def run(self) -> Outcome:
        cfg = self.cfg
        from rig.shim.build import ensure_keeper, ensure_shim

        shim = cfg.shim_path or ensure_shim()
        keeper_path = ensure_keeper()
        tmp = Path(tempfile.mkdtemp(prefix="rig-session-"))
        old_affinity = os.sched_getaffinity(0)
        keeper: _Keeper | None = None
        sel = selectors.DefaultSelector()
        wall0 = time.perf_counter()
        returncode: int | None = None
        self._running = True
        try:
            (tmp / "fakes").mkdir()
            self._open_shm(tmp / "shm")
            listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            listener.bind(str(tmp / "rig.sock"))
            listener.listen(16)
            listener.setblocking(False)
            sel.register(listener, selectors.EVENT_READ, "listen")
            for path in cfg.serial:
                master, slave = os.openpty()
                tty.setraw(slave)  # bytes pass as they are (SBUS is binary); the DUT may set its own mode
                os.set_blocking(master, False)
                self._ptys[path] = _Pty(path, master, slave)
                sel.register(master, selectors.EVENT_READ, ("pty", path))
            if cfg.log_path:
                self._log = open(cfg.log_path, "w", encoding="ascii")
            env = self._dut_env(shim, tmp)
            if cfg.pin or (cfg.pin is None and cfg.lockstep):
                os.sched_setaffinity(0, {max(old_affinity)})  # the keeper and the DUT inherit it
            self._rt_t0 = time.perf_counter()
            keeper = _Keeper(keeper_path, cfg.command, env, cfg.stdout, cfg.stderr, KILL_GRACE_S)
            sel.register(keeper.status, selectors.EVENT_READ, "keeper")
            returncode = self._loop(sel, listener, keeper, wall0)
        finally:
            self._running = False
            if keeper is not None:
                keeper.finish()  # the DUT and everything it started are gone when this returns
            os.sched_setaffinity(0, old_affinity)
            for key in list(sel.get_map().values()):
                sel.unregister(key.fileobj)
                if isinstance(key.fileobj, socket.socket):
                    key.fileobj.close()
            sel.close()
            for pty in self._ptys.values():
                os.close(pty.master)
                os.close(pty.slave)
            if self._log:
                self._log.close()
            self._report_bypassed_bytes(tmp / "fakes")
            shutil.rmtree(tmp, ignore_errors=True)
        return self._outcome(returncode, wall0)

    def _dut_env(self, shim: Path, tmp: Path) -> dict[str, str]:
        env = dict(self.cfg.env if self.cfg.env is not None else os.environ)
        preload = env.get("LD_PRELOAD", "")
        env.update({
            "LD_PRELOAD": f"{shim} {preload}".strip(),
            "RIG_SOCKET": str(tmp / "rig.sock"),
            "RIG_SHM": str(tmp / "shm"),
            "RIG_LOCKSTEP": "1" if self.cfg.lockstep else "0",
            "RIG_I2C_BUSES": str(self.cfg.i2c_bus),
            "RIG_PWM_CHIP": "0",
            "RIG_SERIAL": ":".join(f"{p}={pty.slave_name}" for p, pty in self._ptys.items()),
            "RIG_FAKES": str((tmp / "fakes").resolve()),
        })
        return env

    def _report_bypassed_bytes(self, fakes: Path) -> None:
        """The shim backs each emulated descriptor with a file of its own in ``fakes`` (named after the
        device path, ':' for '/'), which it never writes: bytes there came through a call it does not
        redirect, and reached no device."""
        if not fakes.is_dir():
            return
        for f in sorted(fakes.iterdir()):
            size = f.stat().st_size
            if size:
                self.notes.append(f"{size} bytes written to {f.name.replace(':', '/')} reached no device: "
                                  "the command wrote them with a call the shim does not redirect (a raw "
                                  "syscall, writev, dprintf or a FILE from fdopen)")

    def _loop(self, sel: selectors.BaseSelector, listener: socket.socket, keeper: _Keeper,
              wall0: float) -> int | None:
        """Serves the DUT until its main process has ended; returns its exit status (negative: the
        signal that ended it), or None when it never started."""
        try:
            with interrupts.live():
                self._serve(sel, listener, keeper, wall0)
        except interrupts.Interrupted as e:  # stop the DUT (the keeper does), keep what was recorded
            self.interrupted = e.signum
            self._fail(e.exit_code, f"{e} at sim t={self.now_ns / NS:.3f} s")
            keeper.finish()
        if keeper.exec_errno is not None:
            code = EXIT_NOT_FOUND if keeper.exec_errno == errno.ENOENT else EXIT_NOT_EXECUTABLE
            what = ("not found" if code == EXIT_NOT_FOUND
                    else f"not executable ({os.strerror(keeper.exec_errno)})")
            self._error = (code, f"command {what}: {self.cfg.command[0]}")
            return None
        for conn in list(self._conns):  # notices the DUT sent before it went
            self._on_readable(conn, sel)
        self._collect_serial(self.now_ns)
        return keeper.returncode

    def _serve(self, sel: selectors.BaseSelector, listener: socket.socket, keeper: _Keeper,
               wall0: float) -> None:
        cfg = self.cfg
        last_progress, last_sim = time.perf_counter(), self.now_ns
        stopping = False
        while not keeper.done:
            timeout = 0.1
            if not cfg.lockstep:
                timeout = min(timeout, self._realtime_tick())
            for key, _ in sel.select(max(timeout, 0.0)):
                if key.data == "listen":
                    self._accept(listener, sel)
                elif key.data == "keeper":
                    keeper.read_status()
                elif isinstance(key.data, tuple):
                    self._read_pty(self._ptys[key.data[1]])
                else:
                    if self._on_readable(key.data, sel):
                        last_progress = time.perf_counter()
            now_wall = time.perf_counter()
            sim = self.now_ns
            if sim != last_sim:
                last_sim, last_progress = sim, now_wall
            if not stopping and self._error is None and not self._ended_by_duration:
                if now_wall - wall0 > cfg.wall_timeout:
                    self._fail(EXIT_WATCHDOG, f"wall-time watchdog: still running after "
                                              f"{cfg.wall_timeout:g} s of wall time (sim t={sim / NS:.3f} s)")
                elif cfg.lockstep and now_wall - last_progress > cfg.stall_timeout:
                    self._fail(EXIT_WATCHDOG, "the command stopped answering: no request and no clock "
                                              f"read for {cfg.stall_timeout:g} s of wall time at sim "
                                              f"t={sim / NS:.3f} s (spinning without reading a clock, "
                                              "or blocked outside the emulated devices)")
            if not stopping and (self._error is not None or self._ended_by_duration):
                keeper.stop()  # SIGTERM to the DUT and all it started; SIGKILL after the grace
                stopping = True

    def _realtime_tick(self) -> float:
        """Real time: run due events and keep the world at the wall clock; seconds to the next event."""
        try:
            self._advance(self.now_ns)
        except _Stop:
            return 0.1
        if self._events:
            return max(0.0, (self._events[0][0] - self.now_ns) / NS)
        return 0.1

    # ---- connections ----------------------------------------------------------------------------

    def _accept(self, listener: socket.socket, sel: selectors.BaseSelector) -> None:
        try:
            sock, _ = listener.accept()
        except BlockingIOError:
            return
        sock.setblocking(True)
        self._n_conns += 1
        conn = _Conn(sock, self._n_conns)
        self._conns.append(conn)
        sel.register(sock, selectors.EVENT_READ, conn)

    def _drop(self, conn: _Conn, sel: selectors.BaseSelector) -> None:
        if conn in self._conns:
            self._conns.remove(conn)
            sel.unregister(conn.sock)
            conn.sock.close()

    def _on_readable(self, conn: _Conn, sel: selectors.BaseSelector) -> bool:
        """Reads what the connection has and handles every whole message; True if any arrived."""
        try:
            chunk = conn.sock.recv(1 << 18, socket.MSG_DONTWAIT)
        except BlockingIOError:
            return False
        except OSError:
            chunk = b""
        if not chunk:
            self._drop(conn, sel)
            return False
        conn.buf += chunk
        buf = conn.buf
        size, off, end = P.HEADER.size, 0, len(buf)
        try:
            while end - off >= size:  # every whole message; what they took is cut off the buffer once
                hdr = P.Header.parse(buf, off)
                stop = off + size + hdr.length
                if end < stop:
                    break
                payload = bytes(buf[off + size:stop])
                off = stop
                self._handle(conn, hdr, payload)
        except P.Malformed as e:
            why = f"malformed message on connection {conn.index} (pid {conn.pid or '?'}): {e}; " \
                  "connection closed, session continues"
            self.malformed.append(why)
            self._write_log(self.now_ns, f"c{conn.index} malformed: {e}")
            self._drop(conn, sel)
            return True
        except _Stop:
            buf.clear()
            return True
        del buf[:off]
        return True

    def _send(self, conn: _Conn, data: bytes) -> None:
        if self._in_flight:
            self._deliver_serial()
        try:
            conn.sock.sendall(data)
        except OSError:
            pass  # the DUT is gone; its exit is handled by the loop

    def _handle(self, conn: _Conn, hdr: P.Header, payload: bytes) -> None:
        if self._error is not None or self._ended_by_duration:
            if hdr.type in P.REQUESTS:
                raise _Stop
        if not conn.hello and hdr.type != P.MSG_HELLO:
            raise P.Malformed(f"{P.MSG_NAMES[hdr.type]} before HELLO")
        if hdr.type == P.MSG_HELLO:
            version, pid = P.parse_fixed(payload, P.HELLO_MSG, "HELLO")
            conn.hello, conn.pid = True, pid
            status = 0 if version == P.PROTOCOL_VERSION else errno.EPROTO
            if status:
                self.notes.append(f"pid {pid}: shim protocol {version}, session speaks {P.PROTOCOL_VERSION}")
            self._send(conn, P.reply(P.MSG_HELLO, self.now_ns, status=status))
        elif hdr.type == P.MSG_I2C:
            self._handle_i2c(conn, hdr, payload)
        elif hdr.type == P.MSG_PWM:
            self._handle_pwm(conn, hdr, payload)
        elif hdr.type == P.MSG_WAIT:
            self._handle_wait(conn, hdr, payload)
        else:
            text = payload.decode("utf-8", "replace")[:300]
            if text not in self.notes:
                self.notes.append(text)
            self._write_log(self._notice_time(hdr), f"c{conn.index} note: {text}")

    def _request_time(self, hdr: P.Header) -> int:
        if not self.cfg.lockstep:
            return self.now_ns
        return max(self._shm_now(), hdr.t_ns)

    def _notice_time(self, hdr: P.Header) -> int:
        """A notice's own time: the DUT did not wait for it, and may have moved the shared clock on since
        (after a WAIT AHEAD it runs ahead of what the session has read)."""
        return hdr.t_ns if self.cfg.lockstep else self.now_ns

    def _handle_i2c(self, conn: _Conn, hdr: P.Header, payload: bytes) -> None:
        bus, msgs = P.parse_i2c(payload)
        t = self._request_time(hdr)
        self._advance(t)
        status, results = 0, []
        if bus != self.cfg.i2c_bus:
            status = errno.ENODEV
        else:
            # a 10-bit or out-of-range address reaches nobody: address 0 (general call) never ACKs here
            bus_msgs = [Msg(m.addr if m.addr <= 0x7F and not m.flags & P.I2C_M_TEN else 0, m.read, m.data,
                            0 if m.flags & P.I2C_M_RECV_LEN else m.length, bool(m.flags & P.I2C_M_RECV_LEN))
                        for m in msgs]
            try:
                results = self.world.transfer(bus_msgs, t)
            except I2CNack:
                status = errno.ENXIO
            except I2CProtocolError:
                status = errno.EPROTO
        t_after = t + self._bus_time_ns(msgs, results)
        if self.cfg.lockstep:
            self._shm_set(t_after)
        self.transactions += 1
        if self._log:
            self._write_log(t, f"c{conn.index} i2c-{bus} {_describe(msgs, results)} "
                               f"{'ok' if not status else errno.errorcode[status]}")
        self._send(conn, P.reply(P.MSG_I2C, t_after, b"".join(results), status))

    def _bus_time_ns(self, msgs: list[P.I2CMessage], results: list[bytes]) -> int:
        """START + address + ACK per message, 9 bits per data byte, one STOP: the wire time of a transfer."""
        if not self.cfg.i2c_clock_hz:
            return 0
        reads = iter(results)
        bits = 1
        for m in msgs:
            n = len(next(reads, b"")) if m.read else len(m.data)
            bits += 10 + 9 * n
        return bits * NS // self.cfg.i2c_clock_hz

    def _handle_pwm(self, conn: _Conn, hdr: P.Header, payload: bytes) -> None:
        chip, channel, attr, _, value = P.parse_fixed(payload, P.PWM_MSG, "PWM")
        if chip != 0 or channel >= len(self.world.pwm) or attr not in P.PWM_ATTR_NAMES:
            raise P.Malformed(f"PWM notice for chip {chip} channel {channel} attribute {attr}")
        t = self._notice_time(hdr)
        self._advance(t)
        self.pwm_writes += 1
        ch = self.world.pwm[channel]
        if attr == P.PWM_EXPORT:
            ch.exported = True
        elif attr == P.PWM_UNEXPORT:
            self.world.pwm[channel] = PwmChannel()
        elif attr == P.PWM_PERIOD:
            ch.period_ns = value
        elif attr == P.PWM_DUTY:
            ch.duty_ns = value
        elif attr == P.PWM_ENABLE:
            ch.enabled = bool(value)
        else:
            ch.inversed = bool(value)
        self.world.apply_pwm(channel)
        if self._in_flight:  # the DUT is running (a notice has no reply): hand over what events wrote
            self._deliver_serial()
        if self._log:  # (the message is not even formatted otherwise: this runs per request)
            self._write_log(t, f"c{conn.index} pwm{channel} {P.PWM_ATTR_NAMES[attr]} {value}")

    def _handle_wait(self, conn: _Conn, hdr: P.Header, payload: bytes) -> None:
        wake, kind, _ = P.parse_fixed(payload, P.WAIT_MSG, "WAIT")
        if kind not in (P.WAIT_SLEEP, P.WAIT_POLL, P.WAIT_AHEAD):
            raise P.Malformed(f"WAIT of unknown kind {kind}")
        self.waits += 1
        if kind == P.WAIT_AHEAD:  # a notice: the shim has moved the clock already; catch the world up
            if not self.cfg.lockstep or wake == P.WAIT_FOREVER:
                raise P.Malformed("WAIT AHEAD outside lockstep or without a deadline")
            t = self._notice_time(hdr)
            target = max(wake, t)
            self._advance(target)
            if self._in_flight:  # the DUT is running: hand over what events wrote
                self._deliver_serial()
            if self._log:
                self._write_log(t, f"c{conn.index} wait {_fmt(wake)} -> {_fmt(target)} ahead")
            return
        t = self._request_time(hdr)
        if not self.cfg.lockstep:  # the shim does not virtualise time in real time; answer at once
            self._send(conn, P.reply(P.MSG_WAIT, t, struct.pack("<I", P.WAKE_DEADLINE)))
            return
        target, reason = (t + FOREVER_SLICE_NS, P.WAKE_SLICE) if wake == P.WAIT_FOREVER else (max(wake, t),
                                                                                            P.WAKE_DEADLINE)
        woke = self._advance(target, stop_on_output=kind == P.WAIT_POLL)
        if woke < target:
            target, reason = woke, P.WAKE_EVENT
        self._shm_set(target)
        if self._log:
            self._write_log(t, f"c{conn.index} wait {'forever' if wake == P.WAIT_FOREVER else _fmt(wake)} "
                               f"-> {_fmt(target)}{' event' if reason == P.WAKE_EVENT else ''}")
        self._send(conn, P.reply(P.MSG_WAIT, target, struct.pack("<I", reason)))

    # ---- time and limits ------------------------------------------------------------------------

    def _advance(self, t_ns: int, stop_on_output: bool = False) -> int:
        """Runs scheduled events and the world up to ``t_ns``. Returns the time reached: earlier than
        ``t_ns`` when ``stop_on_output`` and an event sent the DUT data. Raises _Stop at a limit."""
        cfg = self.cfg
        limit = cfg.duration if cfg.duration is not None else cfg.sim_timeout
        if t_ns > limit * NS:
            self._advance(int(limit * NS))
            if cfg.duration is not None:
                self._ended_by_duration = True
            else:
                self._fail(EXIT_WATCHDOG, f"sim-time watchdog: the command was still running after "
                                          f"{cfg.sim_timeout:g} s of sim time")
            raise _Stop
        self._collect_serial(t_ns, read=False)
        while self._events and self._events[0][0] <= t_ns:
            te, _, fn = heapq.heappop(self._events)
            if not cfg.lockstep:
                self._lateness_ns.append(max(0, self.now_ns - te))  # (wall-clock now: not in an event)
            te = max(te, self.world.time_ns)
            self.world.advance_to(te)
            self._event_output = False
            self._event_ns = te
            try:
                fn(self)
            except Exception as e:  # a scenario's event must not take the rig down; the run is void
                self._fail(EXIT_RIG_ERROR, f"event at {_fmt(te)} failed: {type(e).__name__}: {e}")
                raise _Stop from e
            finally:
                self._event_ns = None
            if stop_on_output and self._event_output:
                return te
        self.world.advance_to(t_ns)
        return t_ns

    def _fail(self, code: int, message: str) -> None:
        if self._error is None:
            self._error = (code, message)

    # ---- shared page ----------------------------------------------------------------------------

    def _open_shm(self, path: Path) -> None:
        with open(path, "wb") as f:
            f.write(bytes(P.SHM_SIZE))
        fd = os.open(path, os.O_RDWR)
        try:
            self._mm = mmap.mmap(fd, P.SHM_SIZE)
        finally:
            os.close(fd)
        P.SHM_HEAD.pack_into(self._mm, 0, P.SHM_MAGIC, P.PROTOCOL_VERSION, len(self.world.pwm),
                             self.world.time_ns, self.cfg.quantum_ns, EPOCH_NS, MONO_BASE_NS)
        self._words = memoryview(self._mm).cast("Q")
        limit = self.cfg.duration if self.cfg.duration is not None else self.cfg.sim_timeout
        self._words[P.SHM_LIMIT_OFFSET // 8] = round(limit * NS)

    def _shm_now(self) -> int:
        return self._words[P.SIM_NS_OFFSET // 8]

    def _shm_set(self, t_ns: int) -> None:
        if t_ns > self._words[P.SIM_NS_OFFSET // 8]:
            self._words[P.SIM_NS_OFFSET // 8] = t_ns

    # ---- serial ---------------------------------------------------------------------------------

    def _read_pty(self, pty: _Pty) -> None:
        try:
            pty.pending += os.read(pty.master, 65536)
        except (BlockingIOError, OSError):
            pass

    def _collect_serial(self, t_ns: int, read: bool = True) -> None:
        """Stamps what the DUT wrote since the last request with this request's time: the DUT's own
        writes carry no time, and the next request is the first instant the session can know of them.
        ``read=False`` stamps only what the loop has already read (the pty is in the selector), so a
        request costs no extra read()."""
        for pty in self._ptys.values():
            if read:
                self._read_pty(pty)
            if pty.pending:
                pty.received += pty.pending
                self._write_log(t_ns, f"tty {pty.path} < {bytes(pty.pending).hex()}")
                pty.pending.clear()

    # ---- results --------------------------------------------------------------------------------

    def _write_log(self, t_ns: int, text: str) -> None:
        if self._log:
            self._log.write(f"{_fmt(t_ns)} {text}\n")

    def _outcome(self, returncode: int | None, wall0: float) -> Outcome:
        for pty in self._ptys.values():
            if pty.dropped:
                self.notes.append(f"{pty.path}: {pty.dropped} byte(s) to the DUT were dropped from sim "
                                  f"t={pty.first_drop_ns / NS:.3f} s on: it did not read them, and its "
                                  f"receive buffer ({RX_BUFFER} bytes) was full, as a UART's overflows")
        sim = (max(self.world.time_ns, self._shm_now()) if self.cfg.lockstep else self.now_ns) / NS
        verdict, error, code = "ok", None, 0
        if self._error is not None:
            verdict, (code, error) = "interrupted" if self.interrupted else "error", self._error
        elif self._ended_by_duration:
            pass
        elif returncode is not None and returncode < 0:
            sig = signal.Signals(-returncode).name
            verdict, code = "error", 128 - returncode
            error = f"the command was killed by {sig} at sim t={sim:.3f} s"
        elif self._n_conns == 0 and not self.cfg.allow_no_devices:
            verdict, code = "error", EXIT_RIG_ERROR
            if returncode:  # it ran and gave up: its own words (stderr) say why, not a guess of ours
                error = f"the command exited with status {returncode} before touching the emulated devices"
            else:
                error = ("the command exited without touching the emulated devices (no I2C, PWM or "
                         "wait reached the session: is it statically linked, setuid, or using other "
                         "device paths?)")
        elif self.cfg.duration is not None:
            verdict, code = "error", EXIT_RIG_ERROR
            error = (f"the command exited early, with status {returncode}, at sim t={sim:.3f} s of a "
                     f"{self.cfg.duration:g} s run")
        elif returncode:
            verdict, code = "failed", returncode
        late = sorted(self._lateness_ns) or [0]
        return Outcome(verdict, code, error, returncode, sim, self.world.time_ns / NS,
                       time.perf_counter() - wall0, self.transactions, self.waits, self._n_conns, self.notes,
                       self.malformed, self.world.outputs(), self.pwm_writes, len(self._lateness_ns),
                       sum(x > LATE_NS for x in late), late[-1] / NS, late[int(0.99 * (len(late) - 1))] / NS)


def _pending_input(fd: int) -> int:
    buf = array.array("i", [0])
    fcntl.ioctl(fd, termios.FIONREAD, buf)
    return buf[0]


class _Keeper:
    """The DUT's parent, ``build/rig-keeper`` (rig/shim/keeper.c): a subreaper that ends every process
    the DUT started, however it detached, when the lifeline closes or the DUT exits; and ends them
    even when this process dies (the lifeline closes with it). Its status pipe says when the DUT's
    main process has ended, and how."""

    def __init__(self, path: Path, command: list[str], env: dict[str, str], stdout: IO[str] | int | None,
                 stderr: IO[str] | int | None, grace_s: float) -> None:
        status_r, status_w = os.pipe()
        life_r, self._life = os.pipe()
        kenv = dict(env)
        kenv["RIG_KEEPER_PRELOAD"] = kenv.pop("LD_PRELOAD", "")  # the keeper runs without the shim
        try:
            self.proc = subprocess.Popen([str(path), str(status_w), str(life_r), str(round(grace_s * 1000)),
                                          "--", *command], env=kenv, pass_fds=(status_w, life_r),
                                         start_new_session=True, stdout=stdout, stderr=stderr)
        except BaseException:
            for fd in (status_r, self._life):
                os.close(fd)
            raise
        finally:
            os.close(status_w)
            os.close(life_r)
        self.status = status_r
        os.set_blocking(status_r, False)
        self.grace_s = grace_s
        self._buf = b""
        self.done = False                 # the DUT's main process has ended (or never started)
        self.returncode: int | None = None
        self.exec_errno: int | None = None

    def read_status(self) -> None:
        try:
            chunk = os.read(self.status, 256)
        except BlockingIOError:
            return
        if not chunk:  # the keeper is gone: whatever it did not say, the DUT is over
            self.done = True
            return
        self._buf += chunk
        *lines, self._buf = self._buf.split(b"\n")
        for line in lines:
            what, _, value = line.decode("ascii", "replace").partition(" ")
            if what == "exit":
                self.returncode = os.waitstatus_to_exitcode(int(value))
                self.done = True
            elif what == "exec":
                self.exec_errno = int(value)
                self.done = True

    def stop(self) -> None:
        """Closes the lifeline: the keeper sends SIGTERM to the DUT's processes, SIGKILL after grace."""
        if self._life >= 0:
            os.close(self._life)
            self._life = -1

    def finish(self) -> None:
        """Stops the DUT if it runs, waits until the keeper has ended everything, reads its last words."""
        self.stop()
        try:
            self.proc.wait(timeout=self.grace_s + 5.0)
        except subprocess.TimeoutExpired:  # (a keeper stuck is a bug of ours; do not hang on it)
            self.proc.kill()
            self.proc.wait()
        while not self.done:
            self.read_status()
        if self.status >= 0:
            os.close(self.status)
            self.status = -1


def _fmt(t_ns: int) -> str:
    return f"{t_ns // NS}.{t_ns % NS:09d}"


def _describe(msgs: list[P.I2CMessage], results: list[bytes]) -> str:
    reads = iter(results)
    parts = []
    for m in msgs:
        if m.read:
            got = next(reads, None)
            parts.append(f"R{m.addr:02x}[{'len' if m.flags & P.I2C_M_RECV_LEN else m.length}]"
                         + (f"={got.hex()}" if got is not None else ""))
        else:
            parts.append(f"W{m.addr:02x}" + (f":{m.data.hex()}" if m.data else ""))
    return " ".join(parts)
