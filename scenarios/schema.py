"""The scenario file format (TOML, docs/design.md §7) and its validation.

A scenario is checked completely before anything runs: every table and key is known, every value has
the expected type and range, every signal and metric named by a criterion exists. A bad file raises
ScenarioError naming the file, the key (dotted, with list indices) and what was expected, so a user
reads one line and knows what to fix. The format, key by key, is in the README ("Scenario format").
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rig.emulators.faults import KINDS as FAULT_KINDS
from rig.emulators.faults import TARGETS as FAULT_TARGETS
from rig.emulators.faults import Fault, TargetedFault
from rig.emulators.pwm_capture import TRANSPORTS as CAPTURE_TRANSPORTS
from rig.plant import airframes
from rig.plant.airframes import Airframe, AirframeError
from rig.plant.toml_file import TomlFileError, read_toml
from rig.plant.variables import SCENARIO_INPUTS, VARIABLES, check_parameters
from rig.scenarios import fc_keys
from rig.scenarios.bench import BenchPower, parse_psu
from rig.scenarios.checker import ScenarioError, _Check
from rig.scenarios.criteria import MARGINAL_PCT, METRICS
from rig.scenarios.serial import SERIAL_CRITERION_KEYS, SerialSend, parse_expect, parse_send
from rig.scenarios.signals import SIGNALS
from rig.scenarios.terms import FEATURES, MODES, STICK_TERMS, STICKS

PLANT_PARAMETERS = {v.name for v in VARIABLES if v.causality == "parameter"}
PLANT_INPUTS = set(SCENARIO_INPUTS)
VEHICLE_KEYS = PLANT_PARAMETERS | {"airframe"}
LINK_STATES = ("ok", "lost", "failsafe")
CAPTURES = ("direct", *CAPTURE_TRANSPORTS)  # direct: the DUT's PWM drives the plant with no link


@dataclass(frozen=True)
class Gust:
    """A 1-cosine gust (the certification gust shape): wind rises from 0 to ``peak`` and back over
    ``duration`` seconds from ``start``."""

    start: float
    duration: float
    peak: tuple[float, float, float]


@dataclass(frozen=True)
class Event:
    t: float
    sticks: dict[str, float] = field(default_factory=dict)  # STICK_UNITS, KNOBS or STICK_TERMS
    link: str | None = None
    inputs: dict[str, float] = field(default_factory=dict)
    arm: bool | None = None  # True: arm, False: disarm, as the FC's profile says it is done
    mode: str | None = None  # a flight mode by name (MODES), on the profile's mode channel

    def shifted(self, dt: float) -> Event:
        return dataclasses.replace(self, t=self.t + dt)


@dataclass(frozen=True)
class CriterionSpec:
    name: str
    metric: str
    signal: str
    start: float
    end: float
    target: float | None
    band: float | None
    min: float | None
    max: float | None
    units: str
    baseline_at: float | None = None  # target counts from the signal's value at this time
    marginal: float = MARGINAL_PCT  # a pass closer than this (% of the limit) to a limit is marginal
    uart: int | None = None  # a criterion on a USART's output (rig/scenarios/serial.py), not a signal
    expect: str | int | None = None  # its line's regular expression, or the MSP command replied to


@dataclass(frozen=True)
class Capture:
    """The PWM capture device between the DUT's outputs and the plant."""

    transport: str = "direct"
    resolution_us: float = 1.0
    rate_hz: float = 400.0
    latency_s: float = 0.0
    #: python-can interface and channel of the ``can`` transport: ``virtual`` with a private channel
    #: (CI), or e.g. ``socketcan`` / ``can0`` on a bench
    can_interface: str = "virtual"
    can_channel: str = ""


@dataclass(frozen=True)
class Scenario:
    path: Path
    name: str
    description: str
    seed_paper: str
    duration: float
    #: the [vehicle] table's own parameters, which apply over the airframe's (plant_params)
    plant: dict[str, float]
    #: the vehicle flown: [vehicle] airframe = NAME|FILE, else seed 001's (plant/airframes.py)
    airframe: Airframe
    fc: dict[str, str]
    noise: bool
    baro_noise_pa: float
    baro_drift_pa_per_s: float
    wind: tuple[float, float, float]
    turbulence: float
    turbulence_tau: float
    mag_disturbance: tuple[float, float, float]
    mag_disturbance_start: float
    mag_disturbance_end: float
    gusts: tuple[Gust, ...]
    faults: tuple[TargetedFault, ...]
    timeline: tuple[Event, ...]
    criteria: tuple[CriterionSpec, ...]
    capture: Capture
    bench: BenchPower
    max_angle_deg: float | None  # None: the FC profile's angle per full stick
    max_yaw_rate_dps: float | None
    sha256: str
    serial: tuple[SerialSend, ...] = ()
    #: the modes and features the scenario needs (its [scenario] needs and every mode its timeline asks)
    needs: tuple[str, ...] = ()

    @property
    def first_action(self) -> float | None:
        """When the scenario first moves a stick or arms: the FC must be ready by then."""
        times = [e.t for e in self.timeline if e.sticks or e.arm is not None or e.mode is not None]
        return min(times) if times else None

    @property
    def arms(self) -> bool:
        return any(e.arm for e in self.timeline)

    def stick_terms(self) -> dict[str, float]:
        """The largest magnitude asked of each stick given in degrees or degrees per second."""
        out: dict[str, float] = {}
        for e in self.timeline:
            for k, v in e.sticks.items():
                if k in STICK_TERMS:
                    out[k] = max(out.get(k, 0.0), abs(v))
        return out

    def shifted(self, dt: float) -> Scenario:
        """The scenario ``dt`` seconds later: every time in it (timeline, faults, gusts, the magnetic
        disturbance, criteria windows) and its duration, for an FC that needs longer to start up."""
        if dt <= 0:
            return self
        return dataclasses.replace(
            self,
            duration=self.duration + dt,
            timeline=tuple(e.shifted(dt) for e in self.timeline),
            faults=tuple(TargetedFault(f.target, dataclasses.replace(f.fault, start=f.fault.start + dt,
                                                                     end=f.fault.end + dt))
                         for f in self.faults),
            gusts=tuple(dataclasses.replace(g, start=g.start + dt) for g in self.gusts),
            serial=tuple(dataclasses.replace(send, t=send.t + dt) for send in self.serial),
            mag_disturbance_start=self.mag_disturbance_start + dt,
            mag_disturbance_end=self.mag_disturbance_end + dt,
            criteria=tuple(dataclasses.replace(
                c, start=c.start + dt, end=c.end + dt,
                baseline_at=None if c.baseline_at is None else c.baseline_at + dt) for c in self.criteria),
        )

    def mag_disturbance_at(self, t: float) -> tuple[float, float, float]:
        """The scheduled disturbance field (body, gauss) at sim time ``t``."""
        if self.mag_disturbance_start <= t < self.mag_disturbance_end:
            return self.mag_disturbance
        return (0.0, 0.0, 0.0)

    @property
    def mag_disturbance_window(self) -> tuple[tuple[float, float, float], float, float]:
        """The disturbance and the window [start, end) it acts in, as mag_disturbance_at applies them,
        for those that read it once instead of calling it (the recorder, the lockstep fast path); an
        empty window when the disturbance is zero."""
        if not any(self.mag_disturbance):
            return (0.0, 0.0, 0.0), math.inf, -math.inf
        return self.mag_disturbance, self.mag_disturbance_start, self.mag_disturbance_end

    @property
    def stem(self) -> str:
        return self.path.stem

    def plant_params(self) -> dict[str, float]:
        """The plant's parameters for this scenario: the airframe's, then the [vehicle] table's."""
        return self.airframe.params | self.plant


def with_airframe(scenario: Scenario, airframe: Airframe) -> Scenario:
    """The scenario flying another airframe (``--airframe``): its [vehicle] keys still apply on top.
    Raises ScenarioError when the plant refuses the combination."""
    refused = check_parameters(airframe.params | scenario.plant)
    if refused:
        raise ScenarioError(str(scenario.path), f"vehicle.{refused.split()[0]}",
                            f"the plant refuses it on airframe {airframe.name}: {refused}")
    return dataclasses.replace(scenario, airframe=airframe)


TOP = {
    "scenario",
    "vehicle",
    "fc",
    "sensors",
    "environment",
    "rc",
    "capture",
    "bench",
    "timeline",
    "faults",
    "gusts",
    "criteria",
    "serial",
}
SCENARIO_KEYS = {"name", "description", "seed_paper", "duration", "needs"}
SENSOR_KEYS = {"noise", "baro_noise_pa", "baro_drift_pa_per_s"}
ENV_KEYS = {
    "wind",
    "turbulence",
    "turbulence_tau",
    "mag_disturbance",
    "mag_disturbance_start",
    "mag_disturbance_end",
}
RC_KEYS = {"max_angle_deg", "max_yaw_rate_dps"}
BENCH_KEYS = {"psu", "volts", "current_limit", "max_current", "off_s", "settle_s"}
CAPTURE_KEYS = {"transport", "resolution_us", "rate_hz", "latency_s", "can_interface", "can_channel"}
EVENT_KEYS = {"t", "sticks", "link", "inputs", "arm", "disarm", "mode"}
FAULT_KEYS = {"target", "kind", "start", "end", "magnitude", "period", "duty"}
GUST_KEYS = {"start", "duration", "peak"}
CRITERION_KEYS = {"name", "metric", "signal", "start", "end", "target", "band", "min", "max", "baseline_at",
                  "marginal", *SERIAL_CRITERION_KEYS}


def load(path: str | Path) -> Scenario:
    """Reads and checks one scenario file; raises ScenarioError (never a traceback for bad input)."""
    path = Path(path)
    file = str(path)
    try:
        toml = read_toml(path)
    except TomlFileError as e:
        raise ScenarioError(file, "", str(e)) from None
    return check(toml.data, path, toml.sha256)


def check(data: dict[str, Any], path: Path, sha256: str | None = None) -> Scenario:
    """Checks a scenario's parsed tables (a file's, or a sweep's variant of one: scenarios/sweep.py);
    ``sha256`` identifies its content (default: of the tables, canonically encoded)."""
    file = str(path)
    if sha256 is None:
        sha256 = hashlib.sha256(json.dumps(data, sort_keys=True, default=str).encode()).hexdigest()
    c = _Check(file)
    c.table(data, "", TOP)  # (a file that is not a table of tables: nothing else can be checked)
    duration = math.inf  # (a bad duration: the times are checked against no end)
    meta = c.lenient(data.get("scenario", {}), "scenario", SCENARIO_KEYS)
    with c.part():
        if "scenario" not in data:
            raise c.fail("scenario", "missing; expected a [scenario] table with name and duration")
        if isinstance(data["scenario"], dict):  # (not a table: said above)
            duration = c.number(meta, "duration", "scenario", positive=True, high=3600)

    plant: dict[str, float] = {}
    airframe = airframes.load()
    with c.part():
        vehicle = c.table(data.get("vehicle", {}), "vehicle", VEHICLE_KEYS)
        if "airframe" in vehicle:
            named = c.string(vehicle, "airframe", "vehicle")
            try:  # (a file named relative to the scenario's folder, as a person writing it means)
                airframe = airframes.load(path.parent / named if named.endswith(".toml") else named)
            except AirframeError as e:
                raise c.fail("vehicle.airframe", str(e)) from None
        plant = {k: c.number(vehicle, k, "vehicle") for k in vehicle if k != "airframe"}
        refused = check_parameters(airframe.params | plant)  # the FMU's own rules, before it is asked
        if refused:
            raise c.fail(f"vehicle.{refused.split()[0]}", f"the plant refuses it: {refused}")

    # the reference FC's keys, from its own table: a typo must not fly with a default
    fc: dict[str, Any] = {}
    known_fc = [*fc_keys.keys(), "profile"]
    fc_raw = c.lenient(data.get("fc", {}), "fc", known_fc)
    for k, v in fc_raw.items():
        if k not in known_fc:
            continue  # (said above)
        with c.part():
            if k == "profile":
                fc[k] = c.string(fc_raw, k, "fc", choices=fc_keys.profiles())
                continue
            fc[k], why = fc_keys.keys()[k].check(v)
            if why:
                raise c.fail(f"fc.{k}", why)

    tables: dict[str, dict[str, Any]] = {}
    for name, known in (("sensors", SENSOR_KEYS), ("environment", ENV_KEYS), ("rc", RC_KEYS),
                        ("capture", CAPTURE_KEYS), ("bench", BENCH_KEYS)):
        tables[name] = c.lenient(data.get(name, {}), name, known)
    sensors, env, rc, cap, b = (tables[k] for k in ("sensors", "environment", "rc", "capture", "bench"))
    capture = Capture()
    with c.part():
        capture = Capture(
            c.string(cap, "transport", "capture", "direct", CAPTURES),
            c.number(cap, "resolution_us", "capture", 1.0, positive=True, high=100),
            c.number(cap, "rate_hz", "capture", 400.0, positive=True, high=10_000),
            c.number(cap, "latency_s", "capture", 0.0, low=0, high=1),
            c.string(cap, "can_interface", "capture", "virtual"),
            c.string(cap, "can_channel", "capture", ""),
        )
        if capture.can_interface != "virtual" and not capture.can_channel:
            raise c.fail("capture.can_channel",
                         f"missing; interface {capture.can_interface!r} needs a channel (e.g. can0)")

    bench = BenchPower()
    with c.part():
        psu = c.string(b, "psu", "bench", "") or None
        if psu is not None:
            try:
                parse_psu(psu)
            except ValueError as e:
                raise c.fail("bench.psu", str(e)) from None
        bench = BenchPower(
            psu,
            c.optional(b, "volts", "bench"),
            c.optional(b, "current_limit", "bench"),
            c.optional(b, "max_current", "bench"),
            c.number(b, "off_s", "bench", 1.0, low=0, high=60),
            c.number(b, "settle_s", "bench", 3.0, positive=True, high=60),
        )
        for key in ("volts", "current_limit", "max_current"):
            value = getattr(bench, key)
            if value is not None and not 0 < value <= 100:
                raise c.fail(f"bench.{key}", f"expected a number in 0..100 (exclusive of 0), got {value}")

    timeline = []
    with c.part():
        entries = c.array(data, "timeline")
        for i, entry in enumerate(entries):
            with c.part():
                timeline.append(timeline_event(c, entry, f"timeline[{i}]", duration))

    serial = []
    with c.part():
        for i, entry in enumerate(c.array(data, "serial")):
            with c.part():
                serial.append(parse_send(c, entry, f"serial[{i}]", duration))

    faults = []
    with c.part():
        entries = c.array(data, "faults")
        for i, f in enumerate(entries):
            with c.part():
                faults.append(_fault(c, f, f"faults[{i}]", duration))

    gusts = []
    with c.part():
        entries = c.array(data, "gusts")
        for i, g in enumerate(entries):
            with c.part():
                key = f"gusts[{i}]"
                g = c.table(g, key, GUST_KEYS)
                gusts.append(
                    Gust(
                        c.number(g, "start", key, low=0, high=duration),
                        c.number(g, "duration", key, positive=True),
                        c.vector(g, "peak", key),
                    )
                )

    criteria = []
    with c.part():
        entries = c.array(data, "criteria")
        for i, cr in enumerate(entries):
            criterion = _criterion(c, cr, f"criteria[{i}]", duration)
            if criterion is not None:
                criteria.append(criterion)
        if not entries:
            raise c.fail("criteria", "missing; expected at least one [[criteria]] table")

    values: dict[str, Any] = {}
    for name, read in (
        ("name", lambda: c.string(meta, "name", "scenario", path.stem)),
        ("description", lambda: c.string(meta, "description", "scenario", "")),
        ("seed_paper", lambda: c.string(meta, "seed_paper", "scenario", "")),
        ("noise", lambda: c.boolean(sensors, "noise", "sensors", True)),
        ("baro_noise_pa", lambda: c.number(sensors, "baro_noise_pa", "sensors", 0.0, low=0)),
        ("baro_drift_pa_per_s", lambda: c.number(sensors, "baro_drift_pa_per_s", "sensors", 0.0)),
        ("wind", lambda: c.vector(env, "wind", "environment")),
        ("turbulence", lambda: c.number(env, "turbulence", "environment", 0.0, low=0, high=20)),
        ("turbulence_tau", lambda: c.number(env, "turbulence_tau", "environment", 1.0, positive=True)),
        ("mag_disturbance", lambda: c.vector(env, "mag_disturbance", "environment")),
        ("mag_disturbance_start", lambda: c.number(env, "mag_disturbance_start", "environment", 0.0, low=0)),
        ("mag_disturbance_end", lambda: c.number(env, "mag_disturbance_end", "environment", math.inf)),
        ("max_angle_deg", lambda: c.number(rc, "max_angle_deg", "rc", positive=True, high=90)
         if "max_angle_deg" in rc else None),
        ("max_yaw_rate_dps", lambda: c.number(rc, "max_yaw_rate_dps", "rc", positive=True)
         if "max_yaw_rate_dps" in rc else None),
        ("needs", lambda: _needs(c, meta, timeline)),
    ):
        with c.part():
            values[name] = read()
    c.done()
    return Scenario(
        path=path,
        duration=duration,
        plant=plant,
        airframe=airframe,
        fc=fc,
        gusts=tuple(gusts),
        faults=tuple(faults),
        timeline=tuple(sorted(timeline, key=lambda e: e.t)),
        serial=tuple(sorted(serial, key=lambda e: e.t)),
        criteria=tuple(criteria),
        capture=capture,
        bench=bench,
        sha256=sha256,
        **values,
    )


def timeline_event(c: _Check, entry: Any, key: str, duration: float) -> Event:
    """One [[timeline]] entry (rig exec --sticks checks its own with this too)."""
    ev = c.table(entry, key, EVENT_KEYS)
    t = c.number(ev, "t", key, low=0, high=duration)
    sticks = c.table(ev.get("sticks", {}), f"{key}.sticks", STICKS)
    st: dict[str, float] = {}
    arm: bool | None = None
    mode: str | None = None
    for k in sticks:
        if k == "arm":  # (the older form: the arm switch as a stick)
            arm = c.boolean(sticks, k, f"{key}.sticks", False)
        elif k == "alt_hold":  # (the older form: the reference FC's altitude-hold switch)
            mode = "althold" if c.boolean(sticks, k, f"{key}.sticks", False) else ""
        elif k in STICK_TERMS:
            st[k] = c.number(sticks, k, f"{key}.sticks", low=-2000, high=2000)
        else:
            st[k] = c.number(sticks, k, f"{key}.sticks", low=0 if k == "throttle" else -1, high=1)
    for axis in ("roll", "pitch", "yaw"):
        given = [k for k in sticks if k == axis or k.startswith(f"{axis}_")]
        if len(given) > 1:
            raise c.fail(f"{key}.sticks.{given[1]}",
                         f"{axis} is given twice ({' and '.join(given)}): one of them")
    for action in ("arm", "disarm"):
        if action in ev:
            if not c.boolean(ev, action, key, False):
                raise c.fail(f"{key}.{action}", f"expected true (the action), or no {action} key")
            if arm is not None:
                raise c.fail(f"{key}.{action}", "one arm or disarm per timeline entry")
            arm = action == "arm"
    if "mode" in ev:
        if mode is not None:
            raise c.fail(f"{key}.mode", "the mode is given twice (mode and sticks.alt_hold): one of them")
        mode = c.string(ev, "mode", key, choices=MODES)
    link = c.string(ev, "link", key, choices=LINK_STATES) if "link" in ev else None
    inputs_raw = c.table(ev.get("inputs", {}), f"{key}.inputs", PLANT_INPUTS)
    inputs = {k: c.number(inputs_raw, k, f"{key}.inputs") for k in inputs_raw}
    return Event(t, st, link, inputs, arm, mode)


def _needs(c: _Check, meta: dict[str, Any], timeline: list[Event]) -> tuple[str, ...]:
    """[scenario] needs (modes and features), and every mode the timeline asks for."""
    given = meta.get("needs", [])
    if not isinstance(given, list) or not all(isinstance(x, str) for x in given):
        raise c.fail("scenario.needs", f"expected an array of modes and features "
                                       f"({', '.join(MODES + FEATURES)}), got {given!r}")
    for k, x in enumerate(given):
        c.string({f"needs[{k}]": x}, f"needs[{k}]", "scenario", choices=MODES + FEATURES)
    asked = [e.mode for e in timeline if e.mode]
    return tuple(dict.fromkeys([*given, *asked]))


def _fault(c: _Check, raw: Any, key: str, duration: float) -> TargetedFault:
    f = c.table(raw, key, FAULT_KEYS)
    start = c.number(f, "start", key, low=0, high=duration)
    end = c.number(f, "end", key, math.inf)
    if not end > start:
        raise c.fail(f"{key}.end", f"expected a time after start ({start:g} s), got {end:g}")
    target = c.string(f, "target", key, choices=FAULT_TARGETS)
    kind = c.string(f, "kind", key, choices=FAULT_KINDS)
    try:  # (the fault's own rules: a delay is not negative, …)
        fault = Fault(kind, start, end, c.number(f, "magnitude", key, 0.0),
                      c.number(f, "period", key, 0.1, positive=True),
                      c.number(f, "duty", key, 0.5, low=0, high=1))
        return TargetedFault(target, fault)
    except ValueError as err:
        raise c.fail(key, str(err)) from None


def _criterion(c: _Check, raw: Any, key: str, duration: float) -> CriterionSpec | None:
    """One [[criteria]] table, its parts checked apart (None when any is bad: kept in ``c``)."""
    before = len(c.problems)
    if not isinstance(raw, dict):
        with c.part():
            c.table(raw, key, CRITERION_KEYS)
        return None
    cr = c.lenient(raw, key, CRITERION_KEYS)
    if "uart" in cr:
        return _serial_criterion(c, cr, key, duration, before)
    metric = signal = ""
    with c.part():
        metric = c.string(cr, "metric", key, choices=tuple(METRICS))
        needs = METRICS[metric].needs
        for need in needs:
            if need not in cr:
                raise c.fail(f"{key}.{need}", f"missing; metric {metric} needs {', '.join(needs)}")
    with c.part():
        signal = c.string(cr, "signal", key, choices=tuple(SIGNALS))
    start, end = _window(c, cr, key, duration)
    lo = hi = None
    with c.part():
        lo = c.optional(cr, "min", key)
    with c.part():
        hi = c.optional(cr, "max", key)
    with c.part():
        if "min" not in cr and "max" not in cr:
            raise c.fail(key, "expected a limit: min, max or both")
        if lo is not None and hi is not None and lo > hi:
            raise c.fail(f"{key}.max", f"expected a limit at least min ({lo:g}), got {hi:g}: no value "
                         "could pass")
    baseline_at = target = band = marginal = None
    with c.part():
        target = c.optional(cr, "target", key)
    with c.part():
        baseline_at = c.optional(cr, "baseline_at", key)
        if baseline_at is not None:
            if "target" not in cr:
                raise c.fail(
                    f"{key}.baseline_at", "needs a target (the step size from the value at that time)"
                )
            if not 0 <= baseline_at <= duration:
                raise c.fail(f"{key}.baseline_at", f"expected a time in 0..{duration:g}, got {baseline_at:g}")
    with c.part():
        band = c.optional(cr, "band", key)
        if band is not None and band <= 0:
            raise c.fail(f"{key}.band", f"expected a number > 0, got {band}")
    with c.part():
        marginal = c.optional(cr, "marginal", key)
        if marginal is not None and not 0 <= marginal < 100:
            raise c.fail(f"{key}.marginal", f"expected a percentage in 0..100, got {marginal:g}")
    name = ""
    with c.part():
        name = c.string(cr, "name", key, f"{metric} of {signal}")
    if len(c.problems) > before:
        return None
    return CriterionSpec(
        name,
        metric,
        signal,
        start,
        end,
        target,
        band,
        lo,
        hi,
        METRICS[metric].units or SIGNALS[signal].units,
        baseline_at,
        MARGINAL_PCT if marginal is None else marginal,
    )


def _window(c: _Check, cr: dict[str, Any], key: str, duration: float) -> tuple[float, float]:
    """A criterion's window [start, end] (the whole run by default); kept as a problem when bad."""
    start, end = 0.0, duration
    with c.part():
        start = c.number(cr, "start", key, 0.0, low=0, high=duration)
        end = c.number(cr, "end", key, duration, low=0, high=duration)
        if not end > start:
            raise c.fail(f"{key}.end", f"expected a time after start ({start:g} s), got {end:g}")
    return start, end


def _serial_criterion(c: _Check, cr: dict[str, Any], key: str, duration: float,
                      before: int) -> CriterionSpec | None:
    """A [[criteria]] table on a USART (uart = n, with line or msp_reply): passes when the firmware
    sent it inside the window (rig/scenarios/serial.py)."""
    metric, signal, expect = "", "", None
    with c.part():
        metric, signal, expect = parse_expect(c, cr, key)
    start, end = _window(c, cr, key, duration)
    name = ""
    with c.part():
        what = f"a line matching {expect!r}" if metric == "uart_line" else f"an MSP reply to {expect}"
        name = c.string(cr, "name", key, f"{what} on {signal.upper()}")
    if len(c.problems) > before:
        return None
    return CriterionSpec(name, metric, signal, start, end, None, None, start, end, "s",
                         uart=int(signal[5:]), expect=expect)
