"""The MCU target end to end: the AVR reference FC's image, unmodified, flies library scenarios through
``rig run --mcu BOARD --firmware FILE`` with the scenario's [fc] table as its EEPROM; the same seed gives
the same bytes; a firmware that hangs, resets in a loop, jumps wild or hits a bad opcode ends its run
with an error verdict naming where and when, and the suite goes on; a bad image or board is exit 2
before anything runs."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from rig.runner import run
from rig.scenarios.schema import load
from rig.targets.mcu import McuTarget
from tests.mcu.conftest import REPO, firmware
from tests.scenarios.test_mcap import read

LIB = REPO / "scenarios" / "library"



def rig_run(*args: object) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rig.cli", "run", *map(str, args)], capture_output=True,
                          text=True, timeout=600)


def test_the_avr_reference_fc_flies_the_library_through_the_tier(avr_fc: Path, tmp_path: Path) -> None:
    done = rig_run("--mcu", "mega2560-gy86", "--firmware", avr_fc, "step_roll", "rc_loss_failsafe",
                   "--out", tmp_path)
    assert done.returncode == 0, done.stderr
    for name, duration in (("step_roll", 10.0), ("rc_loss_failsafe", 20.0)):
        r = json.loads((tmp_path / name / "result.json").read_text())
        meta = r["metadata"]
        assert r["verdict"] == "pass"
        assert meta["mode"] == "mcu" and meta["board"] == "mega2560-gy86"
        assert meta["dut_firmware_sha256"] and meta["fc_config"] is not None
        mcu = meta["mcu"]
        # sim time is the MCU's cycle count; the last instruction may end up to 4 cycles past the end
        # (docs/mcu.md, the engine's run_until)
        assert 0 <= mcu["cycles"] - round(16e6 * duration) <= 4
        assert mcu["twi_transactions"] > 100 * duration and mcu["twi_nacks"] == 0
        assert min(mcu["motor_pulses"]) > 400 * duration  # ~490 Hz ESC pulses, all four motors
        assert meta["realtime_factor"] > 0
        told = (tmp_path / name / "dut-telemetry.txt").read_text()
        assert "# fc: configuration: EEPROM image" in told  # the scenario's [fc] table reached it
    # run.mcap's /i2c holds every TWI transaction (one per address phase, as the engine counts them):
    # the firmware's one burst a loop, 25 bytes from I2C_MST_STATUS (0x36), decoded on /sensors
    _, by_topic, meta = read(tmp_path / "step_roll" / "run.mcap")
    mcu = json.loads((tmp_path / "step_roll" / "result.json").read_text())["metadata"]["mcu"]
    i2c = [m for _, m in by_topic["/i2c"]]
    assert len(i2c) == mcu["twi_transactions"] and "note /i2c" not in meta["mcap"]
    bursts = [m for m in i2c if m["address"] == 0x68 and m["register"] == 0x36 and m["read"]]
    assert len(bursts) > 900  # 100 Hz for 10 s
    mpu = [m for _, m in by_topic["/sensors"] if m["chip"] == "MPU-6050"]
    assert len(mpu) == len(bursts)
    raw = bytes.fromhex(bursts[-1]["read"])  # ACCEL_ZOUT at 0x3F: 9 bytes into a burst from 0x36
    assert mpu[-1]["values"]["az"] == int.from_bytes(raw[9:11], "big", signed=True)


def test_the_same_seed_gives_the_same_bytes(avr_fc: Path, tmp_path: Path) -> None:
    sc = load(LIB / "seed000_roll_stand.toml")
    a = run(sc, McuTarget("mega2560-gy86", avr_fc), 3, tmp_path / "a")
    b = run(sc, McuTarget("mega2560-gy86", avr_fc), 3, tmp_path / "b")
    assert a.verdict == b.verdict == "pass"
    assert [m.value for m in a.measurements] == [m.value for m in b.measurements]
    told = {k: (tmp_path / k / "dut-telemetry.txt").read_bytes() for k in "ab"}
    assert told["a"] == told["b"]
    assert all((a.signals[k] == b.signals[k]).all() for k in ("roll", "pwm1", "pwm4"))
    c = run(sc, McuTarget("mega2560-gy86", avr_fc), 4, tmp_path / "c")  # another seed: other noise
    assert (tmp_path / "c" / "dut-telemetry.txt").read_bytes() != told["a"]
    assert c.verdict == "pass"


@pytest.mark.parametrize(
    ("name", "words"),
    [("busy", "hung: no TWI transaction, motor pulse, USART byte sent or output pin change for 1000 ms"),
     ("watchdog", "was reset by its watchdog in a loop: 3 times"),
     ("wild_jump", "crashed: jump outside the program"), ("bad_opcode", "crashed: invalid opcode")],
)
def test_bad_firmware_ends_its_run_with_a_named_error(tmp_path: Path, name: str, words: str) -> None:
    sc = load(LIB / "step_roll.toml")
    r = run(sc, McuTarget("mega2560-gy86", firmware(name, "atmega2560")), 0, tmp_path)
    assert r.verdict == "error"
    assert r.error is not None and r.error.startswith(f"the firmware {words}")
    assert "pc 0x" in r.error and "cycle" in r.error
    assert all(m.outcome == "not judged" for m in r.measurements)
    print(f"{name}: {r.error} ({r.metadata['wall_time']:.2f} s wall)")


def test_a_suite_goes_on_after_a_bad_firmware(tmp_path: Path) -> None:
    done = rig_run("--mcu", "mega2560-gy86", "--firmware", firmware("busy", "atmega2560"), "step_roll",
                   "seed000_roll_stand", "--out", tmp_path)
    assert done.returncode == 3, done.stderr
    assert "[2/2] seed000_roll_stand" in done.stderr and done.stderr.count("ERROR") == 2
    # each run's speed with one decimal, as the report's real-time factor ("1.3x", never "1x" or "0x")
    assert len(re.findall(r"ERROR \(\d+\.\d s wall, \d+\.\dx\)", done.stderr)) == 2


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--firmware", "README.md"], "neither an AVR ELF nor an Intel HEX file"),
        (["--firmware", "no-such.elf"], "cannot read it"),
        (["--mcu", "no-such-board"], "no such board file"),
        ([], "--mcu needs --firmware"),
        (["--dut", "true"], "--mcu runs a firmware image in lockstep: not with --dut"),
    ],
)
def test_bad_options_are_exit_2_before_anything_runs(tmp_path: Path, args: list[str], words: str) -> None:
    base = ["--mcu", "mega2560-gy86"]
    if "--mcu" in args:
        base = []
    if "--firmware" not in args and words != "--mcu needs --firmware":
        base += ["--firmware", str(firmware("busy", "atmega2560"))]
    done = rig_run(*base, *args, "step_roll", "--out", tmp_path / "out")
    assert done.returncode == 2, done.stderr
    assert words in done.stderr
    assert not (tmp_path / "out").exists()


def test_an_image_bigger_than_the_mcus_flash_is_refused(tmp_path: Path) -> None:
    """A 40 KB image is fine for the ATmega2560 (256 KB) and too big for the 328P (32 KB)."""
    big = tmp_path / "big.hex"
    rows = [f":10{a & 0xFFFF:04X}00{'00' * 16}" for a in range(0, 0xA000, 16)]
    lines = []
    for k, r in enumerate(rows):
        if k and (k * 16) % 0x10000 == 0:
            lines.append(f":02000004{k * 16 >> 16:04X}{(-(2 + 4 + (k * 16 >> 16))) & 0xFF:02X}")
        data = bytes.fromhex(r[1:])
        lines.append(r + f"{(-sum(data)) & 0xFF:02X}")
    big.write_text("\n".join([*lines, ":00000001FF"]) + "\n")
    done = rig_run("--mcu", "promini328-gy86", "--firmware", big, "step_roll", "--out", tmp_path / "out")
    assert done.returncode == 2 and "the flash image is 40960 bytes; the MCU has 32768" in done.stderr


def test_what_the_firmware_saw_go_wrong_on_its_bus_is_in_every_report(tmp_path: Path) -> None:
    """twi_busy's case 5 (EEPROM byte 0, a board file of ours preloading it) gives up one wait for TWINT
    and then runs a clean transfer; it never pulses a motor, so the run ends as hung, and its reports
    still say what went wrong on the bus: result.json, report.html's run table, the JUnit properties and
    run.mcap's metadata."""
    shipped = (REPO / "rig" / "mcu" / "boards" / "mega2560-gy86.toml").read_text()
    (tmp_path / "case5.eep").write_bytes(bytes([5]))
    board = tmp_path / "busy-board.toml"
    board.write_text(shipped.replace("fc = true", 'image = "case5.eep"'))
    done = rig_run("--mcu", board, "--firmware", firmware("twi_busy", "atmega2560"), "step_roll",
                   "--out", tmp_path / "out")
    assert done.returncode == 3, done.stderr
    run_dir = tmp_path / "out" / "step_roll"
    meta = json.loads((run_dir / "result.json").read_text())["metadata"]
    want = {"address_nacks": 0, "data_nacks": 0, "ignored_requests": 0, "abandoned_waits": 1,
            "write_collisions": 0, "bus_errors": 0, "arbitration_lost": 0}
    assert meta["bus_problems"] == want
    html = (run_dir / "report.html").read_text()
    assert "I2C problems the firmware saw</th><td><code>1: abandoned waits 1</code>" in html
    assert 'name="bus_problems" value="1: abandoned waits 1"' in (run_dir / "junit.xml").read_text()
    _, _, records = read(run_dir / "run.mcap")
    assert json.loads(records["result"]["bus_problems"]) == want


def test_a_profile_wires_the_motors_and_the_sensor_board_as_its_firmware_expects() -> None:
    """MultiWii 2.4 on a Mega drives its QUADX outputs (rear right, front right, rear left, front left)
    on D3, D5, D6, D2 (Output.cpp PWM_PIN) and reads the GY-86's MPU-6050 X axis as the vehicle's
    right (def.h GY_86: roll = -X, pitch = -Y). pulse_stop pulses D2 (PE4) only: under the multiwii-2.4
    profile that is the front-left motor, the plant's X motor 2; the board file alone gives it motor 1.
    The sensors' frame is the board turned 90°: chip x = body right, y = forward, z = up (FRD rows)."""
    from rig.mcu.session import McuSession
    from rig.plant.variables import PWM_INPUTS
    from rig.scenarios import profile as profiles
    from rig.world import World

    target = McuTarget("mega2560-gy86", firmware("pulse_stop", "atmega2560"))
    multiwii = profiles.load("multiwii-2.4")
    options = target.world_options(multiwii)
    assert options["mounting"] == ((0.0, 1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, -1.0))
    assert target.world_options()["mounting"] == ((1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, -1.0))
    seen: list[float] = []

    def look(s: McuSession) -> None:
        seen[:] = [s.world.plant.u[s.world.plant.u_index[n]] for n in PWM_INPUTS[:4]]

    for profile, motor in ((multiwii, 2), (None, 1)):
        world = World.at_rest(seed=0, **target.world_options(profile))
        session = target.session(world, 0.4, {}, 60.0, profile=profile)
        session.at(0.3, look)
        outcome = session.run()
        world.close()
        assert outcome.verdict == "ok", outcome.error
        assert seen == [1500.0 if k == motor else 0.0 for k in (1, 2, 3, 4)]
