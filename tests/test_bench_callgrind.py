"""bench/callgrind.py's split of a callgrind profile by part: a function no pattern names is charged to
its callers' parts by the cost of their calls, and the split keeps the profile's total. A small
profile written by hand in callgrind's format (name compression, a callee in another object)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.bench_scripts import load_bench

REPO = Path(__file__).resolve().parents[1]


cg = load_bench("callgrind")

# main (10 own) calls plant_step (50 inclusive), sin in libm (5) and helper (35); plant_step (30 own)
# calls helper too (20): helper's 55 are shared 35 : 20 between main's part and the plant's
PROFILE = """# callgrind format
events: Ir
summary: 100
ob=(1) /bin/prog
fl=(1) main.c
fn=(1) main
1 10
cfl=(2) /src/plant/c/step.c
cfn=(2) plant_step
calls=1 1
1 50
cob=(2) /lib/libm.so
cfn=(4) sin
calls=1 1
1 5
cfn=(3) helper
calls=2 1
1 35
fl=(2)
fn=(2)
1 30
cfl=(1)
cfn=(3)
calls=1 1
1 20
fl=(1)
fn=(3)
+2 40
* 15
ob=(2)
fl=(3) s_sin.c
fn=(4)
1 5
"""


def test_parse_reads_costs_calls_and_a_callee_in_another_object() -> None:
    prof = cg.parse(PROFILE)
    assert prof.total == 100
    assert dict(prof.self_cost) == {"/bin/prog:main": 10, "/bin/prog:plant_step": 30, "/bin/prog:helper": 55,
                                    "/lib/libm.so:sin": 5}
    assert dict(prof.calls["/bin/prog:main"]) == {"/bin/prog:plant_step": 50, "/lib/libm.so:sin": 5,
                                                  "/bin/prog:helper": 35}  # helper: back in main's object
    assert prof.where["/bin/prog:plant_step"] == "/bin/prog /src/plant/c/step.c"


def test_an_unnamed_function_is_charged_to_its_callers_parts() -> None:
    by_part = cg.split(cg.parse(PROFILE), [("plant", r"/plant/c/")])
    assert by_part == {"other": pytest.approx(50), "plant": pytest.approx(50)}
    # named by its function instead, helper keeps all of its own
    by_part = cg.split(cg.parse(PROFILE), [("plant", r"/plant/c/"), ("help", r":helper$")])
    assert by_part == {"other": pytest.approx(15), "plant": pytest.approx(30), "help": pytest.approx(55)}


def test_inclusive_sums_the_calls_into_a_function_from_every_caller() -> None:
    prof = cg.parse(PROFILE)
    assert cg.inclusive(prof, "helper") == 55  # 35 from main, 20 from plant_step
    assert cg.inclusive(prof, "plant_step") == 50
    assert cg.inclusive(prof, "main") == 0  # called by nothing
