"""bench/library_reference.py's comparison: which of the library's measurements moved by more than
1e-6 of their limit, or changed verdict, between two reference documents. The rule is what decides
whether a change to the per-cycle path kept the rig's measurements, so it is tested on its own; the
measurements themselves are never asserted."""

from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Any

import pytest

from tests.bench_scripts import load_bench

REPO = Path(__file__).resolve().parents[1]


ref = load_bench("library_reference")


def crit(name: str, value: float | str | None, lo: float | None, hi: float | None, outcome: str = "pass"
         ) -> dict[str, Any]:
    return {"name": name, "metric": "max", "signal": "roll", "units": "deg", "value": value, "min": lo,
            "max": hi, "outcome": outcome}


BEFORE: dict[str, Any] = {"runs": [
    {"scenario": "step_roll", "seed": 0, "verdict": "pass", "error": None, "criteria": [
        crit("overshoot", 1.5, None, 20.0),
        crit("band", -2.0, -5.0, 0.5),
        crit("at zero", 0.25, None, 0.0, "fail"),
        crit("never measured", "nan", None, 3.0, "not judged"),
    ]},
    {"scenario": "hover", "seed": 1, "verdict": "pass", "error": None,
     "criteria": [crit("alt", 2.0, 1.0, 3.0)]},
]}


def after(edit: Any) -> dict[str, Any]:
    doc = copy.deepcopy(BEFORE)
    edit(doc)
    return doc


def bad(doc: dict[str, Any]) -> list[str]:
    return [f"{d.key}: {d.problem}" for d in ref.compare(BEFORE, doc) if d.bad]


def test_identical_documents_have_no_difference() -> None:
    diffs = ref.compare(BEFORE, copy.deepcopy(BEFORE))
    assert len(diffs) == 2 + 4 + 1  # each run's verdict and each criterion
    assert not [d for d in diffs if d.bad or d.difference != 0]  # NaN equals NaN


def test_a_difference_is_measured_against_its_limit() -> None:
    def nudge(doc: dict[str, Any], k: int, by: float) -> None:
        doc["runs"][0]["criteria"][k]["value"] += by

    # overshoot: |limit| 20, so 1e-6 of it is 2e-5
    assert bad(after(lambda d: nudge(d, 0, 1.9e-5))) == []
    assert bad(after(lambda d: nudge(d, 0, 2.1e-5))) == [
        "step_roll/0/overshoot: differs by 1.05e-06 of its limit"]
    # two limits: the smaller non-zero one (0.5) counts, not 5
    assert bad(after(lambda d: nudge(d, 1, 4e-7))) == []
    assert bad(after(lambda d: nudge(d, 1, 6e-7))) != []
    (d,) = [d for d in ref.compare(BEFORE, after(lambda d: nudge(d, 1, 4e-7))) if d.difference]
    assert d.relative == pytest.approx(8e-7)
    # a limit of 0: the tolerance is absolute
    assert bad(after(lambda d: nudge(d, 2, 9e-7))) == []
    assert bad(after(lambda d: nudge(d, 2, 1.1e-6))) != []


def test_a_changed_verdict_is_a_problem_however_small_the_difference() -> None:
    def flip(doc: dict[str, Any]) -> None:
        doc["runs"][0]["criteria"][0]["outcome"] = "fail"
        doc["runs"][0]["verdict"] = "fail"

    assert bad(after(flip)) == ["step_roll/0: run verdict pass -> fail",
                                "step_roll/0/overshoot: verdict pass -> fail"]


def test_nan_against_a_number_limits_that_moved_and_missing_runs_are_problems() -> None:
    def nan(doc: dict[str, Any]) -> None:
        doc["runs"][1]["criteria"][0]["value"] = "nan"

    assert bad(after(nan)) == ["hover/1/alt: differs by inf of its limit"]

    def widen(doc: dict[str, Any]) -> None:
        doc["runs"][1]["criteria"][0]["max"] = 4.0

    assert bad(after(widen)) == ["hover/1/alt: limits [1.0, 3.0] -> [1.0, 4.0]"]
    assert bad(after(lambda d: d["runs"].pop(1))) == ["hover/1: only before"]
    assert bad(after(lambda d: d["runs"][0]["criteria"].append(crit("new", 1.0, None, 2.0)))) == [
        "step_roll/0/new: only after"]


def test_values_round_trip_through_json_and_bad_ones_are_refused() -> None:
    assert [ref.decode(ref.encode(x)) for x in (1.5, None)] == [1.5, None]
    assert math.isnan(ref.decode(ref.encode(math.nan))) and ref.decode(ref.encode(-math.inf)) == -math.inf
    for junk in ("1.5", True, [1]):
        with pytest.raises(ValueError, match="not a number"):
            ref.decode(junk)
    with pytest.raises(ValueError, match="no list 'runs'"):
        ref.compare({}, BEFORE)
