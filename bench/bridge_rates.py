"""The bench path's figures (docs/bench.md), printed, never asserted:

* the link's latency over the virtual bridge's pty: time-sync round trips (p50, p99) at 1 kHz;
* a bench run of hover_turbulence (20 s, the reference FC at a 1 kHz IMU) through the virtual bridge:
  IMU underruns per minute, late samples, and the host loop's lateness p99, on the machine as it is
  and with ``--load N`` busy processes beside it (the default: idle, then 2, about a ``make test``).

``python bench/bridge_rates.py [--load N] [--seconds S]``
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from rig.bridge.port import BridgePort  # noqa: E402
from rig.bridge.vbridge import VirtualBridge  # noqa: E402
from rig.run_cmd import resolve  # noqa: E402
from rig.runner import run  # noqa: E402
from rig.scenarios.schema import load  # noqa: E402
from rig.targets.bridge import BridgeTarget  # noqa: E402

HOG = "while True: pass"


def pct(xs: list[float], q: float) -> float:
    s = sorted(xs)
    return s[min(len(s) - 1, int(q * (len(s) - 1)))]


def link_latency(n: int = 2000) -> None:
    vb = VirtualBridge()
    port = BridgePort(vb.endpoints.link)
    try:
        port.hello()
        rtts: list[float] = []
        for k in range(n):
            t1 = time.monotonic_ns()
            port.send("TIME_SYNC", id=k, host_ns=t1)
            got = False
            while not got:
                for m in port.poll(0.5):
                    if m.name == "TIME_SYNC_REPLY" and int(m.values["id"]) == k:  # type: ignore[call-overload]
                        rtts.append((time.monotonic_ns() - t1) / 1e3)
                        got = True
            time.sleep(max(0.0, 0.001 - (time.monotonic_ns() - t1) / 1e9))
        print(f"link over the pty, {n} time-sync round trips at 1 kHz: p50 {pct(rtts, 0.5):.0f} us, "
              f"p99 {pct(rtts, 0.99):.0f} us, max {max(rtts):.0f} us (one way about half)")
    finally:
        port.close()
        vb.stop()


def bench_run(scenario: str, hogs: int) -> None:
    procs = [subprocess.Popen([sys.executable, "-c", HOG]) for _ in range(hogs)]
    try:
        r = run(load(resolve([scenario])[0]), BridgeTarget("virtual"))
    finally:
        for p in procs:
            p.kill()
            p.wait()
    meta = r.metadata
    b = meta["bridge"]
    assert isinstance(b, dict)
    st, lat = b["bridge_status"], meta["realtime_lateness"]
    assert isinstance(lat, dict)
    minutes = float(meta["sim_time"]) / 60
    imu, mag, baro = (u / minutes for u in st["underruns"])
    late, sent = st["late_samples"] / minutes, b["samples_sent"] / minutes
    print(f"  {scenario}, {hogs} busy process(es) beside it: verdict {r.verdict}; IMU underruns "
          f"{imu:.0f}/min (mag {mag:.0f}, baro {baro:.0f}); samples late at the "
          f"bridge {late:.0f}/min of {sent:.0f}/min; host loop "
          f"lateness p99 {lat['p99_s'] * 1e3:.2f} ms, worst {lat['max_s'] * 1e3:.1f} ms, "
          f"{lat['late_over_1ms']} of {lat['events']} events over 1 ms; time sync drift "
          f"{b['time_sync']['drift_ppm']:.1f} ppm, rtt p50 {b['time_sync']['rtt_p50_us']:.0f} us")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--load", type=int, action="append", help="busy processes beside the run (repeatable)")
    ap.add_argument("--scenario", default="hover_turbulence")
    args = ap.parse_args()
    link_latency()
    print("a bench run through the virtual bridge (the reference FC, IMU at 1 kHz):")
    for hogs in args.load or [0, 2]:
        bench_run(args.scenario, hogs)


if __name__ == "__main__":
    main()
