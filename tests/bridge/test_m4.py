"""The Cortex-M4 runs of the bridge core's tests (tests/bridge/tools.py: run_m4, Tool): QEMU's exit
status is the program's, a run that hangs is killed at its timeout and leaves no QEMU behind, and a
difference between the host and the M4 is an error, never silently passed over."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

from tests.bridge.tools import CHIP_CORE, Tool, bridge_tool, run_m4


@pytest.fixture(scope="module")
def m4_tool() -> Path:
    return bridge_tool(CHIP_CORE, m4=True)


def test_the_programs_exit_status_is_qemus(m4_tool: Path, tmp_path: Path) -> None:
    (tmp_path / "s").write_text("t 5\nstatus\n")
    ok = run_m4(m4_tool, [str(tmp_path / "s"), str(tmp_path / "o")])
    assert ok.returncode == 0
    assert (tmp_path / "o").read_text().endswith("silent 0 agreed 0 preload_misses 0\n")
    missing = run_m4(m4_tool, [str(tmp_path / "nothing-here"), str(tmp_path / "o")])
    assert missing.returncode == 2 and "cannot open" in missing.stderr
    (tmp_path / "bad").write_text("frobnicate\n")
    assert run_m4(m4_tool, [str(tmp_path / "bad"), str(tmp_path / "o")]).returncode == 2


def qemus() -> set[int]:
    out = set()
    for d in Path("/proc").iterdir():
        try:
            if d.name.isdigit() and (d / "comm").read_text().strip() == "qemu-system-arm":
                out.add(int(d.name))
        except OSError:
            continue
    return out


def test_a_run_that_hangs_is_killed_and_leaves_no_qemu(m4_tool: Path, tmp_path: Path) -> None:
    fifo = tmp_path / "never-written"
    os.mkfifo(fifo)  # opening it for reading blocks until a writer comes: none does
    before = qemus()
    with pytest.raises(subprocess.TimeoutExpired):
        run_m4(m4_tool, [str(fifo), str(tmp_path / "o")], timeout=1.0)
    assert qemus() <= before


def test_a_difference_between_host_and_m4_is_an_error(m4_tool: Path) -> None:
    right = Tool(host=bridge_tool(CHIP_CORE), m4=m4_tool, m4_twin=bridge_tool(CHIP_CORE))
    assert right.run("t 1\nstatus\n").endswith("silent 0 agreed 0 preload_misses 0\n")
    # a twin that prints something else than the M4's bridge_tool does
    wrong = Tool(host=bridge_tool(CHIP_CORE), m4=m4_tool, m4_twin=Path("/bin/echo"))
    with pytest.raises(AssertionError, match="differ at line 1"):
        wrong.run("t 1\nstatus\n")
