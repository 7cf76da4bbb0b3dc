"""How `make stm32-engine` finds its engine (rig/mcu/stm32_engine.py): the cache key covers every input
and nothing else, the private apt state takes the machine's own Debian archives, and the cache is found
again without building. The build itself is the engine tests' (tests/stm32/test_clock_gpio.py)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from rig.mcu import stm32_engine
from tests.stm32.conftest import REPO, engine_or_skip


def _models(tmp: Path) -> Path:
    models = tmp / "models"
    shutil.copytree(stm32_engine.MODELS, models)
    return models


def _dsc(tmp: Path, text: str = "Source: qemu\nVersion: 1:7.2+dfsg-7+deb12u18\n") -> Path:
    (tmp / "src").mkdir(parents=True, exist_ok=True)
    dsc = tmp / "src" / "qemu_7.2+dfsg-7+deb12u18.dsc"
    dsc.write_text(text)
    return dsc


def test_the_key_follows_each_input_and_nothing_else(tmp_path: Path) -> None:
    models, dsc = _models(tmp_path), _dsc(tmp_path)
    key = stm32_engine.inputs_hash(dsc, models)
    assert len(key) == 64 and key == stm32_engine.inputs_hash(dsc, models)

    machine = models / "hw" / "rig_stm32f405.c"
    machine.touch()  # a newer time, the same bytes: the same engine
    assert stm32_engine.inputs_hash(dsc, models) == key

    original = machine.read_bytes()
    machine.write_bytes(original + b"\n")
    assert stm32_engine.inputs_hash(dsc, models) != key
    machine.write_bytes(original)
    machine.rename(models / "hw" / "renamed.c")  # a file's name is an input too
    assert stm32_engine.inputs_hash(dsc, models) != key
    (models / "hw" / "renamed.c").rename(machine)

    _dsc(tmp_path, "Source: qemu\nVersion: 1:7.2+dfsg-7+deb12u19\n")
    assert stm32_engine.inputs_hash(dsc, models) != key


def test_the_cached_engine_is_found_without_building(tmp_path: Path) -> None:
    cache = tmp_path / "cache"
    assert stm32_engine.cached_binary(cache) is None  # no source package: nothing is fetched here
    dsc = _dsc(cache)
    assert stm32_engine.cached_binary(cache) is None  # not built
    binary = cache / stm32_engine.inputs_hash(dsc)[:16] / "qemu-system-arm"
    binary.parent.mkdir(parents=True)
    binary.write_bytes(b"\x7fELF")
    assert stm32_engine.cached_binary(cache) == binary


def test_the_cache_keeps_the_engines_used_last(tmp_path: Path) -> None:
    for i in range(6):
        engine = tmp_path / f"{i:016x}"
        engine.mkdir()
        os.utime(engine, (1_000_000 + i, 1_000_000 + i))
    (tmp_path / "src").mkdir()
    (tmp_path / "work-7.2").mkdir()
    stm32_engine.prune(tmp_path, keep=4)
    newest_four = [f"{i:016x}" for i in range(2, 6)]
    assert sorted(p.name for p in tmp_path.iterdir()) == [*newest_four, "src", "work-7.2"]


def test_the_private_apt_state_takes_the_machines_debian_archives(tmp_path: Path) -> None:
    etc = tmp_path / "apt"
    (etc / "sources.list.d").mkdir(parents=True)
    (etc / "sources.list").write_text("# a comment\ndeb http://mirror.example/debian bookworm main contrib\n"
                                      "deb http://mirror.example/debian trixie main\n")
    (etc / "sources.list.d" / "debian.sources").write_text(
        "Types: deb\nURIs: http://archive.example/debian\nSuites: bookworm bookworm-updates\n"
        "Components: main\nSigned-By: /usr/share/keyrings/debian-archive-keyring.gpg\n\n"
        "Types: deb\nURIs: http://security.example/debian-security\nSuites: bookworm-security\n"
        "Components: main\n\n"
        "Types: deb\nURIs: http://off.example/debian\nSuites: bookworm\nComponents: main\nEnabled: no\n")
    (etc / "sources.list.d" / "vendor.sources").write_text(
        "Types: deb\nURIs: https://vendor.example/apt\nSuites: nodistro\nComponents: main\n")
    signed = "[signed-by=/usr/share/keyrings/debian-archive-keyring.gpg]"
    assert stm32_engine.deb_src_lines("bookworm", etc) == [
        "deb-src http://mirror.example/debian bookworm main contrib",
        f"deb-src {signed} http://archive.example/debian bookworm main",
        f"deb-src {signed} http://archive.example/debian bookworm-updates main",
        "deb-src http://security.example/debian-security bookworm-security main",
    ]


def test_a_second_make_builds_nothing_and_says_where_the_engine_is() -> None:
    binary = engine_or_skip()
    done = subprocess.run([sys.executable, "-m", "rig.mcu.stm32_engine"], cwd=REPO, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == [f"stm32-engine: {binary}"]
    where = subprocess.run([sys.executable, "-m", "rig.mcu.stm32_engine", "--where"], cwd=REPO,
                           capture_output=True, text=True, timeout=60)
    assert where.stdout.strip() == str(binary)

