"""The DUT's messages (rig/shim/protocol.h, parsed by rig/protocol.py): HELLO, I2C transfers, PWM
notices, waits and notes, each acted on at its sim time.

This is the session's second job, kept apart from the process and transport loop (rig/session.py) and
from sim time (rig/scheduler.py). A request (HELLO, I2C, a WAIT that is not AHEAD) gets exactly one
reply; a notice (PWM, WAIT AHEAD, NOTE, I2C_WRITE) gets none, so it costs the DUT no round trip. Every
message is checked: a malformed one raises ``protocol.Malformed`` and costs only its connection.
"""

from __future__ import annotations

import errno
import struct
from typing import TYPE_CHECKING, Final

from rig import protocol as P
from rig.emulators.i2c_bus import I2CNack, I2CProtocolError, Msg
from rig.scenarios.result import I2CRecord
from rig.scheduler import EXIT_RIG_ERROR, EXIT_WATCHDOG, NS, Scheduler, SharedPage, Stop, fmt
from rig.world import PwmChannel, World

if TYPE_CHECKING:
    from rig.connection import Conn
    from rig.session import Session, SessionConfig

FOREVER_SLICE_NS: Final = 10_000_000  # a wait with no deadline lets 10 ms pass, then the DUT looks again
I2C_LOG_CAP: Final = 1_000_000  # transfers kept for run.mcap (TargetRun.transactions)
#: the run's error when a promised write (I2C_WRITE) was not acknowledged
BROKEN_PROMISE: Final = "a write the rig told the DUT was acknowledged was not (a rig bug): the run is void"


class Handler:
    """Acts on the DUT's messages: moves sim time (through the scheduler), the world and the clock
    page, and answers through the session's transport. Counts what it saw for the run's outcome."""

    def __init__(self, session: Session, cfg: SessionConfig, sched: Scheduler, world: World,
                 page: SharedPage) -> None:
        self.session, self.cfg, self.sched, self.world, self.page = session, cfg, sched, world, page
        self.lockstep = cfg.lockstep  # in real time the page holds PWM states, not the clock
        self.transactions = self.waits = self.pwm_writes = 0
        self.promised_writes = 0  # I2C_WRITE notices (among the transactions)
        #: PWM notices other than duty acted on here: the fast path keeps the channels' settings until
        #: this changes (rig/lockstep/pwm_duty.c)
        self.pwm_config_changes = 0
        self.notes: list[str] = []
        #: every transfer, for run.mcap: (sim time ns, address, bytes written, bytes read, status); one
        #: tuple append per transfer (the lockstep rate is unchanged, bench/scenario_rates.py)
        self.i2c_log: list[I2CRecord] = []  # (the run's result keeps this list: the fast path adds to it too)

    def handle(self, conn: Conn, hdr: P.Header, payload: bytes) -> None:
        if self.sched.over and hdr.type in P.REQUESTS:
            raise Stop
        if not conn.hello and hdr.type != P.MSG_HELLO:
            raise P.Malformed(f"{P.MSG_NAMES[hdr.type]} before HELLO")
        if hdr.type == P.MSG_HELLO:
            version, pid, flags = P.parse_hello(payload)
            conn.hello, conn.pid = True, pid
            status = 0 if version == P.PROTOCOL_VERSION else errno.EPROTO
            if status:
                self.notes.append(f"pid {pid}: shim protocol {version}, session speaks {P.PROTOCOL_VERSION}")
            self.session.greet(conn, status, not status and bool(flags & P.HELLO_MAILBOX))
        elif hdr.type == P.MSG_I2C:
            self._i2c(conn, hdr, payload)
        elif hdr.type == P.MSG_I2C_WRITE:
            self._i2c(conn, hdr, payload, promised=True)
        elif hdr.type == P.MSG_PWM:
            self._pwm(conn, hdr, payload)
        elif hdr.type == P.MSG_WAIT:
            self._wait(conn, hdr, payload)
        elif hdr.type == P.MSG_STALL:  # a DUT thread spins (rig/shim/threads.c): as the stall watchdog
            text = payload.decode("utf-8", "replace")[:300]
            self.session.log(self._notice_time(hdr), f"c{conn.index} stall: {text}")
            self.sched.fail(EXIT_WATCHDOG, f"the command stalled: {text}")
        else:
            text = payload.decode("utf-8", "replace")[:300]
            if text not in self.notes:
                self.notes.append(text)
            self.session.log(self._notice_time(hdr), f"c{conn.index} note: {text}")

    def _request_time(self, hdr: P.Header) -> int:
        """A request's time: the DUT waits for the answer, so nothing it does can be later than now."""
        if not self.lockstep:
            return self.session.now_ns
        return max(self.page.now(), hdr.t_ns)

    def _notice_time(self, hdr: P.Header) -> int:
        """A notice's own time: the DUT did not wait for it, and may have moved the shared clock on since
        (after a WAIT AHEAD it runs ahead of what the session has read)."""
        return hdr.t_ns if self.lockstep else self.session.now_ns

    def _i2c(self, conn: Conn, hdr: P.Header, payload: bytes, promised: bool = False) -> None:
        """A transfer, answered; ``promised``: an I2C_WRITE notice, a write the shim has already told the
        DUT was acknowledged (the session's promise in the clock page), done at its own time, unanswered."""
        if promised:
            bus, msgs = P.parse_promised_write(payload)
            t = self._notice_time(hdr)
            if not (self.lockstep and self.page.promised(bus, msgs[0].addr, t)):
                raise P.Malformed(f"I2C_WRITE notice to 0x{msgs[0].addr:02x} on bus {bus} at {fmt(t)}, "
                                  "which the session did not promise to acknowledge")
        else:
            bus, msgs = P.parse_i2c(payload)
            t = self._request_time(hdr)
        session = self.session
        session.advance(t)
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
        if self.lockstep:
            self.page.set(t_after)
        self.transactions += 1
        if len(self.i2c_log) < I2C_LOG_CAP:
            wrote = b"".join([m.data for m in msgs if not m.read])
            self.i2c_log.append(I2CRecord(t, msgs[0].addr if msgs else 0, wrote[0] if wrote else None, wrote,
                                          b"".join(results), status == 0))
        if session.logging:
            outcome = "ok" if not status else errno.errorcode[status]
            session.log(t, f"c{conn.index} i2c-{bus} {describe(msgs, results)} {outcome}"
                           f"{' promised' if promised else ''}")
        if not promised:
            session.send(conn, P.reply(P.MSG_I2C, t_after, b"".join(results), status))
        elif status:
            self.promise_broken()
        else:
            self.promised_writes += 1

    def promise_broken(self) -> None:
        """A promised write was not acknowledged: the DUT was told otherwise, so nothing it did after it can
        be judged (a rig bug; the fast path calls this too)."""
        self.sched.fail(EXIT_RIG_ERROR, BROKEN_PROMISE)

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

    def _pwm(self, conn: Conn, hdr: P.Header, payload: bytes) -> None:
        chip, channel, attr, _, value = P.parse_fixed(payload, P.PWM_MSG, "PWM")
        world = self.world
        if chip != 0 or channel >= len(world.pwm) or attr not in P.PWM_ATTR_NAMES:
            raise P.Malformed(f"PWM notice for chip {chip} channel {channel} attribute {attr}")
        t = self._notice_time(hdr)
        session = self.session
        session.advance(t)
        self.pwm_writes += 1
        if attr != P.PWM_DUTY:
            self.pwm_config_changes += 1
        ch = world.pwm[channel]
        if attr == P.PWM_EXPORT:
            ch.exported = True
        elif attr == P.PWM_UNEXPORT:
            world.pwm[channel] = PwmChannel()
        elif attr == P.PWM_PERIOD:
            ch.period_ns = value
        elif attr == P.PWM_DUTY:
            ch.duty_ns = value
        elif attr == P.PWM_ENABLE:
            ch.enabled = bool(value)
        else:
            ch.inversed = bool(value)
        world.apply_pwm(channel)
        if session.in_flight:  # the DUT is running (a notice has no reply): hand over what events wrote
            session.deliver_serial()
        if session.logging:  # (the message is not even formatted otherwise: this runs per request)
            session.log(t, f"c{conn.index} pwm{channel} {P.PWM_ATTR_NAMES[attr]} {value}")

    def _wait(self, conn: Conn, hdr: P.Header, payload: bytes) -> None:
        wake, kind, _ = P.parse_fixed(payload, P.WAIT_MSG, "WAIT")
        if kind not in (P.WAIT_SLEEP, P.WAIT_POLL, P.WAIT_AHEAD):
            raise P.Malformed(f"WAIT of unknown kind {kind}")
        self.waits += 1
        session, page = self.session, self.page
        if kind == P.WAIT_AHEAD:  # a notice: the shim has moved the clock already; catch the world up
            if not self.lockstep or wake == P.WAIT_FOREVER:
                raise P.Malformed("WAIT AHEAD outside lockstep or without a deadline")
            t = self._notice_time(hdr)
            target = max(wake, t)
            session.advance(target)
            if session.in_flight:  # the DUT is running: hand over what events wrote
                session.deliver_serial()
            if session.logging:
                session.log(t, f"c{conn.index} wait {fmt(wake)} -> {fmt(target)} ahead")
            return
        t = self._request_time(hdr)
        if not self.lockstep:  # the shim does not virtualise time in real time; answer at once
            session.send(conn, P.reply(P.MSG_WAIT, t, struct.pack("<I", P.WAKE_DEADLINE)))
            return
        target, reason = (t + FOREVER_SLICE_NS, P.WAKE_SLICE) if wake == P.WAIT_FOREVER else (max(wake, t),
                                                                                            P.WAKE_DEADLINE)
        woke = session.advance(target, stop_on_output=kind == P.WAIT_POLL)
        if woke < target:
            target, reason = woke, P.WAKE_EVENT
        page.set(target)
        if session.logging:
            session.log(t, f"c{conn.index} wait {'forever' if wake == P.WAIT_FOREVER else fmt(wake)} "
                           f"-> {fmt(target)}{' event' if reason == P.WAKE_EVENT else ''}")
        session.send(conn, P.reply(P.MSG_WAIT, target, struct.pack("<I", reason)))


def describe(msgs: list[P.I2CMessage], results: list[bytes]) -> str:
    """A transfer as the log shows it: W68:3b R68[14]=…"""
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
