"""What a DUT does with its serial ports must not break the run: a DUT that never reads its RC port
(the line drops what does not fit, as a UART does, and the run goes on at full speed), and telemetry
that arrives in pieces or carries non-finite values."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from rig.runner import parse_telemetry, run
from rig.targets.process import ProcessTarget
from scenarios.schema import load

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
