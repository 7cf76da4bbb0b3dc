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
