"""The mailbox (rig/shim/ring.h): in lockstep a DUT process's messages go through shared memory in place
of its socket. It changes only how fast a run goes: the same flight gives the same signals, measurements
and I2C log through either; a second implementation of the DUT's side (device_clients/mailbox_client.py,
from the documented layout) is served across both rings' ends; and a broken ring costs only its own
connection."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from rig.session import TRANSPORT_ENV
from tests.rig.helpers import DUTS, PY, rig_exec

TOUCH_BUS = "from smbus2 import SMBus; b = SMBus(1); b.read_byte_data(0x68, 0x75); "
MAPPED = TOUCH_BUS + "print('rig-mailbox' in open('/proc/self/maps').read())"
RING = 1 << 20


def test_a_lockstep_program_has_a_mailbox_unless_told_otherwise(tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    lockstep = rig_exec(tmp_path, PY, "-c", MAPPED)
    realtime = rig_exec(tmp_path, PY, "-c", MAPPED, options=("--realtime",))
    assert lockstep.returncode == realtime.returncode == 0, lockstep.stderr + realtime.stderr
    assert (lockstep.stdout.strip(), realtime.stdout.strip()) == ("True", "False")
    monkeypatch.setenv(TRANSPORT_ENV, "socket")
    socket_only = rig_exec(tmp_path, PY, "-c", MAPPED)
    assert socket_only.returncode == 0 and socket_only.stdout.strip() == "False"


def test_a_flight_through_the_mailbox_is_the_flight_through_the_socket(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import scenarios
    from rig.runner import run
    from rig.targets.process import ProcessTarget
    from scenarios.schema import load

    library = Path(scenarios.__file__).parent / "library"
    sc = dataclasses.replace(load(library / "step_roll.toml"), duration=3.0)
    mailbox = run(sc, ProcessTarget(), seed=1, work_dir=tmp_path / "mailbox")
    monkeypatch.setenv(TRANSPORT_ENV, "socket")
    sock = run(sc, ProcessTarget(), seed=1, work_dir=tmp_path / "socket")
    assert mailbox.verdict == sock.verdict and mailbox.error is None is sock.error
    assert [dataclasses.astuple(m) for m in mailbox.measurements] == [
        dataclasses.astuple(m) for m in sock.measurements]
    assert mailbox.signals.keys() == sock.signals.keys()
    for name, values in mailbox.signals.items():
        assert np.array_equal(values, sock.signals[name], equal_nan=True), name
    assert mailbox.i2c is not None and len(mailbox.i2c) > 1000 and mailbox.i2c == sock.i2c
    assert mailbox.rc_frames == sock.rc_frames


def test_a_second_implementation_is_served_across_both_rings_ends(tmp_path: Path) -> None:
    run = rig_exec(tmp_path, PY, str(DUTS / "mailbox_client.py"), "wrap")
    assert run.returncode == 0, run.stderr
    seen, who = run.stdout.splitlines()
    words = seen.split()
    assert words[:4] == ["reads", "300", "absent", "300"]   # every 8 KB read whole, every NACK seen
    up, down = int(words[5]), int(words[7])
    assert up > 2 * RING and down > 2 * RING                # each ring went round twice
    assert words[8] == "across" and int(words[9]) >= 2 and int(words[10]) >= 2  # a header across its end
    assert who == "0x68"
    assert run.summary["transactions"] == 601
    assert all(note == "p" * 300 for note in run.summary["notes"])  # the padding, as it was sent


def test_a_broken_mailbox_costs_only_its_connection(tmp_path: Path) -> None:
    run = rig_exec(tmp_path, PY, str(DUTS / "mailbox_client.py"), "broken")
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["closed", "0x68"]          # dropped; the shim's connection still served
    assert len(run.summary["malformed"]) == 1
    assert "its mailbox is broken" in run.summary["malformed"][0]
