"""Pointers the kernel refuses: where i2c-dev and sysfs copy from or to user memory and the address is
bad, the call fails with EFAULT and the DUT lives on, as on a kernel; and a fuzz of the i2c-dev surface
never crashes the DUT inside the shim."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.rig.helpers import build_client, rig_exec

FUZZ_SEED = 20251123
FUZZ_CALLS = 10000


@pytest.fixture(scope="module")
def bad_pointers(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_client(tmp_path_factory, "bad_pointers")


@pytest.fixture(scope="module")
def i2c_fuzz(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_client(tmp_path_factory, "i2c_fuzz")


def test_bad_pointers_are_efault_and_the_dut_lives_on(tmp_path: Path, bad_pointers: Path) -> None:
    run = rig_exec(tmp_path, str(bad_pointers))
    assert run.returncode == 0, run.stderr
    out = dict(line.split(" ", 1) for line in run.stdout.splitlines())
    efault = ["funcs_garbage", "funcs_null", "funcs_readonly", "write_garbage", "write_prot_none",
              "read_garbage", "read_readonly", "write_past_stack_top", "rdwr_arg_garbage",
              "rdwr_msgs_garbage", "rdwr_msgs_prot_none", "rdwr_write_buf_garbage",
              "rdwr_read_buf_garbage", "rdwr_read_buf_readonly", "rdwr_read_buf_prot_none",
              "rdwr_write_buf_past_stack_top", "smbus_arg_garbage", "smbus_read_byte_data_garbage",
              "smbus_read_byte_data_readonly", "smbus_write_byte_data_garbage",
              "smbus_read_word_prot_none", "smbus_i2c_block_garbage", "smbus_block_write_garbage",
              "smbus_proc_call_garbage", "pwm_export_write_garbage", "pwm_period_write_garbage",
              "pwm_period_pwrite_prot_none", "pwm_period_read_garbage", "pwm_period_pread_readonly"]
    assert {name: out.get(name) for name in efault} == dict.fromkeys(efault, "EFAULT")
    assert out["rdwr_msgs_null"] == "EINVAL"           # i2c-dev since Linux 5.11
    assert out["rdwr_no_msgs"] == "EINVAL"
    assert out["rdwr_empty_message_garbage_buf"] == "ok 1"   # nothing to copy, nothing to fault
    assert out["pwm_export"] == "ok 1"
    assert out["pwm_period_write"] == "ok 7"
    assert out["pwm_period_pread"] == "ok 8"
    assert out["pwm_period_value"] == "2500000"
    assert out["who_am_i_rdwr"] == "ok 2"
    assert out["who_am_i"] == "0x68"
    assert out["who_am_i_smbus"] == "ok 0"
    assert out["who_am_i_smbus_value"] == "0x68"
    assert run.summary["verdict"] == "ok"


def test_fuzzing_i2c_dev_never_crashes_the_dut(tmp_path: Path, i2c_fuzz: Path) -> None:
    print(f"fuzz seed {FUZZ_SEED}, {FUZZ_CALLS} calls")
    run = rig_exec(tmp_path, str(i2c_fuzz), str(FUZZ_SEED), str(FUZZ_CALLS))
    assert run.returncode == 0, run.stderr
    lines = run.stdout.splitlines()
    assert lines[0] == f"seed {FUZZ_SEED} calls {FUZZ_CALLS}"
    assert f"child exit 0 after {FUZZ_CALLS} calls" in lines, run.stdout
    counts = next(line for line in lines if line.startswith("child ok ")).split()
    ok, efault, other, unexpected = (int(x) for x in counts[2::2])
    assert unexpected == 0, run.stdout
    assert ok + efault + other == FUZZ_CALLS
    assert min(ok, efault, other) > FUZZ_CALLS // 20, run.stdout   # each kind of outcome well exercised
    assert "child who_am_i 0x68" in lines
    assert "parent who_am_i 0x68" in lines
    assert run.summary["verdict"] == "ok"
    assert run.summary["malformed"] == []
