"""What the farm takes from others is checked before it is used: a worker's archive of a run's folder
is unpacked only as regular files and folders inside it (no absolute path, no ``..``, no link out, no
device), and a bench's entry in the scheduler's metadata, which anyone reaching the scheduler can
write, is used only in the shape `rig bench-host` gives it."""

from __future__ import annotations

import io
import tarfile
from pathlib import Path

import pytest

from rig.service.farm import _pack, matches, published_bench, unpack


def archive(*members: tuple[str, bytes | None, bytes]) -> bytes:
    """A tar.gz of (name, link target or None, data) members."""
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w:gz") as tar:
        for name, link, data in members:
            info = tarfile.TarInfo(name)
            if link is not None:
                info.type, info.linkname = tarfile.SYMTYPE, link.decode()
            else:
                info.size = len(data)
            tar.addfile(info, io.BytesIO(data) if link is None else None)
    return buf.getvalue()


def test_a_run_folder_round_trips_without_its_inputs(tmp_path: Path) -> None:
    run = tmp_path / "run"
    (run / "step_roll").mkdir(parents=True)
    (run / "step_roll" / "result.json").write_text("{}")
    (run / ".scenarios").mkdir()
    (run / ".scenarios" / "step_roll.toml").write_text("x")
    back = tmp_path / "back"
    unpack(_pack(run, {".scenarios"}), back)
    assert sorted(str(p.relative_to(back)) for p in back.rglob("*")) == ["step_roll", "step_roll/result.json"]


@pytest.mark.parametrize("member", [("../escaped", None, b"x"), ("/tmp/absolute", None, b"x"),
                                    ("link", b"/etc/passwd", b"")])
def test_an_archive_reaching_out_of_the_run_folder_is_refused(
    tmp_path: Path, member: tuple[str, bytes | None, bytes]
) -> None:
    folder = tmp_path / "runs" / "7"
    with pytest.raises(ValueError, match="came back unreadable"):
        unpack(archive(("ok.txt", None, b"fine"), member), folder)
    assert not (tmp_path / "runs" / "escaped").exists() and not (folder / "link").exists()
    assert not (folder / "tmp").exists()


def test_garbage_is_no_archive(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="came back unreadable"):
        unpack(b"not a tar", tmp_path)


def test_only_a_bench_host_shaped_entry_is_a_bench() -> None:
    good = {"name": "a", "host": "h", "bridge": "virtual", "psu": None, "labels": {"site": "x"}}
    assert published_bench("a", good) and matches(good, {"site": "x"}) and not matches(good, {"site": "y"})
    assert matches(good, {})  # (no selector: any bench)
    for name, bad in [("a", {**good, "labels": ["site=x"]}), ("a", {**good, "labels": {"site": 3}}),
                      ("b", good), ("../a", {**good, "name": "../a"}), ("a", "a bench"),
                      ("a", {**good, "host": None})]:
        assert not published_bench(name, bad), bad


def test_a_workers_progress_report_is_taken_only_for_a_run_in_flight(tmp_path: Path) -> None:
    from rig.service.db import Db
    from rig.service.farm import Farm, Flight
    from rig.service.store import Store

    db = Db(tmp_path / "rig.sqlite")
    try:
        farm = Farm(db, tmp_path / "runs", Store(tmp_path, db), "tcp://127.0.0.1:1")
        run_id = db.submit(["step_roll"], 0, {}, "lockstep", 0)
        run = db.claim("lockstep")
        assert run is not None
        farm._flights[run_id] = Flight(run, None, {})
        for bad in [{"run": run_id, "progress": 150.0}, {"run": True, "progress": 10.0},
                    {"run": str(run_id), "progress": 10.0}, {"run": run_id + 1, "progress": 10.0},
                    {"run": run_id, "progress": "50"}, "50"]:
            farm._progressed((0.0, bad))
        assert (db.get(run_id) or {})["progress"] == 0.0
        farm._progressed((0.0, {"run": run_id, "progress": 50.0}))
        assert (db.get(run_id) or {})["progress"] == 50.0
    finally:
        db.close()
