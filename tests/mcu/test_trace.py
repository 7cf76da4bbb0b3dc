"""The MCU tier's VCD traces and ``rig exec --mcu``: the writer's files, read back by an independent
reader (vcdvcd, from PyPI) and decoded by a small I2C decoder of the test's own (SCL rising samples SDA,
SDA falling / rising with SCL high is START / STOP), carry exactly the TWI records and the motor
pulses; a firmware's run traces the same bytes as its figures count; two runs give byte-identical
files; exec's exit statuses and usage errors."""

from __future__ import annotations

import io
import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import vcdvcd  # type: ignore[import-untyped]

from rig.mcu.engine import TwiRecord
from rig.mcu.vcd import McuTrace, Var, mcu_trace, write_vcd
from tests.mcu.conftest import REPO, firmware

# vcdvcd sets SIGPIPE to SIG_DFL when imported: in a pytest-xdist worker (every worker imports every
# test module) a later test writing to a child that had exited then killed the whole worker. Back to
# Python's own: ignored, a write to a closed pipe is an EPIPE error (tests/test_sigpipe.py)
signal.signal(signal.SIGPIPE, signal.SIG_IGN)


def read(path: Path) -> vcdvcd.VCDVCD:
    return vcdvcd.VCDVCD(str(path))


def i2c_decode(vcd: vcdvcd.VCDVCD) -> list[tuple[str, int, bool]]:
    """("S", 0, False), ("B", byte, acked), ("P", 0, False) from twi.scl and twi.sda."""
    changes: dict[int, dict[str, int]] = {}
    for name in ("scl", "sda"):
        for t, v in vcd[f"twi.{name}"].tv:
            changes.setdefault(t, {})[name] = int(v)
    scl = sda = 1
    bits: list[int] = []
    out: list[tuple[str, int, bool]] = []
    for t in sorted(changes):
        c = changes[t]
        assert len(c) == 1 or c["scl"] == scl or c["sda"] == sda, f"SCL and SDA change together at {t}"
        if "sda" in c and c["sda"] != sda and scl == 1:
            out.append(("S" if c["sda"] == 0 else "P", 0, False))
            bits = []
        if "scl" in c and c["scl"] == 1 and scl == 0 and out and out[-1][0] != "P":
            bits.append(c.get("sda", sda))
            if len(bits) == 9:
                out.append(("B", int("".join(map(str, bits[:8])), 2), bits[8] == 0))
                bits = []
        scl, sda = c.get("scl", scl), c.get("sda", sda)
    return out


def expected(records: list[TwiRecord]) -> list[tuple[str, int, bool]]:
    return [(r.kind, 0, False) if r.kind in "SP" else ("B", r.value, r.ack) for r in records]


RECORDS = [
    TwiRecord(10_000, "S", 0, False), TwiRecord(40_000, "A", 0x68 << 1, True),
    TwiRecord(70_000, "W", 0x3B, True), TwiRecord(80_000, "S", 0, False),
    TwiRecord(110_000, "A", 0x68 << 1 | 1, True), TwiRecord(140_000, "R", 0xA5, True),
    TwiRecord(141_000, "R", 0x00, False),  # (closer than a byte's bits at 400 kHz: drawn faster)
    TwiRecord(150_000, "P", 0, False),
    TwiRecord(200_000, "S", 0, False), TwiRecord(230_000, "A", 0x50 << 1, False),
    TwiRecord(240_000, "P", 0, False),
]


def test_the_twi_records_decode_back_from_scl_and_sda(tmp_path: Path) -> None:
    pulses = [[(5_000, 1_000_000, 2_040_000), (2_045_000, 1_500_000, 2_040_000)], []]
    path = tmp_path / "t.vcd"
    mcu_trace(path, RECORDS, pulses, ["m1_PE4", "m2_PE5"], 400_000)
    vcd = read(path)
    assert vcd.timescale["unit"] == "ns" and vcd.timescale["magnitude"] == 1
    assert i2c_decode(vcd) == expected(RECORDS)
    assert vcd["motors.m1_PE4"].tv == [(0, "0"), (5_000, "1"), (1_005_000, "0"), (2_045_000, "1"),
                                       (3_545_000, "0")]
    assert vcd["motors.m2_PE5"].tv == [(0, "0")]
    assert [(t, int(v, 2)) for t, v in vcd["twi.byte"].tv[1:]] == [
        (r.t_ns, r.value) for r in RECORDS if r.kind in "AWR"]
    assert vcd["twi.busy"].tv == [(0, "0"), (10_000, "1"), (150_000, "0"), (200_000, "1"), (240_000, "0")]


def test_a_trace_written_step_by_step_is_the_one_written_at_once(tmp_path: Path) -> None:
    """As the session writes it: 1 ms steps, each pulse reported in the step it ends in (its rise in an
    earlier one), the file written as the run goes; the same bytes as from all changes at once."""
    pulses = [(t, 1_500_000, 2_040_000) for t in range(100_000, 298_000_000, 2_040_000)]
    records = [TwiRecord(r.t_ns + k * 1_000_000, r.kind, r.value, r.ack) for k in range(0, 300, 7)
               for r in RECORDS]
    mcu_trace(tmp_path / "once.vcd", records, [pulses], ["m1_PE4"], 400_000)
    trace = McuTrace(tmp_path / "steps.vcd", ["m1_PE4"], 400_000)
    for step in range(1, 301):
        now = step * 1_000_000
        trace.add([r for r in records if now - 1_000_000 < r.t_ns <= now],
                  [[p for p in pulses if now - 1_000_000 < p[0] + p[1] <= now]], now)
    trace.close()
    once = (tmp_path / "once.vcd").read_bytes()
    assert (tmp_path / "steps.vcd").read_bytes() == once
    assert once.count(b"\n1&\n") == len(pulses)


def test_the_writer_orders_changes_and_drops_repeats() -> None:
    out = io.StringIO()
    write_vcd(out, [Var("a", "x"), Var("a", "v", 4, 0)], [(30, 0, 1), (10, 1, 3), (10, 1, 5), (20, 1, 5),
                                                          (30, 0, 0)])
    body = out.getvalue().split("$enddefinitions $end\n")[1]
    # (at 10 v is 3 then 5: the later wins; at 20 it is 5 already; at 30 x is 1 then 0: 0)
    assert body == '#0\n$dumpvars\nx!\nb0 "\n$end\n#10\nb101 "\n#30\n0!\n'
    with pytest.raises(ValueError, match="without spaces"):
        write_vcd(io.StringIO(), [Var("a", "two words")], [])


def rig_exec(*args: object) -> subprocess.CompletedProcess[bytes]:
    return subprocess.run([sys.executable, "-m", "rig.cli", "exec", *map(str, args)], capture_output=True,
                          timeout=600, cwd=REPO)



def test_exec_mcu_traces_what_its_figures_count_and_the_same_bytes_twice(avr_fc: Path,
                                                                         tmp_path: Path) -> None:
    runs = []
    for k in "ab":
        done = rig_exec("--mcu", "mega2560-gy86", "--firmware", avr_fc, "--duration", "1.2", "--seed", 1,
                        "--summary", tmp_path / f"{k}.json", "--trace", tmp_path / k)
        assert done.returncode == 0, done.stderr
        assert b"# fc: configuration: EEPROM image" in done.stdout  # its telemetry USART, on stdout
        runs.append(json.loads((tmp_path / f"{k}.json").read_text()))
    a, b = ((tmp_path / k / "fc.vcd").read_bytes() for k in "ab")
    assert a == b
    s = runs[0]
    assert s["verdict"] == "ok" and s["sim_time"] == 1.2 and s["realtime_factor"] > 0
    mcu = s["mcu"]
    # the run stops at the first instruction boundary at or past 1.2 s: past it by at most 4 cycles (the
    # longest an ATmega2560 instruction or interrupt entry takes is 5: its instruction set summary)
    assert 0 <= mcu["cycles"] - round(16e6 * 1.2) <= 4
    assert mcu["twi_nacks"] == 0 and mcu["twi_collisions"] == 0
    motors = ["m1_PE4", "m2_PE5", "m3_PE3", "m4_PH3"]
    check_trace_against_figures(read(tmp_path / "a" / "fc.vcd"), mcu, motors)


def check_trace_against_figures(vcd: vcdvcd.VCDVCD, mcu: dict, motors: list[str]) -> None:
    """A run's trace against its figures (either tier): the decoded STARTs followed by an address are the
    transactions counted, the bytes the transactions (their addresses) and the bytes counted, and each
    motor output (``motors``: the VCD's names) rises once for each pulse counted."""
    decoded = i2c_decode(vcd)
    starts = [i for i, d in enumerate(decoded) if d[0] == "S"]
    assert len(starts) >= mcu["twi_transactions"] > 100  # (a repeated START is a START, not a transfer)
    addresses = sum(1 for i in starts if i + 1 < len(decoded) and decoded[i + 1][0] == "B")
    assert addresses == mcu["twi_transactions"]
    assert sum(d[0] == "B" for d in decoded) == mcu["twi_transactions"] + mcu["twi_bytes"]
    for m, name in enumerate(motors):
        rises = sum(v == "1" for _, v in vcd[f"motors.{name}"].tv)
        assert rises == mcu["motor_pulses"][m] > 400


def test_run_mcu_traces_each_scenario_into_the_folder(avr_fc: Path, tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, "-m", "rig.cli", "run", "--mcu", "mega2560-gy86", "--firmware",
                           avr_fc, "--trace", tmp_path / "traces", "--out", tmp_path / "out",
                           "gust_rejection"],
                          capture_output=True, text=True, timeout=600, cwd=REPO)
    assert done.returncode == 0, done.stderr
    mcu = json.loads((tmp_path / "out" / "gust_rejection" / "result.json").read_text())["metadata"]["mcu"]
    assert mcu["trace"] == str(tmp_path / "traces" / "gust_rejection.vcd")
    vcd = read(tmp_path / "traces" / "gust_rejection.vcd")
    assert sum(d[0] == "B" for d in i2c_decode(vcd)) == mcu["twi_transactions"] + mcu["twi_bytes"]
    assert sum(v == "1" for _, v in vcd["motors.m1_PE4"].tv) == mcu["motor_pulses"][0]


def test_exec_mcu_a_crashing_firmware_is_125_with_where_and_when(tmp_path: Path) -> None:
    done = rig_exec("--mcu", "mega2560-gy86", "--firmware", firmware("wild_jump", "atmega2560"),
                    "--duration", "2", "--summary", tmp_path / "s.json")
    assert done.returncode == 125
    assert b"rig exec: error: the firmware crashed:" in done.stderr and b"pc 0x" in done.stderr
    assert json.loads((tmp_path / "s.json").read_text())["verdict"] == "error"


@pytest.mark.parametrize(
    ("args", "says"),
    [(["--firmware", "x.elf", "--duration", "1"], "goes with --mcu"),
     (["--mcu", "mega2560-gy86", "--duration", "1"], "--mcu needs --firmware"),
     (["--mcu", "mega2560-gy86", "--firmware", "F"], "--mcu needs --duration"),
     (["--mcu", "mega2560-gy86", "--firmware", "F", "--duration", "1", "--", "true"], "not a command"),
     (["--mcu", "mega2560-gy86", "--firmware", "F", "--duration", "1", "--realtime"], "not with --realtime"),
     (["--mcu", "nosuchboard", "--firmware", "F", "--duration", "1"], "--mcu:"),
     (["--mcu", "mega2560-gy86", "--firmware", "pyproject.toml", "--duration", "1"], "--mcu:")],
)
def test_exec_mcu_usage_errors_are_exit_2(avr_fc: Path, args: list[str], says: str) -> None:
    args = [str(avr_fc) if a == "F" else a for a in args]
    done = rig_exec(*args)
    assert done.returncode == 2, done.stderr
    assert says in done.stderr.decode()
