"""A session: one DUT process under device redirection, and the world it lives in. This module is the
process and transport side: the DUT and its keeper, the shim connections, the ptys, the select loop and
the wall-time watchdogs; the DUT's messages are rig/handler.py's, sim time is rig/scheduler.py's.

The session owns time. In lockstep the DUT's clock is a shared page the shim reads (and nudges by a
quantum per read); the DUT waits by asking the session, which runs the world (plant, devices,
scheduled events) up to the wake-up time and then answers. Nothing moves while the DUT computes, so
a run is a function of the DUT, the seed and the scenario, and runs as fast as the CPU allows. In
real time the session follows the wall clock and the shim leaves the clocks alone.

The session is a single-threaded select loop over the shim connections, the ptys and the status pipe
of the DUT's keeper (its parent process, which ends everything the DUT started).
It never trusts what arrives: a malformed message costs only the connection it came on (as does one
that leaves its replies unread: protocol.REPLY_TIMEOUT_S), a DUT that
crashes, hangs or never shows up ends the run with an error verdict, and watchdogs on sim time, wall
time and wall time without progress bound every run.
"""

from __future__ import annotations

import array
import errno
import fcntl
import os
import selectors
import shutil
import socket
import struct
import termios
import time
import tty
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Final

from rig import interrupts, scratch
from rig import protocol as P
from rig.connection import Conn
from rig.cores import SPIN_NS, placement
from rig.dut_process import Keeper, dut_env, running_threads
from rig.handler import Handler
from rig.lockstep import FastPath, attach, pending_input
from rig.pace import FrozenHeap, RealtimeHost
from rig.scheduler import (
    EXIT_WATCHDOG,
    MONO_BASE_NS,
    NS,
    Scheduler,
    SharedPage,
    Stop,
    fmt,
)
from rig.world import World

KILL_GRACE_S: Final = 2.0
EXIT_NOT_EXECUTABLE: Final = 126
EXIT_NOT_FOUND: Final = 127
#: What a serial port holds for a DUT that has not read it: the tty's read buffer (N_TTY_BUF_SIZE - 1)
RX_BUFFER: Final = 4095
#: "socket": no connection gets a mailbox (rig/connection.py); every message crosses the socket
TRANSPORT_ENV: Final = "RIG_TRANSPORT"


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
    spin: bool = False                # lockstep: a core each, polling for messages (rig/cores.py)
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
    #: real time only: scheduled events run, how many ran over 1 ms late, the worst, the 99th
    #: percentile and the median lateness (s). Measured and reported, never hidden (docs/design.md §1)
    pwm_writes: int = 0               # sysfs PWM writes the DUT made (export, period, duty, enable …)
    events_run: int = 0
    events_late: int = 0
    max_lateness_s: float = 0.0
    p99_lateness_s: float = 0.0
    p50_lateness_s: float = 0.0
    #: real time only: how the loop ran (rig.pace.HostState.as_dict: SCHED_FIFO, mlockall, why not)
    host_state: dict[str, object] = field(default_factory=dict)
    #: lockstep only: how the DUT's messages came (the connections, how many of them had a mailbox,
    #: whether both sides spun): the results are the same either way, the speed is not
    transport: dict[str, object] = field(default_factory=dict)


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


class Session:
    def __init__(self, config: SessionConfig, world: World) -> None:
        """``world`` is the DUT's world (plant, sensors, board: World.at_rest); the session steps it."""
        self.cfg = config
        self.world = world
        if len(self.world.pwm) > P.PWM_MAX:
            raise ValueError(f"at most {P.PWM_MAX} PWM channels")
        self.sched = Scheduler(world, self, config.duration, config.sim_timeout,
                               None if config.lockstep else self._wall_ns)
        self.page: SharedPage | None = None  # the clock page, made when the run starts
        self.handler: Handler | None = None
        self.fast: FastPath | None = None  # the per-cycle messages in C (rig/lockstep), lockstep only
        self._pump_fd = -1  # the loop's epoll set, for FastPath.pump; -1 while none
        self._ptys: dict[str, _Pty] = {}
        #: (master fd, pending) of each pty, for FastPath.pump, which reads them in the loop's place
        self._pump_ptys: tuple[tuple[int, bytearray], ...] = ()
        self.in_flight: dict[int, int] = {}  # pty slave fd -> bytes readable once delivered
        #: the bytes readable on a descriptor: the fast path's C call once it is attached (open_page)
        self._pending: Callable[[int], int] = _pending_input
        self._unstamped = False  # a pty has bytes from the DUT that no request has stamped yet
        self.notes: list[str] = []
        self.malformed: list[str] = []
        self._log: IO[str] | None = None
        self.logging = False
        self._conns: list[Conn] = []
        self._n_conns = 0
        self._n_mailboxes = 0  # (connections granted a mailbox)
        self._rt_t0 = 0.0
        self._rt_host = RealtimeHost()  # real time: SCHED_FIFO and mlockall where permitted (rig/pace)
        self._heap = FrozenHeap()  # lockstep: the collector walks what the run makes, not the rig (rig/pace)
        self._running = False
        self._mailboxes = os.environ.get(TRANSPORT_ENV, "") != "socket"
        self.interrupted: int | None = None  # the signal that stopped the rig mid-run (rig.interrupts)

    # ---- the API scenarios use ------------------------------------------------------------------

    def at(self, t: float, fn: Callable[[Session], None]) -> None:
        """Runs ``fn(session)`` at sim time ``t`` seconds (before any DUT request at or after it)."""
        self.sched.at(t, fn)

    def serial_silence(self, path: str) -> None:
        """The device behind ``path`` sends nothing for now (a lost RC link): on a pty that is no bytes,
        nothing to do (a bench bridge has to be told, rig/bridge/session.py)."""

    def serial_write(self, path: str, data: bytes) -> None:
        """Sends bytes to the DUT on a serial path; in lockstep they are readable by the DUT before
        it runs again, and a DUT polling that port wakes at this instant. Like a UART, the line does
        not wait for its reader: what does not fit the DUT's receive buffer (RX_BUFFER bytes unread)
        is dropped and counted, and the run's notes say so."""
        pty = self._ptys[path]
        before = self.in_flight.get(pty.slave)
        if before is None:
            before = self._pending(pty.slave)
        room = max(0, RX_BUFFER - before)
        if len(data) > room:
            self._overflow(pty, len(data) - room)
            data = data[:room]
        sent = 0  # (one write takes it all but for a full kernel buffer: no view and slices made for that)
        while sent < len(data):
            try:
                sent += os.write(pty.master, data[sent:] if sent else data)
            except BlockingIOError:  # (real time: the kernel's own buffers are full too)
                self._overflow(pty, len(data) - sent)
                data = data[:sent]
                break
        if self.cfg.lockstep:  # delivered before the DUT next runs (see deliver_serial)
            self.in_flight[pty.slave] = before + len(data)
        self.sched.event_output = True
        if self.logging:  # (the message is not even formatted otherwise: this runs per request)
            self.log(self.now_ns, f"tty {path} > {data.hex()}")

    def _overflow(self, pty: _Pty, n: int) -> None:
        if not pty.dropped:
            pty.first_drop_ns = self.now_ns
        pty.dropped += n

    def deliver_serial(self) -> None:
        """Waits until the bytes written to the DUT's serial ports are readable on its side. The pty
        hands them over asynchronously (a kernel worker), so this waits for the count, not a fixed
        time; it runs just before the DUT is let run again, so the handover overlaps the session's
        own work instead of stalling each write."""
        deadline = time.monotonic() + 1.0
        for slave, target in self.in_flight.items():
            while self._pending(slave) < target and time.monotonic() < deadline:
                time.sleep(0)
        self.in_flight.clear()

    def serial_output(self, path: str) -> bytes:
        """Everything the DUT has written to ``path`` so far."""
        if self._running:
            self._collect_serial(self.now_ns)
        return bytes(self._ptys[path].received)

    @property
    def now_ns(self) -> int:
        """Sim time now; inside an event, the event's own time (the DUT's clock may still lag it)."""
        event_ns = self.sched.event_ns
        if event_ns is not None:
            return event_ns
        if self.cfg.lockstep and self.page is not None:
            return self.page.now()
        return self._wall_ns()

    def _wall_ns(self) -> int:
        """Real time: the wall time since the run began."""
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
        tmp = scratch.make("session")
        old_affinity = os.sched_getaffinity(0)
        # (a list, not an Optional: compiled by mypyc, a local narrowed to Keeper in the try is checked
        # as one in the finally, and an error before it was set became a TypeError that hid the error)
        keepers: list[Keeper] = []
        # real time: a selector that waits in C for the next event's absolute deadline (rig/pace)
        sel = (selectors.DefaultSelector() if cfg.lockstep
               else self._rt_host.selector(self._deadline_ns, self._realtime_tick, self.sched))
        wall0 = time.perf_counter()
        returncode: int | None = None
        self._running = True
        self._pump_fd = sel.fileno() if isinstance(sel, selectors.EpollSelector) else -1
        try:
            (tmp / "fakes").mkdir()
            self.open_page(tmp / "shm")
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
            self._pump_ptys = tuple((pty.master, pty.pending) for pty in self._ptys.values())
            if cfg.log_path:
                self._log = open(cfg.log_path, "w", encoding="ascii")
                self.logging = True
            env = self._dut_env(shim, tmp)
            cores = placement(set(old_affinity), cfg.lockstep, cfg.pin, cfg.spin)
            if cores.dut is not None:
                os.sched_setaffinity(0, cores.dut)  # the keeper and the DUT inherit it
            if not cfg.lockstep:  # before sim time 0: locking the memory takes a while (the DUT: not FIFO)
                self._rt_host.start()
            else:
                self._heap.start()
            keeper = Keeper(keeper_path, cfg.command, env, cfg.stdout, cfg.stderr, KILL_GRACE_S)
            keepers.append(keeper)
            if cores.session is not None:
                os.sched_setaffinity(0, cores.session)
            # sim time 0 once the keeper runs (it starts the DUT only now): its few milliseconds of
            # start-up made the first events late in real time
            self._rt_t0 = time.perf_counter()
            sel.register(keeper.status, selectors.EVENT_READ, "keeper")
            returncode = self._loop(sel, listener, keeper, wall0)
        finally:
            self._running = False
            for conn in self._conns:
                conn.release()
            self._pump_fd = -1
            self._pump_ptys = ()
            self._rt_host.stop()
            self._heap.stop()
            for k in keepers:
                k.finish()  # the DUT and everything it started are gone when this returns
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
        return dut_env(self.cfg.env, shim, tmp / "rig.sock", tmp / "shm", self.cfg.lockstep, self.cfg.i2c_bus,
                       {p: pty.slave_name for p, pty in self._ptys.items()}, tmp / "fakes",
                       SPIN_NS if self.cfg.spin else 0)

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

    def _loop(self, sel: selectors.BaseSelector, listener: socket.socket, keeper: Keeper,
              wall0: float) -> int | None:
        """Serves the DUT until its main process has ended; returns its exit status (negative: the
        signal that ended it), or None when it never started."""
        try:
            with interrupts.live():
                self._serve(sel, listener, keeper, wall0)
                # a signal to the process group ends the DUT too: its death may be seen before this
                # (compiled) loop ran the rig's handler, which a call into Python runs now, so the run
                # reads as stopped by the signal, not as a DUT killed
                interrupts.check()
        except interrupts.Interrupted as e:  # stop the DUT (the keeper does), keep what was recorded
            self.interrupted = e.signum
            self.sched.fail(e.exit_code, f"{e} at sim t={self.now_ns / NS:.3f} s")
            keeper.finish()
        if keeper.exec_errno is not None:
            code = EXIT_NOT_FOUND if keeper.exec_errno == errno.ENOENT else EXIT_NOT_EXECUTABLE
            what = ("not found" if code == EXIT_NOT_FOUND
                    else f"not executable ({os.strerror(keeper.exec_errno)})")
            self.sched.error = (code, f"command {what}: {self.cfg.command[0]}")
            return None
        for conn in list(self._conns):  # notices the DUT sent before it went
            self._on_readable(conn, sel)
        self._collect_serial(self.now_ns)
        return keeper.returncode

    def _serve(self, sel: selectors.BaseSelector, listener: socket.socket, keeper: Keeper,
               wall0: float) -> None:
        cfg = self.cfg
        last_progress, last_sim = time.perf_counter(), self.now_ns
        stopping = False
        fast = self.fast
        while not keeper.done:
            timeout = 0.1
            if not cfg.lockstep:
                timeout = min(timeout, self._realtime_tick())
            # a mailbox's message wakes this epoll by a byte on its socket from here on; one put there
            # before that has rung nothing (rig/lockstep/mailbox.c)
            ready = fast.mailbox_ready() if fast is not None else []
            if ready:
                timeout = 0.0
                for conn in [c for c in self._conns if c.sock.fileno() in ready]:
                    if self._on_readable(conn, sel):
                        last_progress = time.perf_counter()
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
            if not stopping and not self.sched.over:
                if now_wall - wall0 > cfg.wall_timeout:
                    self.sched.fail(EXIT_WATCHDOG, f"wall-time watchdog: still running after "
                                              f"{cfg.wall_timeout:g} s of wall time (sim t={sim / NS:.3f} s)")
                elif cfg.lockstep and now_wall - last_progress > cfg.stall_timeout:
                    running = running_threads([c.pid for c in self._conns if c.pid])
                    self.sched.fail(EXIT_WATCHDOG, "the command stopped answering: no request and no clock "
                                              f"read for {cfg.stall_timeout:g} s of wall time at sim "
                                              f"t={sim / NS:.3f} s (spinning without reading a clock, "
                                              "or blocked outside the emulated devices)"
                                              + (f"; running: {', '.join(running)}" if running else ""))
            if not stopping and self.sched.over:
                keeper.stop()  # SIGTERM to the DUT and all it started; SIGKILL after the grace
                stopping = True

    def message_counts(self) -> tuple[int, int, int, int]:
        """The I2C transfers, waits, PWM writes and promised writes (transfers the shim answered itself:
        rig/shim/protocol.h RIG_MSG_I2C_WRITE) the DUT made: the handler's and the fast path's."""
        handler, fast = self.handler, self.fast
        if handler is None:
            return 0, 0, 0, 0
        i2c, waits, pwm, promised = fast.counts if fast is not None else (0, 0, 0, 0)
        return (handler.transactions + i2c, handler.waits + waits, handler.pwm_writes + pwm,
                handler.promised_writes + promised)

    def _deadline_ns(self) -> int | None:
        """Real time: the next event's due time on CLOCK_MONOTONIC (ns), or None."""
        due = self.sched.next_event_ns()
        return None if due is None else round(self._rt_t0 * NS) + due

    def _realtime_tick(self) -> float:
        """Real time: run due events and keep the world at the wall clock; seconds to the next event."""
        try:
            self.advance(self.now_ns)
        except Stop:
            return 0.1
        due = self.sched.next_event_ns()
        return 0.1 if due is None else max(0.0, (due - self.now_ns) / NS)

    # ---- connections ----------------------------------------------------------------------------

    def _accept(self, listener: socket.socket, sel: selectors.BaseSelector) -> None:
        try:
            sock, _ = listener.accept()
        except BlockingIOError:
            return
        sock.setblocking(True)
        whole, frac = divmod(P.REPLY_TIMEOUT_S, 1)  # (a DUT that never reads must not hold the loop)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDTIMEO, struct.pack("ll", int(whole), int(frac * 1e6)))
        self._n_conns += 1
        conn = Conn(sock, self._n_conns)
        self._conns.append(conn)
        sel.register(sock, selectors.EVENT_READ, conn)

    def _drop(self, conn: Conn, sel: selectors.BaseSelector) -> None:
        if conn in self._conns:
            self._conns.remove(conn)
            sel.unregister(conn.sock)
            conn.close()

    def _on_readable(self, conn: Conn, sel: selectors.BaseSelector) -> bool:
        """Reads what the connection has and handles every whole message; True if any arrived.

        While the fast path may act (below), it reads the connection itself and acts in C until this
        loop is needed (FastPath.pump): a wake of this loop per message cost more than the message."""
        buf = conn.buf
        fast, fd = self.fast, conn.sock.fileno()
        got = -1
        if fast is not None and conn.hello and self._pump_fd >= 0 and self._quiet():
            try:
                got = fast.pump(fd, self._pump_fd, buf, self._pump_ptys)
            except Stop:
                buf.clear()
                return True
            except P.Malformed as e:  # (its replies not taken: pump's send shut the connection)
                self._close_for(conn, sel, e)
                return True
            finally:
                self._unstamped |= bool(self._pump_ptys)  # (pump may have read a pty into its pending)
            if got == 0:
                return False
        size, off, end = P.HEADER.size, 0, 0
        handler = self.handler
        assert handler is not None
        try:
            if got < 0:
                got = conn.receive()
                if got == 0:
                    return False
                if got < 0:
                    self._drop(conn, sel)
                    return False
            end = len(buf)
            while end - off >= size:  # every whole message; what they took is cut off the buffer once
                # the fast path acts on what it takes; never before HELLO, nor unless quiet
                if fast is not None and conn.hello and self._quiet():
                    off = fast.handle(fd, buf, off)
                    if end - off < size:
                        break
                hdr = P.Header.parse(buf, off)
                stop = off + size + hdr.length
                if end < stop:
                    break
                payload = bytes(buf[off + size:stop])
                off = stop
                handler.handle(conn, hdr, payload)  # (a native call, compiled)
        except P.Malformed as e:
            self._close_for(conn, sel, e)
            return True
        except Stop:
            buf.clear()
            return True
        del buf[:off]
        return True

    def _close_for(self, conn: Conn, sel: selectors.BaseSelector, e: P.Malformed) -> None:
        """A connection that broke the protocol costs only itself: reported, then closed."""
        what = "replies not taken" if isinstance(e, P.RepliesUnread) else "malformed message"
        why = f"{what} on connection {conn.index} (pid {conn.pid or '?'}): {e}; " \
              "connection closed, session continues"
        self.malformed.append(why)
        self.log(self.now_ns, f"c{conn.index} malformed: {e}")
        self._drop(conn, sel)

    def _quiet(self) -> bool:
        """Nothing for the handler or the session to do between messages: no log to write, no serial
        bytes to hand over. Only then may the fast path act (and pump read) on its own. (What the DUT
        wrote and the loop has read may wait for its stamp: the stamp's time is only the log's, and
        the handler's next request, serial_output and the run's end all take it into ``received``.)"""
        return not (self.logging or self.in_flight)

    def send(self, conn: Conn, data: bytes) -> None:
        """A reply to the DUT; what events wrote to its ports is readable before it runs again."""
        if self.in_flight:
            self.deliver_serial()
        conn.send(data)

    def greet(self, conn: Conn, status: int, mailbox: bool) -> None:
        """The HELLO reply; with the mailbox the process asked for (rig/connection.py) when the fast
        path serves this session, unless RIG_TRANSPORT=socket keeps every message on the socket."""
        fast = self.fast
        if mailbox and fast is not None and self._mailboxes:
            if self.in_flight:
                self.deliver_serial()
            granted = P.HELLO_GRANTED.pack(P.HELLO_MAILBOX)
            if conn.grant(fast, P.reply(P.MSG_HELLO, self.now_ns, granted, status)):
                self._n_mailboxes += 1
                return
        self.send(conn, P.reply(P.MSG_HELLO, self.now_ns, status=status))

    # ---- sim time (rig/scheduler.py) -----------------------------------------------------------

    def open_page(self, path: Path) -> None:
        """Creates the clock page the DUT's shim maps, and the handler that answers the DUT."""
        self.page = SharedPage(path, len(self.world.pwm), self.world.time_ns, self.cfg.quantum_ns,
                               self.sched.limit_ns)
        if self.cfg.lockstep and not self.cfg.i2c_clock_hz:  # (a write's bus time is the session's to say)
            self.page.promise_acks(self.cfg.i2c_bus, self.world.board.write_acks())
        self.handler = Handler(self, self.cfg, self.sched, self.world, self.page)
        self.fast = attach(self.handler)
        if self.fast is not None:
            self._pending = pending_input()

    def advance(self, t_ns: int, stop_on_output: bool = False) -> int:
        """Stamps what the DUT wrote so far, then runs events and the world to ``t_ns``
        (Scheduler.advance: raises Stop at a limit)."""
        if self._unstamped:  # (a flag, not a walk over the ptys: this runs for every message)
            self._collect_serial(t_ns, read=False)
        return self.sched.advance(t_ns, stop_on_output)

    # ---- serial ---------------------------------------------------------------------------------

    def _read_pty(self, pty: _Pty) -> None:
        try:
            data = os.read(pty.master, 65536)
        except (BlockingIOError, OSError):
            return
        if data:
            pty.pending += data
            self._unstamped = True

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
                if self.logging:
                    self.log(t_ns, f"tty {pty.path} < {bytes(pty.pending).hex()}")
                pty.pending.clear()
        self._unstamped = False

    # ---- results --------------------------------------------------------------------------------

    def log(self, t_ns: int, text: str) -> None:
        """A line of the transaction log (--log), stamped in sim time."""
        if self._log:
            self._log.write(f"{fmt(t_ns)} {text}\n")

    def _outcome(self, returncode: int | None, wall0: float) -> Outcome:
        for pty in self._ptys.values():
            if pty.dropped:
                self.notes.append(f"{pty.path}: {pty.dropped} byte(s) to the DUT were dropped from sim "
                                  f"t={pty.first_drop_ns / NS:.3f} s on: it did not read them, and its "
                                  f"receive buffer ({RX_BUFFER} bytes) was full, as a UART's overflows")
        page_ns = self.page.now() if self.page is not None and self.cfg.lockstep else 0
        sim = (max(self.world.time_ns, page_ns) if self.cfg.lockstep else self.now_ns) / NS
        verdict, code, error = self.sched.verdict(returncode, sim, self._n_conns > 0,
                                                  self.cfg.allow_no_devices, self.interrupted is not None)
        handler = self.handler
        counts = self.message_counts()
        notes = (handler.notes if handler else []) + self.notes
        events, late, worst, p99, p50 = self.sched.lateness()
        return Outcome(verdict, code, error, returncode, sim, self.world.time_ns / NS,
                       time.perf_counter() - wall0, counts[0], counts[1], self._n_conns, notes,
                       self.malformed, self.world.outputs(), counts[2], events, late, worst, p99, p50,
                       {} if self.cfg.lockstep else self._rt_host.state.as_dict(),
                       {"connections": self._n_conns, "mailboxes": self._n_mailboxes, "spin": self.cfg.spin,
                        "promised_writes": counts[3]}
                       if self.cfg.lockstep else {})


def _pending_input(fd: int) -> int:
    buf = array.array("i", [0])
    fcntl.ioctl(fd, termios.FIONREAD, buf)
    return buf[0]
