"""The virtual bridge (build/vbridge: the bridge core as a Linux process) driven as a host drives a bench
bridge: over its pty with pyserial and the link's Python codec, with real shimmed processes (i2c-tools,
a shell writing sysfs PWM) as the board. Hello and version; streamed IMU samples read back as register
bytes; a bus-NACK fault; a host that stops streaming; malformed frames; PWM writes as captured pulses;
SBUS channels as frames on the RC pty. Waits are on events (a message arriving, a process ending), each
with a generous bound."""

from __future__ import annotations

import os
import select
import shutil
import signal
import struct
import subprocess
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import serial

from rig.bridge.link import Decoded, Receiver, encode
from rig.bridge.messages import PROTOCOL_VERSION
from rig.emulators import sbus
from tests.bridge.tools import REPO, vbridge
from tests.suite_rules import NOT_BUILT
from tests.waits import BOUND_S, wait_gone

SHIM = REPO / "build" / "librigshim.so"
G = 9.80665
I2C_TOOLS = "/usr/sbin"


def endpoints(line: str) -> dict[str, str]:
    """`vbridge link=… board=… shm=… rc=… can=… fakes=… pid=…` as a dict."""
    head, *pairs = line.split()
    assert head == "vbridge"
    return dict(p.split("=", 1) for p in pairs)


class Host:
    """The host's end of the link: frames out with a sequence, messages in, waited for by content."""

    def __init__(self, path: str) -> None:
        self.port = serial.Serial(path, baudrate=2_000_000, timeout=0)
        self.rx = Receiver("up")
        self.got: list[Decoded] = []
        self.seq = 0

    def send(self, name: str, **values: object) -> None:
        self.raw(encode(name, self.seq, **values))
        self.seq += 1

    def raw(self, wire: bytes) -> None:
        self.port.write(wire)
        self.port.flush()

    def wait(self, name: str, pred: Callable[[dict[str, object]], bool] = lambda v: True,
             bound: float = BOUND_S) -> dict[str, object]:
        """The first message ``name`` from now on that satisfies ``pred``."""
        start = len(self.got)
        deadline = time.monotonic() + bound
        while True:
            for m in self.got[start:]:
                if m.name == name and pred(m.values):
                    return m.values
            start = len(self.got)
            left = deadline - time.monotonic()
            assert left > 0, f"no {name} as expected within {bound} s; last: {self.got[-3:]}"
            ready, _, _ = select.select([self.port.fileno()], [], [], left)
            if ready:
                self.got += self.rx.feed(self.port.read(4096))

    def now_us(self) -> int:
        """The bridge's clock, by a time-sync exchange (vbridge's clock is this machine's monotonic)."""
        probe = int.from_bytes(os.urandom(4), "little")
        self.send("TIME_SYNC", id=probe, host_ns=time.monotonic_ns())
        reply = self.wait("TIME_SYNC_REPLY", lambda v: v["id"] == probe)
        tx = reply["tx_us"]
        assert isinstance(tx, int)
        return tx

    def close(self) -> None:
        self.port.close()


class VBridge:
    def __init__(self, proc: subprocess.Popen[bytes], ends: dict[str, str]) -> None:
        self.proc, self.ends = proc, ends
        self.host = Host(ends["link"])

    def dut_env(self) -> dict[str, str]:
        env = dict(os.environ)
        env.update({"LD_PRELOAD": str(SHIM), "RIG_SOCKET": self.ends["board"], "RIG_SHM": self.ends["shm"],
                    "RIG_LOCKSTEP": "0", "RIG_I2C_BUSES": "1", "RIG_PWM_CHIP": "0",
                    "RIG_SERIAL": f"/dev/ttyRC0={self.ends['rc']}", "RIG_FAKES": self.ends["fakes"]})
        return env

    def dut(self, *argv: str) -> subprocess.CompletedProcess[str]:
        """A program as the board: it runs under the shim against this bridge, to its end."""
        return subprocess.run(list(argv), env=self.dut_env(), capture_output=True, text=True, timeout=BOUND_S)


def start_vbridge() -> tuple[subprocess.Popen[bytes], dict[str, str]]:
    proc = subprocess.Popen([str(vbridge())], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdout is not None
    ready, _, _ = select.select([proc.stdout], [], [], BOUND_S)
    assert ready, "vbridge printed no endpoints line"
    return proc, endpoints(proc.stdout.readline().decode())


@pytest.fixture
def vb() -> Iterator[VBridge]:
    if not SHIM.is_file():
        pytest.skip(f"{NOT_BUILT}build/librigshim.so (make shim)")
    proc, ends = start_vbridge()
    v = VBridge(proc, ends)
    try:
        v.host.send("HELLO", version=PROTOCOL_VERSION, nonce=1)
        v.host.wait("HELLO_REPLY")
        yield v
    finally:
        v.host.close()
        proc.send_signal(signal.SIGTERM)
        assert wait_gone(proc.pid) and proc.wait() == 0
        assert not Path(ends["board"]).parent.exists()  # its folder went with it


def i2c(vb: VBridge, *argv: str) -> subprocess.CompletedProcess[str]:
    return vb.dut(f"{I2C_TOOLS}/{argv[0]}", *argv[1:])


def wake_mpu(vb: VBridge) -> None:
    for reg, value in ((0x1A, 0x01), (0x6B, 0x00)):  # DLPF 1 (1 kHz sampling), out of sleep
        assert i2c(vb, "i2cset", "-y", "1", "0x68", hex(reg), hex(value)).returncode == 0


def stream_imu(vb: VBridge, accel: tuple[float, float, float], gyro: tuple[float, float, float],
               temp_c: float, n: int = 12, t0: int | None = None) -> None:
    """n samples a millisecond apart from the bridge's now on (the chip queue holds 64)."""
    t0 = vb.host.now_us() if t0 is None else t0
    for k in range(n):
        vb.host.send("IMU_SAMPLE", valid_us=t0 + 1000 * k, accel=list(accel), gyro=list(gyro), temp_c=temp_c)


Vec = tuple[float, float, float]


def expected_bytes(accel: Vec, temp_c: float, gyro: Vec) -> list[int]:
    a = [round(x / G * 16384) for x in accel]
    g = [round(x * 57.29578 * 131) for x in gyro]
    return list(struct.pack(">7h", *a, round((temp_c - 36.53) * 340), *g))


def read_burst(vb: VBridge) -> list[int]:
    done = i2c(vb, "i2ctransfer", "-y", "1", "w1@0x68", "0x3b", "r14")
    assert done.returncode == 0, done.stderr
    return [int(x, 16) for x in done.stdout.split()]


def test_the_endpoints_line_and_a_clean_end_on_hangup() -> None:
    proc, ends = start_vbridge()
    try:
        assert set(ends) == {"link", "board", "shm", "rc", "can", "fakes", "pid"}
        assert int(ends["pid"]) == proc.pid
        assert Path(ends["board"]).is_socket() and Path(ends["link"]).exists() and Path(ends["rc"]).exists()
        host = Host(ends["link"])
        host.send("HELLO", version=PROTOCOL_VERSION, nonce=7)
        reply = host.wait("HELLO_REPLY")
        assert reply["version"] == PROTOCOL_VERSION and reply["nonce"] == 7
        name = reply["bridge_id"]
        assert isinstance(name, list) and bytes(name).rstrip(b"\0") == b"vbridge"
        host.close()  # the host hangs up: the bridge ends by itself
        assert wait_gone(proc.pid) and proc.wait() == 0
        assert not Path(ends["board"]).parent.exists()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
            shutil.rmtree(Path(ends["board"]).parent, ignore_errors=True)


def test_another_protocol_version_is_refused_and_its_samples_not_applied(vb: VBridge) -> None:
    wake_mpu(vb)
    vb.host.send("HELLO", version=PROTOCOL_VERSION + 1, nonce=2)
    assert vb.host.wait("HELLO_REPLY", lambda v: v["nonce"] == 2)["version"] == PROTOCOL_VERSION
    # (no time sync: it would be refused too; the bridge's clock is this machine's monotonic one)
    stream_imu(vb, (1.0, 2.0, 3.0), (0.0, 0.0, 0.0), 30.0, n=3, t0=time.monotonic_ns() // 1000)
    assert vb.host.wait("STATUS", lambda v: v["refused"] == 3)
    # nothing of them reached the chip: awake, it holds the zero sample it started with (a 0 °C die)
    assert read_burst(vb) == expected_bytes((0.0, 0.0, 0.0), 0.0, (0.0, 0.0, 0.0))


def test_streamed_samples_are_what_the_board_reads(vb: VBridge) -> None:
    who = i2c(vb, "i2cget", "-y", "1", "0x68", "0x75")
    assert who.returncode == 0 and who.stdout.strip() == "0x68"
    wake_mpu(vb)
    accel, gyro, temp = (0.5, -1.25, -G), (0.1, -0.2, 0.3), 31.5
    stream_imu(vb, accel, gyro, temp)
    assert read_burst(vb) == expected_bytes(accel, temp, gyro)
    vb.host.wait("STATUS")  # (the register writes came before it)
    writes = [(m.values["addr"], m.values["reg"], m.values["value"]) for m in vb.host.got
              if m.name == "REG_WRITE"]
    assert (0x68, 0x1A, 0x01) in writes and (0x68, 0x6B, 0x00) in writes


def test_a_bus_nack_fault_fails_the_board_transfer_and_is_counted(vb: VBridge) -> None:
    t = vb.host.now_us()
    vb.host.send("FAULT", target=4, kind=6, start_us=t, end_us=t + 600_000_000)  # the MPU off, 10 min
    vb.host.now_us()  # (the fault is in once the sync after it is answered)
    done = i2c(vb, "i2cget", "-y", "1", "0x68", "0x75")
    assert done.returncode != 0 and "Read failed" in done.stderr
    assert i2c(vb, "i2cget", "-y", "1", "0x77", "0xa2", "w").returncode == 0  # the barometer still answers
    assert vb.host.wait("STATUS", lambda v: v["i2c_errors"] == 1)


def test_a_silent_host_is_flagged_and_the_board_still_answered(vb: VBridge) -> None:
    wake_mpu(vb)
    accel, gyro, temp = (0.0, 0.0, -G), (0.0, 0.0, 0.0), 25.0
    stream_imu(vb, accel, gyro, temp)
    silent = vb.host.wait("STATUS", lambda v: v["host_silent"] == 1)  # the host just stops
    underruns = silent["underruns"]
    assert isinstance(underruns, list) and underruns[0] > 0
    assert read_burst(vb) == expected_bytes(accel, temp, gyro)  # the last sample, held
    who = i2c(vb, "i2cget", "-y", "1", "0x68", "0x75")
    assert who.returncode == 0 and who.stdout.strip() == "0x68"
    vb.host.send("HEARTBEAT")
    assert vb.host.wait("STATUS", lambda v: v["host_silent"] == 0)


def test_malformed_frames_are_counted_and_ignored(vb: VBridge) -> None:
    wake_mpu(vb)
    accel, gyro, temp = (1.0, 1.0, 1.0), (0.0, 0.0, 0.0), 20.0
    stream_imu(vb, accel, gyro, temp)
    t = vb.host.now_us()
    bad = bytearray(encode("IMU_SAMPLE", 99, valid_us=t, accel=[-5.0, -5.0, -5.0], gyro=[1, 1, 1],
                           temp_c=40.0))
    bad[10] ^= 0x40  # one bit flipped: the CRC fails
    vb.host.raw(bytes(bad))
    vb.host.raw(os.urandom(300).replace(b"\0", b"\1") + b"\0")  # noise longer than any frame
    vb.host.raw(encode("PULSES", 0, t_us=1) + b"\x05\x05\x00")  # a message that goes the other way; junk
    status = vb.host.wait("STATUS", lambda v: isinstance(v["frames_bad"], int) and v["frames_bad"] >= 4)
    assert status["frames_bad"] == 4
    assert read_burst(vb) == expected_bytes(accel, temp, gyro)  # nothing of them applied
    assert vb.host.now_us() > t  # and the bridge goes on


def test_pwm_writes_become_captured_pulse_widths(vb: VBridge) -> None:
    chip = "/sys/class/pwm/pwmchip0"
    script = "true"
    for ch, width_us in enumerate((1100, 1250, 1500, 1975)):  # 400 Hz ESC pulses
        script += (f" && echo {ch} > {chip}/export && echo 2500000 > {chip}/pwm{ch}/period"
                   f" && echo {width_us * 1000} > {chip}/pwm{ch}/duty_cycle"
                   f" && echo 1 > {chip}/pwm{ch}/enable")
    done = vb.dut("sh", "-c", script)
    assert done.returncode == 0, done.stderr
    pulses = vb.host.wait("PULSES", lambda v: v["width_tenth_us"] == [11000, 12500, 15000, 19750])
    assert isinstance(pulses["t_us"], int) and pulses["t_us"] > 0
    done = vb.dut("sh", "-c", "echo 0 > /sys/class/pwm/pwmchip0/pwm2/enable")
    assert done.returncode == 0, done.stderr
    vb.host.wait("PULSES", lambda v: v["width_tenth_us"] == [11000, 12500, 0, 19750])  # stale: no pulse


def test_sbus_channels_leave_as_frames_on_the_rc_pty(vb: VBridge) -> None:
    fd = os.open(vb.ends["rc"], os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        channels = sbus.Sticks(roll=0.25, pitch=-0.5, throttle=0.4, yaw=0.1, arm=True).channels()
        vb.host.send("SBUS", channels=channels, flags=0)
        want = sbus.encode(channels)
        data = b""
        deadline = time.monotonic() + BOUND_S
        while data.count(want) < 3:  # three frames, 14 ms apart
            left = deadline - time.monotonic()
            assert left > 0, f"no SBUS frames on the RC pty: {data[-50:].hex()}"
            if select.select([fd], [], [], left)[0]:
                data += os.read(fd, 4096)
        assert data[data.index(want):].startswith(want * 3)  # back to back, nothing between
    finally:
        os.close(fd)
