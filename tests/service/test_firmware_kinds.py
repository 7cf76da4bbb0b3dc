"""A firmware image through the service (a real uvicorn on 127.0.0.1): an upload's kind is told from its
bytes and anything that is neither a Linux program nor an MCU image (AVR or ARM) is refused naming what
it looks like; a board (shipped by name, or uploaded and checked as ``rig run --mcu`` checks one) goes
with an image its MCU's engine runs (AVR on an AVR, ARM on an STM32); a run of the AVR reference FC
(make avr) on a board flies it under emulation, locally and through ``rig submit --firmware --board``,
and the STM32 tier's hover firmware flies on stm32f405-gy86 through the API."""

from __future__ import annotations

import hashlib
import struct
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.service.test_api import Service, post_bytes, start, stop
from tests.short_scenario import SHORT_BENCH
from tests.stm32.conftest import engine_or_skip, firmware
from tests.stm32.test_run import SCENARIO as STM32_HOVER

REPO = Path(__file__).resolve().parents[2]
BOARD = REPO / "rig" / "mcu" / "boards" / "mega2560-gy86.toml"


def avr_image() -> Path:
    """build/avr/fc.elf, the AVR reference FC, brought up to date by make."""
    done = subprocess.run(["make", "-s", "--no-print-directory", "avr"], cwd=REPO, capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stderr
    return REPO / "build" / "avr" / "fc.elf"


@pytest.fixture(scope="module")
def avr_fc() -> Path:
    return avr_image()


@pytest.fixture
def service(tmp_path: Path) -> Iterator[Service]:
    svc = start(tmp_path / "data", "--slots", "1")
    yield svc
    stop(svc)


def elf_header(machine: int, kind: int = 2) -> bytes:
    """An ELF32 little-endian header (the ELF specification's layout: e_ident, e_type, e_machine)."""
    return b"\x7fELF\x01\x01\x01" + bytes(9) + struct.pack("<HH", kind, machine) + bytes(32)


def board_and_image(svc: Service, image: Path) -> tuple[str, str]:
    """A board file of our own (the shipped mega2560-gy86's, renamed "my …") and the image, uploaded:
    their SHA-256s, as a run names them."""
    mine = BOARD.read_text().replace('name = "', 'name = "my ', 1).encode()
    status, board = post_bytes(svc, "/api/boards", mine)
    assert status == 201 and board["sha256"] == hashlib.sha256(mine).hexdigest(), board
    status, fw = post_bytes(svc, "/api/firmware", image.read_bytes())
    assert status == 201 and fw["kind"] == "avr-elf", fw
    return board["sha256"], fw["sha256"]


def problems(answer: object) -> str:
    assert isinstance(answer, dict)
    return " ".join(answer["detail"]["problems"])


def test_uploads_are_told_apart_and_the_rest_refused_by_what_they_are(service: Service, avr_fc: Path,
                                                                      tmp_path: Path) -> None:
    for data, words in ((b"\x89PNG\r\n\x1a\n" + bytes(20), "a PNG image"),
                        (elf_header(8), "an ELF for MIPS: neither an MCU image (AVR, or ARM 32-bit "
                                        "little-endian) nor a program this host"),
                        (elf_header(40)[:4] + b"\x02" + elf_header(40)[5:], "an ELF for ARM: neither"),
                        (b"hello, I am a text file\n", "text without a #! line"),
                        (bytes([0, 1, 2, 250, 251]), "binary data beginning 00 01 02 fa fb")):
        status, answer = post_bytes(service, "/api/firmware", data)
        assert status == 422 and words in problems(answer), answer
    hexfile = tmp_path / "fc.hex"
    subprocess.run(["avr-objcopy", "-O", "ihex", "-R", ".eeprom", str(avr_fc), str(hexfile)], check=True)
    kinds = {}
    python = Path(sys.executable).resolve()
    for path, kind in ((avr_fc, "avr-elf"), (hexfile, "intel-hex"), (python, "linux-elf")):
        status, answer = post_bytes(service, "/api/firmware", path.read_bytes())
        assert status == 201 and answer["kind"] == kind, answer
        assert answer["sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
        kinds[kind] = answer["sha256"]
    listed = {f["sha256"]: f["kind"] for f in service.call("GET", "/api/firmware")[1]}
    assert listed == {sha: kind for kind, sha in kinds.items()}
    # an AVR image as a program: no; a Linux program on a board: no; a board that is none: no
    for dut, words in (({"firmware": kinds["avr-elf"]}, "is an AVR image (ELF): it flies on a board"),
                       ({"firmware": kinds["linux-elf"], "board": "mega2560-gy86"},
                        f"(ELF or Intel HEX); {kinds['linux-elf'][:12]} is a Linux program"),
                       ({"firmware": kinds["avr-elf"], "board": "no-such-board"},
                        "no shipped board 'no-such-board'"),
                       ({"board": "mega2560-gy86"}, "dut: "),
                       ({"firmware": kinds["avr-elf"], "board": "promini328-gy86"},
                        "bytes; the MCU has 32768")):  # (the ATmega328P: 32 KiB of flash)
        status, answer = service.call("POST", "/api/runs", {"scenarios": ["step_roll"], "dut": dut})
        assert status == 422 and words in problems(answer), (dut, answer)
    status, answer = service.call("POST", "/api/runs", {"scenarios": ["step_roll"], "mode": "bridge",
                                                        "dut": {"firmware": kinds["intel-hex"],
                                                                "board": "mega2560-gy86"}})
    assert status == 422 and "not in mode bridge" in problems(answer)
    assert service.call("GET", "/api/runs")[1] == []  # nothing was queued


def test_boards_are_shipped_or_uploaded_and_checked(service: Service) -> None:
    shipped = {b["board"]: b["mcu"] for b in service.call("GET", "/api/boards")[1]}
    assert shipped == {"mega2560-gy86": "atmega2560", "promini328-gy86": "atmega328p",
                       "nano328-gy521": "atmega328p", "stm32f405-gy86": "stm32f405",
                       "stm32f411-blackpill-gy86": "stm32f411"}
    text = BOARD.read_text()
    z80 = text.replace('mcu = "atmega2560"', 'mcu = "z80"').encode()
    status, answer = post_bytes(service, "/api/boards", z80)
    assert status == 422 and "board.mcu" in problems(answer) and "z80" in problems(answer)
    outside = text.replace("fc = true", 'image = "/etc/passwd"').encode()
    status, answer = post_bytes(service, "/api/boards", outside)
    assert status == 422 and "eeprom.image" in problems(answer), answer
    mine = text.replace('name = "', 'name = "my ', 1).encode()
    status, answer = post_bytes(service, "/api/boards", mine)
    assert status == 201 and answer["sha256"] == hashlib.sha256(mine).hexdigest()
    assert answer["mcu"] == "atmega2560"
    assert answer["name"].startswith("my ")
    listed = {b["board"]: b["origin"] for b in service.call("GET", "/api/boards")[1]}
    assert listed[answer["sha256"]] == "uploaded"


def test_an_avr_image_flies_on_an_uploaded_board_and_through_rig_submit(service: Service, avr_fc: Path,
                                                                       tmp_path: Path) -> None:
    assert post_bytes(service, "/api/scenarios?name=short", SHORT_BENCH.encode())[0] == 201
    board, image = board_and_image(service, avr_fc)
    status, body = service.call("POST", "/api/runs", {"scenarios": ["short"],
                                                      "dut": {"firmware": image, "board": board}})
    assert status == 201
    run = service.follow(body["id"])
    assert run["status"] == "passed", run
    result = service.call("GET", f"/api/runs/{body['id']}/artifacts/short/result.json")[1]
    assert result["metadata"]["dut_firmware_sha256"] == hashlib.sha256(avr_fc.read_bytes()).hexdigest()
    assert result["metadata"]["board"].startswith("my ")
    # the command line: the image uploaded, a shipped board by name, the run followed to its end
    board_file = tmp_path / "board.toml"
    board_file.write_text(BOARD.read_text().replace('name = "', 'name = "my ', 1))
    for given in ("mega2560-gy86", str(board_file)):
        done = subprocess.run([sys.executable, "-m", "rig.cli", "submit", "--server", service.url, "short",
                               "--firmware", str(avr_fc), "--board", given, "--wait"],
                              capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        assert "passed" in done.stderr.splitlines()[-1]
    done = subprocess.run([sys.executable, "-m", "rig.cli", "submit", "--server", service.url, "short",
                           "--firmware", str(avr_fc)], capture_output=True, text=True)
    assert done.returncode == 2 and "it flies on a board" in done.stderr and "Traceback" not in done.stderr


def test_the_page_uploads_an_image_and_a_board_and_flies_them(service: Service, avr_fc: Path,
                                                              tmp_path: Path) -> None:
    from playwright.sync_api import expect

    from tests.browser import chromium_page

    assert post_bytes(service, "/api/scenarios?name=short", SHORT_BENCH.encode())[0] == 201
    (tmp_path / "picture.png").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(20))
    (tmp_path / "board.toml").write_text(BOARD.read_text().replace('name = "', 'name = "my ', 1))
    with chromium_page(service.url + "/") as (page, errors):
        page.set_input_files("#upload-firmware", str(tmp_path / "picture.png"))
        refused = page.locator("#upload-refused")
        expect(refused).to_contain_text("picture.png not uploaded: the upload is a PNG image")
        page.set_input_files("#upload-firmware", str(avr_fc))
        expect(page.locator("#upload-done")).to_contain_text("(avr-elf, ")
        page.set_input_files("#upload-board", str(tmp_path / "board.toml"))
        expect(page.locator("#upload-done")).to_contain_text("my ")
        image = hashlib.sha256(avr_fc.read_bytes()).hexdigest()
        board = hashlib.sha256((tmp_path / "board.toml").read_bytes()).hexdigest()
        assert page.locator("#start select[name=firmware]").input_value() == image  # (chosen)
        assert page.locator("#start select[name=board]").input_value() == board
        page.select_option("#start select[name=scenarios]", ["short"])
        page.click("#start button")
        expect(page.locator("#started")).to_contain_text("queued run")
        started = int(page.locator("#started a").inner_text().split()[-1])
        assert not errors, errors
    run = service.follow(started)
    assert run["dut"] == {"firmware": image, "board": board} and run["status"] == "passed", run


def test_an_arm_image_flies_on_an_stm32_board_and_the_wrong_pairs_are_refused(service: Service,
                                                                             avr_fc: Path) -> None:
    """An ARM ELF (the ELF specification: EM_ARM = 40, ELFCLASS32, little-endian) is kind arm-elf; on
    stm32f405-gy86 it flies (the STM32 tier's hover firmware, as tests/stm32/test_run.py flies it with
    rig run); an ARM image on an AVR board and an AVR image on an STM32 board are refused naming both."""
    engine_or_skip()
    hover = firmware("hover_rate")
    status, arm = post_bytes(service, "/api/firmware", hover.read_bytes())
    assert status == 201 and arm["kind"] == "arm-elf", arm
    assert arm["sha256"] == hashlib.sha256(hover.read_bytes()).hexdigest()
    status, avr = post_bytes(service, "/api/firmware", avr_fc.read_bytes())
    assert status == 201 and avr["kind"] == "avr-elf", avr
    status, header_only = post_bytes(service, "/api/firmware", elf_header(40))
    assert status == 201 and header_only["kind"] == "arm-elf", header_only
    for dut, words in (({"firmware": arm["sha256"], "board": "mega2560-gy86"},
                        "the board mega2560-gy86 (atmega2560) flies an AVR image (ELF or Intel HEX); "
                        f"{arm['sha256'][:12]} is an ARM image (ELF)"),
                       ({"firmware": avr["sha256"], "board": "stm32f405-gy86"},
                        "the board stm32f405-gy86 (stm32f405) flies an ARM image (ELF); "
                        f"{avr['sha256'][:12]} is an AVR image (ELF)"),
                       ({"firmware": arm["sha256"]}, "is an ARM image (ELF): it flies on a board"),
                       ({"firmware": header_only["sha256"], "board": "stm32f405-gy86"},
                        "nothing loads at the start of flash")):
        status, answer = service.call("POST", "/api/runs", {"scenarios": ["step_roll"], "dut": dut})
        assert status == 422 and words in problems(answer), (dut, answer)
        assert len(problems(answer).splitlines()) == 1
    assert service.call("GET", "/api/runs")[1] == []  # nothing was queued
    assert post_bytes(service, "/api/scenarios?name=stm32_hover", STM32_HOVER.encode())[0] == 201
    status, body = service.call("POST", "/api/runs", {"scenarios": ["stm32_hover"],
                                                      "dut": {"firmware": arm["sha256"],
                                                              "board": "stm32f405-gy86"}})
    assert status == 201, body
    run = service.follow(body["id"])
    assert run["status"] == "passed", (run, service.call("GET", f"/api/runs/{body['id']}/artifacts")[1])
    result = service.call("GET", f"/api/runs/{body['id']}/artifacts/stm32_hover/result.json")[1]
    assert result["metadata"]["dut_firmware_sha256"] == arm["sha256"]
    assert result["metadata"]["board"] == "stm32f405-gy86" and result["metadata"]["mode"] == "mcu"
