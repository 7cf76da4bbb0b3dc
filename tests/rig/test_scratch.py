"""The rig's temporary folders (rig/scratch.py): a folder whose owner was killed with SIGKILL is removed
by the next rig, and nothing else is: not a live owner's, not a young one's, not one without an owner
file, not one whose owner lived in another pid namespace. A reused pid (a live process with the
owner's id but another start time) does not keep a dead run's folder."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from rig import scratch

OLD = scratch.GRACE_S + 1  # (s) how far back a folder's time is set, to be judged at all


def _aged(path: Path) -> Path:
    t = time.time() - OLD
    os.utime(path, (t, t))
    return path


def _killed_owners_folder(root: Path) -> Path:
    """A folder made by another process, which is then killed with SIGKILL (it never cleans up)."""
    code = ("import sys; from pathlib import Path; from rig import scratch; "
            "print(scratch.make('session', Path(sys.argv[1])), flush=True); sys.stdin.read()")
    child = subprocess.Popen([sys.executable, "-c", code, str(root)], stdin=subprocess.PIPE,
                             stdout=subprocess.PIPE, text=True, cwd=Path(__file__).resolve().parents[2])
    assert child.stdout is not None
    path = Path(child.stdout.readline().strip())
    assert path.is_dir() and (path / scratch.OWNER).is_file()
    child.send_signal(signal.SIGKILL)
    child.wait(timeout=30)
    assert child.stdin is not None
    child.stdin.close()
    child.stdout.close()
    return path


def test_a_killed_owners_folder_goes_and_a_live_ones_stays(tmp_path: Path) -> None:
    dead = _killed_owners_folder(tmp_path)
    (dead / "rig.sock").write_bytes(b"")  # what a session leaves (its socket, page, fakes)
    live = scratch.make("bench", tmp_path)
    assert scratch.reap(tmp_path) == []  # both young: neither judged yet
    _aged(dead), _aged(live)
    assert scratch.reap(tmp_path) == [dead]
    assert not dead.exists() and live.is_dir()


def test_a_reused_pid_does_not_keep_a_dead_runs_folder(tmp_path: Path) -> None:
    """Our own pid, but a start time that is not ours: the process that wrote it is gone."""
    folder = scratch.make("run", tmp_path)
    pid, start, namespace = (folder / scratch.OWNER).read_text().split()
    assert int(pid) == os.getpid() and start.isdigit()
    (folder / scratch.OWNER).write_text(f"{pid} {int(start) + 1} {namespace}\n")
    assert scratch.reap(tmp_path, now=time.time() + OLD) == [folder]


def test_what_it_cannot_judge_it_leaves(tmp_path: Path) -> None:
    no_owner = tmp_path / "rig-session-x"
    no_owner.mkdir()
    _aged(no_owner)
    elsewhere = scratch.make("session", tmp_path)  # a dead pid, but in another pid namespace
    (elsewhere / scratch.OWNER).write_text("999999 1 pid:[1]\n")
    garbled = scratch.make("session", tmp_path)
    (garbled / scratch.OWNER).write_text("not an owner\n")
    not_ours = _aged(scratch.make("x", tmp_path).rename(tmp_path / "other-x"))  # not rig-*
    (not_ours / scratch.OWNER).write_text("999999 1 x\n")
    later = time.time() + OLD
    assert scratch.reap(tmp_path, now=later) == []
    assert all(p.is_dir() for p in (no_owner, elsewhere, garbled, not_ours))
    assert scratch.reap(tmp_path / "missing", now=later) == []


def test_the_folder_goes_after_its_with(tmp_path: Path) -> None:
    with scratch.folder("farm", tmp_path) as f:
        assert f.name.startswith("rig-farm-") and (f / scratch.OWNER).is_file()
    assert not f.exists()


def test_every_rig_command_reaps_first(tmp_path: Path) -> None:
    """`rig` itself (here `rig --version`) removes a killed run's folder from its temporary directory."""
    dead = _aged(_killed_owners_folder(tmp_path))
    env = {**os.environ, "TMPDIR": str(tmp_path)}
    done = subprocess.run([sys.executable, "-m", "rig.cli", "--version"], env=env, capture_output=True,
                          text=True, timeout=120, cwd=Path(__file__).resolve().parents[2])
    assert done.returncode == 0, done.stderr
    assert not dead.exists()
