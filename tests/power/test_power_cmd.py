"""``rig power`` as a user runs it (a real process), against the simulated supplies on ptys."""

from __future__ import annotations

import subprocess
import sys

from tests.power.sim_supplies import SimKorad, SimRiden


def rig(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rig.cli", *args], capture_output=True, text=True,
                          timeout=60)


def test_status_on_off_cycle_on_a_riden() -> None:
    s = SimRiden()
    try:
        spec = f"riden:{s.path}@115200"
        r = rig("power", "status", "--psu", spec)
        assert r.returncode == 0, r.stderr
        assert "Riden RD6006" in r.stdout
        assert "output off: 0.000 V, 0.0000 A (set 12.000 V, limit 2.0000 A" in r.stdout
        r = rig("power", "on", "--psu", spec, "--volts", "7.4")
        assert r.returncode == 0, r.stderr
        assert "output on: 7.400 V, 0.3500 A" in r.stdout
        r = rig("power", "cycle", "--psu", spec, "--off-s", "0")
        assert r.returncode == 0, r.stderr
        r = rig("power", "off", "--psu", spec)
        assert r.returncode == 0 and "output off" in r.stdout
        assert s.writes() == [(8, 740), (18, 1), (18, 0), (18, 1), (18, 0)]
    finally:
        s.close()


def test_korad_status() -> None:
    s = SimKorad()
    try:
        r = rig("power", "status", "--psu", f"korad:{s.path}")
        assert r.returncode == 0, r.stderr
        assert "KORAD KA3005P" in r.stdout and "output off" in r.stdout
    finally:
        s.close()


def test_bad_usage_and_a_silent_supply() -> None:
    r = rig("power", "status", "--psu", "owon:/dev/x")
    assert r.returncode == 2 and "MAKE one of riden, korad" in r.stderr
    s = SimRiden()
    s.mode = "bad_crc"
    try:
        r = rig("power", "status", "--psu", f"riden:{s.path}", "--timeout", "0.2")
        assert r.returncode == 3 and "no valid answer" in r.stderr and "Traceback" not in r.stderr
    finally:
        s.close()
