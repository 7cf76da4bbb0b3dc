"""The session's cost of one reference-FC cycle, without a DUT process: the messages of a 250 Hz cycle
(an MPU-6050 burst read, four PWM duty writes, a sleep that goes ahead) pushed through the session's
message handling over a socketpair, with the MPU at 1 kHz behind its DLPF and the plant stepping 4 ms.

Why: these VMs change speed by half from one minute to the next, so wall-clock A/B comparisons of a
change need many interleaved runs. With ``--instructions`` the cost is counted in instructions under
valgrind (two run lengths, subtracted, so start-up cancels; ASLR off, a fixed hash seed, OpenBLAS on
one thread: its idle worker spins for a time-dependent number of instructions, which made the count
vary by 4-6 %). The count does not follow the machine's speed; it is taken three times and the median
and range are printed. Prints; asserts nothing.

    python bench/cycle_cost.py                  # microseconds per cycle (wall clock, noisy)
    python bench/cycle_cost.py --instructions   # instructions per cycle (needs valgrind)
    python bench/cycle_cost.py --instructions --breakdown [--parts FILE.json]
                                                # and by part, from callgrind (bench/callgrind.py)

Three routes into the session, each printed (``ROUTES``):

* ``peer``: as in a flight. The DUT's side is another process (this file with ``--peer``: it sends a
  cycle's messages, waits for the burst read's reply, sends the next), and the session reads and acts
  on them in C (``FastPath.pump``, rig/lockstep/pump.c) from the loop's epoll set, returning to Python
  only when pump's time budget is spent. Counted in the session's process alone: the session's cost.
* ``pump``: the DUT's side in this process, the session entered once per cycle through pump (its epoll
  set holds a pipe that is always readable, so pump returns after each cycle's messages): the harness's
  socket calls (about 3.5 k) and the loop's entry into pump (about 3.5 k) per cycle are counted too.
* ``handler``: as ``pump`` but without it (``Conn.receive`` and ``FastPath.handle`` from Python, what
  the loop does for a connection pump declines): how the figures before pump.c were counted.

``--breakdown`` profiles the same two run lengths under callgrind, counting only inside the session's
entry (``Session._on_readable``: the harness's socket calls are not in it), and subtracts each part's
instructions (message handling, plant, samples, chip core, scheduler; "other" is what no part
reaches). It also prints the fast path's own share (``handle_bytes``). ``--parts`` replaces
callgrind.PARTS with a JSON list of [part, pattern] pairs, for a per-cycle path in new files.
"""

from __future__ import annotations

import os
import select
import shutil
import socket
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from rig.compiled import all_compiled, install, status  # noqa: E402

install()  # the compiled hot modules, before they are imported
import rig.protocol as P  # noqa: E402
from rig.connection import Conn  # noqa: E402
from rig.session import Session, SessionConfig  # noqa: E402
from rig.world import World  # noqa: E402

CYCLE_NS = 4_000_000


def _msg(t_ns: int, payload: bytes, mtype: int) -> bytes:
    return P.HEADER.pack(len(payload), mtype, 0, t_ns) + payload


def _i2c(t_ns: int, parts: list[tuple[int, int, int, bytes]]) -> bytes:
    descs = b"".join(P.I2C_MSG.pack(addr, flags, n, 0) for addr, flags, n, _ in parts)
    return _msg(t_ns, P.I2C_HEAD.pack(1, len(parts)) + descs + b"".join(d for *_, d in parts), P.MSG_I2C)


def _pwm(t_ns: int, channel: int, attr: int, value: int) -> bytes:
    return _msg(t_ns, P.PWM_MSG.pack(0, channel, attr, 0, value), P.MSG_PWM)


def _cycle(t_ns: int) -> bytes:
    out = [_i2c(t_ns, [(0x68, 0, 1, b"\x3b"), (0x68, P.I2C_M_RD, 14, b"")])]
    out += [_pwm(t_ns + 1000, ch, P.PWM_DUTY, 1_500_000) for ch in range(4)]
    out.append(_msg(t_ns + 2000, P.WAIT_MSG.pack(t_ns + CYCLE_NS, P.WAIT_AHEAD, 0), P.MSG_WAIT))
    return b"".join(out)


class _Cycles:
    """The cycle's messages built once, only their times written each cycle: built anew in Python every
    cycle (``_cycle``) they cost the harness about 40 k instructions a cycle, a quarter of the count."""

    def __init__(self) -> None:
        self.buf = bytearray(_cycle(0))
        self.times: list[tuple[int, int]] = []  # (offset, time at cycle start 0) of each u64 time
        pos = 0
        while pos < len(self.buf):
            length, mtype, _, t_rel = P.HEADER.unpack_from(self.buf, pos)
            self.times.append((pos + 8, t_rel))  # (HEADER: len, type, status, t_ns)
            pos += P.HEADER.size
            if mtype == P.MSG_WAIT:  # (WAIT_MSG: wake_ns, kind, zero)
                self.times.append((pos, P.WAIT_MSG.unpack_from(self.buf, pos)[0]))
            pos += length

    def at(self, t_ns: int) -> bytearray:
        for offset, t_rel in self.times:
            _U64.pack_into(self.buf, offset, t_ns + t_rel)
        return self.buf


_U64 = struct.Struct("<Q")


#: how the session is entered (module docstring)
ROUTES = ("peer", "pump", "handler")
ROUTE_WORDS = {
    "peer": "as in a flight (the DUT's side in its own process, pump.c reading; the session's process alone)",
    "pump": "entered once per cycle through pump.c (the harness's socket calls, ~3.5 k, counted too)",
    "handler": "entered once per cycle without pump.c (the route of the figures before it; harness too)",
}


def run_cycles(n: int, built: int | None = None, route: str = "pump") -> float:
    """Runs ``n`` cycles; returns CPU seconds per cycle. The messages of ``built`` cycles (at least
    ``n``) are made before the first: two counts of different lengths that make the same number
    subtract it away, so what is left per cycle is the session's and this loop's: its socket calls
    (``sendall`` of a cycle's messages, ``recv_into`` of the replies) and its turn, about 3.5 k
    instructions of 31 k on the ``handler`` route (the ``peer`` route's are in the peer). Made in the loop,
    the messages were 12 k more of the count."""
    session = Session(SessionConfig(command=["true"], duration=1e6), World.at_rest())
    with tempfile.TemporaryDirectory(prefix="rig-cycle-") as tmp:
        session.open_page(Path(tmp) / "shm")  # (mapped: the file may go at once)
    ours, dut = socket.socketpair()
    conn = Conn(ours, 1)
    conn.hello = True
    setup = [_i2c(0, [(0x68, 0, 2, bytes(rv))]) for rv in ((0x6B, 0x00), (0x1A, 0x03), (0x19, 0x00))]
    for ch in range(4):  # the FC's MPU set-up (awake, DLPF 3, 1 kHz) and PWM channels
        setup += [_pwm(0, ch, P.PWM_EXPORT, 0), _pwm(0, ch, P.PWM_PERIOD, 2_500_000),
                  _pwm(0, ch, P.PWM_DUTY, 1_000_000), _pwm(0, ch, P.PWM_ENABLE, 1)]
    dut.sendall(b"".join(setup))
    session._on_readable(conn, None)  # type: ignore[arg-type]  # (the selector is not used here)
    dut.recv(1 << 20)
    t = 10_000_000
    if route == "peer":  # (the peer makes the cycles' messages)
        return _run_with_peer(session, conn, dut, t, n, max(n, built or 0))
    cycles = _Cycles()
    assert cycles.at(t) == _cycle(t) and cycles.at(t + CYCLE_NS) == _cycle(t + CYCLE_NS)
    sent = [bytes(cycles.at(t + k * CYCLE_NS)) for k in range(max(n, built or 0))]
    replies = bytearray(65536)
    if route == "pump":  # the loop's epoll set, with something else always ready in it (see above)
        loop_set, (ready, wakes) = select.epoll(), os.pipe()
        os.write(wakes, b"!")
        loop_set.register(ready, select.EPOLLIN)
        session._pump_fd = loop_set.fileno()
    c0 = time.process_time()
    for k in range(n):
        dut.sendall(sent[k])
        session._on_readable(conn, None)  # type: ignore[arg-type]
        dut.recv_into(replies)
    return (time.process_time() - c0) / n


def _run_with_peer(session: Session, conn: Conn, dut: socket.socket, t: int, n: int, built: int) -> float:
    """The ``peer`` route (module docstring): ``n`` cycles from another process; CPU s per cycle."""
    loop_set = select.epoll()
    loop_set.register(conn.sock.fileno(), select.EPOLLIN)
    session._pump_fd = loop_set.fileno()
    fast = session.fast
    assert fast is not None
    args = [str(dut.fileno()), str(t), str(n), str(built)]
    peer = subprocess.Popen([sys.executable, __file__, "--peer", *args], pass_fds=[dut.fileno()])
    dut.close()
    transfers = fast.counts[0] + n
    c0 = time.process_time()
    while fast.counts[0] < transfers:
        session._on_readable(conn, None)  # type: ignore[arg-type]
    cpu = time.process_time() - c0
    conn.sock.close()  # (the peer waits for this end)
    if peer.wait(timeout=60):
        sys.exit(f"the peer failed (status {peer.returncode})")
    return cpu / n


def _peer(fd: int, t: int, n: int, built: int) -> None:
    """The DUT's side of the ``peer`` route: a cycle's messages, then the burst read's reply, ``n`` times
    (the messages of ``built`` cycles made first, as run_cycles makes them), then the session's close."""
    sock = socket.socket(fileno=fd)
    cycles = _Cycles()
    sent = [bytes(cycles.at(t + k * CYCLE_NS)) for k in range(built)]
    reply = P.HEADER.size + 14
    for k in range(n):
        sock.sendall(sent[k])
        got = 0
        while got < reply:
            chunk = sock.recv(reply - got)
            if not chunk:
                sys.exit(f"the session closed at cycle {k}")
            got += len(chunk)
    sock.recv(1)  # (the session's close: its count is done)


def instructions(argv: list[str], env: dict[str, str]) -> int:
    """The instructions Python running ``argv`` executes, counted by cachegrind (its own process only;
    ASLR off, a fixed hash seed, OpenBLAS on one thread: see above)."""
    env = {**os.environ, **env, "PYTHONHASHSEED": "0", "OPENBLAS_NUM_THREADS": "1"}
    cmd = ["setarch", "-R", "valgrind", "--tool=cachegrind", "--cache-sim=no",
           "--cachegrind-out-file=/dev/null", sys.executable, *argv]
    done = subprocess.run(cmd, capture_output=True, text=True, env=env, check=True)
    line = next(x for x in done.stderr.splitlines() if "I   refs:" in x or "I refs:" in x)
    return int(line.split()[-1].replace(",", ""))


def _instructions(n: int, built: int, route: str) -> int:
    env = {"RIG_CYCLES": str(n), "RIG_BUILT": str(built), "RIG_ROUTE": route}
    return instructions([__file__, "--child"], env)


#: What the breakdown counts: the session's entry as the harness calls it (mypyc's wrapper of
#: ``Session._on_readable``), everything under it and nothing else. Profiled from the start, the import
#: and set-up's hundreds of millions of instructions ran through the same interpreter functions as the
#: cycles (a call cycle through ``_PyEval_EvalFrameDefault``), so the split (which shares a function's
#: cost among its callers by their totals) charged the two run lengths differently and the subtraction
#: printed negative parts.
SESSION_ENTRY = "CPyPy_session___Session____on_readable"
#: ... and within it, the fast path's work on the messages (``handle_bytes``, as pump.c calls it). The
#: breakdown profiles the ``peer`` route: what is under the entry is then what a flight's session does.
FAST_PATH = "handle_bytes"


def _profile(n: int, built: int) -> Any:
    """callgrind's profile (bench/callgrind.py) of ``n`` cycles, under the session's entry only."""
    import callgrind

    env = {**os.environ, "PYTHONHASHSEED": "0", "OPENBLAS_NUM_THREADS": "1", "RIG_CYCLES": str(n),
           "RIG_BUILT": str(built), "RIG_ROUTE": "peer"}
    with tempfile.TemporaryDirectory(prefix="rig-callgrind-") as tmp:
        out = Path(tmp) / "callgrind.out"
        cmd = ["setarch", "-R", "valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
               "--collect-atstart=no", f"--toggle-collect={SESSION_ENTRY}",
               sys.executable, __file__, "--child"]
        subprocess.run(cmd, capture_output=True, text=True, env=env, check=True)
        return callgrind.parse(out.read_text())


def breakdown(short: int, long: int, parts: list[tuple[str, str]] | None) -> None:
    import callgrind

    if not all_compiled():
        sys.exit("--breakdown counts from the compiled session's entry: build it (make compiled), "
                 "without RIG_PURE_PYTHON")
    a, b = _profile(short, long), _profile(long, long)
    if not b.total:
        sys.exit(f"--breakdown: callgrind counted nothing under {SESSION_ENTRY}")
    sa, sb = callgrind.split(a, parts), callgrind.split(b, parts)
    per = {p: (sb.get(p, 0) - sa.get(p, 0)) / (long - short) for p in dict.fromkeys([*sb, *sa])}
    total = sum(per.values())
    fast = (callgrind.inclusive(b, FAST_PATH) - callgrind.inclusive(a, FAST_PATH)) / (long - short)
    print(f"by part (callgrind, {long} - {short} cycles, under Session._on_readable): {total / 1000:.1f} k "
          f"instructions per cycle; the fast path's ({FAST_PATH}, a flight's per-cycle path) "
          f"{fast / 1000:.1f} k")
    for part, cost in sorted(per.items(), key=lambda kv: -kv[1]):
        print(f"  {part:18} {cost / 1000:7.1f} k ({cost / total * 100:5.1f} %)")


OPTIONS = ("--instructions", "--breakdown", "--parts")


def main() -> None:
    if "--peer" in sys.argv:
        _peer(*(int(a) for a in sys.argv[sys.argv.index("--peer") + 1:][:4]))
        return
    if "--child" in sys.argv:
        run_cycles(int(os.environ["RIG_CYCLES"]), int(os.environ.get("RIG_BUILT", "0")),
                   os.environ.get("RIG_ROUTE", "pump"))
        return
    if {"-h", "--help"} & set(sys.argv):
        print(__doc__)
        return
    unknown = [a for a in sys.argv[1:] if a.startswith("-") and a not in OPTIONS]
    if unknown:
        sys.exit(f"cycle_cost.py: unknown option {unknown[0]} (--help: the options)")
    print(status())
    if "--instructions" in sys.argv:
        if not shutil.which("valgrind") or not shutil.which("setarch"):
            sys.exit("--instructions needs valgrind and setarch (apt-get install valgrind util-linux)")
        short, long = 300, 900
        for route in ROUTES:
            per = sorted((_instructions(long, long, route) - _instructions(short, long, route))
                         / (long - short) / 1000 for _ in range(3))
            print(f"session cost of one FC cycle, {ROUTE_WORDS[route]}: {per[1]:.1f} k instructions "
                  f"(median of 3; {per[0]:.1f}-{per[2]:.1f})")
        if "--breakdown" in sys.argv:
            parts = None
            if "--parts" in sys.argv:
                import json

                raw = json.loads(Path(sys.argv[sys.argv.index("--parts") + 1]).read_text())
                if not (isinstance(raw, list) and all(isinstance(x, list) and len(x) == 2 for x in raw)):
                    sys.exit("--parts: a JSON list of [part, pattern] pairs")
                parts = [(str(p), str(pat)) for p, pat in raw]
            breakdown(short, long, parts)
    else:
        for route in ROUTES:
            runs = sorted(run_cycles(2500, route=route) * 1e6 for _ in range(3))
            print(f"session cost of one FC cycle ({route}): {runs[1]:.0f} us CPU (median of 3; best "
                  f"{runs[0]:.0f}); {CYCLE_NS / 1e3 / runs[1]:.0f}x real time for this part alone")


if __name__ == "__main__":
    main()
