"""The suite's own rules, checked on every run (tests/README.md says them for people):

* A ``slow`` test (never run by ``make test``) names the default-run test that covers its behaviour:
  ``@pytest.mark.slow(reason="... tests/PATH.py::test_name")``. A slow test without one, or naming a test
  that is not there or is slow itself, stops the run at collection: a behaviour only ``make test-slow``
  checks is a behaviour CI never checks. (Checked by a run without pytest-xdist: make test's second
  part, make test-slow, a run of a few files.)
* A test that ends inconclusive (``pytest.skip`` with ``INCONCLUSIVE``: tests/realtime.py, the host
  could not keep real time) is a ``paced`` test; one that is not fails, saying so, so that every
  inconclusive test is counted below.
* A test skipped because a build it needs is missing (``pytest.skip`` with ``NOT_BUILT``) fails in a run
  given ``--built``, as make test's runs are: make test built everything first, so such a skip means a
  build went missing (an engine pruned from the cache by another worktree's build, say) and the run
  would go green having checked none of it.
* At the end of a run with paced tests the count is printed: how many were inconclusive, how many
  skipped for another reason (a missing privilege, say). Either way the test verified no real-time
  path; more than ``MAX_UNVERIFIED_SHARE`` of the paced tests unverified fails the run, which is then
  not green however the other tests went (``--max-unverified-paced`` sets another share).

Works under pytest-xdist: the reports reach the controller, which counts; a worker's own session only
rewrites the reports of the tests it ran."""

from __future__ import annotations

import re
from collections.abc import Generator
from pathlib import Path
from typing import Any

import pytest

from tests.realtime import INCONCLUSIVE

#: the share of the paced tests that may end unverified (inconclusive or skipped) without failing the run
MAX_UNVERIFIED_SHARE = 0.5
#: the start of a skip's reason when a build the test needs is missing (fails under --built)
NOT_BUILT = "not built: "
#: how a slow test's reason names the default-run test that covers it
COVERED_BY = re.compile(r"(tests/[\w/]+\.py)::(\w+)")


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--max-unverified-paced", type=float, default=MAX_UNVERIFIED_SHARE, metavar="SHARE",
                     help="fail the run when more than this share of its paced tests ended inconclusive or "
                          f"skipped (default {MAX_UNVERIFIED_SHARE})")
    parser.addoption("--built", action="store_true",
                     help="every build the tests need was made before the run (make test): a test skipped "
                          "because one is missing fails")


def _skip_reason(report: pytest.TestReport) -> str:
    """A skipped report's reason, without pytest's "Skipped: " ("" for another report)."""
    longrepr = report.longrepr
    if not report.skipped or not isinstance(longrepr, (tuple, list)) or len(longrepr) != 3:
        return ""
    return str(longrepr[2]).removeprefix("Skipped: ")


def uncovered_slow_tests(items: list[pytest.Item], root: Path) -> list[str]:
    """Each slow test whose marker does not name an existing default-run test covering it, in words."""
    slow_ids = {item.nodeid.split("[")[0] for item in items if item.get_closest_marker("slow")}
    problems = []
    for item in items:
        marker = item.get_closest_marker("slow")
        if marker is None:
            continue
        test = item.nodeid.split("[")[0]  # (one line for all of a test's parameters)
        found = COVERED_BY.search(str(marker.kwargs.get("reason", "")))
        if found is None:
            problems.append(f"{test}: slow without naming the default-run test that covers it "
                            '(@pytest.mark.slow(reason="... tests/PATH.py::test_name"))')
            continue
        path, name = found.groups()
        source = root / path
        if not source.is_file() or not re.search(rf"^def {name}\(", source.read_text(), re.MULTILINE):
            problems.append(f"{test}: its slow marker names {path}::{name}, which is not there")
        elif f"{path}::{name}" in slow_ids:
            problems.append(f"{test}: its slow marker names {path}::{name}, slow itself")
    return sorted(set(problems))


@pytest.hookimpl(tryfirst=True)  # (before -m deselects the slow tests: every run checks them)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if hasattr(config, "workerinput"):  # (an xdist worker's error is lost in its controller's internal
        return  # error: the runs without -n check, make test's paced part among them)
    problems = uncovered_slow_tests(items, config.rootpath)
    if problems:
        raise pytest.UsageError("tests/suite_rules.py: " + "\n".join(problems))


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Generator[None, Any, Any]:
    report: pytest.TestReport = yield
    reason = _skip_reason(report)  # (read before the outcome changes: a failed report has none)
    if reason.startswith(INCONCLUSIVE) and item.get_closest_marker("paced") is None:
        report.outcome = "failed"
        report.longrepr = (f"{reason}\n(tests/suite_rules.py: a test that can end inconclusive "
                           "is paced by the wall clock: mark it paced, so that make test counts it)")
    elif reason.startswith(NOT_BUILT) and item.config.getoption("built"):
        report.outcome = "failed"
        report.longrepr = (f"{reason}\n(tests/suite_rules.py: this run was told every build "
                           "was made (--built), so a missing one is a failure, not a skip)")
    return report


class PacedCount:
    """The paced tests of this run and how each that verified nothing ended."""

    def __init__(self) -> None:
        self.paced: set[str] = set()
        self.inconclusive: dict[str, str] = {}
        self.skipped: dict[str, str] = {}

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        if "paced" not in report.keywords:
            return
        self.paced.add(report.nodeid)
        reason = _skip_reason(report)
        if reason:
            (self.inconclusive if reason.startswith(INCONCLUSIVE) else self.skipped)[report.nodeid] = reason

    def unverified_share(self) -> float:
        return (len(self.inconclusive) + len(self.skipped)) / len(self.paced) if self.paced else 0.0

    def pytest_terminal_summary(self, terminalreporter: Any, config: pytest.Config) -> None:
        if not self.paced:
            return
        limit = config.getoption("max_unverified_paced")
        over = self.unverified_share() > limit
        terminalreporter.write_sep("=", "paced tests", red=over, green=not over and not self.inconclusive,
                                   yellow=not over and bool(self.inconclusive))
        terminalreporter.write_line(
            f"paced tests: {len(self.paced)}; inconclusive (the host could not keep real time): "
            f"{len(self.inconclusive)}; skipped for another reason: {len(self.skipped)}")
        for nodeid in sorted(self.skipped):
            terminalreporter.write_line(f"  skipped: {nodeid}: {self.skipped[nodeid]}")
        if over:
            terminalreporter.write_line(
                f"FAILED: {self.unverified_share():.0%} of the paced tests verified nothing, over the "
                f"{limit:.0%} allowed (tests/README.md): this run checked too little of the real-time path")

    @pytest.hookimpl(trylast=True)
    def pytest_sessionfinish(self, session: pytest.Session, exitstatus: int) -> None:
        limit = session.config.getoption("max_unverified_paced")
        if self.paced and self.unverified_share() > limit and exitstatus == pytest.ExitCode.OK:
            session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_configure(config: pytest.Config) -> None:
    if not hasattr(config, "workerinput"):  # (an xdist worker: its controller counts)
        config.pluginmanager.register(PacedCount(), "paced-count")
