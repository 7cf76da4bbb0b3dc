"""What a DUT does with its serial ports must not break the run: a DUT that never reads its RC port
(the line drops what does not fit, as a UART does, and the run goes on at full speed), and telemetry
that arrives in pieces or carries non-finite values."""

from __future__ import annotations

import math
import random
import sys
from pathlib import Path

import numpy as np
import pytest

from rig.runner import parse_telemetry, run
from rig.scenarios.schema import load
from rig.targets.process import ProcessTarget
from rig.telemetry import native, read_columns

LIB = Path(__file__).resolve().parents[2] / "scenarios" / "library"
#: stand-in firmware, each with the misbehaviour a test needs
DUTS = Path(__file__).resolve().parent / "misbehaving_firmware"


def test_a_dut_that_never_reads_its_rc_port_does_not_stall_the_run(tmp_path: Path) -> None:
    """The session used to wait up to a second per request once the pty was full (553 s of wall time
    for 10 sim-s) and, past 11.5 s, ended with BlockingIOError. 20 sim-s of SBUS is 36 kB, nine times
    the DUT's receive buffer."""
    r = run(load(LIB / "hover_turbulence.toml"), ProcessTarget([sys.executable, str(DUTS / "deaf_to_rc.py")]),
            work_dir=tmp_path, wall_timeout=60.0)
    assert r.verdict in ("pass", "fail"), r.error  # judged: not a watchdog, not an exception
    assert r.metadata["sim_time"] >= 20.0
    note = next(n for n in r.notes if n.startswith("/dev/ttyRC0:"))
    frames = math.floor(20.0 / 0.014) + 1  # a 25-byte frame every 14 ms from t = 0
    assert int(note.split()[1]) == 25 * frames - 4095  # all but what the DUT's buffer held


def test_telemetry_in_pieces_and_with_nan_values_is_kept(tmp_path: Path) -> None:
    sc = load(LIB / "step_roll.toml")
    r = run(sc, ProcessTarget([sys.executable, str(DUTS / "chunked_telemetry.py")]), work_dir=tmp_path)
    assert not any("did not parse" in n for n in r.notes), r.notes
    t, est_roll, est_alt = r.signals["t"], r.signals["est_roll"], r.signals["est_alt"]
    reported = np.isfinite(est_roll)
    assert reported.sum() > 0.8 * len(t) and np.all(est_roll[reported] == 1.5)  # every line reassembled
    assert np.isnan(est_alt[t > 2.0]).all()
    assert any(n.startswith("the DUT reported alt as not a number from sim t=") for n in r.notes)
    assert (tmp_path / "dut-telemetry.txt").read_bytes().count(b"\n") > 300  # kept as it came


def test_a_non_finite_value_leaves_the_rest_of_its_line() -> None:
    text = b"T t=1001.0 roll=2.0 pitch=1.0 yaw=3.0 alt=-nan armed=1\nT t=1002.0 roll=inf alt=1.5\njunk\n"
    cols, bad, nonfinite = parse_telemetry(text, 1000.0)
    assert bad == 1  # the junk line only
    assert cols["t"].tolist() == [1.0, 2.0]
    assert cols["roll"][0] == 2.0 and math.isnan(cols["roll"][1])
    assert math.isnan(cols["alt"][0]) and cols["alt"][1] == 1.5
    assert nonfinite == {"alt": 1.0, "roll": 2.0}


def _plain_reading(text: bytes, base: float) -> tuple[dict[str, list[float]], int, dict[str, float]]:
    """parse_telemetry's docstring read literally, as a second implementation: each line of ``T`` items
    into a dict of every item (split at its first ``=``)."""
    keys = ["roll", "pitch", "yaw", "alt", "armed"]
    cols: dict[str, list[float]] = {"t": [], **{k: [] for k in keys}}
    bad, nonfinite = 0, dict[str, float]()
    text = text[:text.rfind(b"\n") + 1]  # (a last line without its end: cut by the run's end)
    for line in text.decode("ascii", "replace").splitlines():
        if line.startswith("#"):
            continue
        if not line.startswith("T "):
            bad += bool(line.strip())
            continue
        try:
            items = dict(item.split("=", 1) for item in line[2:].split())
            t = float(items["t"]) - base
            values = {k: float(items[k]) for k in keys if k in items}
        except (ValueError, KeyError):
            bad += 1
            continue
        if not math.isfinite(t):
            bad += 1
            continue
        cols["t"].append(t)
        for k in keys:
            v = values.get(k, math.nan)
            if k in values and not math.isfinite(v):
                nonfinite.setdefault(k, t)
                v = math.nan
            cols[k].append(v)
    return cols, bad, nonfinite


def test_the_telemetry_parser_reads_what_a_plain_reading_reads() -> None:
    """Odd lines and two thousand random edits of a reference FC line: the same columns (NaN for NaN),
    the same count of lines that did not parse and the same first non-finite times."""
    good = "T t=1001.25 roll=0.123 pitch=-0.456 yaw=1.234 alt=1.500 armed=1 rc=1 loop_us=35 overruns=0"
    odd = [good, good.replace(" ", "\t"), good.replace(" ", "\x1c"), good + " roll=7", good + " bare",
           "T t=1 roll=1=2", "T =5 t=2", "T roll=1", "T t=nan", "T t=inf roll=1", "T t=3 alt=-inf yaw=NaN",
           "T t=4 roll==1", "T t=5 Roll=1 rolls=2 xroll=3", "T", "T  ", "Tt=1", "# fc: hello", "", "   ",
           "T t=6 pitch=1e400 armed=", "T t=0x10", "T t=7 rc=abc", "t=8 roll=1", "T t=9 roll=1\x85alt=2",
           "T t=1_0 roll=2_5", "T t=1__0", "T t=11 roll=1\x00", "T t=12\r\nT t=13\rT t=14\x1eT t=15",
           "T t=16 roll=\u00e9", "T t=17 r\u00e9=1 alt=2", "T t=" + "1" * 100, "T t=18 yaw=" + "0" * 80 + "1",
           "T t=19\x1froll=1", "\x1f \t", "T t=20 roll=INFINITY pitch=-Infinity yaw=+nan"]
    rng = random.Random(11)
    alphabet = " =.-+_eEtT#\t\x0b\r\x1c\x1f\x00naifrolpchyw0123456789x\u00e9"
    lines = list(odd)
    for _ in range(2000):
        chars = list(good)
        for _ in range(rng.randint(1, 4)):
            at = rng.randrange(len(chars))
            what = rng.randrange(3)
            if what == 0:
                del chars[at]
            elif what == 1:
                chars.insert(at, rng.choice(alphabet))
            else:
                chars[at] = rng.choice(alphabet)
        lines.append("".join(chars))
    text = "\n".join(lines).encode("utf-8")
    cols, bad, nonfinite = parse_telemetry(text, 1000.0)
    want_cols, want_bad, want_nonfinite = _plain_reading(text, 1000.0)
    assert (bad, nonfinite) == (want_bad, want_nonfinite)
    assert set(cols) == set(want_cols)
    for k, want in want_cols.items():
        assert np.array_equal(cols[k], np.array(want, dtype=float), equal_nan=True), k
    assert 300 < want_bad < 1900 and len(want_cols["t"]) > 300 and want_nonfinite  # every kind was met


def test_the_telemetry_reader_refuses_what_it_cannot_read() -> None:
    """Clear errors for arguments that are not text and keys (the C reader's own checks), and any
    buffer of bytes read alike."""
    with pytest.raises(TypeError):
        read_columns("T t=1", 0.0, ["roll"])  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="keys are str"):
        native().parse(b"T t=1", 0.0, ("t", 5))
    with pytest.raises(ValueError, match="keys"):
        native().parse(b"T t=1", 0.0, ())
    with pytest.raises(ValueError, match="keys"):
        native().parse(b"T t=1", 0.0, tuple(f"k{i}" for i in range(33)))
    text = b"T t=2.5 roll=1\nT t=3 roll=x\nT t=3.5 ro"
    for given in (text, bytearray(text), memoryview(text)):
        cols, bad, _ = read_columns(given, 0.5, ["roll"])
        assert (cols["t"].tolist(), cols["roll"].tolist(), bad) == ([2.0], [1.0], 1)  # (the cut line: unread)
