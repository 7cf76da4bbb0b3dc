"""A bench session: the world in real time against a board behind a bridge (docs/design.md §8 "Host
side"), for ``rig run --bridge`` and ``rig exec --bridge``.

What differs from rig/session.py: the board's I2C traffic never reaches the host (the bridge answers
it), so the host's loop streams instead of answering. On absolute deadlines it runs the scheduled
events and the plant at the wall clock (rig/scheduler.py, as a real-time session does), and sends
the bridge what changes: sensor samples stamped with the bridge time at which they become valid (a
lead Δ ahead), sticks as SBUS channels, time-sync probes at 10 Hz. What comes back: the board's
register writes (followed, so samples match its configuration), the captured ESC pulse widths (the
plant's motor commands) and the bridge's counters. A bridge that falls silent or hangs up ends the run
as an error within half a second (rig/bridge/port.py).

With ``virtual`` the bridge is build/vbridge and the board a Linux-process DUT started here against
the virtual bridge's board side (its shim connects there, not to us); with a port, the board is real
and there is no process to start: the run lasts its duration.
"""

from __future__ import annotations

import math
import os
import selectors
import shutil
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, TYPE_CHECKING, Final, NoReturn

from rig import interrupts, scratch
from rig.bridge.esc import esc_protocol
from rig.bridge.messages import Message
from rig.bridge.port import BridgeError, BridgePort, bridge_id
from rig.bridge.stream import SampleStream
from rig.bridge.timesync import ClockMap, Exchange
from rig.bridge.vbridge import Endpoints, VirtualBridge
from rig.dut_process import Keeper, dut_env
from rig.emulators import sbus
from rig.emulators.faults import BUS_TARGETS, KINDS, TARGETS, FaultSet
from rig.pace import RealtimeHost
from rig.plant.variables import MOTORS
from rig.scheduler import EXIT_RIG_ERROR, EXIT_WATCHDOG, NS, Scheduler, Stop
from rig.session import KILL_GRACE_S, Outcome, _Pty
from rig.world import World

if TYPE_CHECKING:
    from rig.bridge.can_capture import CanPulses

SYNC_PERIOD_S: Final = 0.1
RT_PRIORITY: Final = 10  # SCHED_RR: the virtual bridge and its DUT, above other work (the loop: rig.pace)
SBUS_OUT_OFF: Final = 0x80  # SBUS flags: the bridge sends no frames (messages.py)
FAULT_NEVER_US: Final = 1 << 53  # a fault with no end (the bridge takes ends up to 2^64 ns)
SYNC_START: Final = 8  # exchanges before the run starts: the clock map has a line by then
TOPOLOGY_CODES: Final = {"gy86": 0, "direct": 1}


@dataclass
class BenchConfig:
    bridge: str                       # "virtual" or the bridge's serial port
    command: list[str] | None = None  # the DUT (virtual bridge only); None: a real board
    rc_path: str = "/dev/ttyRC0"      # where the DUT reads SBUS (its pty is the virtual bridge's)
    serial: list[str] = field(default_factory=list)  # other ports of the DUT, served here (telemetry)
    i2c_bus: int = 1
    topology: str = "gy86"
    duration: float | None = None
    sim_timeout: float = 600.0
    wall_timeout: float = 600.0
    lead_s: float = 0.003             # Δ: samples are streamed this far ahead of their valid time
    faults: Mapping[str, FaultSet] = field(default_factory=dict)  # bus faults go to the bridge
    can: str | None = None            # INTERFACE:CHANNEL: the motors from a CAN capture device instead
    sbus_period_ms: int = 14
    esc: str = "pwm"                  # the board's ESC protocol (rig.bridge.esc): capture limits, scaling
    #: called once the bridge is configured, before sim time 0: a bench supply switches the board on
    #: here, so it boots into chips that answer (raises BridgeError to end the run)
    power_on: Callable[[], None] | None = None
    env: dict[str, str] | None = None
    shim_path: Path | None = None
    stdout: IO[str] | int | None = None   # the DUT's (None: inherited)
    stderr: IO[str] | int | None = None


@dataclass
class BridgeFigures:
    """What result.json says of the link (the bridge's own counters as last reported)."""

    bridge_id: str = ""
    protocol: int = 0
    core_version: int = 0
    firmware_sha256: str = ""
    status: dict[str, object] = field(default_factory=dict)
    reg_writes: int = 0
    pulses: int = 0
    pulses_driven: int = 0  # reports in which a motor had a pulse
    samples_sent: int = 0
    samples_late: int = 0  # streamed after their valid time had passed on the bridge


class BenchSession:
    """The interface the scenario runner uses (``at``, ``serial_write``, ``serial_output``, ``world``,
    ``now_ns``, ``dut_clock_base_s``), as rig/session.py's Session offers it."""

    def __init__(self, config: BenchConfig, world: World,
                 on_reg_write: Callable[[int, int, int, int], None] | None = None) -> None:
        self.cfg = config
        self.esc = esc_protocol(config.esc)  # (an unknown name: ValueError before anything starts)
        self.world = world
        world.direct_pwm = False  # the motors follow the bridge's captured pulses
        self.sched = Scheduler(world, self, config.duration, config.sim_timeout, self._wall_ns)
        self.clock = ClockMap()
        self.figures = BridgeFigures()
        self.notes: list[str] = []
        self.on_reg_write = on_reg_write
        self.port: BridgePort | None = None
        self.vbridge: VirtualBridge | None = None  # with --bridge virtual, while the run lasts
        self.can: CanPulses | None = None  # with a CAN capture device, while the run lasts
        self._ptys: dict[str, _Pty] = {}
        self._t0_ns = 0  # host monotonic ns at sim time 0
        self._sync_id = 0
        self._probes: dict[int, int] = {}
        self.interrupted: int | None = None
        self.stream = SampleStream(self)
        self._rc_silent = False
        self._rt_host = RealtimeHost()  # the loop under SCHED_FIFO and mlockall where permitted

    # ---- the API scenarios use -----------------------------------------------------------------

    def at(self, t: float, fn: Callable[[BenchSession], None]) -> None:
        self.sched.at(t, fn)

    @property
    def now_ns(self) -> int:
        event_ns = self.sched.event_ns
        return event_ns if event_ns is not None else self._wall_ns()

    def _wall_ns(self) -> int:
        return time.monotonic_ns() - self._t0_ns

    def _deadline_ns(self) -> int | None:
        """The next event's due time on CLOCK_MONOTONIC (ns), or None."""
        due = self.sched.next_event_ns()
        return None if due is None else self._t0_ns + due

    @property
    def dut_clock_base_s(self) -> float:
        """The DUT's CLOCK_MONOTONIC at sim time 0 (nothing virtualises it on a bench)."""
        return self._t0_ns / NS

    def serial_write(self, path: str, data: bytes) -> None:
        """The RC port's SBUS frames go to the bridge, which sends them on its UART; other ports are
        served here, as a session serves them."""
        if path == self.cfg.rc_path:
            self._rc_silent = False
            channels, flags = sbus.decode(data)
            self._send("SBUS", channels=channels, flags=flags)
            return
        os.write(self._ptys[path].master, data)

    def serial_silence(self, path: str) -> None:
        """The RC receiver stopped its output (a lost link): the bridge sends no frames until the next."""
        if path == self.cfg.rc_path and not self._rc_silent:
            self._rc_silent = True
            self._send("SBUS", channels=[0] * sbus.CHANNELS, flags=SBUS_OUT_OFF)

    def serial_output(self, path: str) -> bytes:
        pty = self._ptys.get(path)
        if pty is None:
            return b""
        self._read_pty(pty)
        return bytes(pty.received)

    def to_bridge_us(self, sim_ns: int) -> int:
        """The bridge's clock at this sim instant (what a sample valid then is stamped with)."""
        return round(self.clock.to_bridge_us(self._t0_ns + sim_ns))

    def to_sim_ns(self, bridge_us: float) -> int:
        """The sim instant at which the bridge's clock reads ``bridge_us``."""
        return round(self.clock.to_host_ns(bridge_us)) - self._t0_ns

    def send_sample(self, msg: Message, valid_sim_ns: int, values: list[float]) -> None:
        """A sensor sample valid from sim time ``valid_sim_ns``, ``values`` its fields after ``valid_us``
        in table order, arrays spread (the list is taken: the bridge time goes in front); counted late
        when that instant has already passed on the bridge (the board may have read the previous one)."""
        if valid_sim_ns < self._wall_ns():
            self.figures.samples_late += 1
        if self.port is not None:
            values.insert(0, self.to_bridge_us(valid_sim_ns))
            try:
                self.port.send_flat(msg, values)
            except BridgeError as e:
                self._link_failed(e)
        self.figures.samples_sent += 1

    # ---- running --------------------------------------------------------------------------------

    def run(self) -> Outcome:
        cfg = self.cfg
        wall0 = time.perf_counter()
        tmp = scratch.make("bench")
        vbridge: VirtualBridge | None = None
        keeper: Keeper | None = None
        # not epoll: epoll_wait counts its timeout in whole milliseconds, which made every event due
        # within the next millisecond up to a millisecond late; the wait is rig.pace's, on absolute deadlines
        sel = self._rt_host.selector(self._deadline_ns, self._run_due, self.sched)
        returncode: int | None = None
        policy = self._raise_priority()
        try:
            with interrupts.live():
                try:
                    if cfg.bridge == "virtual":
                        vbridge = self.vbridge = VirtualBridge()
                    elif cfg.command is not None:
                        raise BridgeError("a command runs against the virtual bridge only (--bridge "
                                          "virtual); on a bench the board is the DUT")
                    self.port = BridgePort(vbridge.endpoints.link if vbridge else cfg.bridge)
                    if cfg.can is not None:
                        self.can = self._open_can(cfg.can, vbridge)
                    self._start_link()
                    if cfg.power_on is not None:
                        cfg.power_on()
                    sel.register(self.port.fileno(), selectors.EVENT_READ, "bridge")
                    for path in cfg.serial:
                        master, slave = os.openpty()
                        os.set_blocking(master, False)
                        self._ptys[path] = _Pty(path, master, slave)
                        sel.register(master, selectors.EVENT_READ, ("pty", path))
                    self._rt_host.start(fifo=False)  # (before sim time 0: locking the memory takes a while)
                    if cfg.command is not None and vbridge is not None:
                        from rig.shim.build import ensure_keeper, ensure_shim

                        (tmp / "fakes").mkdir()
                        env = self._dut_env(cfg.shim_path or ensure_shim(), tmp, vbridge.endpoints)
                        keeper = Keeper(ensure_keeper(), cfg.command, env, cfg.stdout, cfg.stderr,
                                         KILL_GRACE_S)
                        sel.register(keeper.status, selectors.EVENT_READ, "keeper")
                    # sim time 0 once the DUT is started (it takes milliseconds to reach its first
                    # read): started after it, every event due in the first 5 ms ran 1.4-4.7 ms late,
                    # the run's worst lateness
                    self._t0_ns = time.monotonic_ns()
                    self._send_faults()
                    self.stream.start()
                    self.at(0.0, _sync_tick)
                    self._rt_host.take_fifo()  # (once the bridge and the DUT run: they stay SCHED_RR)
                    self._serve(sel, keeper, wall0)
                except BridgeError as e:
                    self.sched.fail(EXIT_RIG_ERROR, f"bridge: {e}")
            if keeper is not None and keeper.exec_errno is None:
                returncode = keeper.returncode
        except interrupts.Interrupted as e:
            self.interrupted = e.signum
            self.sched.fail(e.exit_code, f"{e} at sim t={self.now_ns / NS:.3f} s")
        finally:
            self._rt_host.stop()
            if keeper is not None:
                keeper.finish()
            for pty in self._ptys.values():
                self._read_pty(pty)
            for key in list(sel.get_map().values()):
                sel.unregister(key.fileobj)
            sel.close()
            self._final_status()
            if self.port is not None:
                self.port.close()
            if self.can is not None:
                self.can.close()
            if vbridge is not None:
                vbridge.stop()
            for pty in self._ptys.values():
                os.close(pty.master)
                os.close(pty.slave)
            shutil.rmtree(tmp, ignore_errors=True)
            if policy is not None:
                os.sched_setscheduler(0, *policy)
        return self._outcome(returncode, wall0, keeper)

    def _raise_priority(self) -> tuple[int, os.sched_param] | None:
        """Real time on a shared machine: what the host starts (the virtual bridge, the keeper and the
        DUT inherit it) runs under SCHED_RR at RT_PRIORITY when allowed (root, or CAP_SYS_NICE /
        RLIMIT_RTPRIO); the loop itself runs above them, SCHED_FIFO (rig.pace.RealtimeHost). They
        sleep most of the time; the kernel keeps 5 % of each core for everything else even if one spins
        (sched_rt_runtime_us). A raised nice value was not enough here: with scheduling autogroups a
        nice value ranks a process only inside its session's group, and the bridge and the DUT start
        sessions of their own. Returns the old policy to restore, or
        None; not allowed, the run goes on as it is and its notes say so."""
        old = os.sched_getscheduler(0), os.sched_getparam(0)
        if old[0] != os.SCHED_OTHER:
            return None  # already real time (or batch/idle by choice): left as it is
        try:
            os.sched_setscheduler(0, os.SCHED_RR, os.sched_param(RT_PRIORITY))
        except OSError:
            self.notes.append("real time: could not run the host loop under SCHED_RR (not permitted); "
                              "other work on this machine can make it late")
            return None
        return old

    def _start_link(self) -> None:
        port = self.port
        assert port is not None
        reply = port.hello()
        fw = bytes(reply.values["firmware_sha256"])  # type: ignore[call-overload]
        self.figures.bridge_id = bridge_id(reply)
        self.figures.protocol = int(reply.values["version"])  # type: ignore[call-overload]
        self.figures.core_version = int(reply.values["core_version"])  # type: ignore[call-overload]
        self.figures.firmware_sha256 = fw.hex()
        port.send("CONFIG", topology=TOPOLOGY_CODES[self.cfg.topology], mpu_addr=0x68, hmc_addr=0x1E,
                  baro_addr=0x77, sbus_period_ms=self.cfg.sbus_period_ms, capture_channels=MOTORS,
                  pulse_min_us=self.esc.pulse_min_us, pulse_max_us=self.esc.pulse_max_us,
                  period_min_us=self.esc.period_min_us)
        deadline = time.monotonic() + 2.0
        while self.clock.exchanges < SYNC_START:
            if time.monotonic() > deadline:
                raise BridgeError(f"the bridge answered {self.clock.exchanges} of {SYNC_START} time-sync "
                                  "probes within 2 s")
            self._probe()
            for m in port.poll(0.05):
                self._on_message(m)

    def _dut_env(self, shim: Path, tmp: Path, ends: Endpoints) -> dict[str, str]:
        serial = {self.cfg.rc_path: ends.rc} | {p: pty.slave_name for p, pty in self._ptys.items()}
        return dut_env(self.cfg.env, shim, ends.board, ends.shm, False, self.cfg.i2c_bus, serial,
                       tmp / "fakes")

    def _run_due(self) -> None:
        """Runs the events due by now and the world to now (the paced wait calls it at each deadline)."""
        if not self.sched.over:
            try:
                self.sched.advance(self._wall_ns())
            except Stop:
                pass

    def _serve(self, sel: selectors.BaseSelector, keeper: Keeper | None, wall0: float) -> None:
        stopping = False
        port = self.port
        assert port is not None
        while keeper is None or not keeper.done:
            timeout = 0.05
            if not self.sched.over:
                self._run_due()
                due = self.sched.next_event_ns()
                if due is not None:
                    timeout = min(timeout, max(0.0, (due - self._wall_ns()) / NS))
            if self.sched.over:
                if keeper is None:
                    return
                if not stopping:
                    # nothing reads the link once the run is over: left registered, its unread bytes
                    # woke the wait at once, again and again, and that loop at SCHED_FIFO starved the
                    # keeper stopping the DUT on a one-core host (the run never ended)
                    sel.unregister(port.fileno())
                    keeper.stop()
                    stopping = True
            ready = sel.select(timeout)
            for key, _ in ready:
                if key.data == "keeper":
                    assert keeper is not None
                    keeper.read_status()
                elif isinstance(key.data, tuple):
                    self._read_pty(self._ptys[key.data[1]])
            if not self.sched.over:
                if self.can is not None:
                    self.can.poll(self.world, self.esc.to_pwm_us)
                try:
                    for m in port.poll(0.0):
                        self._on_message(m)
                except BridgeError as e:
                    self.sched.fail(EXIT_RIG_ERROR, f"bridge: {e}")
                if time.perf_counter() - wall0 > self.cfg.wall_timeout:
                    self.sched.fail(EXIT_WATCHDOG, f"wall-time watchdog: still running after "
                                                   f"{self.cfg.wall_timeout:g} s")

    # ---- the link -------------------------------------------------------------------------------

    def _send(self, name: str, **values: object) -> None:
        if self.port is None:
            return
        try:
            self.port.send(name, **values)
        except BridgeError as e:
            self._link_failed(e)

    def _link_failed(self, e: BridgeError) -> NoReturn:
        self.sched.fail(EXIT_RIG_ERROR, f"bridge: {e}")
        raise Stop from e

    def _probe(self) -> None:
        assert self.port is not None
        self._sync_id = (self._sync_id + 1) & 0xFFFFFFFF
        t1 = time.monotonic_ns()
        self._probes[self._sync_id] = t1
        if len(self._probes) > 64:  # replies that never came
            del self._probes[min(self._probes)]
        self.port.send("TIME_SYNC", id=self._sync_id, host_ns=t1)

    def _on_message(self, m: object) -> None:
        from rig.bridge.link import Decoded

        assert isinstance(m, Decoded)
        v = m.values
        if m.name == "TIME_SYNC_REPLY":
            t1 = self._probes.pop(int(v["id"]), None)  # type: ignore[call-overload]
            if t1 is not None:
                self.clock.add(Exchange(t1, int(v["rx_us"]), int(v["tx_us"]),  # type: ignore[call-overload]
                                        time.monotonic_ns()))
        elif m.name == "PULSES":
            self.figures.pulses += 1
            self.figures.pulses_driven += any(v["width_tenth_us"][:MOTORS])  # type: ignore[index]
            if self.can is None:  # (with a CAN capture device the motors follow its frames)
                for motor, w in enumerate(v["width_tenth_us"][:MOTORS]):  # type: ignore[index]
                    self.world.set_motor(motor, self.esc.motor_us(w))
        elif m.name == "REG_WRITE":
            self.figures.reg_writes += 1
            write = (int(v["t_us"]), int(v["addr"]), int(v["reg"]), int(v["value"]))  # type: ignore[call-overload]
            self.stream.on_reg_write(*write)
            if self.on_reg_write is not None:
                self.on_reg_write(*write)
        elif m.name == "STATUS":
            self.figures.status = dict(v)

    @staticmethod
    def _open_can(spec: str, vbridge: VirtualBridge | None) -> CanPulses:
        # (here, not at the top: python-can is a tenth of a second of every rig command's start)
        from rig.bridge.can_capture import VBRIDGE_CHANNEL, CanPulses, parse

        try:
            interface, channel = parse(spec)
        except ValueError as e:
            raise BridgeError(f"--can: {e}") from e
        if channel == VBRIDGE_CHANNEL:
            if vbridge is None or not vbridge.endpoints.can:
                raise BridgeError("--can ...:vbridge names the virtual bridge's CAN pty: use it with "
                                  "--bridge virtual")
            channel = vbridge.endpoints.can
        return CanPulses(interface, channel)

    def _send_faults(self) -> None:
        """The scenario's bus faults (a chip that does not answer, answers now and then, or answers
        garbage), scheduled on the bridge's clock; signal faults act in the host's sensor models."""
        for target, fs in self.cfg.faults.items():
            if target not in BUS_TARGETS:
                continue
            for f in fs.faults:
                end = FAULT_NEVER_US if math.isinf(f.end) else self.to_bridge_us(round(f.end * NS))
                self._send("FAULT", target=TARGETS.index(target), kind=KINDS.index(f.kind),
                           start_us=self.to_bridge_us(round(f.start * NS)), end_us=end,
                           magnitude=f.magnitude, period_s=f.period, duty=f.duty)

    def _final_status(self) -> None:
        """The bridge's counters as of the run's end: the first STATUS stamped after it (the bridge
        sends one every 200 ms), waited for at most half a second."""
        port = self.port
        if port is None or not self.clock.ready:
            return
        end_us = self.clock.to_bridge_us(time.monotonic_ns())
        deadline = time.monotonic() + 0.5
        try:
            while time.monotonic() < deadline:
                for m in port.poll(max(0.0, deadline - time.monotonic())):
                    self._on_message(m)
                    if m.name == "STATUS" and int(m.values["t_us"]) >= end_us:  # type: ignore[call-overload]
                        return
        except BridgeError:
            pass

    # ---- serial ---------------------------------------------------------------------------------

    def _read_pty(self, pty: _Pty) -> None:
        while True:
            try:
                data = os.read(pty.master, 65536)
            except (BlockingIOError, OSError):
                return
            if not data:
                return
            pty.received += data

    # ---- results --------------------------------------------------------------------------------

    def _outcome(self, returncode: int | None, wall0: float, keeper: Keeper | None) -> Outcome:
        sim = self.world.time_ns / NS
        reached = (self.figures.reg_writes > 0 or self.figures.pulses > 0
                   or bool(self.figures.status.get("i2c_acked")))
        verdict, code, error = self.sched.verdict(returncode, sim, reached, keeper is None,
                                                  self.interrupted is not None)
        if keeper is not None and keeper.exec_errno is not None:
            verdict, code, error = "error", 127, f"command not found or not executable: {self.cfg.command}"
        events, late, worst, p99, p50 = self.sched.lateness()
        acked = self.figures.status.get("i2c_acked", 0)  # the board's transfers are the bridge's to count
        transfers = int(acked) if isinstance(acked, int) else 0
        return Outcome(verdict, code, error, returncode, sim, sim, time.perf_counter() - wall0, transfers, 0,
                       0, self.notes + self.stream.figures.notes, [], self.world.outputs(),
                       self.figures.pulses_driven, events, late, worst, p99, p50,
                       self._rt_host.state.as_dict())

    def link_figures(self) -> dict[str, object]:
        """For result.json: the bridge's identity and the link's figures."""
        f = self.figures
        return {
            "bridge": self.cfg.bridge, "bridge_id": f.bridge_id, "protocol": f.protocol,
            "core_version": f.core_version, "firmware_sha256_8": f.firmware_sha256,
            "lead_s": self.cfg.lead_s, "samples_sent": f.samples_sent, "samples_late": f.samples_late,
            "samples": {"imu": self.stream.figures.imu, "mag": self.stream.figures.mag,
                        "baro": self.stream.figures.baro,
                        "imu_extrapolated": self.stream.figures.imu_extrapolated},
            "reg_writes": f.reg_writes, "pulse_reports": f.pulses, "bridge_status": f.status,
            "time_sync": self.clock.figures(), "link": self.port.figures() if self.port else {},
            "capture": self.can.figures.as_dict(self.can.interface, self.can.channel) if self.can
            else "bridge",
        }


def _sync_tick(session: BenchSession) -> None:
    """A time-sync probe every SYNC_PERIOD_S (the bridge's drift is followed all run)."""
    session._probe()
    t = session.sched.event_ns or 0
    session.at(t / NS + SYNC_PERIOD_S, _sync_tick)
