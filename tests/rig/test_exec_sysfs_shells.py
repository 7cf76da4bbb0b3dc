"""Sysfs PWM the way shells use it: bash builtins (echo, printf, read), coreutils run by a shell (echo,
printf, cat, ls, sed) and directory listings, with the kernel's answers. Bash writes its builtins'
output through stdio, and a program the shell starts inherits the redirected descriptor across exec,
so these take other paths through the shim than dash's echo or a C program's write()."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.rig.helpers import PY, rig_exec

CHIP = "/sys/class/pwm/pwmchip0"


def pwm_events(log: Path) -> list[str]:
    return [line.split(" ", 2)[2] for line in log.read_text().splitlines() if " pwm" in line]


def test_bash_builtin_echo_exports_a_channel(tmp_path: Path) -> None:
    log = tmp_path / "log"
    run = rig_exec(tmp_path, "bash", "-c", f"echo 0 > {CHIP}/export; echo rc=$?; ls -d {CHIP}/pwm0",
                   options=("--log", str(log)))
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["rc=0", f"{CHIP}/pwm0"]
    assert pwm_events(log) == ["pwm0 export 0"]
    assert run.summary["verdict"] == "ok"


def test_bash_builtins_get_the_kernels_errors(tmp_path: Path) -> None:
    script = f"""
        echo 9 > {CHIP}/export; echo st=$?
        echo 0 > {CHIP}/export; echo st=$?
        echo 0 > {CHIP}/export; echo st=$?
        printf abc > {CHIP}/pwm0/enable; echo st=$?
        echo 1 > {CHIP}/pwm0/enable; echo st=$?
        echo 8 > {CHIP}/npwm; echo st=$?
    """
    run = rig_exec(tmp_path, "bash", "-c", script)
    assert run.stdout.split() == ["st=1", "st=0", "st=1", "st=1", "st=1", "st=1"]
    errors = [line.split(": ", 3)[-1] for line in run.stderr.splitlines() if line.startswith("bash: ")]
    assert errors == ["write error: No such device",            # channel 9 of 8
                      "write error: Device or resource busy",   # exported twice
                      "write error: Invalid argument",          # garbage
                      "write error: Invalid argument",          # enable with a zero period
                      "Permission denied"]                      # npwm is read-only: open fails
    assert "echo: write error: No such device" in run.stderr
    assert "printf: write error: Invalid argument" in run.stderr


def test_echo_9_to_export_fails_with_status_1(tmp_path: Path) -> None:
    run = rig_exec(tmp_path, "bash", "-c", f"echo 9 > {CHIP}/export")
    assert run.returncode == 1
    assert "No such device" in run.stderr


def test_programs_started_by_bash_write_through_the_redirection(tmp_path: Path) -> None:
    """/bin/echo and printf write through stdio, in a process exec'd after the redirection."""
    script = f"""
        /bin/echo 0 > {CHIP}/export; echo st=$?
        /usr/bin/printf 2500000 > {CHIP}/pwm0/period; echo st=$?
        /bin/echo 9 > {CHIP}/export; echo st=$?
        /usr/bin/printf 3000000 > {CHIP}/pwm0/duty_cycle; echo st=$?
        exec 3> {CHIP}/pwm0/duty_cycle
        /bin/echo 1200000 >&3; echo st=$?
        cat {CHIP}/pwm0/duty_cycle
    """
    log = tmp_path / "log"
    run = rig_exec(tmp_path, "bash", "-c", script, options=("--log", str(log)))
    assert run.stdout.split() == ["st=0", "st=0", "st=1", "st=1", "st=0", "1200000"]
    assert "echo: write error: No such device" in run.stderr
    assert "printf: write error: Invalid argument" in run.stderr
    assert pwm_events(log) == ["pwm0 export 0", "pwm0 period 2500000", "pwm0 duty_cycle 1200000"]


def test_bash_builtins_drive_a_motor(tmp_path: Path) -> None:
    script = f"""
        echo 0 > {CHIP}/export
        printf 2500000 > {CHIP}/pwm0/period
        echo 1500000 > {CHIP}/pwm0/duty_cycle
        echo 1 > {CHIP}/pwm0/enable
        read duty < {CHIP}/pwm0/duty_cycle; echo duty=$duty
        sleep 1
    """
    log = tmp_path / "log"
    run = rig_exec(tmp_path, "bash", "-c", script, options=("--log", str(log)))
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["duty=1500000"]
    assert pwm_events(log) == ["pwm0 export 0", "pwm0 period 2500000", "pwm0 duty_cycle 1500000",
                               "pwm0 enable 1"]
    # ESC: omega = (1500 us - 1000 us) / 1000 us * omega_max (600 rad/s), settled after 1 s (tau 20 ms)
    assert run.summary["plant"]["omega1"] == pytest.approx(300.0, rel=1e-6)


def test_cat_and_sed_read_the_attributes(tmp_path: Path) -> None:
    """cat copies with copy_file_range when both ends look like regular files; sed reads stdin
    through stdio."""
    out = tmp_path / "copy"
    value = tmp_path / "value"
    value.write_text("2000000\n")
    script = f"""
        cat {CHIP}/npwm
        echo 0 > {CHIP}/export
        echo 2500000 > {CHIP}/pwm0/period
        cat {CHIP}/pwm0/period
        cat {CHIP}/pwm0/period > {out}; cat {out}
        cat {value} > {CHIP}/pwm0/duty_cycle; echo st=$?
        sed -n p < {CHIP}/pwm0/duty_cycle
    """
    log = tmp_path / "log"
    run = rig_exec(tmp_path, "bash", "-c", script, options=("--log", str(log)))
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["8", "2500000", "2500000", "st=0", "2000000"]
    assert pwm_events(log)[-1] == "pwm0 duty_cycle 2000000"


def test_ls_lists_the_pwm_class_directories(tmp_path: Path) -> None:
    script = f"""
        ls {CHIP}/; echo --
        echo 3 > {CHIP}/export; echo 0 > {CHIP}/export
        ls {CHIP}; echo --
        ls /sys/class/pwm/; echo --
        ls {CHIP}/pwm3; echo --
        echo 3 > {CHIP}/unexport
        ls {CHIP}/pwm3 2>&1 || echo pwm3_gone
    """
    run = rig_exec(tmp_path, "bash", "-c", script)
    assert run.stdout.split("--\n") == [
        "export\nnpwm\nunexport\n",
        "export\nnpwm\npwm0\npwm3\nunexport\n",
        "pwmchip0\n",
        "duty_cycle\nenable\nperiod\npolarity\n",
        f"ls: cannot access '{CHIP}/pwm3': No such file or directory\npwm3_gone\n",
    ]


def test_ls_la_shows_dot_and_dot_dot(tmp_path: Path) -> None:
    run = rig_exec(tmp_path, "bash", "-c", f"ls -la /sys/class/pwm; ls -la {CHIP}")
    assert run.returncode == 0, run.stderr
    lines = [line.split() for line in run.stdout.splitlines() if not line.startswith("total")]
    assert [(mode[0], name[-1]) for mode, *name in lines] == [
        ("d", "."), ("d", ".."), ("d", "pwmchip0"),
        ("d", "."), ("d", ".."), ("-", "export"), ("-", "npwm"), ("-", "unexport")]


def test_python_subprocess_writes_to_an_attribute(tmp_path: Path) -> None:
    """subprocess starts the child with vfork (3.11): the child's dup2 of the attribute onto its
    stdout must not make the parent's stdout the attribute (they share memory until exec)."""
    script = f"""
import subprocess
with open("{CHIP}/export", "w") as f:
    ok = subprocess.run(["/bin/echo", "4"], stdout=f)
    busy = subprocess.run(["/bin/echo", "4"], stdout=f, stderr=subprocess.PIPE, text=True)
print("statuses", ok.returncode, busy.returncode)
print("stderr", busy.stderr.strip())
"""
    log = tmp_path / "log"
    run = rig_exec(tmp_path, PY, "-c", script, options=("--log", str(log)))
    assert run.returncode == 0, run.stderr
    assert run.stdout.splitlines() == ["statuses 0 1",
                                       "stderr /bin/echo: write error: Device or resource busy"]
    assert pwm_events(log) == ["pwm4 export 4"]


def test_shutil_copyfile_writes_to_an_attribute(tmp_path: Path) -> None:
    """shutil.copyfile copies with sendfile."""
    value = tmp_path / "value"
    value.write_text("5\n")
    log = tmp_path / "log"
    run = rig_exec(tmp_path, PY, "-c", f"import shutil; shutil.copyfile('{value}', '{CHIP}/export')",
                   options=("--log", str(log)))
    assert run.returncode == 0, run.stderr
    assert pwm_events(log) == ["pwm5 export 5"]


def test_python_lists_the_pwm_class_directories(tmp_path: Path) -> None:
    script = f"""
import json, os
out = {{}}
with open("{CHIP}/export", "w") as f:
    f.write("1")
out["chip"] = sorted(os.listdir("{CHIP}"))
out["kinds"] = sorted((e.name, e.is_dir(), e.is_file()) for e in os.scandir("{CHIP}"))
out["class"] = os.listdir("/sys/class/pwm")
fd = os.open("{CHIP}/pwm1", os.O_RDONLY | os.O_DIRECTORY)
out["by_fd"] = sorted(os.listdir(fd))
out["read_dir"] = "ok"
try:
    os.read(fd, 10)
except IsADirectoryError:
    out["read_dir"] = "EISDIR"
try:
    os.open("{CHIP}/npwm", os.O_RDONLY | os.O_DIRECTORY)
except NotADirectoryError:
    out["npwm_as_dir"] = "ENOTDIR"
print(json.dumps(out))
"""
    run = rig_exec(tmp_path, PY, "-c", script)
    assert run.returncode == 0, run.stderr
    out = run.json_out()
    assert out["chip"] == ["export", "npwm", "pwm1", "unexport"]
    assert out["kinds"] == [["export", False, True], ["npwm", False, True], ["pwm1", True, False],
                            ["unexport", False, True]]
    assert out["class"] == ["pwmchip0"]
    assert out["by_fd"] == ["duty_cycle", "enable", "period", "polarity"]
    assert out["read_dir"] == "EISDIR"
    assert out["npwm_as_dir"] == "ENOTDIR"


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
