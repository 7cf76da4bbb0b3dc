"""``rig exec`` with a Python driver (smbus2): the bytes decode to the plant's truth, and the i2c-dev
node behaves as the kernel's does, errors included."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from tests.rig.helpers import DUTS, PY, rig_exec


@pytest.mark.parametrize("mode", [(), ("--bridge", "virtual")], ids=["session", "vbridge"])
@pytest.mark.parametrize("site", [{}, {"p_ground": 95461.3, "t_ground": 31.5}], ids=["isa", "warm-high"])
def test_smbus2_reads_rest_truth_hmc_id_and_pressure(tmp_path: Path, site: dict[str, float],
                                                     mode: tuple[str, ...]) -> None:
    """Through the virtual bridge the same bytes come from samples the host streamed to the chip core."""
    params = mode + tuple(x for k, v in site.items() for x in ("--param", f"{k}={v}"))
    run = rig_exec(tmp_path, PY, str(DUTS / "smbus_probe.py"), options=params)
    assert run.returncode == 0, run.stderr
    out = run.json_out()
    assert out["who_am_i"] == 0x68
    ax, ay, az = out["accel_g"]
    assert abs(ax) < 0.03 and abs(ay) < 0.03 and abs(az - 1.0) < 0.03     # (0, 0, +1 g) +- noise
    assert all(abs(w) < 0.5 for w in out["gyro_dps"])                       # at rest
    assert out["hmc_id"] == "H43"
    truth = run.summary["plant"]
    assert abs(out["pressure_pa"] - truth["pressure"]) <= 1.0
    assert abs(out["baro_temp_c"] - truth["temperature"]) <= 0.01
    assert math.isclose(truth["pressure"], site.get("p_ground", 101325.0))  # at rest on the ground


def test_i2c_dev_node_behaves_like_the_kernel(tmp_path: Path) -> None:
    run = rig_exec(tmp_path, PY, str(DUTS / "i2c_dev_semantics.py"))
    assert run.returncode == 0, run.stderr
    out = run.json_out()
    assert out["stat"] == [True, 89, 1] and out["access"] is True
    assert out["other_bus"] == "ENOENT"                    # only the emulated bus exists
    assert out["funcs"] == [True, True, True, False]       # I2C, quick, block read; no PEC
    assert out["slave_0x80"] == "EINVAL"
    assert out["unknown_ioctl"] == "ENOTTY"
    assert out["read_before_slave"] == "ENXIO"
    assert out["plain_read"] == 0x68
    assert out["pec"] == "EINVAL"
    assert out["pread"] == "ESPIPE"
    assert (out["quick_68"], out["quick_50"]) == ("ok", "ENXIO")
    assert out["word_6b"] == out["bytes_6b"][0] | out["bytes_6b"][1] << 8 == 0x0001
    assert out["after_word_write"] == [0x04, 0x03]         # LSB first, as SMBus words go
    assert out["after_block_write"] == [0x18, 0x08]
    assert out["receive_byte"] == 0x68
    assert out["block_read"] == "EPROTO"
    assert out["slv0_addr_reg"] == [0x34, 0x12]
    assert out["proc_call"] == out["proc_call_expected"]
    assert out["rdwr"] == [0x68] and out["rdwr_nack"] == "ENXIO"
    assert any("I2C_PEC" in n for n in run.summary["notes"])
