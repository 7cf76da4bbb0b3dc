"""Sysfs PWM the way shells use it: bash builtins (echo, printf, read), coreutils run by a shell (echo,
printf, cat, ls, sed) and directory listings, with the kernel's answers. Bash writes its builtins'
output through stdio, and a program the shell starts inherits the redirected descriptor across exec,
so these take other paths through the shim than dash's echo or a C program's write()."""

from __future__ import annotations

from pathlib import Path

from tests.rig.helpers import PY, rig_exec

CHIP = "/sys/class/pwm/pwmchip0"


def pwm_events(log: Path) -> list[str]:
    return [line.split(" ", 2)[2] for line in log.read_text().splitlines() if " pwm" in line]


def test_a_descriptor_copied_with_fcntl_dupfd_stays_the_attribute(tmp_path: Path) -> None:
    """dash saves a redirected descriptor with fcntl(F_DUPFD) and puts it back with dup2."""
    script = f"""
        exec > {CHIP}/export
        echo 0
        echo 0 > {CHIP}/unexport
        echo 1
    """
    log = tmp_path / "log"
    run = rig_exec(tmp_path, "sh", "-c", script, options=("--log", str(log)))
    assert run.returncode == 0, run.stderr
    assert pwm_events(log) == ["pwm0 export 0", "pwm0 unexport 0", "pwm1 export 1"]
    py = f"""
import fcntl, os
fd = os.open("{CHIP}/export", os.O_WRONLY)
copy = fcntl.fcntl(fd, fcntl.F_DUPFD_CLOEXEC, 20)
os.close(fd)
os.write(copy, b"2")
"""
    log2 = tmp_path / "log2"
    run = rig_exec(tmp_path, PY, "-c", py, options=("--log", str(log2)))
    assert run.returncode == 0, run.stderr
    assert pwm_events(log2) == ["pwm2 export 2"]


def test_a_child_inherits_an_attribute_descriptor(tmp_path: Path) -> None:
    """The shell opens the attribute; the programs it starts write to it through write()."""
    script = f"""
        exec 3> {CHIP}/export
        sh -c 'echo 0 >&3'
        {PY} -c 'import os; os.write(3, b"1")'
        {PY} -c 'import os; os.write(3, b"9")' 2>&1 | tail -1
    """
    log = tmp_path / "log"
    run = rig_exec(tmp_path, "bash", "-c", script, options=("--log", str(log)))
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "OSError: [Errno 19] No such device"
    assert pwm_events(log) == ["pwm0 export 0", "pwm1 export 1"]


def test_a_command_that_only_reads_an_attribute_touched_the_devices(tmp_path: Path) -> None:
    run = rig_exec(tmp_path, "cat", f"{CHIP}/npwm")
    assert run.returncode == 0, run.stderr
    assert run.stdout == "8\n"
    assert run.summary["verdict"] == "ok"


def test_bytes_that_bypass_the_shim_are_reported(tmp_path: Path) -> None:
    """A raw write syscall on an attribute's descriptor never reaches the emulation: the run says so
    instead of losing the bytes silently."""
    script = f"""
import ctypes, os
fd = os.open("{CHIP}/export", os.O_WRONLY)
ctypes.CDLL(None, use_errno=True).syscall(1, fd, b"0\\n", 2)   # SYS_write
"""
    run = rig_exec(tmp_path, PY, "-c", script, options=("--allow-no-devices",))
    assert run.returncode == 0, run.stderr
    assert any(f"2 bytes written to {CHIP}/export" in note for note in run.summary["notes"]), \
        run.summary["notes"]
