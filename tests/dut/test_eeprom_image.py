"""The AVR firmware's EEPROM configuration (scenarios/eeprom.py writes it, dut/src/config_image.c reads
it) against the Linux FC's config file parser: for every library scenario, and for tables that use a
profile, arrays and integers, both give the same configuration (in float, as the AVR keeps it); and an
image that is corrupt, for another key table, or out of range leaves the defaults and says why."""

from __future__ import annotations

import struct
import subprocess
from pathlib import Path

import pytest

from rig.scenarios import eeprom
from rig.scenarios.schema import load
from rig.targets import reference_config

REPO = Path(__file__).resolve().parents[2]
DUMP = REPO / "build" / "dut" / "config_dump"
LIBRARY = sorted((REPO / "scenarios" / "library").glob("*.toml"))


@pytest.fixture(scope="module")
def dump() -> Path:
    subprocess.run(["make", "-s", "-C", str(REPO / "dut"), "../build/dut/config_dump"], check=True)
    return DUMP


def run(dump: Path, kind: str, data: bytes | str, tmp: Path) -> list[str]:
    f = tmp / ("in." + kind)
    f.write_bytes(data) if isinstance(data, bytes) else f.write_text(data)
    done = subprocess.run([str(dump), kind, str(f)], capture_output=True, text=True, check=True)
    return done.stdout.splitlines()


@pytest.mark.parametrize("path", LIBRARY, ids=[p.stem for p in LIBRARY])
def test_every_library_scenario_configures_the_avr_as_the_linux_fc(dump: Path, tmp_path: Path,
                                                                    path: Path) -> None:
    sc = load(path)
    from_file = run(dump, "conf", reference_config(sc), tmp_path)
    from_image = run(dump, "image", eeprom.image(sc.fc), tmp_path)
    assert from_file[0] == "status = ok"
    assert from_image == from_file


def test_a_profile_arrays_and_integers_survive_the_image(dump: Path, tmp_path: Path) -> None:
    fc = {"profile": "seed002", "rate_kp": "100", "alpha": [1.1, 1.0, 1.0, 0.9], "telemetry_every": 10,
          "est_rate_hz": 500, "ctrl_rate_hz": 125, "acc_offset": "0.1, -0.2, 0.05", "mixer": 1}
    conf = "".join(f"{k} = {', '.join(map(str, v)) if isinstance(v, list) else v}\n" for k, v in fc.items())
    from_image = run(dump, "image", eeprom.image(fc), tmp_path)
    assert from_image == run(dump, "conf", conf, tmp_path)
    defaults = run(dump, "image", b"\xff" * eeprom.size(), tmp_path)
    assert defaults[0] == "status = blank"
    changed = {a.split(" =")[0] for a, b in zip(from_image, defaults, strict=True) if a != b} - {"status"}
    assert changed == {"rate_kp", "rate_ki", "rate_kd", "alpha", "telemetry_every", "est_rate_hz",
                       "ctrl_rate_hz", "acc_offset", "mixer"}


def resealed(img: bytearray) -> bytes:
    img[-2:] = struct.pack("<H", eeprom.crc16(bytes(img[:-2])))
    return bytes(img)


def test_a_bad_image_leaves_the_defaults_and_says_why(dump: Path, tmp_path: Path) -> None:
    defaults = run(dump, "conf", "", tmp_path)[1:]
    good = bytearray(eeprom.image({"estimator": 1, "hover_us": 1400}))
    flipped = bytearray(good)
    flipped[20] ^= 0x10
    other_table = bytearray(good)
    other_table[2] ^= 1
    # est_rate_hz is the first number key after the integer ones: find its slot and write 5 Hz (< 10)
    bad_value = bytearray(eeprom.image({"est_rate_hz": 250}))
    slot = bytes(bad_value).index(struct.pack("<f", 250.0))
    bad_value[slot:slot + 4] = struct.pack("<f", 5.0)
    rates = eeprom.image({"est_rate_hz": 100, "ctrl_rate_hz": 100})
    rates_bad = bytearray(rates)
    slot = bytes(rates_bad).rindex(struct.pack("<f", 100.0))
    rates_bad[slot:slot + 4] = struct.pack("<f", 200.0)
    cases = {"crc": bytes(flipped), "layout": resealed(other_table), "value": resealed(bad_value),
             "rates": resealed(rates_bad), "magic": b"\x00" * eeprom.size(), "blank": b"\xff" * 4096}
    for why, img in cases.items():
        out = run(dump, "image", img, tmp_path)
        assert out[0] == f"status = {why}", why
        assert out[1:] == defaults, why
    assert run(dump, "image", bytes(good), tmp_path)[0] == "status = ok"


def test_the_image_builder_refuses_what_the_firmware_would() -> None:
    with pytest.raises(eeprom.EepromError, match="nope"):
        eeprom.image({"nope": 1})
    with pytest.raises(eeprom.EepromError, match="profile"):
        eeprom.image({"profile": "fast"})
    with pytest.raises(eeprom.EepromError, match="est_rate_hz"):
        eeprom.image({"est_rate_hz": 5})
    with pytest.raises(eeprom.EepromError, match="16-bit"):
        eeprom.image({"telemetry_every": 40000})
    assert eeprom.size() <= eeprom.EEPROM_BYTES


def test_the_cli_writes_raw_bytes_and_intel_hex(tmp_path: Path) -> None:
    raw, hx = tmp_path / "fc.eep", tmp_path / "fc.hex"
    assert eeprom.main(["angle_tracking", "-o", str(raw)]) == 0
    assert eeprom.main(["angle_tracking", "-o", str(hx), "--ihex"]) == 0
    data = raw.read_bytes()
    assert data == eeprom.image(load(REPO / "scenarios" / "library" / "angle_tracking.toml").fc)
    records = hx.read_text().split()
    back = b"".join(bytes.fromhex(r[9:-2]) for r in records[:-1])
    assert back == data and records[-1] == ":00000001FF"
    assert all(sum(bytes.fromhex(r[1:])) & 0xFF == 0 for r in records)
