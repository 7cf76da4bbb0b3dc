"""The mailbox (rig/shim/ring.h): in lockstep a DUT process's messages go through shared memory in place
of its socket. It changes only how fast a run goes: the same flight gives the same signals, measurements
and I2C log through either; a second implementation of the DUT's side (device_clients/mailbox_client.py,
from the documented layout) is served across both rings' ends; and a broken ring costs only its own
connection."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from rig.scheduler import EXIT_WATCHDOG
from rig.session import TRANSPORT_ENV
from tests.rig.helpers import DUTS, PY, assert_same_flight, rig_exec

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
    from rig import scenarios
    from rig.runner import run
    from rig.scenarios.schema import load
    from rig.targets.process import ProcessTarget

    library = Path(scenarios.__file__).parent / "library"
    sc = dataclasses.replace(load(library / "step_roll.toml"), duration=3.0)
    mailbox = run(sc, ProcessTarget(), seed=1, work_dir=tmp_path / "mailbox")
    monkeypatch.setenv(TRANSPORT_ENV, "socket")
    sock = run(sc, ProcessTarget(), seed=1, work_dir=tmp_path / "socket")
    assert_same_flight(mailbox, sock)
    # result.json says which it was: every connection of the FC had a mailbox, or none
    used, kept = mailbox.metadata["transport"], sock.metadata["transport"]
    assert used["connections"] == kept["connections"] >= 1
    assert (used["mailboxes"], kept["mailboxes"]) == (used["connections"], 0)
    assert used["spin"] is kept["spin"] is False


def test_a_second_implementation_is_served_across_both_rings_ends(tmp_path: Path) -> None:
    run = rig_exec(tmp_path, PY, str(DUTS / "mailbox_client.py"), "wrap")
    assert run.returncode == 0, run.stderr
    sealed, seen, who = run.stdout.splitlines()
    assert sealed == "sealed"
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
    # sealed: a mailbox shrunk under the session would have been a SIGBUS in it; then the broken head
    # dropped this connection, and the shim's own connection was still served
    assert run.stdout.split() == ["sealed", "closed", "0x68"]
    assert len(run.summary["malformed"]) == 1
    assert "its mailbox is broken" in run.summary["malformed"][0]


def test_a_message_on_the_socket_of_a_mailbox_is_malformed(tmp_path: Path) -> None:
    # a process that lost the mailbox's descriptor (at its limit of open files) and talks on the socket:
    # its bytes are not taken for bells and dropped unseen (it would wait for ever for its reply)
    run = rig_exec(tmp_path, PY, str(DUTS / "mailbox_client.py"), "nofd")
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["closed", "0x68"]
    assert len(run.summary["malformed"]) == 1
    assert "bytes other than bells" in run.summary["malformed"][0]


def test_a_dut_that_floods_its_mailbox_still_meets_the_watchdog(tmp_path: Path) -> None:
    # every request is one the fast path takes in C, and the ring is never empty: pump still hands back
    # to the loop within its budget, whose wall-time watchdog ends the run
    run = rig_exec(tmp_path, PY, str(DUTS / "mailbox_client.py"), "flood",
                   options=("--duration", "3600", "--wall-timeout", "2"))
    assert run.returncode == EXIT_WATCHDOG, run.stderr
    assert "wall-time watchdog" in run.stderr


AT_THE_LIMIT = """
import os, resource
from smbus2 import SMBus
top = max(int(f) for f in os.listdir("/proc/self/fd"))  # (the listing's own descriptor is free again)
resource.setrlimit(resource.RLIMIT_NOFILE, (top + 2, resource.getrlimit(resource.RLIMIT_NOFILE)[1]))
with SMBus(1) as bus:  # two descriptors left: the device's and the socket's; none for a mailbox
    who = bus.read_byte_data(0x68, 0x75)
print(hex(who), 'rig-mailbox' in open('/proc/self/maps').read())
"""


def test_a_process_at_its_limit_of_open_files_talks_through_its_socket(tmp_path: Path) -> None:
    run = rig_exec(tmp_path, PY, "-c", AT_THE_LIMIT)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["0x68", "False"]
    assert run.summary["notes"] == ["a mailbox's descriptor did not reach this process (at its limit of open "
                                    "files?): its messages go through the socket"]
    assert run.summary["malformed"] == []
