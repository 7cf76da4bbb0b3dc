"""``rig exec`` with Debian's i2c-tools: unmodified third-party binaries against the emulated GY-86, in
the session (lockstep) and through the virtual bridge (the chip core behind a link, in real time), with
the same answers."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from rig.emulators.ms5611 import DEFAULT_PROM
from tests.rig.helpers import rig_exec, tool

#: where the devices are: the session's own, or the virtual bridge's
MODES = pytest.mark.parametrize("mode", [(), ("--bridge", "virtual")], ids=["session", "vbridge"])


def detected(table: str) -> set[int]:
    """Addresses i2cdetect printed (hex cells, not '--' or 'UU')."""
    found = set()
    for line in table.splitlines():
        m = re.match(r"^([0-7]0):(.*)$", line)
        if m:
            row = int(m.group(1), 16)
            for col, cell in enumerate(m.group(2)[1:].split(" ")[:16]):
                if re.fullmatch(r"[0-9a-f]{2}", cell):
                    assert int(cell, 16) == row + col, line
                    found.add(int(cell, 16))
    return found


@MODES
def test_i2cdetect_sees_mpu_and_baro_and_the_hmc_only_in_bypass(tmp_path: Path, mode: tuple[str, ...]
                                                                 ) -> None:
    detect, iset = tool("i2cdetect"), tool("i2cset")
    script = (f"{detect} -y 1; echo ==; {iset} -y 1 0x68 0x37 0x02; {detect} -y 1; echo ==; "
              f"{iset} -y 1 0x68 0x37 0x00; {detect} -y 1")
    run = rig_exec(tmp_path, "sh", "-c", script, options=mode)
    assert run.returncode == 0, run.stderr
    before, bypass, after = run.stdout.split("==\n")
    assert detected(before) == {0x68, 0x77}
    assert detected(bypass) == {0x1E, 0x68, 0x77}
    assert detected(after) == {0x68, 0x77}


@MODES
def test_i2cget_reads_who_am_i(tmp_path: Path, mode: tuple[str, ...]) -> None:
    run = rig_exec(tmp_path, tool("i2cget"), "-y", "1", "0x68", "0x75", options=mode)
    assert (run.returncode, run.stdout.strip()) == (0, "0x68"), run.stderr


@MODES
def test_i2ctransfer_reads_the_ms5611_prom_and_its_crc4_checks(tmp_path: Path, mode: tuple[str, ...]) -> None:
    xfer = tool("i2ctransfer")
    reads = " ".join(f"w1@0x77 0x{0xA0 + 2 * i:02x} r2" for i in range(8))
    run = rig_exec(tmp_path, "sh", "-c", f"{xfer} -y 1 w1@0x77 0x1e && {xfer} -y 1 {reads}", options=mode)
    assert run.returncode == 0, run.stderr
    data = [int(x, 16) for x in run.stdout.split()]
    words = [data[2 * i] << 8 | data[2 * i + 1] for i in range(8)]
    assert tuple(words) == DEFAULT_PROM
    assert words[7] & 0xF == an520_crc4(words)


def an520_crc4(prom: list[int]) -> int:
    """Measurement Specialties AN520's reference CRC-4, transcribed bit for bit (a second implementation)."""
    n_prom = list(prom)
    n_rem = 0
    crc_read = n_prom[7]
    n_prom[7] = 0xFF00 & n_prom[7]
    for cnt in range(16):
        n_rem ^= (n_prom[cnt >> 1] & 0x00FF) if cnt % 2 == 1 else (n_prom[cnt >> 1] >> 8)
        for _ in range(8, 0, -1):
            n_rem = ((n_rem << 1) ^ 0x3000) if n_rem & 0x8000 else (n_rem << 1)
            n_rem &= 0xFFFF
    n_rem = (n_rem >> 12) & 0x000F
    n_prom[7] = crc_read
    return n_rem ^ 0x00


@MODES
def test_i2cset_wakes_the_mpu(tmp_path: Path, mode: tuple[str, ...]) -> None:
    """Through the virtual bridge the +1 g read after the wake is a sample the host streamed: it followed
    the wake from the board's register write."""
    get, iset = tool("i2cget"), tool("i2cset")
    run = rig_exec(tmp_path, "sh", "-c",
                   f"{get} -y 1 0x68 0x6b; sleep 0.1; {get} -y 1 0x68 0x3f; {iset} -y 1 0x68 0x6b 0x00; "
                   f"{get} -y 1 0x68 0x6b; sleep 0.1; {get} -y 1 0x68 0x3f", options=mode)
    assert run.returncode == 0, run.stderr
    pwr_before, accel_z_hi_asleep, pwr_after, accel_z_hi_awake = (int(x, 16) for x in run.stdout.split())
    assert pwr_before == 0x40               # reset value: SLEEP set
    assert accel_z_hi_asleep == 0x00        # asleep: no samples
    assert pwr_after == 0x00
    assert 0x3C <= accel_z_hi_awake <= 0x43  # ACCEL_ZOUT_H near 0x40: +1 g at 16384 LSB/g


@MODES
def test_exit_status_passes_through_and_a_nack_is_an_i2c_tools_error(tmp_path: Path,
                                                                    mode: tuple[str, ...]) -> None:
    run = rig_exec(tmp_path, tool("i2cget"), "-y", "1", "0x50", "0x00", options=mode)
    assert run.returncode == 2                       # i2cget's own status for a failed read
    assert "Read failed" in run.stderr
    run = rig_exec(tmp_path, "sh", "-c", f"{tool('i2cget')} -y 1 0x68 0x75 >/dev/null; exit 7", options=mode)
    assert run.returncode == 7 and run.summary["verdict"] == "failed"
