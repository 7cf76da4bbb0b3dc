"""mypyc's analysis and the linters' mypy run side by side in `make test` (-j2) and must share no cache.

mypy 2 keeps its cache in SQLite databases under `.mypy_cache`; when mypyc's build used the same folder,
one of the two failed with "database is locked" under load. rig/mypyc_build.py gives mypyc a cache of
its own in the build's temporary folder."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

MODULE = "def twice(x: int) -> int:\n    return 2 * x\n"


def _mypyc_analysis(cwd: Path, cache_parent: Path) -> subprocess.Popen[str]:
    """mypyc's own entry (mypycify: mypy's analysis and the C it generates, no compiler run) with the
    build's options, in a process of its own as `make` runs it."""
    code = ("import sys\nfrom pathlib import Path\nfrom mypyc.build import mypycify\n"
            "from rig.mypyc_build import mypyc_options\n"
            "mypycify([*mypyc_options(Path(sys.argv[1])), 'hot.py'], target_dir='c', multi_file=True)\n")
    return subprocess.Popen([sys.executable, "-c", code, str(cache_parent)], cwd=cwd, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)


def test_mypyc_analysis_writes_nothing_into_mypys_cache(tmp_path: Path) -> None:
    (tmp_path / "hot.py").write_text(MODULE)
    done = _mypyc_analysis(tmp_path, tmp_path / "build")
    out, _ = done.communicate(timeout=300)
    assert done.returncode == 0, out
    assert not (tmp_path / ".mypy_cache").exists()
    assert any((tmp_path / "build" / "mypy-cache").rglob("*.db"))


def test_mypy_and_mypyc_side_by_side_both_succeed(tmp_path: Path) -> None:
    (tmp_path / "hot.py").write_text(MODULE)
    lint = subprocess.Popen([sys.executable, "-m", "mypy", "hot.py"], cwd=tmp_path, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    build = _mypyc_analysis(tmp_path, tmp_path / "build")
    lint_out, _ = lint.communicate(timeout=300)
    build_out, _ = build.communicate(timeout=300)
    assert lint.returncode == 0, lint_out
    assert build.returncode == 0, build_out
    assert any((tmp_path / ".mypy_cache").rglob("*.db"))  # the linters' cache ...
    assert any((tmp_path / "build" / "mypy-cache").rglob("*.db"))  # ... and mypyc's, apart
