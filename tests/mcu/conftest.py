"""The MCU tier's tests run real firmwares (tests/mcu/firmware, built by make mcu-test-firmware) under the
real engine: `firmware(name, mcu)` builds what is missing or stale through make, as the rig's C libraries
are built on first use; the `avr_fc` fixture is the AVR reference FC (make avr)."""

from __future__ import annotations

import functools
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
MCUS = ("atmega328p", "atmega2560")


@functools.cache  # (once a session: make's own check costs 50-100 ms)
def firmware(name: str, mcu: str) -> Path:
    target = f"build/mcu/test/{name}-{mcu}.elf"
    done = subprocess.run(["make", "-s", "--no-print-directory", target], cwd=REPO, capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stderr
    return REPO / target


@pytest.fixture(scope="session")
def avr_fc() -> Path:
    """build/avr/fc.elf, the AVR reference FC, brought up to date by make."""
    done = subprocess.run(["make", "-s", "--no-print-directory", "avr"], cwd=REPO, capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stderr
    return REPO / "build" / "avr" / "fc.elf"
