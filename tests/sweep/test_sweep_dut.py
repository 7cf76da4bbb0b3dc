"""A sweep's runs are its DUT's: the folder records the DUT (its command and the SHA-256 of its
firmware), every row and runs.parquet carry it, summary.html and junit.xml name it, and a resume with
another DUT, or with the same path rebuilt, is refused (exit 2, naming both, nothing written) unless
--fresh. Each sweep here is step_roll at two seeds; the DUTs other than the reference FC end at once
(error rows)."""

from __future__ import annotations

import hashlib
import xml.etree.ElementTree as ET
from pathlib import Path

from rig.sweep import store
from rig.targets import REFERENCE_FC
from tests.sweep.test_sweep_cli import sweep

SPEC = '[sweep]\nscenario = "step_roll"\nseeds = [3, 5]\n'


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def snapshot(folder: Path) -> dict[str, tuple[int, int]]:
    """Every file of the folder with its size and modification time (the lock file aside: it only says
    who holds the folder)."""
    return {
        str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns)
        for p in folder.rglob("*")
        if p.is_file() and p.name != ".rig-run.lock"
    }


def test_a_resume_with_another_dut_is_refused_unless_fresh(tmp_path: Path) -> None:
    spec, out = tmp_path / "spec.toml", tmp_path / "out"
    spec.write_text(SPEC)
    r = sweep(spec, "--out", out)
    assert r.returncode == 0, r.stderr
    fc = sha256(REFERENCE_FC)
    t = store.read(out / store.TABLE)
    assert t["dut_command"] == [f"reference FC {REFERENCE_FC}"] * 2 and t["dut_sha256"] == [fc] * 2
    page = (out / "summary.html").read_text()
    assert str(REFERENCE_FC) in page and fc in page
    props = {p.get("name"): p.get("value") for p in ET.parse(out / "junit.xml").getroot().iter("property")}
    assert props["dut_command"] == f"reference FC {REFERENCE_FC}" and props["dut_sha256"] == fc
    before = snapshot(out)
    r = sweep(spec, "--out", out, "--dut", "/bin/false")
    false = sha256(Path("/bin/false"))
    assert r.returncode == 2, r.stderr
    assert all(s in r.stderr for s in (str(REFERENCE_FC), fc, "/bin/false", false, "--fresh")), r.stderr
    assert "done already" not in r.stderr and snapshot(out) == before
    r = sweep(spec, "--out", out, "--dut", "/bin/false", "--fresh")
    assert r.returncode == 3 and "0 done already, 2 to run" in r.stderr, r.stderr
    t = store.read(out / store.TABLE)
    assert t["verdict"] == ["error"] * 2
    assert t["dut_command"] == ["/bin/false"] * 2 and t["dut_sha256"] == [false] * 2
    page = (out / "summary.html").read_text()
    assert "/bin/false" in page and false in page and fc not in page


def test_a_dut_rebuilt_at_the_same_path_is_refused_unless_fresh(tmp_path: Path) -> None:
    spec, out, dut = tmp_path / "spec.toml", tmp_path / "out", tmp_path / "dut.sh"
    spec.write_text(SPEC)
    dut.write_text("#!/bin/sh\nexit 1\n")
    dut.chmod(0o755)
    first = sha256(dut)
    r = sweep(spec, "--out", out, "--dut", dut)
    assert r.returncode == 3 and "0 done already, 2 to run" in r.stderr, r.stderr
    assert store.read(out / store.TABLE)["dut_sha256"] == [first] * 2
    r = sweep(spec, "--out", out, "--dut", dut)  # the same DUT: a resume, nothing to fly
    assert r.returncode == 3 and "2 done already, 0 to run" in r.stderr, r.stderr
    dut.write_text("#!/bin/sh\nexit 2\n")  # rebuilt at the same path
    second = sha256(dut)
    before = snapshot(out)
    r = sweep(spec, "--out", out, "--dut", dut)
    assert r.returncode == 2 and first in r.stderr and second in r.stderr and str(dut) in r.stderr, r.stderr
    assert snapshot(out) == before
    r = sweep(spec, "--out", out, "--dut", dut, "--fresh")
    assert r.returncode == 3 and "0 done already, 2 to run" in r.stderr, r.stderr
    assert store.read(out / store.TABLE)["dut_sha256"] == [second] * 2
