"""Sysfs PWM as the kernel's pwm class presents it (driven from a shell), and the wire protocol's
numbers, which live in a C header and a Python module, agreeing."""

from __future__ import annotations

import re
from pathlib import Path

from rig import protocol as P
from rig.shim.build import SHIM_DIR
from tests.rig.helpers import PY, rig_exec

CHIP = "/sys/class/pwm/pwmchip0"


def test_sysfs_pwm_from_a_shell_with_kernel_errors(tmp_path: Path) -> None:
    script = f"""
        cd {CHIP} 2>/dev/null || true
        test -d {CHIP} && echo chip_is_dir
        cat {CHIP}/npwm
        test -e {CHIP}/pwm0 || echo pwm0_absent
        echo 0 > {CHIP}/export && echo exported
        echo 0 > {CHIP}/export 2>/dev/null || echo export_twice_refused
        echo 8 > {CHIP}/export 2>/dev/null || echo channel8_refused
        echo 2500000 > {CHIP}/pwm0/period
        echo 3000000 > {CHIP}/pwm0/duty_cycle 2>/dev/null || echo duty_above_period_refused
        echo abc > {CHIP}/pwm0/enable 2>/dev/null || echo garbage_refused
        echo 1500000 > {CHIP}/pwm0/duty_cycle
        echo inversed > {CHIP}/pwm0/polarity
        echo 1 > {CHIP}/pwm0/enable
        cat {CHIP}/pwm0/duty_cycle {CHIP}/pwm0/enable {CHIP}/pwm0/polarity
        sleep 1
        echo 1 > {CHIP}/unexport 2>/dev/null || echo unexport_unexported_refused
    """
    log = tmp_path / "log"
    run = rig_exec(tmp_path, "sh", "-c", script, options=("--log", str(log)))
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["chip_is_dir", "8", "pwm0_absent", "exported", "export_twice_refused",
                                  "channel8_refused", "duty_above_period_refused", "garbage_refused",
                                  "1500000", "1", "inversed", "unexport_unexported_refused"]
    # inversed: the high time is period - duty = 1000 us, the ESC's zero: motor 1 does not turn
    assert run.summary["plant"]["omega1"] == 0.0
    events = [line.split(" ", 2)[2] for line in log.read_text().splitlines() if " pwm0 " in line]
    assert events == ["pwm0 export 0", "pwm0 period 2500000", "pwm0 duty_cycle 1500000",
                      "pwm0 polarity 1", "pwm0 enable 1"]


def test_protocol_numbers_agree_between_c_and_python() -> None:
    header = (SHIM_DIR / "protocol.h").read_text()
    defines = {m[1]: int(m[2], 0) for m in re.finditer(r"#define (RIG_\w+) (0x[0-9a-fA-F]+|\d+)u?", header)}
    enums = {}
    for body in re.findall(r"enum \{([^}]*)\}", header):
        value = -1
        for item in re.sub(r"/\*.*?\*/", "", body, flags=re.S).split(","):
            if not item.strip():
                continue
            name, _, expr = item.partition("=")
            value = int(expr.strip(), 0) if expr.strip() else value + 1
            enums[name.strip()] = value
    assert defines["RIG_PROTOCOL_VERSION"] == P.PROTOCOL_VERSION
    assert defines["RIG_MAX_PAYLOAD"] == P.MAX_PAYLOAD
    assert defines["RIG_SHM_MAGIC"] == P.SHM_MAGIC
    assert defines["RIG_PWM_MAX"] == P.PWM_MAX
    for name in ("MSG_HELLO", "MSG_I2C", "MSG_PWM", "MSG_WAIT", "MSG_NOTE", "MSG_I2C_WRITE", "PWM_EXPORT",
                 "PWM_UNEXPORT",
                 "PWM_PERIOD", "PWM_DUTY", "PWM_ENABLE", "PWM_POLARITY", "WAIT_SLEEP", "WAIT_POLL",
                 "WAIT_AHEAD", "WAKE_DEADLINE", "WAKE_EVENT", "WAKE_SLICE"):
        assert enums[f"RIG_{name}"] == getattr(P, name), name
    # struct layouts: field types in declaration order give the Python struct formats
    sizes = {"uint64_t": "Q", "uint32_t": "I", "uint16_t": "H"}

    def layout(struct_name: str) -> str:
        body = re.search(rf"struct {struct_name} \{{(.*?)\}};", header, re.S)
        assert body is not None, struct_name
        return "<" + "".join(sizes[t] for t in re.findall(r"^\s*(uint\d+_t) \w+", body[1], re.M))

    assert layout("rig_hdr") == P.HEADER.format
    assert layout("rig_i2c_msg") == P.I2C_MSG.format
    assert layout("rig_pwm_msg") == P.PWM_MSG.format
    assert layout("rig_pwm_state") == P.SHM_PWM.format
    assert layout("rig_ack") == P.SHM_ACK.format
    # the head, the PWM array (not matched: an array), then the run's limit, the mailboxes' futex word
    # and the session's state, then the promises (an array too)
    assert layout("rig_shm") == P.SHM_HEAD.format + "QII"
    limit_at = P.SHM_HEAD.size + P.PWM_MAX * P.SHM_PWM.size
    assert P.SHM_LIMIT_OFFSET == defines["RIG_SHM_LIMIT_OFFSET"] == limit_at
    assert P.SHM_WAKE_OFFSET == defines["RIG_SHM_WAKE_OFFSET"] == limit_at + 8
    assert P.SHM_ACKS_OFFSET == defines["RIG_SHM_ACKS_OFFSET"] == limit_at + 16
    assert defines["RIG_ACK_MAX"] == P.ACK_MAX
    assert P.SHM_ACKS_OFFSET + P.ACK_MAX * P.SHM_ACK.size <= P.SHM_SIZE
    assert defines["RIG_HELLO_MAILBOX"] == P.HELLO_MAILBOX
    assert P.SHM_HEAD.size + P.PWM_MAX * P.SHM_PWM.size <= P.SHM_SIZE


def test_a_forked_child_gets_a_connection_of_its_own(tmp_path: Path) -> None:
    """The shim keeps its pid (getpid() is a syscall per message otherwise); a fork's child must forget
    it, or it would talk on its parent's connection and the two would read each other's replies."""
    script = """
import os, time
time.sleep(0.001)
pid = os.fork()
if pid == 0:
    time.sleep(0.002)
    time.sleep(0.002)
    os._exit(0)
os.waitpid(pid, 0)
time.sleep(0.001)
"""
    run = rig_exec(tmp_path, PY, "-c", script)
    assert run.returncode == 0, run.stderr
    assert run.summary["connections"] == 2
    assert run.summary["verdict"] == "ok"
