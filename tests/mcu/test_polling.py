"""The polling-loop skip (rig/mcu/polling.c) changes nothing but the engine's speed: a firmware of ours
waiting in each kind of polling loop (a timer's overflow flag, a 16-bit and an 8-bit timer counter, a flag
in RAM an interrupt sets, TWINT, UDRE, RXC, an input pin, TWINT with a count that gives up, as MultiWii
waits, when the byte ends first and when the count runs out) gives, with the skip on and off, the same USART
bytes in the same 1 ms steps, the same figures (cycles, instructions, program counter, stack pointer) and
the same data space, byte for byte, at the end; with it on, the loops were skipped (and rig exec's
summary says how much). The reference FC flying a scenario writes the same trace, EEPROM and result.json
either way (but its wall-clock fields: when it started, how long it took, the real-time factor). The
expected times are the datasheet's timer periods and the pin's edges."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from rig.mcu.engine import POLL_SKIP_ENV, AvrEngine, EngineConfig
from tests.mcu.conftest import MCUS, REPO, firmware

CLOCK = 16_000_000
BAUD = CLOCK // (16 * 9)  #: UBRR0 = 8
RAMEND = {"atmega328p": 0x8FF, "atmega2560": 0x21FF}
MS = 1_000_000


Run = tuple[list[bytes], dict[str, object], bytes, dict[str, int]]


#: mode 5's pin: PD3 high at 10.5 ms, low at 20.25 ms, high at 40 ms
EDGES = [(10_500_000, 1), (20_250_000, 0), (40_000_000, 1)]


def fly(mcu: str, mode: int, skip: bool, ms: int = 60, sends: tuple[tuple[int, bytes], ...] = ()) -> Run:
    """poll_loops in ``mode`` for ``ms`` 1 ms steps: the USART0 bytes of each step, the figures, the data
    space at the end, what the skip did. ``sends``: (step, bytes) into USART0 at that step's start; mode
    5 has EDGES on PD3."""
    cfg = EngineConfig(mcu, CLOCK, firmware("poll_loops", mcu), eeprom=bytes([mode]), poll_skip=skip,
                       hang_ns=0)
    with AvrEngine(cfg, None) as e:
        if mode == 5:
            e.pin_drive("PD3", EDGES)
        steps = []
        for k in range(ms):
            for at, data in sends:
                if at == k:
                    e.uart_send(0, data, BAUD)
            assert e.run_until((k + 1) * MS).kind == "reached"
            steps.append(e.uart_take(0))
        figures = {k: v for k, v in e.figures().items() if k != "sim_ns"}
        memory = bytes(e.peek(a) for a in range(RAMEND[mcu] + 1))
        return steps, figures, memory, e.poll_figures()


def steps_with(steps: list[bytes], marker: bytes) -> list[int]:
    return [i for i, got in enumerate(steps) if marker in got]


@pytest.mark.parametrize("mcu", MCUS)
@pytest.mark.parametrize("mode", [0, 1, 2, 3, 4, 5, 6, 7])
def test_a_polling_loop_skipped_is_the_same_run(mcu: str, mode: int) -> None:
    sends = ((5, b"ab"), (20, b"xyz")) if mode == 4 else ()
    on = fly(mcu, mode, True, sends=sends)
    off = fly(mcu, mode, False, sends=sends)
    assert on[0] == off[0]
    assert on[1] == off[1]
    assert on[2] == off[2]
    assert off[3]["skips"] == 0
    assert on[3]["skips"] > 0 and on[3]["skipped_cycles"] > 0 and on[3]["mismatches"] == 0
    steps = on[0]
    assert steps[0].startswith(b"%d" % mode)
    if mode == 0:  # TOV2 every 256 * 64 cycles: 'T' every 10 overflows, 10.24 ms
        want = [int(10.24 * k) for k in range(1, 6)]
        assert all(got - w in (0, 1) for got, w in zip(steps_with(steps, b"T"), want, strict=True))
    elif mode == 1:  # 5000 counts at clk/8: 2.5 ms; then TCNT0 to 200 at clk/256: 3.2 ms more
        assert steps_with(steps, b"C")[0] == 2 and steps_with(steps, b"c")[0] == 5
    elif mode == 2:  # OCR1A 9999 at clk/8: every 5 ms
        assert steps_with(steps, b"F") == list(range(5, 60, 5))
    elif mode == 3:  # SLA+W not acknowledged: status 0x20 (datasheet, master transmitter)
        assert len(steps_with(steps, b"W\x20")) > 10
    elif mode == 4:
        assert b"".join(steps[5:25]) == b"ab" + b"xyz"
    elif mode == 6:  # the byte (9 SCL periods of 16 + 2 * TWBR cycles) ends before 255 polls of 5-8 cycles
        sent = b"".join(steps)[1:]
        waits = [sent[i:i + 3] for i in range(0, len(sent) - 2, 3)]
        byte_cycles = 9 * (16 + 2 * 12)
        polls_left = range(255 - byte_cycles // 5, 255 - byte_cycles // 8 + 1)
        assert len(waits) > 10 and all(w[:2] == b"w\x20" and w[2] in polls_left for w in waits)
    elif mode == 7:  # the count runs out every time: the waits given up are counted 1, 2, 3... (a byte)
        sent = b"".join(steps)[1:]
        counted = b"".join(b"e" + bytes([n % 256]) for n in range(1, len(sent) // 2 + 1))
        assert len(sent) > 20 and sent[: len(counted)] == counted
    else:  # each edge answered in the step it falls in
        assert steps_with(steps, b"P") == [10, 40] and steps_with(steps, b"p") == [20]


def test_the_skip_is_off_with_the_environment_variable(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(POLL_SKIP_ENV, "0")
    cfg = EngineConfig("atmega2560", CLOCK, firmware("poll_loops", "atmega2560"), eeprom=bytes([2]),
                       hang_ns=0)
    with AvrEngine(cfg, None) as e:
        assert e.run_until(30 * MS).kind == "reached"
        assert e.poll_figures()["skips"] == 0
    monkeypatch.setenv(POLL_SKIP_ENV, "1")
    with AvrEngine(cfg, None) as e:
        assert e.run_until(30 * MS).kind == "reached"
        assert e.poll_figures()["skips"] > 0


def test_the_reference_fc_flies_the_same_bytes_with_the_skip_on_and_off(avr_fc: Path, tmp_path: Path) -> None:
    out, traces = tmp_path / "out", tmp_path / "traces"
    kept = {}
    for skip in ("0", "1"):
        done = subprocess.run([sys.executable, "-m", "rig.cli", "run", "--mcu", "mega2560-gy86", "--firmware",
                               avr_fc, "--trace", traces, "--out", out, "step_roll"],
                              capture_output=True, text=True, timeout=600, cwd=REPO,
                              env={**os.environ, POLL_SKIP_ENV: skip})
        assert done.returncode == 0, done.stderr
        result = json.loads((out / "step_roll" / "result.json").read_text())
        for wall_clock in ("started", "wall_time", "realtime_factor"):  # (what two runs never share)
            result["metadata"].pop(wall_clock)
        kept[skip] = (result, (traces / "step_roll.vcd").read_bytes(),
                      (out / "step_roll" / "eeprom.bin").read_bytes())
        shutil.rmtree(out)
        shutil.rmtree(traces)
    assert kept["0"] == kept["1"]
    assert kept["1"][0]["verdict"] == "pass"


def test_exec_summary_says_what_the_skip_did(avr_fc: Path, tmp_path: Path) -> None:
    done = subprocess.run([sys.executable, "-m", "rig.cli", "exec", "--mcu", "mega2560-gy86", "--firmware",
                           avr_fc, "--duration", "1.5", "--summary", tmp_path / "s.json"],
                          capture_output=True, timeout=600, cwd=REPO, env={**os.environ, POLL_SKIP_ENV: "1"})
    assert done.returncode == 0, done.stderr
    skip = json.loads((tmp_path / "s.json").read_text())["poll_skip"]
    assert skip["skipped_cycles"] > 0 and skip["skips"] > 0 and skip["mismatches"] == 0
