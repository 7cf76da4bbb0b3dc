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

from rig import __version__, scratch
from rig.emulators.faults import Fault, fault_sets
from rig.emulators.sensor_models import Normals
from rig.host import Host
from rig.plant.variables import MOTORS
from rig.rc import StickEmulator
from rig.scenarios.criteria import NOT_JUDGED, Measurement, measure
from rig.scenarios.result import RcFrame, RunResult
from rig.scenarios.schema import Event, Scenario
from rig.scenarios.signals import BENCH_SIGNALS, RECORD_PERIOD, SIGNALS
from rig.targets import RC_PATH, TELEMETRY_PATH, RunContext, Target
from rig.targets.process import ProcessTarget
from rig.telemetry import read_columns
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
                 faults: list[Fault]) -> None:
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
        self._angle_scale: float = scenario.max_angle_deg
        self._yaw_scale: float = scenario.max_yaw_rate_dps
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
) -> RunResult:
    """Runs ``scenario`` against ``target`` (rig/targets: a Linux program in lockstep or real time, a
    board behind a bridge, a firmware image under emulation; None: the reference FC in lockstep). The
    DUT's stdout, stderr and telemetry go to ``work_dir`` (with None, to a temporary folder removed
    afterwards)."""
    if target is None:
        target = ProcessTarget()
    if work_dir is None:
        with scratch.folder("run") as tmp:
            return run(scenario, target, seed, Path(tmp), wall_timeout, stall_timeout)
    work = Path(work_dir)
    work.mkdir(parents=True, exist_ok=True)
    notes: list[str] = []
    metadata: dict[str, object] = {
        **identity(scenario, seed),
        **target.describe(scenario, work, notes),
        "duration": scenario.duration,
        "mode": target.mode,
    }
    faults = fault_sets(scenario.faults, seed)
    world = World.at_rest(
        seed=seed,
        noise=scenario.noise,
        params=scenario.plant_params(),
        faults=faults,
        mag_disturbance=scenario.mag_disturbance_at if any(scenario.mag_disturbance) else None,
        baro_noise_pa=scenario.baro_noise_pa,
        baro_drift_pa_per_s=scenario.baro_drift_pa_per_s,
        **target.world_options(),
    )
    stderr_path = work / "dut-stderr.txt"
    try:  # (the world holds the plant, whose instance close() frees)
        metadata["plant_fmu_sha256"] = world.plant.fmu_sha256
        with open(stderr_path, "w") as err, open(work / "dut-stdout.txt", "w") as out:
            ctx = RunContext(scenario, world, faults, work, out, err, wall_timeout, stall_timeout, notes)
            target_run = target.open(ctx)
            try:
                session = target_run.session
                rc = StickEmulator(RC_PATH)
                rc.start(session)
                wind = _Wind(scenario, seed)
                if wind.active():
                    session.at(0.0, lambda s: wind.tick(s, 0.0))
                rec = _Recorder(scenario, world, rc, wind, [f.fault for f in scenario.faults])
                session.at(0.0, rec.tick)
                for ev in scenario.timeline:
                    session.at(ev.t, _apply_event(rc, ev))
                outcome = session.run()
                signals = rec.signals()
                metadata.update(target_run.figures(outcome))
                signals.update(target_run.signals(signals["t"]))
                idle = target_run.idle(outcome) if outcome.verdict == "ok" else None
                i2c = target_run.transactions()
            finally:
                target_run.close()
    finally:
        world.close()
    raw_telemetry = session.serial_output(TELEMETRY_PATH)
    (work / "dut-telemetry.txt").write_bytes(raw_telemetry)  # the DUT's own words, kept as they came
    tel, bad, nonfinite = parse_telemetry(raw_telemetry, session.dut_clock_base_s)
    if bad:
        notes.append(f"{bad} telemetry line(s) from the DUT did not parse and were skipped")
    for key, since in nonfinite.items():
        notes.append(f"the DUT reported {key} as not a number from sim t={since:.3f} s on (its telemetry, "
                     "dut-telemetry.txt)")
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
        measure(
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
        verdict = "pass" if all(m.outcome == "pass" for m in measurements) else "fail"
    notes += outcome.notes
    assert set(SIGNALS) - set(BENCH_SIGNALS) <= set(signals), set(SIGNALS) - set(signals)
    rc_frames = list(map(functools.partial(tuple.__new__, RcFrame), rc.frames))  # (no Python frame each)
    return RunResult(scenario, verdict, error, measurements, signals, metadata, outcome.exit_code, stderr,
                     notes, i2c, rc_frames)


def identity(scenario: Scenario, seed: int) -> dict[str, object]:
    """What every result.json says about where and when it was made, errored or not."""
    return {
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


def not_run(scenario: Scenario, seed: int, error: str, target: Target | None = None) -> RunResult:
    """The result of a scenario the rig could not fly at all (an error before the DUT started):
    nothing recorded, nothing judged."""
    empty = {name: np.zeros(0) for name in ("t", *SIGNALS)}
    measurements = [
        Measurement(c.name, c.metric, c.signal, math.nan, c.units, c.min, c.max, c.start, c.end, NOT_JUDGED,
                    "the run did not take place")
        for c in scenario.criteria
    ]
    metadata: dict[str, object] = {**identity(scenario, seed), "duration": scenario.duration,
                                   **(target or ProcessTarget()).not_run_metadata()}
    return RunResult(scenario, "error", error, measurements, empty, metadata)


def _last_words(stderr: str) -> str:
    """The DUT's last line on stderr (its own reason for stopping, when it gave one), shortened."""
    lines = [line.strip() for line in stderr.splitlines() if line.strip()]
    return lines[-1][:300] if lines else ""


def _apply_event(rc: StickEmulator, ev: Event) -> Callable[[Host], None]:
    def apply(session: Host) -> None:
        for k, v in ev.sticks.items():
            setattr(rc.sticks, k, v)
        if ev.link is not None:
            rc.link = ev.link
        for k, v in ev.inputs.items():
            session.world.set_input(k, v)

    return apply
