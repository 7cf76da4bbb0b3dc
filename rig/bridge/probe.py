"""`rig bridge probe PORT|virtual`: asks a bridge who it is and how its link is doing, without running
anything: its identity (HELLO_REPLY: name, protocol and core versions, firmware hash, clock), its clock
against the host's (TIME_SYNC exchanges 25 ms apart: offset, drift over those 0.4 s, round trips)
and the link's statistics from both ends (the bridge's STATUS, which it sends every 200 ms, and the
host's own counts). The probe talks as a host in a run does, so the bridge never finds it silent:
HEARTBEATs while it waits for the STATUS. The first thing to run on a freshly flashed board
(docs/bridge-firmware.md).

``virtual`` starts the virtual bridge (build/vbridge) for the probe and stops it after.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import asdict, dataclass, field

from rig.bridge.firmware import firmware_hash
from rig.bridge.port import BridgeError, BridgePort, bridge_id
from rig.bridge.timesync import ClockMap, Exchange
from rig.bridge.vbridge import VirtualBridge

SYNCS = 16
#: at most this many (25 s at SYNC_INTERVAL_S): 100000 took 40 minutes, and past a few hundred the drift
#: estimate gains nothing a run's own time sync does not measure better
MAX_SYNCS = 1000
#: probes this far apart (as a session's are, 10 Hz or more): 16 span 0.4 s, enough for a first drift
SYNC_INTERVAL_S = 0.025
#: the bridge sends STATUS every 200 ms: a second without one means it is not sending them
STATUS_TIMEOUT_S = 1.0


@dataclass
class Probe:
    port: str
    bridge_id: str = ""
    protocol: int = 0
    core_version: int = 0
    firmware_sha256: str = ""
    clock_hz: int = 0
    clock: dict[str, float | int] = field(default_factory=dict)
    status: dict[str, object] = field(default_factory=dict)
    host: dict[str, object] = field(default_factory=dict)
    #: what this checkout's firmware sources hash to (rig/bridge/firmware.py), "" when it cannot tell
    checkout_sha256: str = ""

    def _which_firmware(self) -> str:
        if self.port == "virtual":  # (build/vbridge, started by the probe: no firmware image to compare)
            return " (the virtual bridge: this checkout's build/vbridge, no firmware image)"
        if not self.checkout_sha256:
            return ""
        if self.firmware_sha256 == self.checkout_sha256:
            return " (this checkout's)"
        return f" (not this checkout's {self.checkout_sha256})"

    def lines(self) -> list[str]:
        c, s, h = self.clock, self.status, self.host
        out = [f"bridge   {self.bridge_id} on {self.port}",
               f"protocol {self.protocol}, core {self.core_version}, firmware {self.firmware_sha256}"
               + self._which_firmware(),
               f"clock    {self.clock_hz / 1e6:g} MHz core; bridge time {c.get('bridge_us', 0):.0f} us, "
               f"drift {c.get('drift_ppm', 0.0):+.1f} ppm over {c.get('exchanges', 0)} exchanges, "
               f"round trip p50 {c.get('rtt_p50_us', 0.0):.0f} us, max {c.get('rtt_max_us', 0.0):.0f} us"]
        if s:
            out.append(f"bridge's link  frames ok {s['frames_ok']}, bad {s['frames_bad']}, seq gaps "
                       f"{s['seq_gaps']}, refused {s['refused']}; host silent {s['host_silent']}")
            out.append(f"bridge's board I2C acked {s['i2c_acked']}, errors {s['i2c_errors']}, preload misses "
                       f"{s['i2c_preload_misses']}, pulse glitches "
                       f"{s['pulse_glitches']}, SBUS dropped {s['sbus_dropped']}, underruns {s['underruns']}")
        else:
            out.append("bridge's link  no STATUS came")
        if h:
            out.append(f"host's link    frames sent {h['frames_sent']}, received {h['frames_received']}, "
                       f"bad {h['frames_bad']}, seq gaps {h['seq_gaps']}, bytes down {h['bytes_down']}, "
                       f"up {h['bytes_up']}")
        return out


def probe_port(path: str, syncs: int = SYNCS, status_timeout_s: float = STATUS_TIMEOUT_S) -> Probe:
    """HELLO, ``syncs`` TIME_SYNC exchanges SYNC_INTERVAL_S apart, then the first STATUS that counts
    them all. BridgeError when the bridge does not answer, speaks another protocol or the link dies."""
    port = BridgePort(path)
    try:
        reply = port.hello()
        p = Probe(path, bridge_id(reply), int(reply.values["version"]),  # type: ignore[call-overload]
                  int(reply.values["core_version"]),  # type: ignore[call-overload]
                  bytes(reply.values["firmware_sha256"]).hex(),  # type: ignore[call-overload]
                  int(reply.values["clock_hz"]))  # type: ignore[call-overload]
        p.checkout_sha256 = _checkout_hash()
        clock = ClockMap()
        for k in range(syncs):
            if k:
                _pause(port, SYNC_INTERVAL_S)
            t1 = time.monotonic_ns()
            port.send("TIME_SYNC", id=k, host_ns=t1)
            deadline = time.monotonic() + status_timeout_s
            answered = False
            while not answered:
                if time.monotonic() > deadline:
                    raise BridgeError(f"the bridge on {path} did not answer time-sync probe {k} within "
                                      f"{status_timeout_s:g} s")
                for m in port.poll(0.05):
                    if m.name == "TIME_SYNC_REPLY" and m.values["id"] == k:
                        clock.add(Exchange(t1, int(m.values["rx_us"]),  # type: ignore[call-overload]
                                           int(m.values["tx_us"]), time.monotonic_ns()))  # type: ignore[call-overload]
                        answered = True
        p.clock = {**clock.figures(), "bridge_us": clock.to_bridge_us(time.monotonic_ns())}
        counted = 1 + syncs  # the HELLO and the probes: the bridge's counts start again at the HELLO
        deadline = time.monotonic() + status_timeout_s
        while not p.status and time.monotonic() < deadline:
            port.send("HEARTBEAT")
            for m in port.poll(0.05):
                if m.name == "STATUS" and int(m.values["frames_ok"]) >= counted:  # type: ignore[call-overload]
                    p.status = dict(m.values)
        p.host = {k: v for k, v in port.figures().items() if k != "bad_reasons"}
        return p
    finally:
        port.close()


def _checkout_hash() -> str:
    """The firmware hash this checkout's sources give, when its generated headers are there (a
    `make firmware` or `make test` wrote them); "" otherwise: the probe writes nothing."""
    try:
        return firmware_hash().hex()
    except OSError:
        return ""


def _pause(port: BridgePort, seconds: float) -> None:
    """Reads (and drops) what comes for ``seconds``: a bridge that dies meanwhile is still noticed."""
    end = time.monotonic() + seconds
    while (left := end - time.monotonic()) > 0:
        port.poll(left)


def probe(target: str, syncs: int = SYNCS) -> Probe:
    """``target``: a serial port, or ``virtual`` for a virtual bridge started for the probe."""
    if target != "virtual":
        return probe_port(target, syncs)
    vb = VirtualBridge()
    try:
        p = probe_port(vb.endpoints.link, syncs)
        p.port = "virtual"
        return p
    finally:
        vb.stop()


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    bridge = sub.add_parser("bridge", help="talk to a bench bridge (docs/bridge-firmware.md)")
    bsub = bridge.add_subparsers(dest="bridge_command", required=True)
    p = bsub.add_parser("probe", help="a bridge's identity, firmware hash, clock and link statistics")
    p.add_argument("port", help="the bridge's serial port (/dev/ttyACM0), or 'virtual'")
    p.add_argument("--syncs", type=int, default=SYNCS,
                   help=f"time-sync exchanges, 1..{MAX_SYNCS} (default {SYNCS})")
    p.add_argument("--json", action="store_true", help="print the result as JSON")


def main(args: argparse.Namespace) -> int:
    if not 1 <= args.syncs <= MAX_SYNCS:
        print(f"rig bridge probe: --syncs: expected 1..{MAX_SYNCS} ({SYNC_INTERVAL_S * 1000:g} ms each), "
              f"got {args.syncs}", file=sys.stderr)
        return 2
    try:
        p = probe(args.port, args.syncs)
    except BridgeError as e:
        print(f"rig bridge probe: {e}", file=sys.stderr)
        return 1
    print(json.dumps(asdict(p), indent=2) if args.json else "\n".join(p.lines()))
    return 0
