"""EEPROM that persists: every run writes the EEPROM as the firmware left it (eeprom.bin beside
result.json; rig exec --eeprom-out), and --eeprom FILE (rig run, rig exec, the API, the pytest plugin)
starts a run from one, so runs chain as power cycles do. The eeprom_count firmware counts its boots in
byte 0 and writes "saved" at 1-5; an erased EEPROM reads 0xFF (the datasheets' "EEPROM ... erased"), so
the expected images are written here from that, not read from the engine."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from rig import api
from rig.mcu.engine import AvrEngine, EngineConfig
from tests.mcu.conftest import MCUS, REPO, firmware

CLOCK = 16_000_000
SIZE = {"atmega328p": 1024, "atmega2560": 4096}  # the datasheets' EEPROM sizes


def after_boot(start: bytes, mcu: str) -> bytes:
    """The EEPROM after one eeprom_count boot from ``start`` (the rest erased)."""
    whole = start + b"\xff" * (SIZE[mcu] - len(start))
    return bytes([(whole[0] + 1) & 0xFF]) + b"saved" + whole[6:]


def rig(*args: object) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rig.cli", *map(str, args)], capture_output=True, text=True,
                          cwd=REPO, timeout=300)


@pytest.mark.parametrize("mcu", MCUS)
def test_the_engine_gives_the_eeprom_as_the_firmware_left_it(mcu: str) -> None:
    for start in (b"", bytes([41, 1, 2, 3, 4, 5, 6, 7])):
        cfg = EngineConfig(mcu, CLOCK, firmware("eeprom_count", mcu), eeprom=start or None, hang_ns=0)
        with AvrEngine(cfg, None) as e:
            assert e.run_until(50_000_000).kind == "reached"
            assert e.uart_take(0) == bytes([(start or b"\xff")[0]])
            assert e.eeprom() == after_boot(start, mcu)


def test_rig_run_writes_eeprom_bin_and_takes_it_back(tmp_path: Path) -> None:
    """Two runs chained through --eeprom, the first from an Intel HEX .eep (one record: 41 at 0), the
    second from the first's eeprom.bin; the board's own EEPROM ([fc]) is not used, and result.json names
    the file. The firmware never drives a motor: each run ends as hung, and still writes its EEPROM."""
    fw = firmware("eeprom_count", "atmega2560")
    eep = tmp_path / "start.eep"
    record = bytes([1, 0, 0, 0, 41])
    eep.write_text(f":{record.hex().upper()}{-sum(record) & 0xFF:02X}\n:00000001FF\n")
    first = rig("run", "--mcu", "mega2560-gy86", "--firmware", fw, "--eeprom", eep, "seed000_roll_stand",
                "--out", tmp_path / "a")
    assert first.returncode == 3, first.stderr
    saved = tmp_path / "a" / "seed000_roll_stand" / "eeprom.bin"
    assert saved.read_bytes() == after_boot(bytes([41]), "atmega2560")
    meta = json.loads((saved.parent / "result.json").read_text())["metadata"]
    assert meta["eeprom_file"] == str(eep) and meta["fc_config"] is None
    second = rig("run", "--mcu", "mega2560-gy86", "--firmware", fw, "--eeprom", saved, "seed000_roll_stand",
                 "--out", tmp_path / "b")
    assert second.returncode == 3, second.stderr
    again = (tmp_path / "b" / "seed000_roll_stand" / "eeprom.bin").read_bytes()
    assert again == after_boot(after_boot(bytes([41]), "atmega2560"), "atmega2560") and again[0] == 43


def test_rig_exec_takes_and_gives_an_eeprom(tmp_path: Path) -> None:
    start = tmp_path / "start.bin"
    start.write_bytes(bytes([7]))
    out = tmp_path / "end.bin"
    done = rig("exec", "--mcu", "promini328-gy86", "--firmware", firmware("eeprom_count", "atmega328p"),
               "--duration", "0.1", "--allow-no-devices", "--eeprom", start, "--eeprom-out", out)
    assert done.returncode == 0, done.stderr
    assert out.read_bytes() == after_boot(bytes([7]), "atmega328p")


@pytest.mark.parametrize(
    ("args", "words"),
    [(["--eeprom", "no-such.bin"], "cannot read it"),
     (["--eeprom", "big.bin"], "the EEPROM image is 1025 bytes; the atmega328p has 1024")],
)
def test_a_bad_eeprom_is_exit_2_before_anything_runs(tmp_path: Path, args: list[str], words: str) -> None:
    (tmp_path / "big.bin").write_bytes(bytes(1025))
    args = [str(tmp_path / a) if a.endswith(".bin") else a for a in args]
    done = rig("run", "--mcu", "promini328-gy86", "--firmware", firmware("eeprom_count", "atmega328p"), *args,
               "seed000_roll_stand", "--out", tmp_path / "out")
    assert done.returncode == 2 and words in done.stderr
    done = rig("run", "--eeprom", tmp_path / "big.bin", "seed000_roll_stand", "--out", tmp_path / "out")
    assert done.returncode == 2 and "--eeprom goes with --mcu BOARD" in done.stderr


def test_the_api_takes_an_eeprom(tmp_path: Path) -> None:
    start = tmp_path / "start.bin"
    start.write_bytes(bytes([99]))
    r = api.run("seed000_roll_stand", mcu=("mega2560-gy86", firmware("eeprom_count", "atmega2560")),
                eeprom=start, out=tmp_path / "out")
    assert r.verdict == "error"  # (hung: no bus, no pulses)
    saved = (tmp_path / "out" / "seed000_roll_stand" / "eeprom.bin").read_bytes()
    assert saved[:6] == bytes([100]) + b"saved"
