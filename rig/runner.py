"""Runs one scenario against a DUT in a session and judges it.

Everything the scenario scripts happens as session events in sim time: the SBUS stick emulator's
frames, timeline changes, wind (steady + first-order Gauss-Markov turbulence + 1-cosine gusts, updated
every 10 ms), and the recorder, which samples every signal on a 100 Hz grid. Sensor faults live in the
world's sensor models and bus wrappers, switched by sim time. After the run the DUT's telemetry lines
(``T t=… roll=…``, the reference FC's format) are parsed, held onto the grid, and the criteria are
measured. A DUT that crashes, exits early or hangs ends with verdict "error" and the reason.
"""

from __future__ import annotations

import dataclasses
import datetime
import functools
import math
import socket
from collections.abc import Callable
from pathlib import Path
from typing import Final

import numpy as np

from rig import __version__, scratch, uart_criteria
from rig.emulators.faults import Fault, fault_sets
from rig.emulators.sbus import KNOBS
from rig.emulators.sensor_models import Normals
from rig.host import Host
from rig.plant.variables import MOTORS
from rig.rc import StickEmulator
from rig.scenarios import profile as profiles
from rig.scenarios.criteria import NOT_JUDGED, NOT_MEASURED, SKIPPED, Measurement, measure
from rig.scenarios.profile import Profile
from rig.scenarios.result import RcFrame, RunResult
from rig.scenarios.schema import Event, Scenario
from rig.scenarios.signals import BENCH_SIGNALS, RECORD_PERIOD, SIGNALS
from rig.scenarios.terms import STICK_TERMS
from rig.targets import RC_PATH, RunContext, Target, TargetRun, telemetry_path
from rig.targets.process import ProcessTarget
from rig.telemetry import msp, read_columns
from rig.telemetry.binary import MAVLINK_WATCH_PERIOD, Watch
from rig.world import World

WIND_PERIOD: Final = 0.01
TELEMETRY_KEYS = {
    "roll": "est_roll",
    "pitch": "est_pitch",
    "yaw": "est_yaw",
    "alt": "est_alt",
    "armed": "armed",
}


class _Wind:
    """Steady wind + turbulence + gusts, written into the plant's wind inputs every WIND_PERIOD."""

    def __init__(self, scenario: Scenario, seed: int) -> None:
        self.sc = scenario
        self.normals = Normals(np.random.default_rng(seed + 101))
        self.turb: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self.a = math.exp(-WIND_PERIOD / scenario.turbulence_tau)
        self.now = tuple(scenario.wind)
        # the scenario's numbers, read once (a Scenario is plain Python: 7 attribute lookups a tick)
        self._steady = scenario.wind
        self._turbulence = scenario.turbulence
        self._s = scenario.turbulence * math.sqrt(1 - self.a**2)
        self._gusts = tuple(scenario.gusts)

    def active(self) -> bool:
        return any(self.sc.wind) or self.sc.turbulence > 0 or bool(self.sc.gusts)

    def tick(self, session: Host, t: float) -> None:
        # three scalars, not sequences, zips and numpy calls: this runs a hundred times a second (the
        # same float operations in the same order as per-axis sequences would do them)
        tn, te, td = self.turb
        if self._turbulence > 0:
            a, s = self.a, self._s
            zn, ze, zd = self.normals.take(3)
            tn, te, td = a * tn + s * zn, a * te + s * ze, a * td + s * zd
            self.turb = (tn, te, td)
        steady = self._steady
        wn, we, wd = steady[0] + tn, steady[1] + te, steady[2] + td
        for g in self._gusts:
            if g.start <= t <= g.start + g.duration:
                shape = 0.5 * (1 - math.cos(2 * math.pi * (t - g.start) / g.duration))
                wn, we, wd = wn + g.peak[0] * shape, we + g.peak[1] * shape, wd + g.peak[2] * shape
        world = session.world
        world.set_input("wind_n", wn)
        world.set_input("wind_e", we)
        world.set_input("wind_d", wd)
        self.now = (wn, we, wd)
        nxt = t + WIND_PERIOD
        session.at(nxt, lambda s: self.tick(s, nxt))


#: The plant outputs the recorder reads, before the motors' pulse widths (World.probe)
RECORDED = ("roll", "pitch", "yaw", "pd", "vd", "vn", "ve", "p", "q", "r")
#: the recorder's table is made with room for the whole run up to this many rows (about 17 minutes)
MAX_ROWS_AT_ONCE: Final = 100_000
#: What each row holds after the outputs and the motors: the recorder's own values
EXTRAS = ("t", "on_ground", "roll_sp", "pitch_sp", "yaw_rate_sp", "throttle", "rc_link", "fault",
          "wind_n", "wind_e", "wind_d")


class _Recorder:
    """Samples the plant, the motor inputs, the sticks and the scenario state on the 100 Hz grid, into a
    table the world's probe writes in C (the signals derived from them are computed after the run)."""

    def __init__(self, scenario: Scenario, world: World, rc: StickEmulator, wind: _Wind,
                 faults: list[Fault], profile: Profile) -> None:
        self.sc, self.world, self.rc, self.wind, self.faults = scenario, world, rc, wind, faults
        self.k = 0
        # the grid's rows (the table grows by doubling past MAX_ROWS_AT_ONCE)
        d = scenario.duration
        rows = int(d / RECORD_PERIOD) + 2 if 0 <= d < MAX_ROWS_AT_ONCE * RECORD_PERIOD else MAX_ROWS_AT_ONCE
        self._probe = world.probe(RECORDED, len(EXTRAS), rows)
        # the magnetic disturbance's window, read once (Scenario.mag_disturbance_at is plain Python);
        # so are the stick scales and the period: a plain dataclass's attribute and another module's
        # global are a dictionary lookup each, about 1 k instructions a tick of the 100 Hz recorder
        _, self._mag_from, self._mag_to = scenario.mag_disturbance_window
        # (the setpoints the sticks stand for: the scenario's [rc] when it says, else the FC profile's)
        self._angle_scale: float = scenario.max_angle_deg or profile.modes.angle_deg or 0.0
        self._yaw_scale: float = scenario.max_yaw_rate_dps or profile.modes.yaw_rate_dps
        self._period: float = RECORD_PERIOD

    def tick(self, session: Host) -> None:
        t = self.k * self._period
        st = self.rc.sticks
        faulted = self._mag_from <= t < self._mag_to
        for f in self.faults:
            faulted = faulted or f.active(t)
        wn, we, wd = self.wind.now
        angle = self._angle_scale
        self._probe.record((
            t, float(self.world.on_ground), st.roll * angle, st.pitch * angle,
            st.yaw * self._yaw_scale, st.throttle, float(self.rc.link == "ok"), float(faulted),
            wn, we, wd,
        ))
        self.k += 1
        session.at(self.k * self._period, self.tick)

    def signals(self) -> dict[str, np.ndarray]:
        a = self._probe.rows()
        col = {name: a[:, i] for i, name in enumerate(RECORDED)}
        first_motor = len(RECORDED)
        col.update((name, a[:, first_motor + MOTORS + i]) for i, name in enumerate(EXTRAS))
        deg = 180 / math.pi
        s = {
            "t": col["t"],
            "roll": col["roll"] * deg,
            "pitch": col["pitch"] * deg,
            "yaw": col["yaw"] * deg,
            "alt": -col["pd"],
            "climb": -col["vd"],
            # math.hypot as the row was computed before (numpy's rounds differently in the last bit)
            "speed": np.array(list(map(math.hypot, col["vn"].tolist(), col["ve"].tolist())), dtype=float),
            "p": col["p"] * deg,
            "q": col["q"] * deg,
            "r": col["r"] * deg,
        }
        motors = a[:, first_motor:first_motor + MOTORS]
        for m in range(MOTORS):
            s[f"pwm{m + 1}"] = motors[:, m]
        s["pwm_max"], s["pwm_min"] = motors.max(axis=1), motors.min(axis=1)
        for name in ("on_ground", "roll_sp", "pitch_sp", "yaw_rate_sp", "throttle", "rc_link", "fault"):
            s[name] = col[name]
        s["wind"] = np.array(list(map(math.hypot, col["wind_n"].tolist(), col["wind_e"].tolist(),
                                      col["wind_d"].tolist())), dtype=float)
        s["roll_track_error"], s["pitch_track_error"] = s["roll"] - s["roll_sp"], s["pitch"] - s["pitch_sp"]
        s["tilt"] = np.maximum(np.abs(s["roll"]), np.abs(s["pitch"]))
        return s


#: the telemetry's columns after t, in TELEMETRY_KEYS' order
_TELEMETRY_COLUMNS: Final = tuple(TELEMETRY_KEYS)


def parse_telemetry(text: bytes, clock_base_s: float) -> tuple[dict[str, np.ndarray], int, dict[str, float]]:
    """The DUT's ``T t=… key=value …`` lines as columns (rig/telemetry: time in sim seconds, the DUT's
    monotonic clock minus ``clock_base_s``, its reading at sim time 0, ``Session.dut_clock_base_s``),
    the count of lines skipped, and per key the sim time it was first non-finite."""
    return read_columns(text, clock_base_s, _TELEMETRY_COLUMNS)


def _hold(t_grid: np.ndarray, t_src: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Zero-order hold of (t_src, v) onto t_grid; NaN before the first sample."""
    idx = np.searchsorted(t_src, t_grid + 1e-9, side="right") - 1
    out = np.full(len(t_grid), math.nan)
    ok = idx >= 0
    out[ok] = v[idx[ok]]
    return out


def _wrap180(x: np.ndarray) -> np.ndarray:
    return (x + 180.0) % 360.0 - 180.0


def run(
    scenario: Scenario,
    target: Target | None = None,
    seed: int = 0,
    work_dir: Path | None = None,
    wall_timeout: float = 600.0,
    stall_timeout: float = 30.0,
    profile: Profile | None = None,
) -> RunResult:
    """Runs ``scenario`` against ``target`` (rig/targets: a Linux program in lockstep or real time, a
    board behind a bridge, a firmware image under emulation; None: the reference FC in lockstep), flown
    as ``profile`` says that FC is flown (None: the reference FC's). The DUT's stdout, stderr and
    telemetry go to ``work_dir`` (with None, to a temporary folder removed afterwards)."""
    if target is None:
        target = ProcessTarget()
    if profile is None:
        profile = profiles.load()
    if work_dir is None:
        with scratch.folder("run") as tmp:
            return run(scenario, target, seed, Path(tmp), wall_timeout, stall_timeout, profile)
    work = Path(work_dir)
    work.mkdir(parents=True, exist_ok=True)
    why_not = cannot_fly(scenario, profile)
    if why_not:
        return not_run(scenario, seed, why_not, target, profile, verdict=SKIPPED)
    notes: list[str] = []
    first = first_action(scenario, profile)
    if first is not None and profile.startup_s > first:
        notes.append(f"the FC's profile {profile.name!r} needs {profile.startup_s:g} s to start up; the "
                     f"scenario acts first at {first:g} s{_gesture_words(scenario, profile)}, so all of it "
                     f"runs {profile.startup_s - first:g} s later")
        scenario = scenario.shifted(profile.startup_s - first)
    if profile.config.fc:  # (the reference FC made to fly as the profile says; the scenario's [fc] on top)
        scenario = dataclasses.replace(scenario, fc={**dict(profile.config.fc), **scenario.fc})
    metadata: dict[str, object] = {
        **identity(scenario, seed, profile),
        **target.describe(scenario, work, notes, profile),
        "duration": scenario.duration,
        "mode": target.mode,
    }
    faults = fault_sets(scenario.faults, seed)
    world = World.at_rest(
        seed=seed,
        noise=scenario.noise,
        params=plant_params(scenario, profile, notes),
        faults=faults,
        mag_disturbance=scenario.mag_disturbance_at if any(scenario.mag_disturbance) else None,
        baro_noise_pa=scenario.baro_noise_pa,
        baro_drift_pa_per_s=scenario.baro_drift_pa_per_s,
        baro_osr_noise=profile.baro_noise,
        **{"motor_order": profile.motors.order, "pwm_channels": max(profile.motors.pwm_channels, 8),
           **target.world_options(profile)},
    )
    stderr_path = work / "dut-stderr.txt"
    try:  # (the world holds the plant, whose instance close() frees)
        metadata["plant_fmu_sha256"] = world.plant.fmu_sha256
        with open(stderr_path, "w") as err, open(work / "dut-stdout.txt", "w") as out:
            ctx = RunContext(scenario, world, faults, work, out, err, wall_timeout, stall_timeout, notes,
                             profile)
            target_run = target.open(ctx)
            try:
                session = target_run.session
                rc = StickEmulator(RC_PATH, cmap=profile.channel_map())
                rc.start(session)
                wind = _Wind(scenario, seed)
                if wind.active():
                    session.at(0.0, lambda s: wind.tick(s, 0.0))
                rec = _Recorder(scenario, world, rc, wind, [f.fault for f in scenario.faults], profile)
                session.at(0.0, rec.tick)
                for ev in scenario.timeline:
                    lead = arming_lead(profile) if ev.arm else 0.0
                    if lead:  # (the gesture ends at the arm's time: armed when the scenario says)
                        session.at(ev.t - lead, functools.partial(_arming, rc=rc, arm=True, t=ev.t - lead,
                                                                  profile=profile, notes=notes))
                        ev = dataclasses.replace(ev, arm=None)
                    session.at(ev.t, apply_event(rc, ev, profile, notes))
                _schedule_sends(scenario, target_run, session, notes)
                watch = _watch(profile)
                if watch is not None:
                    session.at(0.0, watch.tick)
                outcome = session.run()
                if watch is not None:
                    watch.finish(session, outcome.sim_time)
                signals = rec.signals()
                metadata.update(target_run.figures(outcome))
                signals.update(target_run.signals(signals["t"]))
                idle = target_run.idle(outcome) if outcome.verdict == "ok" else None
                i2c = target_run.transactions()
                uarts = target_run.uarts()
            finally:
                target_run.close()
    finally:
        world.close()
    raw_telemetry = session.serial_output(telemetry_path(profile))
    (work / "dut-telemetry.txt").write_bytes(raw_telemetry)  # the DUT's own words, kept as they came
    if watch is None:
        tel, bad, nonfinite = parse_telemetry(raw_telemetry, session.dut_clock_base_s)
        if bad:
            notes.append(f"{bad} telemetry line(s) from the DUT did not parse and were skipped")
        for key, since in nonfinite.items():
            notes.append(f"the DUT reported {key} as not a number from sim t={since:.3f} s on (its "
                         "telemetry, dut-telemetry.txt)")
    else:
        tel = watch.columns()
        metadata["telemetry"] = telemetry_figures(watch)
        unready = why_unready(scenario, profile, watch)
        if unready:
            notes.append(unready)
    for k, name in TELEMETRY_KEYS.items():
        signals[name] = (
            _hold(signals["t"], tel["t"], tel[k]) if len(tel["t"]) else np.full(len(signals["t"]), math.nan)
        )
    for ax in ("roll", "pitch", "alt"):
        signals[f"{ax}_est_error"] = signals[f"est_{ax}"] - signals[ax]
    signals["yaw_est_error"] = _wrap180(signals["est_yaw"] - signals["yaw"])
    metadata.update(
        sim_time=outcome.sim_time,
        wall_time=outcome.wall_time,
        realtime_factor=outcome.sim_time / outcome.wall_time if outcome.wall_time > 0 else None,
        dut_returncode=outcome.dut_returncode,
        dut_clock_base_s=session.dut_clock_base_s,
        bus_transactions=outcome.transactions,
    )
    if outcome.transport:
        metadata["transport"] = outcome.transport
    if target.realtime:
        metadata["realtime_lateness"] = {
            "events": outcome.events_run,
            "late_over_1ms": outcome.events_late,
            "max_s": outcome.max_lateness_s,
            "p99_s": outcome.p99_lateness_s,
            "p50_s": outcome.p50_lateness_s,
            **outcome.host_state,
        }
        if outcome.events_late:
            notes.append(
                f"real time: {outcome.events_late} of {outcome.events_run} scheduled events ran over 1 ms "
                f"late (worst {outcome.max_lateness_s * 1000:.1f} ms)"
            )
    for name in BENCH_SIGNALS:  # a criterion on the supply's signals, in a run without one: NaN, not judged
        signals.setdefault(name, np.full(len(signals["t"]), math.nan))
    measurements = [
        uart_criteria.measure(c, uarts) if c.uart is not None else measure(
            c.name,
            c.metric,
            c.signal,
            signals["t"],
            signals[c.signal],
            c.start,
            c.end,
            c.target,
            c.band,
            c.min,
            c.max,
            c.units,
            c.baseline_at,
            c.marginal,
        )
        for c in scenario.criteria
    ]
    measurements = judge_flight(scenario, profile, signals, measurements, notes)
    stderr = stderr_path.read_text(errors="replace")
    error = idle
    if error:  # a DUT that never flew passes nothing, however still the vehicle stayed
        verdict = "error"
        measurements = [dataclasses.replace(m, outcome=NOT_JUDGED, reason="the DUT did not fly the vehicle",
                                            marginal=False) for m in measurements]
    elif outcome.verdict != "ok":
        error = outcome.error or f"the DUT ended the run itself (status {outcome.dut_returncode})"
        said = _last_words(stderr)
        if outcome.dut_returncode is not None and said:
            error += f"; the DUT said: {said}"
        verdict = "interrupted" if outcome.verdict == "interrupted" else "error"
        # a run that ended in error judged nothing: its measurements stay, none of them passed
        measurements = [dataclasses.replace(m, outcome=NOT_JUDGED, reason="the run ended in error",
                                            marginal=False) for m in measurements]
    else:
        # (not measured is no pass, nor a failure; a scenario with only those was skipped: cannot_fly)
        verdict = "pass" if all(m.outcome in ("pass", NOT_MEASURED) for m in measurements) else "fail"
    notes += outcome.notes
    assert set(SIGNALS) - set(BENCH_SIGNALS) <= set(signals), set(SIGNALS) - set(signals)
    rc_frames = list(map(functools.partial(tuple.__new__, RcFrame), rc.frames))  # (no Python frame each)
    return RunResult(scenario, verdict, error, measurements, signals, metadata, outcome.exit_code, stderr,
                     notes, i2c, rc_frames)


def _watch(profile: Profile) -> Watch | None:
    """The reader of the FC's MSP or MAVLink telemetry through the run (None: text lines, read after,
    or none)."""
    kind = profile.telemetry.kind
    if kind not in ("msp", "mavlink"):
        return None
    period = 1 / profile.telemetry.poll_hz if kind == "msp" else MAVLINK_WATCH_PERIOD
    return Watch(telemetry_path(profile), kind, period)


def telemetry_figures(watch: Watch) -> dict[str, object]:
    """result.json's account of the FC's binary telemetry: what came, what was refused, when it first
    answered."""
    return {"kind": watch.kind, "messages": dict(sorted(watch.counts.items())), "bad_frames": watch.bad,
            "first_valid_s": watch.ready_s}


def why_unready(scenario: Scenario, profile: Profile, watch: Watch) -> str:
    """With ``startup.ready = "telemetry"``: "" when the FC's first valid reply (MSP) or heartbeat
    (MAVLink) came before the scenario's first action, else what it did not say, and when."""
    first = scenario.first_action
    if profile.ready != "telemetry" or first is None:
        return ""
    what = "reply" if watch.kind == "msp" else "heartbeat"
    if watch.ready_s is None:
        return f"the FC never gave a valid {watch.kind.upper()} {what}: it never said it was ready"
    if watch.ready_s > first:
        return (f"the FC's first valid {watch.kind.upper()} {what} came at {watch.ready_s:.2f} s, after the "
                f"scenario's first action at {first:g} s: it acted before the FC was ready")
    return ""


def plant_params(scenario: Scenario, profile: Profile, notes: list[str]) -> dict[str, float]:
    """The plant's parameters: the scenario's airframe and [vehicle] table, with the frame the FC's
    profile flies (the airframe is built for the FC's mixer) unless the scenario sets one itself."""
    frame = 1.0 if profile.motors.frame == "x" else 0.0
    params = scenario.plant_params()
    own = scenario.plant.get("frame")
    if own is None:
        params["frame"] = frame
    elif own != frame:
        notes.append(f"the scenario's vehicle frame ({own:g}) is not the FC profile's "
                     f"({profile.motors.frame!r}); the scenario's is flown")
    return params


def identity(scenario: Scenario, seed: int, profile: Profile | None = None) -> dict[str, object]:
    """What every result.json says about where and when it was made, errored or not, and for which FC."""
    if profile is None:
        profile = profiles.load()
    return {
        "fc_profile": profile.name,
        "fc_profile_file": str(profile.path),
        "fc_profile_sha256": profile.sha256,
        "rig_version": __version__,
        "scenario": scenario.stem,
        "scenario_name": scenario.name,
        "scenario_file": str(scenario.path.resolve()),
        "scenario_sha256": scenario.sha256,
        "airframe": scenario.airframe.describe(),
        "airframe_file": str(scenario.airframe.path.resolve()),
        "airframe_sha256": scenario.airframe.sha256,
        "seed": seed,
        "started": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "host": socket.gethostname(),
    }


def not_run(scenario: Scenario, seed: int, error: str, target: Target | None = None,
            profile: Profile | None = None, verdict: str = "error") -> RunResult:
    """The result of a scenario the rig could not fly at all (an error before the DUT started), or
    did not fly (``verdict`` SKIPPED: an FC that cannot fly it, ``error`` says why): nothing recorded,
    nothing judged."""
    empty = {name: np.zeros(0) for name in ("t", *SIGNALS)}
    outcome, why = (SKIPPED, error) if verdict == SKIPPED else (NOT_JUDGED, "the run did not take place")
    measurements = [
        Measurement(c.name, c.metric, c.signal, math.nan, c.units, c.min, c.max, c.start, c.end, outcome, why)
        for c in scenario.criteria
    ]
    metadata: dict[str, object] = {**identity(scenario, seed, profile), "duration": scenario.duration,
                                   **(target or ProcessTarget()).not_run_metadata()}
    return RunResult(scenario, verdict, error, measurements, empty, metadata)


def _last_words(stderr: str) -> str:
    """The DUT's last line on stderr (its own reason for stopping, when it gave one), shortened."""
    lines = [line.strip() for line in stderr.splitlines() if line.strip()]
    return lines[-1][:300] if lines else ""


def _schedule_sends(scenario: Scenario, target_run: TargetRun, session: Host, notes: list[str]) -> None:
    """The scenario's [[serial]] sends, each at its time on its USART; a DUT without USARTs gets none
    (the notes say so)."""
    for send in scenario.serial:
        port = target_run.serial_port(send.uart, send.baud)
        if port is None:
            notes.append(f"{len(scenario.serial)} [[serial]] send(s) not made: this DUT has no USART "
                         "the rig reaches (an MCU target's)")
            return
        data = send.data if send.msp is None else msp.request(*send.msp)
        session.at(send.t, functools.partial(_send, port, data))


def _send(port: str, data: bytes, session: Host) -> None:
    session.serial_write(port, data)


def apply_event(rc: StickEmulator, ev: Event, profile: Profile, notes: list[str]) -> Callable[[Host], None]:
    """A timeline entry as an event: its sticks (degrees through the FC's profile), mode, arming, link
    state and plant inputs (rig exec --sticks too)."""
    def apply(session: Host) -> None:
        for k, v in ev.sticks.items():
            if k in STICK_TERMS:  # degrees or degrees per second: the FC's stick for them
                axis, x = profiles.stick(profile, k, v)
                setattr(rc.sticks, axis, x)
            else:
                setattr(rc.sticks, k, v)
        if ev.mode is not None:
            rc.sticks.mode = ev.mode
        if ev.arm is not None:
            _arming(session, rc, ev.arm, ev.t, profile, notes)
        if ev.link is not None:
            rc.link = ev.link
        for k, v in ev.inputs.items():
            session.world.set_input(k, v)

    return apply


def arming_lead(profile: Profile) -> float:
    """How long before a scenario's ``arm`` the FC's arming begins: a stick gesture is held for its time
    and ends at the arm's time, so the FC is armed when the scenario says and the sticks it gives after
    the arm apply when it gives them (an FC such as ArduCopter wants the rudder held 3 s); a switch
    acts at once."""
    return profile.arming.hold_s if profile.arming.method == "sticks" else 0.0


def first_action(scenario: Scenario, profile: Profile) -> float | None:
    """When the FC is first acted on: the scenario's first action, or its first arming gesture's start."""
    first = scenario.first_action
    arms = [e.t - arming_lead(profile) for e in scenario.timeline if e.arm]
    return min([first, *arms]) if first is not None else None


def _gesture_words(scenario: Scenario, profile: Profile) -> str:
    lead = arming_lead(profile)
    return f" (its arming gesture, held {lead:g} s before the arm)" if lead and scenario.arms else ""


def _arming(session: Host, rc: StickEmulator, arm: bool, t: float, profile: Profile,
            notes: list[str]) -> None:
    """Arms or disarms as the FC's profile says: a switch, or a stick gesture held for its time (the
    scenario's own stick changes meanwhile apply when it ends)."""
    method = profile.arming.method
    rc.sticks.arm = arm
    if method == "sticks":
        gesture = "arm" if arm else "disarm"
        rc.sticks.gesture = gesture

        def release(_: Host) -> None:
            if rc.sticks.gesture == gesture:
                rc.sticks.gesture = ""

        session.at(t + profile.arming.hold_s, release)
    elif method == "telemetry":
        notes.append(f"the FC's profile {profile.name!r} arms by a telemetry command, which this rig does "
                     f"not send yet: the {'arm' if arm else 'disarm'} at {t:g} s was not done")


#: the signals that come from the FC's telemetry (its estimates and its armed flag)
TELEMETRY_SIGNALS: Final = frozenset({*TELEMETRY_KEYS.values(), "roll_est_error", "pitch_est_error",
                                      "yaw_est_error", "alt_est_error"})


def cannot_fly(scenario: Scenario, profile: Profile) -> str:
    """Why the FC cannot fly this scenario under its profile (a mode or feature it lacks, more than a
    full stick, nothing the rig can measure of it), or ""."""
    why = profiles.fly_check(profile, scenario.needs, scenario.stick_terms())
    if why:
        return why
    knobs = sorted({k for e in scenario.timeline for k in e.sticks if k in KNOBS} - set(profile.rc.extra))
    if knobs:
        return f"the FC's profile {profile.name!r} has no {', '.join(knobs)} channel (rc.extra)"
    if not profile.reads_telemetry and all(c.signal in TELEMETRY_SIGNALS for c in scenario.criteria):
        return f"every criterion is on the FC's estimates: {profile.not_measured_reason()}"
    return ""


def judge_flight(scenario: Scenario, profile: Profile, signals: dict[str, np.ndarray],
                 measurements: list[Measurement], notes: list[str]) -> list[Measurement]:
    """The criteria the FC's telemetry cannot give are not measured; in a scenario that arms, an FC
    that never armed, or a free vehicle that never left the ground, fails every criterion with that
    reason (a vehicle that sat still does not pass "holds attitude")."""
    reason = profile.not_measured_reason()
    out = [dataclasses.replace(m, value=math.nan, outcome=NOT_MEASURED, reason=reason, margin=None,
                               marginal=False)
           if reason and m.signal in TELEMETRY_SIGNALS else m for m in measurements]
    still = why_still(scenario, profile, signals)
    if still:
        notes.append(still)
        out = [dataclasses.replace(m, outcome="fail", reason=still, marginal=False)
               if m.outcome in ("pass", "fail") else m for m in out]
    return out


def why_still(scenario: Scenario, profile: Profile, signals: dict[str, np.ndarray]) -> str:
    """In a scenario that arms: "" when the FC armed (and a free vehicle given take-off throttle lifted
    off), else what it did not do and how the rig knows."""
    arms = [e.t for e in scenario.timeline if e.arm]
    if not arms or not len(signals["t"]):
        return ""
    after = signals["t"] >= arms[0]
    said = signals["armed"][after]
    # (by its telemetry's flag when it sent any; a DUT that sends none is judged by its motors)
    if profile.arming.detect == "telemetry" and profile.reads_telemetry and not bool(np.all(np.isnan(said))):
        armed = bool(np.any(np.nan_to_num(said) > 0.5))
        how = "its telemetry never said armed"
    else:
        armed = bool(np.any(signals["pwm_max"][after] > profile.arming.idle_us))
        how = f"no motor pulse above {profile.arming.idle_us:g} us"
    if not armed:
        return f"the FC never armed ({how} after the arm at {arms[0]:g} s): nothing it did was a flight"
    climb = [e.t for e in scenario.timeline
             if e.t >= arms[0] and e.sticks.get("throttle", 0.0) >= LIFT_THROTTLE]
    if (climb and scenario.plant.get("stand", 0.0) == 0.0
            and bool(np.all(signals["on_ground"][signals["t"] >= climb[0]] > 0.5))):
        return (f"the vehicle never left the ground after the throttle went to take-off at {climb[0]:g} s: "
                "nothing was flown")
    return ""


#: a free vehicle given at least this throttle after arming is expected to leave the ground (the
#: library's hover is 0.5 to 0.56); below it a scenario may mean to stay on the ground
LIFT_THROTTLE: Final = 0.5
