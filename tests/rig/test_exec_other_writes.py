"""Writes through libc's other doors (dprintf, vdprintf, writev, pwrite, a FILE from fdopen) reach the
emulated devices with the kernel's answers, as ArduPilot's Linux HAL writes its sysfs PWM attributes:
none of their bytes may end in a backing file nobody reads."""

from __future__ import annotations

import pytest

from tests.rig.helpers import Run, build_client, rig_exec


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Run, list[str]]:
    dut = build_client(tmp_path_factory, "other_writes")
    tmp = tmp_path_factory.mktemp("other_writes")
    log = tmp / "log"
    done = rig_exec(tmp, str(dut), options=("--serial", "/dev/ttyRC0", "--log", str(log)))
    assert done.returncode == 0, done.stderr
    return done, [line.split(" ", 1)[1] for line in log.read_text().splitlines()]  # after the time


def results(run: Run) -> dict[str, list[str]]:
    return {name: rest for name, *rest in (line.split() for line in run.stdout.splitlines())}


def test_every_write_returns_what_the_kernel_returns(run: tuple[Run, list[str]]) -> None:
    out = results(run[0])
    # byte counts of the text written ("0", "1\n", "2\n", "3"; "2500000"; "1200000\n"; ...)
    assert out["dprintf_export"] == ["1"] and out["vdprintf_export"] == ["2"]
    assert out["writev_export"] == ["2"] and out["pwrite_export"] == ["1"]
    assert out["dprintf_period"] == ["7"] and out["vdprintf_duty"] == ["8"]
    assert out["pwrite_period"] == ["7"] and out["writev_duty"] == ["8"] and out["pwrite64_enable"] == ["1"]
    # the pwm class's errors: a channel exported twice, a duty above the period
    assert out["dprintf_export_again"] == ["-1", "EBUSY"]
    assert out["dprintf_duty_above_period"] == ["-1", "EINVAL"]
    assert out["fdopen_period_fclose"] == out["fdopen_duty_fclose"] == out["fdopen_enable_fclose"] == ["0"]
    assert out["fdopen_mode_refused"] == ["-1", "EINVAL"]      # "w" on a descriptor opened O_RDONLY
    # i2c-dev has only .write: writev is one message per piece (2 + 1 bytes), a NACK is ENXIO
    assert out["writev_i2c"] == ["3"] and out["who_am_i"] == ["104"]  # 0x68, the MPU-6050's WHO_AM_I
    assert out["writev_i2c_nack"] == ["-1", "ENXIO"]
    assert out["dprintf_serial"] == ["8"] and out["writev_serial"] == ["9"]


def test_the_writes_reach_the_motors_the_bus_and_the_serial_line(run: tuple[Run, list[str]]) -> None:
    done, events = run
    events = [e.removeprefix("c1 ") for e in events]                   # (connection 1: the DUT)
    pwm = [e for e in events if e.startswith("pwm")]
    assert pwm[:4] == [f"pwm{c} export {c}" for c in range(4)]
    for channel, duty in enumerate((1_100_000, 1_200_000, 1_300_000, 1_400_000)):
        assert [e for e in pwm if e.startswith(f"pwm{channel} ")][1:] == [
            f"pwm{channel} period 2500000", f"pwm{channel} duty_cycle {duty}", f"pwm{channel} enable 1"]
    i2c = [e.split()[1] for e in events if e.startswith("i2c-1")]
    assert i2c == ["W68:6b00", "W68:75", "R68[1]=68", "W50:00"]
    assert [e for e in events if e.startswith("tty")] == [
        "tty /dev/ttyRC0 < " + b"hello 42 and more".hex()]
    # ESC: omega = (pulse - 1000 us) / 1000 us * omega_max (600 rad/s), settled after 2 s (tau 20 ms)
    for motor, pulse_us in enumerate((1100, 1200, 1300, 1400), start=1):
        omega = (pulse_us - 1000) / 1000 * 600
        assert done.summary["plant"][f"omega{motor}"] == pytest.approx(omega, rel=1e-9)
    assert done.summary["notes"] == []          # no bytes left in a backing file
