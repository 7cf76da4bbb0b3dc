"""`rig bridge probe` (rig/bridge/probe.py) against the virtual bridge, whose clock is the host's own
CLOCK_MONOTONIC in microseconds: so the probed bridge time can be checked against an independent truth,
and its link counts against what the probe sent."""

from __future__ import annotations

import json
import os
import pty
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from rig.bridge.firmware import firmware_hash
from rig.bridge.messages import PROTOCOL_VERSION
from rig.bridge.probe import Probe, probe
from rig.cli import main
from tests.bridge.tools import vbridge


@pytest.fixture(scope="module")
def built() -> Path:
    return vbridge()


def test_probe_of_the_virtual_bridge(built: Path) -> None:
    p = probe("virtual", syncs=8)
    assert isinstance(p, Probe) and p.port == "virtual"
    assert (p.bridge_id, p.protocol, p.clock_hz) == ("vbridge", PROTOCOL_VERSION, 1_000_000)
    assert p.firmware_sha256 == "00" * 8 and p.core_version == 1
    # the virtual bridge carries no firmware hash, and is this checkout's own build/vbridge: said so, not
    # "not this checkout's" as a board running other firmware would be
    assert p.checkout_sha256 == firmware_hash().hex() and "not this checkout's" not in p.lines()[1]
    assert p.lines()[1].endswith("(the virtual bridge: this checkout's build/vbridge, no firmware image)")
    assert p.clock["exchanges"] == 8 and p.clock["rejected"] == 0 and 0 < p.clock["rtt_p50_us"]
    # the virtual bridge counts CLOCK_MONOTONIC microseconds: the mapped bridge time is the host's
    assert abs(float(p.clock["bridge_us"]) - time.monotonic_ns() / 1000) < 500_000
    s, h = p.status, p.host
    assert s["frames_bad"] == 0 and s["seq_gaps"] == 0 and s["refused"] == 0 and s["host_silent"] == 0
    assert 1 + 8 <= int(s["frames_ok"]) <= int(h["frames_sent"])  # type: ignore[call-overload]
    assert h["frames_bad"] == 0 and int(h["frames_received"]) >= 1 + 8 + 1  # type: ignore[call-overload]


def test_a_bridge_running_this_checkouts_firmware_is_named_so() -> None:
    p = Probe("/dev/ttyACM0", "stm32g431", 1, 1, firmware_hash().hex(), 170_000_000,
              checkout_sha256=firmware_hash().hex())
    assert p.lines()[1].endswith(f"firmware {firmware_hash().hex()} (this checkout's)")
    assert Probe("x", firmware_sha256="ab" * 8).lines()[1].endswith("firmware " + "ab" * 8)  # cannot tell


def test_the_command_prints_the_probe_and_json(built: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bridge", "probe", "virtual", "--syncs", "4"]) == 0
    text = capsys.readouterr().out
    assert text.startswith("bridge   vbridge on virtual\n") and "frames ok" in text and "drift" in text
    assert main(["bridge", "probe", "virtual", "--syncs", "2", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["bridge_id"] == "vbridge" and got["clock"]["exchanges"] == 2
    assert got["status"]["frames_ok"] >= 3


@pytest.fixture
def silent_port() -> Iterator[str]:
    master, slave = pty.openpty()
    name = os.ttyname(slave)
    os.close(slave)
    yield name
    os.close(master)


def test_a_port_where_nothing_answers_is_a_clear_error(silent_port: str,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bridge", "probe", silent_port]) == 1
    # (the port's own silence rule speaks first: half a second without a frame)
    assert f"the bridge on {silent_port} sent no valid frame" in capsys.readouterr().err
    assert main(["bridge", "probe", "/nonexistent/ttyACM9"]) == 1
    assert "cannot open the bridge's port /nonexistent/ttyACM9" in capsys.readouterr().err
    assert main(["bridge", "probe", silent_port, "--syncs", "0"]) == 2
    # no unbounded probe: 100000 exchanges 25 ms apart took 40 minutes
    assert main(["bridge", "probe", silent_port, "--syncs", "100000"]) == 2
    assert "--syncs: expected 1..1000 (25 ms each), got 100000" in capsys.readouterr().err
