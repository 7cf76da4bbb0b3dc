"""PWM capture: the codecs against independent truth (the CRC check value, cantools' own decoding,
COBS framing), and the CAN and serial paths flying the same scenario as the direct path within the
capture resolution; corrupted frames are rejected and counted, never applied."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rig.emulators.pwm_capture import (
    CanCodec,
    CaptureFrameError,
    SerialDeframer,
    crc16,
    decode_serial,
    encode_serial,
)
from rig.runner import run
from rig.scenarios.schema import Capture, load
from rig.targets.process import ProcessTarget

LIB = Path(__file__).resolve().parents[2] / "scenarios" / "library"


def test_crc16_is_ccitt_false() -> None:
    assert crc16(b"123456789") == 0x29B1  # the catalogue check value of CRC-16/CCITT-FALSE


def test_can_frames_follow_the_dbc() -> None:
    codec = CanCodec()
    frames = codec.encode(9, [1511.0, 1000.0, 1999.9, 1234.5])
    assert [fid for fid, _ in frames] == [0x210, 0x211]
    fid, data = frames[0]
    assert int.from_bytes(data[0:2], "little") == 15110 and data[4] == 9  # 0.1 us units, seq byte
    assert codec.decode(*frames[1]) == (2, 9, [1999.9, 1234.5])
    bad = bytearray(data)
    bad[1] ^= 0x01
    with pytest.raises(CaptureFrameError, match="CRC"):
        codec.decode(fid, bytes(bad))
    with pytest.raises(CaptureFrameError, match="unknown CAN id"):
        codec.decode(0x300, data)


def test_serial_frames_are_cobs_with_crc_and_split_across_reads() -> None:
    stream = encode_serial(1, [1500.0, 1600.0, 1700.0, 1800.0]) + encode_serial(2, [1000.0] * 4)
    assert stream.count(0) == 2  # COBS leaves zeros only as delimiters
    d = SerialDeframer()
    frames = d.feed(stream[:7]) + d.feed(stream[7:])
    assert [decode_serial(f)[0] for f in frames] == [1, 2]
    assert decode_serial(frames[0])[1] == [1500.0, 1600.0, 1700.0, 1800.0]
    corrupt = bytearray(frames[0])
    corrupt[5] ^= 0x40
    with pytest.raises(CaptureFrameError):
        decode_serial(bytes(corrupt))


@pytest.fixture(scope="module")
def direct(tmp_path_factory: pytest.TempPathFactory) -> object:
    return run(load(LIB / "step_roll.toml"), work_dir=tmp_path_factory.mktemp("direct"))


@pytest.mark.parametrize("transport", ["can", "serial"])
def test_capture_paths_fly_like_the_direct_path(direct: object, transport: str, tmp_path: Path) -> None:
    sc = dataclasses.replace(load(LIB / "step_roll.toml"), capture=Capture(transport, 1.0, 1000.0, 0.0))
    r = run(sc, work_dir=tmp_path)
    stats = r.metadata["capture_stats"]
    assert r.verdict == "pass" and stats["frames_rejected"] == 0 and stats["sequence_gaps"] == 0
    assert stats["max_quantisation_us"] <= 0.5 + 1e-9  # within the resolution
    roll_a, roll_b = direct.signals["roll"], r.signals["roll"]  # type: ignore[attr-defined]
    assert np.max(np.abs(roll_a - roll_b)) < 0.5  # degrees: the same flight
    assert np.max(np.abs(direct.signals["pwm1"][600:] - r.signals["pwm1"][600:])) < 15  # type: ignore[attr-defined]


@pytest.mark.parametrize("transport", ["can", "serial"])
def test_corrupted_frames_are_rejected_and_counted(transport: str, tmp_path: Path) -> None:
    sc = dataclasses.replace(load(LIB / "step_roll.toml"), capture=Capture(transport, 1.0, 400.0, 0.0))
    r = run(sc, ProcessTarget(corrupt_every=50), work_dir=tmp_path)
    stats = r.metadata["capture_stats"]
    frames_per_report = 2 if transport == "can" else 1
    assert stats["frames_rejected"] == stats["frames_sent"] // 50
    assert stats["frames_applied"] == stats["frames_sent"] - stats["frames_rejected"]
    assert stats["frames_sent"] >= frames_per_report * 400 * (sc.duration - 0.1)  # every report travelled
    assert r.verdict == "pass"  # a lost frame is survivable


def test_a_named_can_channel_carries_the_frames(tmp_path: Path) -> None:
    """The bench form of the CAN link (interface + channel), on python-can's virtual interface: the
    frames travel on the channel given, and a listener on that channel hears the DBC's frame ids."""
    import can

    channel = f"rig-test-{tmp_path.name}"
    listener = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
    try:
        cap = Capture("can", 1.0, 400.0, 0.0, can_interface="virtual", can_channel=channel)
        sc = dataclasses.replace(load(LIB / "step_roll.toml"), duration=2.0, capture=cap, criteria=())
        r = run(sc, work_dir=tmp_path)
        heard = {m.arbitration_id for m in iter(lambda: listener.recv(timeout=0), None)}
    finally:
        listener.shutdown()
    assert r.verdict in ("pass", "fail") and r.metadata["capture_stats"]["frames_applied"] > 0
    assert heard == {0x210, 0x211}


def test_a_can_interface_that_cannot_open_is_a_clear_usage_error(tmp_path: Path) -> None:
    """SocketCAN with a channel this machine does not have (no can0 on CI): `rig run --can` names the
    interface and channel and exits 2 before anything runs, with no traceback."""
    sc = tmp_path / "can_step.toml"
    sc.write_text((LIB / "step_roll.toml").read_text() + '\n[capture]\ntransport = "can"\n')
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "rig.cli",
            "run",
            str(sc),
            "--out",
            str(tmp_path / "out"),
            "--can",
            "socketcan:rignosuchcan0",
        ],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 2, done.stderr
    assert "cannot open CAN interface 'socketcan' channel 'rignosuchcan0'" in done.stderr
    assert "Traceback" not in done.stderr
    bad = subprocess.run(
        [sys.executable, "-m", "rig.cli", "run", str(sc), "--can", "can0"], capture_output=True, text=True
    )
    assert bad.returncode == 2 and "expected INTERFACE:CHANNEL" in bad.stderr



def test_every_transport_a_scenario_may_name_has_a_registered_class() -> None:
    from rig.capture import TRANSPORTS, CaptureTransport
    from rig.emulators.pwm_capture import TRANSPORTS as NAMED

    assert set(TRANSPORTS) == set(NAMED)
    assert all(issubclass(cls, CaptureTransport) and cls.name == name for name, cls in TRANSPORTS.items())
