"""The suite's rules (tests/suite_rules.py) on a small suite of their own, run by pytest in a process of its
own as `make test` runs the suite, with pytest-xdist too: the paced tests that verified nothing are
counted and fail the run above the share; an inconclusive test that is not paced fails; a slow test
that names no default-run test covering it stops the run."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.realtime import INCONCLUSIVE
from tests.suite_rules import MAX_UNVERIFIED_SHARE, NOT_BUILT

REPO = Path(__file__).resolve().parents[1]
INI = """[pytest]
addopts = -p tests.suite_rules --strict-markers -p no:cacheprovider -p no:hypothesispytest -p no:rig
markers =
    slow: slow
    paced: paced
"""


def suite(tmp_path: Path, body: str, *args: str) -> subprocess.CompletedProcess[str]:
    (tmp_path / "pytest.ini").write_text(INI)
    (tmp_path / "test_it.py").write_text("import pytest\n\n" + body)
    return subprocess.run([sys.executable, "-m", "pytest", "-q", *args], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120, env={**os.environ, "PYTHONPATH": str(REPO)})


def paced(passed: int, inconclusive: int, skipped: int) -> str:
    """A suite of paced tests: so many pass, so many end inconclusive, so many skip for another reason."""
    tests = [f"def test_pass_{k}():\n    assert True\n" for k in range(passed)]
    tests += [f"def test_starved_{k}():\n    pytest.skip({INCONCLUSIVE + 'starved twice'!r})\n"
              for k in range(inconclusive)]
    tests += [f"def test_no_root_{k}():\n    pytest.skip('needs root')\n" for k in range(skipped)]
    return "pytestmark = pytest.mark.paced\n\n" + "\n".join(tests)


def test_the_stated_share_is_half() -> None:
    assert MAX_UNVERIFIED_SHARE == 0.5  # (tests/README.md states it)


COVER = "tests/test_cover.py::test_cover"


def test_unverified_paced_tests_are_counted_and_an_unpaced_inconclusive_test_fails(tmp_path: Path) -> None:
    """2 of 4 paced tests unverified: not over half. Beside them a test that ends inconclusive without
    the paced marker (fails), and a slow test naming the test that covers it (runs)."""
    (tmp_path / "tests").mkdir()  # (the rule reads the named file under the suite's root)
    (tmp_path / "tests" / "test_cover.py").write_text("def test_cover():\n    pass\n")
    others = (f"@pytest.mark.slow(reason='a soak of {COVER}')\ndef test_soak():\n    pass\n\n"
              f"def test_unmarked():\n    pytest.skip({INCONCLUSIVE + 'starved'!r})\n")
    (tmp_path / "test_others.py").write_text("import pytest\n\n" + others)
    done = suite(tmp_path, paced(2, 1, 1), "test_it.py", "test_others.py")
    assert done.returncode == 1, done.stdout + done.stderr
    assert "paced tests: 4; inconclusive (the host could not keep real time): 1; skipped for another " \
           "reason: 1" in done.stdout, done.stdout
    assert "test_it.py::test_no_root_0: needs root" in done.stdout and "FAILED: " not in done.stdout
    assert "1 failed, 3 passed, 2 skipped" in done.stdout, done.stdout  # the soak ran, as asked
    assert "FAILED test_others.py::test_unmarked" in done.stdout and "mark it paced" in done.stdout
    assert "inconclusive: starved" in done.stdout, done.stdout  # (the reason kept)


def test_over_half_unverified_fails_the_run_under_xdist_too(tmp_path: Path) -> None:
    over = suite(tmp_path, paced(1, 2, 1), "-n", "1")  # 3 of 4: a controller and its worker, as in make test
    assert over.returncode == 1, over.stdout
    assert "FAILED: 75% of the paced tests verified nothing, over the 50% allowed" in over.stdout
    assert "1 passed, 3 skipped" in over.stdout  # (no test failed: the count did)


def test_a_slow_test_names_a_default_run_test_covering_it(tmp_path: Path) -> None:
    body = ("@pytest.mark.slow\ndef test_bare():\n    pass\n\n"
            "@pytest.mark.slow(reason='tests/nowhere.py::test_x')\ndef test_lost():\n    pass\n\n"
            "@pytest.mark.slow(reason='test_it.py::test_bare')\ndef test_loop():\n    pass\n")
    done = suite(tmp_path, body, "-m", "not slow")  # (checked though none of them runs)
    assert done.returncode == pytest.ExitCode.USAGE_ERROR, done.stdout + done.stderr
    assert "test_it.py::test_bare: slow without naming the default-run test that covers it" in done.stderr
    assert "test_it.py::test_lost: its slow marker names tests/nowhere.py::test_x, which is not there" \
        in done.stderr
    assert "test_it.py::test_loop: slow without naming" in done.stderr  # (a test outside tests/: none)


def test_a_skip_for_a_missing_build_fails_a_run_told_everything_was_built(tmp_path: Path) -> None:
    """make test builds first and says so (--built): a test that then finds its build missing fails
    (a green run would have checked none of it); without --built (a developer's partial run) it skips."""
    body = (f"def test_needs_an_engine():\n    pytest.skip({NOT_BUILT + 'the engine (make engine)'!r})\n\n"
            "def test_needs_root():\n    pytest.skip('needs root')\n")
    told = suite(tmp_path, body, "--built", "-n", "1")
    assert told.returncode == 1, told.stdout
    assert "1 failed, 1 skipped" in told.stdout, told.stdout
    assert "FAILED test_it.py::test_needs_an_engine" in told.stdout and "(--built)" in told.stdout
    assert "not built: the engine (make engine)" in told.stdout, told.stdout  # (the reason kept)
    untold = suite(tmp_path, body)
    assert untold.returncode == 0 and "2 skipped" in untold.stdout, untold.stdout
