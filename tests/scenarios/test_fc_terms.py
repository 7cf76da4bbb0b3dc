"""Scenarios in the FC's neutral terms, flown by the reference FC under profiles made from its own:
`arm`, `mode` and `roll_deg` send what the profile says; criteria on estimates an FC cannot give are
"not measured" in every report, never passed; an FC that never arms fails every criterion saying so;
a scenario the FC cannot fly is skipped; a stick gesture holds its sticks for its time, ending at the arm's
time; a slow start-up
shifts the scenario. Expected SBUS values follow the reference FC's mapping (992 ± 819 per full stick)."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from rig.reports import acceptance, html_report, junit
from rig.run_cmd import write_run
from rig.runner import run
from rig.scenarios import profile as profiles
from rig.scenarios.schema import ScenarioError, load

REFERENCE = (profiles.PROFILES / "reference.toml").read_text()

NEUTRAL = """
[scenario]
name = "neutral"
duration = 4.0
needs = ["angle"]
[[timeline]]
t = 1.2
arm = true
sticks = { throttle = 0.0 }
[[timeline]]
t = 1.5
sticks = { throttle = 0.5 }
[[timeline]]
t = 2.5
sticks = { roll_deg = 10 }
[[timeline]]
t = 3.0
mode = "althold"
[vehicle]
stand = 4
[[criteria]]
name = "rolled"
metric = "max"
signal = "roll"
start = 2.5
min = 2.0
[[criteria]]
name = "estimate follows"
metric = "peak_error"
signal = "roll_est_error"
start = 2.5
max = 3.0
"""


def scenario(tmp_path: Path, text: str = NEUTRAL, name: str = "neutral") -> Path:
    p = tmp_path / f"{name}.toml"
    p.write_text(text)
    return p


def profile(tmp_path: Path, *changes: tuple[str, str]) -> profiles.Profile:
    text = REFERENCE
    for old, new in changes:
        assert old in text, old
        text = text.replace(old, new)
    p = tmp_path / "fc.toml"
    p.write_text(text)
    return profiles.load(p)


def channels_at(r: object, t: float) -> tuple[int, ...]:
    frames = [f for f in r.rc_frames if f.t_ns <= t * 1e9]  # type: ignore[attr-defined]
    return frames[-1].channels


def test_neutral_actions_send_the_profile_s_channels(tmp_path: Path) -> None:
    r = run(load(scenario(tmp_path)), seed=0)
    assert r.verdict == "pass", [(m.name, m.value, m.reason) for m in r.measurements]
    assert channels_at(r, 1.1)[4] == 172 and channels_at(r, 1.3)[4] == 1811  # arm switch on channel 5
    assert channels_at(r, 2.6)[0] == round(992 + 10 / 30 * 819)  # 10 deg of 30 per full stick
    assert channels_at(r, 2.9)[5] == 172 and channels_at(r, 3.1)[5] == 1811  # angle, then althold
    assert r.metadata["fc_profile"] == "reference"


def test_criteria_on_estimates_are_not_measured_without_telemetry(tmp_path: Path) -> None:
    fc = profile(tmp_path, ('kind = "text"', 'kind = "none"'), ('detect = "telemetry"', 'detect = "motors"'))
    r = run(load(scenario(tmp_path)), seed=0, work_dir=tmp_path / "run", profile=fc)
    by = {m.name: m for m in r.measurements}
    assert by["rolled"].outcome == "pass"
    est = by["estimate follows"]
    assert est.outcome == "not measured" and "has no telemetry" in est.reason
    assert r.verdict == "pass"  # every criterion measured passed; the other is not counted as one
    write_run(tmp_path / "run", r)
    result = json.loads((tmp_path / "run" / "result.json").read_text())
    assert {m["name"]: m["outcome"] for m in result["measurements"]}["estimate follows"] == "not measured"
    cases = ET.fromstring(junit.render([r])).iter("testcase")
    case = next(c for c in cases if c.get("name") == "estimate follows")
    skipped = case.find("skipped")
    assert skipped is not None and "has no telemetry" in (skipped.get("message") or "")
    assert case.find("failure") is None
    page = html_report.render(r)
    assert "1 of 2 criteria not measured" in page and "has no telemetry" in page
    pdf_source = acceptance.render([r], [], "")
    assert "not measured" in pdf_source and "1 criteria not measured" in pdf_source


def test_only_estimates_to_judge_and_no_telemetry_is_a_skip(tmp_path: Path) -> None:
    fc = profile(tmp_path, ('kind = "text"', 'kind = "none"'), ('detect = "telemetry"', 'detect = "motors"'))
    text = NEUTRAL[:NEUTRAL.index("[[criteria]]\nname = \"rolled\"")] + NEUTRAL[NEUTRAL.index(
        "[[criteria]]\nname = \"estimate follows\""):]
    r = run(load(scenario(tmp_path, text)), seed=0, profile=fc)
    assert r.verdict == "skipped" and "has no telemetry" in (r.error or "")
    assert all(m.outcome == "skipped" for m in r.measurements)


def test_an_fc_that_never_arms_fails_every_criterion_saying_so(tmp_path: Path) -> None:
    text = NEUTRAL.replace("[vehicle]", "[fc]\ndefect_never_arm = 1\n[vehicle]")
    r = run(load(scenario(tmp_path, text)), seed=0)
    assert r.verdict == "fail"
    assert all(m.outcome == "fail" and "the FC never armed" in m.reason for m in r.measurements), \
        [(m.name, m.outcome, m.reason) for m in r.measurements]
    assert any("never armed" in n for n in r.notes)


def test_a_mode_the_fc_lacks_is_a_skip_with_the_reason(tmp_path: Path) -> None:
    fc = profile(tmp_path,
                 ("positions = { angle = 987.5, althold = 2011.875 }", "positions = { angle = 987.5 }"))
    r = run(load(scenario(tmp_path)), seed=0, profile=fc)
    assert r.verdict == "skipped" and "has no althold" in (r.error or "")
    too_far = NEUTRAL.replace("roll_deg = 10", "roll_deg = 40").replace(', "althold"', "")
    r = run(load(scenario(tmp_path, too_far.replace('mode = "althold"', 'mode = "angle"'), "far")), seed=0)
    assert r.verdict == "skipped" and "more than a full stick" in (r.error or "")


def test_a_stick_gesture_holds_its_sticks_for_its_time(tmp_path: Path) -> None:
    # the reference FC arms by its switch only: under a stick-arming profile it never arms, and says so
    fc = profile(tmp_path,
                 ('method = "switch"\nchannel = 5\non_us = 2011.875                 # above half travel, '
                  'with the throttle under 5 %\noff_us = 987.5\n',
                  'method = "sticks"\narm = { throttle = "low", yaw = "high" }\n'
                  'disarm = { throttle = "low", yaw = "low" }\nhold_s = 1.0\n'))
    r = run(load(scenario(tmp_path)), seed=0, profile=fc)
    # the gesture ends at the arm's time, 1.2 s: throttle low (173), yaw right (1811) from 0.2 s, but the
    # profile's FC needs 1 s to start up, so the whole scenario runs 0.8 s later: held from 1.0 to 2.0 s
    assert any("arming gesture" in n and "runs 0.8 s later" in n for n in r.notes), r.notes
    assert channels_at(r, 0.95)[2:4] == (173, 992)  # (before it: throttle low, yaw centred)
    for t in (1.05, 1.5, 1.95):
        assert channels_at(r, t)[2:4] == (173, 1811), t
    assert channels_at(r, 2.1)[2:4] == (173, 992)  # then the scenario's: throttle 0 at the arm, yaw 0
    assert channels_at(r, 2.4)[2:4] == (992, 992)  # and throttle 0.5 (mid travel) at 1.5 + 0.8 s
    assert channels_at(r, 2.4)[4] == 992  # no arm switch: channel 5 rests at the centre
    assert r.verdict == "fail" and "the FC never armed" in r.measurements[0].reason


def test_a_slow_start_up_shifts_the_scenario(tmp_path: Path) -> None:
    fc = profile(tmp_path, ("seconds = 1.0 ", "seconds = 3.0 "))
    r = run(load(scenario(tmp_path)), seed=0, profile=fc)
    assert any("runs 1.8 s later" in n for n in r.notes), r.notes
    assert r.measurements[0].start == pytest.approx(4.3) and r.metadata["duration"] == pytest.approx(5.8)
    assert channels_at(r, 2.9)[4] == 172 and channels_at(r, 3.1)[4] == 1811  # armed at 3.0 s


def test_the_scenario_s_terms_are_checked(tmp_path: Path) -> None:
    for change, words in ((('mode = "althold"', 'mode = "altold"'), "did you mean 'althold'"),
                          (("arm = true", "arm = false"), "expected true"),
                          (('needs = ["angle"]', 'needs = ["failsave"]'), "did you mean 'failsafe'"),
                          (("roll_deg = 10", "roll_deg = 10, roll = 0.1"), "roll is given twice")):
        with pytest.raises(ScenarioError, match=words):
            load(scenario(tmp_path, NEUTRAL.replace(*change)))
    sc = load(scenario(tmp_path))
    assert sc.needs == ("angle", "althold") and sc.arms and sc.first_action == 1.2


def test_a_free_vehicle_given_take_off_throttle_that_stays_down_fails(tmp_path: Path) -> None:
    # free (stand 0) with throttle 0.5 but a vehicle four times too heavy to lift: not "level" by sitting
    text = NEUTRAL.replace("stand = 4", "mass = 4.8").replace(', "althold"', "")
    text = text.replace('[[timeline]]\nt = 3.0\nmode = "althold"\n', "")
    r = run(load(scenario(tmp_path, text, "heavy")), seed=0)
    assert r.verdict == "fail"
    assert all("never left the ground" in m.reason for m in r.measurements if m.outcome == "fail")
    assert any(m.outcome == "fail" for m in r.measurements)
    # at zero throttle staying on the ground is what the scenario asks: judged as it is
    idle = text.replace("sticks = { throttle = 0.5 }", "sticks = { throttle = 0.0 }").replace(
        "sticks = { roll_deg = 10 }", "sticks = { roll_deg = 0 }")
    r = run(load(scenario(tmp_path, idle, "idle")), seed=0)
    assert not any("never left the ground" in m.reason for m in r.measurements)


LIBRARY = Path(__file__).resolve().parents[2] / "scenarios" / "library"
#: what each shipped profile cannot fly of the library, and the words of why (from the FCs' documented
#: features: neither third-party FC has the reference FC's altitude-setpoint knob)
CANNOT = {
    "reference": {},
    "multiwii-2.4": {"step_altitude": "has no alt_offset channel"},
    "arducopter-4": {"step_altitude": "has no alt_offset channel"},
}


@pytest.mark.parametrize("name", sorted(CANNOT))
def test_the_library_states_its_modes_and_each_profile_skips_what_it_cannot_fly(name: str) -> None:
    from rig.runner import cannot_fly

    fc = profiles.load(name)
    said = {}
    for path in sorted(LIBRARY.glob("*.toml")):
        sc = load(path)
        assert "angle" in sc.needs, path  # every library scenario says the mode it flies
        why = cannot_fly(sc, fc)
        if why:
            said[path.stem] = why
    assert set(said) == set(CANNOT[name]), said
    for stem, words in CANNOT[name].items():
        assert words in said[stem]
