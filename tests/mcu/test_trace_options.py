"""Traces a person can keep: --trace-signals keeps the signals chosen, --trace-window the changes in a
sim time window (with the values at its start), --trace-gzip writes a .vcd.gz GTKWave opens, the same
VCD compressed. Judged against the whole trace of the same run, read by a VCD reader written here from
IEEE 1364 §18 (identifiers, #time, scalar and b-vector changes)."""

from __future__ import annotations

import gzip
import subprocess
import sys
from pathlib import Path

from tests.mcu.conftest import REPO, firmware


def changes(text: str) -> dict[str, list[tuple[int, str]]]:
    """scope.name -> [(time, value)] from a VCD's text, the $dumpvars values at time 0."""
    names: dict[str, str] = {}
    scope = ""
    out: dict[str, list[tuple[int, str]]] = {}
    t = 0
    for line in text.splitlines():
        words = line.split()
        if not words:
            continue
        if words[0] == "$scope":
            scope = words[2]
        elif words[0] == "$var":
            names[words[3]] = f"{scope}.{words[4]}"
            out[names[words[3]]] = []
        elif line.startswith("#"):
            t = int(line[1:])
        elif line[0] in "01xz" and line[1:] in names:
            out[names[line[1:]]].append((t, line[0]))
        elif line[0] == "b" and len(words) == 2 and words[1] in names:
            out[names[words[1]]].append((t, words[0][1:]))
    return out


def trace(tmp_path: Path, name: str, *options: str) -> Path:
    out = tmp_path / name
    fw = firmware("imu_reader", "atmega328p")
    done = subprocess.run([sys.executable, "-m", "rig.cli", "exec", "--mcu", "promini328-gy86", "--firmware",
                           str(fw), "--duration", "0.3", "--trace", str(out), *options],
                          capture_output=True, text=True, cwd=REPO, timeout=300)
    assert done.returncode == 0, done.stderr
    return out


def test_gzip_signals_and_window(tmp_path: Path) -> None:
    whole = (trace(tmp_path, "whole") / "imu_reader-atmega328p.vcd").read_text()
    packed = trace(tmp_path, "gz", "--trace-gzip") / "imu_reader-atmega328p.vcd.gz"
    assert gzip.decompress(packed.read_bytes()).decode() == whole
    assert len(packed.read_bytes()) * 5 < len(whole)  # (compressed: the run's VCD is repetitive)
    start, end = 100_000_000, 200_000_000
    cut = trace(tmp_path, "cut", "--trace-gzip", "--trace-signals", "m1,twi.byte",
                "--trace-window", "0.1:0.2")
    kept = changes(gzip.decompress((cut / "imu_reader-atmega328p.vcd.gz").read_bytes()).decode())
    full = changes(whole)
    assert set(kept) == {"motors.m1_PB1", "twi.byte"}
    for name, got in kept.items():
        before = [v for t, v in full[name] if t < start]
        inside = [(t, v) for t, v in full[name] if start <= t <= end]
        at_start = [] if before[-1:] == [full[name][0][1]] else [(start, before[-1])]
        assert got == [full[name][0]] + at_start + inside, name
    rises = [t for t, v in kept["motors.m1_PB1"] if v == "1" and t > 0]
    assert len(rises) == 40  # (400 Hz ESC pulses in 0.1 s)


def test_bad_trace_options_are_exit_2(tmp_path: Path) -> None:
    for options, words in ((["--trace-signals", "m9"], "no trace signal 'm9'"),
                           (["--trace-window", "2:1"], "START < END"),
                           (["--trace-window", "a:b"], "expected START:END")):
        done = subprocess.run([sys.executable, "-m", "rig.cli", "exec", "--mcu", "promini328-gy86",
                               "--firmware", str(firmware("imu_reader", "atmega328p")), "--duration", "0.1",
                               "--trace", str(tmp_path), *options], capture_output=True, text=True, cwd=REPO,
                              timeout=300)
        assert done.returncode == 2 and words in done.stderr, done.stderr
    done = subprocess.run([sys.executable, "-m", "rig.cli", "run", "--trace-gzip", "step_roll"],
                          capture_output=True, text=True, cwd=REPO, timeout=300)
    assert done.returncode == 2 and "--trace-gzip goes with --mcu" in done.stderr
