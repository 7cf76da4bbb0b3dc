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
import math
import os
import shlex
import socket
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Final

import numpy as np

from emulators.faults import Fault, fault_sets
from emulators.sensor_models import Normals
from plant.native_build import BUILD
from plant.variables import MOTORS
from rig import __version__, firmware
from rig.bridge.port import BridgeError
from rig.bridge.session import BenchConfig, BenchSession
from rig.capture import install_capture
from rig.host import Host
from rig.power.bench_run import PsuRun
from rig.power.supply import PsuError
from rig.rc import StickEmulator
from rig.scheduler import EXIT_RIG_ERROR
from rig.session import Outcome, Session, SessionConfig
from rig.world import World
from scenarios.criteria import NOT_JUDGED, Measurement, measure
from scenarios.result import RunResult
from scenarios.schema import Event, Scenario
from scenarios.signals import BENCH_SIGNALS, RECORD_PERIOD, SIGNALS

# (the build folder from a module that is never compiled: this one may run from build/mypyc,
# rig/compiled.py, where __file__ is not the source's)
REFERENCE_FC: Final = BUILD / "dut" / "fc"
RC_PATH: Final = "/dev/ttyRC0"
TELEMETRY_PATH: Final = "/dev/ttyTEL0"
WIND_PERIOD: Final = 0.01
TELEMETRY_KEYS = {
    "roll": "est_roll",
    "pitch": "est_pitch",
    "yaw": "est_yaw",
    "alt": "est_alt",
    "armed": "armed",
}


PSU_SAMPLE_S: Final = 0.1  # the bench supply's readings join the run's record at 10 Hz


def absolute_command(command: list[str], cwd: Path) -> list[str]:
    """The command as the report records it: the program and every operand naming an existing file
    given by a relative path, made absolute (``./fc fc.conf`` says nothing once the folder is gone)."""
    out = []
    for k, a in enumerate(command):
        p = Path(a)
        named = (k == 0 and "/" in a) or (cwd / p).exists()
        if a and not a.startswith("-") and not p.is_absolute() and named:
            a = os.path.normpath(cwd / p)
        out.append(a)
    return out


def mode(realtime: bool, bridge: str | None = None) -> str:
    """result.json's ``mode``: how the DUT met the rig: in lockstep, in real time, or behind a bench
    bridge (real time too)."""
    return "bridge" if bridge is not None else "real time" if realtime else "lockstep"


def reference_config(scenario: Scenario) -> str:
    lines = [f"rc_path = {RC_PATH}", f"telemetry_path = {TELEMETRY_PATH}", "telemetry_every = 5"]
    lines += [f"{k} = {v}" for k, v in scenario.fc.items()]
    return "\n".join(lines) + "\n"


class _Wind:
    """Steady wind + turbulence + gusts, written into the plant's wind inputs every WIND_PERIOD."""

    def __init__(self, scenario: Scenario, seed: int) -> None:
        self.sc = scenario
        self.normals = Normals(np.random.default_rng(seed + 101))
        self.turb: tuple[float, ...] = (0.0, 0.0, 0.0)
        self.a = math.exp(-WIND_PERIOD / scenario.turbulence_tau)
        self.now = tuple(scenario.wind)

    def active(self) -> bool:
        return any(self.sc.wind) or self.sc.turbulence > 0 or bool(self.sc.gusts)

    def tick(self, session: Host, t: float) -> None:
        # plain floats: three values a hundred times a second are cheaper than numpy calls
        sc = self.sc
        if sc.turbulence > 0:
            a, s = self.a, sc.turbulence * math.sqrt(1 - self.a**2)
            self.turb = tuple(a * x + s * z for x, z in zip(self.turb, self.normals.take(3), strict=True))
        w = [base + x for base, x in zip(sc.wind, self.turb, strict=True)]
        for g in sc.gusts:
            if g.start <= t <= g.start + g.duration:
                shape = 0.5 * (1 - math.cos(2 * math.pi * (t - g.start) / g.duration))
                w = [x + peak * shape for x, peak in zip(w, g.peak, strict=True)]
        world = session.world
        for k, name in enumerate(("wind_n", "wind_e", "wind_d")):
            world.set_input(name, w[k])
        self.now = tuple(w)
        nxt = t + WIND_PERIOD
        session.at(nxt, lambda s: self.tick(s, nxt))


#: The plant outputs the recorder reads, before the motors' pulse widths (World.probe)
RECORDED = ("roll", "pitch", "yaw", "pd", "vd", "vn", "ve", "p", "q", "r")
#: What each row holds after t, the outputs and the motors
ROW_TAIL = ("on_ground", "roll_sp", "pitch_sp", "yaw_rate_sp", "throttle", "rc_link", "fault", "wind")


class _Recorder:
    """Samples the plant, the motor inputs, the sticks and the scenario state on the 100 Hz grid."""

    def __init__(self, scenario: Scenario, world: World, rc: StickEmulator, wind: _Wind,
                 faults: list[Fault]) -> None:
        self.sc, self.world, self.rc, self.wind, self.faults = scenario, world, rc, wind, faults
        self.rows: list[tuple[float, ...]] = []
        self.k = 0
        self._probe = world.probe(RECORDED)

    def tick(self, session: Host) -> None:
        values = self._probe.read()
        roll, pitch, yaw, pd, vd, vn, ve, p, q, r = values[:len(RECORDED)]
        t = self.k * RECORD_PERIOD
        st = self.rc.sticks
        faulted = any(f.active(t) for f in self.faults) or any(self.sc.mag_disturbance_at(t))
        self.rows.append(
            (
                t, roll, pitch, yaw, -pd, -vd, math.hypot(vn, ve), p, q, r,
                *values[len(RECORDED):],
                float(self.world.on_ground),
                st.roll * self.sc.max_angle_deg,
                st.pitch * self.sc.max_angle_deg,
                st.yaw * self.sc.max_yaw_rate_dps,
                st.throttle,
                float(self.rc.link == "ok"),
                float(faulted),
                math.hypot(*self.wind.now),
            )
        )
        self.k += 1
        session.at(self.k * RECORD_PERIOD, self.tick)

    def signals(self) -> dict[str, np.ndarray]:
        first_motor = 10  # after t, roll, pitch, yaw, alt, climb, speed, p, q, r
        tail = first_motor + MOTORS
        a = np.array(self.rows, dtype=float).reshape(-1, tail + len(ROW_TAIL))
        deg = 180 / math.pi
        s = {
            "t": a[:, 0],
            "roll": a[:, 1] * deg,
            "pitch": a[:, 2] * deg,
            "yaw": a[:, 3] * deg,
            "alt": a[:, 4],
            "climb": a[:, 5],
            "speed": a[:, 6],
            "p": a[:, 7] * deg,
            "q": a[:, 8] * deg,
            "r": a[:, 9] * deg,
        }
        for m in range(MOTORS):
            s[f"pwm{m + 1}"] = a[:, first_motor + m]
        motors = a[:, first_motor:tail]
        s["pwm_max"], s["pwm_min"] = motors.max(axis=1), motors.min(axis=1)
        for k, n in enumerate(ROW_TAIL):
            s[n] = a[:, tail + k]
        s["roll_track_error"], s["pitch_track_error"] = s["roll"] - s["roll_sp"], s["pitch"] - s["pitch_sp"]
        s["tilt"] = np.maximum(np.abs(s["roll"]), np.abs(s["pitch"]))
        return s


def parse_telemetry(text: bytes, clock_base_s: float) -> tuple[dict[str, np.ndarray], int, dict[str, float]]:
    """The DUT's ``T t=… key=value …`` lines as columns (time in sim seconds: the DUT's monotonic clock
    minus ``clock_base_s``, its reading at sim time 0, ``Session.dut_clock_base_s``). Lines that do not
    parse are counted and skipped: the DUT's bytes are not trusted. A value the DUT reports as NaN or
    infinite is kept as NaN (the rest of its line stands); the third result gives, per key, the sim
    time it was first non-finite."""
    cols: dict[str, list[float]] = {"t": [], **{k: [] for k in TELEMETRY_KEYS}}
    bad = 0
    nonfinite: dict[str, float] = {}
    for line in text.decode("ascii", "replace").splitlines():
        if not line.startswith("T "):
            bad += bool(line.strip())
            continue
        try:
            kv = dict(item.split("=", 1) for item in line[2:].split())
            t = float(kv["t"]) - clock_base_s
            row = {k: float(kv[k]) for k in TELEMETRY_KEYS if k in kv}
        except (ValueError, KeyError):
            bad += 1
            continue
        if not math.isfinite(t):
            bad += 1
            continue
        cols["t"].append(t)
        for k in TELEMETRY_KEYS:
            v = row.get(k, math.nan)
            if k in row and not math.isfinite(v):
                nonfinite.setdefault(k, t)
                v = math.nan
            cols[k].append(v)
    return {k: np.array(v, dtype=float) for k, v in cols.items()}, bad, nonfinite


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
    dut: list[str] | None = None,
    seed: int = 0,
    work_dir: Path | None = None,
    wall_timeout: float = 600.0,
    stall_timeout: float = 30.0,
    corrupt_every: int = 0,
    realtime: bool = False,
    bridge: str | None = None,
    can: str | None = None,
    esc: str = "pwm",
) -> RunResult:
    """Runs ``scenario``; the reference FC (configured from the scenario's [fc] table) when ``dut`` is
    None. The DUT's stdout, stderr and telemetry go to ``work_dir`` (with None, to a temporary folder
    removed afterwards). Lockstep virtual time by default; ``realtime`` paces the run by the wall clock
    (a bench) and reports how late the scheduled events ran. ``bridge`` ("virtual" or a bridge's serial
    port) runs it in real time through a bench bridge (rig/bridge/session.py): the sensors are the
    bridge's, the motors its captured pulses (``esc``: their protocol, rig/bridge/esc.py); behind a port
    the DUT is the board wired to it."""
    if work_dir is None:
        with tempfile.TemporaryDirectory(prefix="rig-run-") as tmp:
            return run(scenario, dut, seed, Path(tmp), wall_timeout, stall_timeout, corrupt_every, realtime,
                       bridge, can)
    realtime = realtime or bridge is not None
    board = bridge is not None and bridge != "virtual"  # a real board: nothing for the rig to start
    work = Path(work_dir)
    work.mkdir(parents=True, exist_ok=True)
    notes: list[str] = []
    if board:
        if dut is not None:
            raise ValueError("behind a bridge's port the DUT is the board wired to it: no DUT command")
        command = []
    elif dut is None:
        if not REFERENCE_FC.is_file():
            raise FileNotFoundError(f"reference FC not built at {REFERENCE_FC}; run `make dut`")
        conf = work / "fc.conf"
        conf.write_text(reference_config(scenario))
        command = [str(REFERENCE_FC), str(conf)]
    else:
        command = list(dut)
        if scenario.fc:
            notes.append("the scenario's [fc] table configures the reference FC only; ignored for this DUT")
    metadata: dict[str, object] = {
        **identity(scenario, seed),
        "dut_command": shlex.join(absolute_command(command, Path.cwd())) if command
        else f"the board behind the bridge at {bridge}",
        **(firmware.identify(command) if command else {}),
        "fc_config": dict(line.split(" = ", 1) for line in reference_config(scenario).splitlines())
        if dut is None and not board else None,
        "capture": scenario.capture.transport if bridge is None else f"can ({can})" if can else "bridge",
        "duration": scenario.duration,
        "mode": mode(realtime, bridge),
        "lockstep": not realtime,
    }
    faults = fault_sets(scenario.faults, seed)
    world = World.at_rest(
        seed=seed,
        noise=scenario.noise,
        params=scenario.plant,
        faults=faults,
        mag_disturbance=scenario.mag_disturbance_at if any(scenario.mag_disturbance) else None,
        baro_noise_pa=scenario.baro_noise_pa,
        baro_drift_pa_per_s=scenario.baro_drift_pa_per_s,
    )
    psu: PsuRun | None = None
    if bridge is not None and scenario.bench.psu is not None:
        psu = PsuRun(scenario.bench)
    elif scenario.bench.psu is not None:
        notes.append("the scenario's [bench] supply powers a board behind a bridge only: not used here")
    stderr_path = work / "dut-stderr.txt"
    try:  # (the world holds the plant, whose instance close() frees)
        metadata["plant_fmu_sha256"] = world.plant.fmu_sha256
        with open(stderr_path, "w") as err, open(work / "dut-stdout.txt", "w") as out:
            cfg = SessionConfig(
                command=command,
                serial=[RC_PATH, TELEMETRY_PATH],
                duration=scenario.duration,
                lockstep=not realtime,
                wall_timeout=wall_timeout,
                stall_timeout=stall_timeout,
                stdout=out,
                stderr=err,
            )
            session: Session | BenchSession
            if bridge is not None:  # the bridge captures the pulses itself
                if psu is not None:
                    _psu_prepare(psu)
                session = BenchSession(BenchConfig(
                    bridge=bridge, command=None if board else command, rc_path=RC_PATH,
                    serial=[] if board else [TELEMETRY_PATH], duration=scenario.duration,
                    wall_timeout=wall_timeout, stdout=out, stderr=err, faults=faults, can=can, esc=esc,
                    power_on=None if psu is None else _psu_switch_on(psu)), world)
                if psu is not None:
                    session.at(0.0, _psu_sampler(psu, session))
                capture = None
            else:
                session = Session(cfg, world)
                capture = install_capture(session, scenario.capture, corrupt_every)
            rc = StickEmulator(RC_PATH)
            rc.start(session)
            wind = _Wind(scenario, seed)
            if wind.active():
                session.at(0.0, lambda s: wind.tick(s, 0.0))
            rec = _Recorder(scenario, world, rc, wind, [f.fault for f in scenario.faults])
            session.at(0.0, rec.tick)
            for ev in scenario.timeline:
                session.at(ev.t, _apply_event(rc, ev))
            try:
                outcome = session.run()
            finally:
                if capture is not None:
                    capture.close()
    finally:
        world.close()
        if psu is not None:
            psu.close()
    signals = rec.signals()
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
    if capture is not None:
        metadata["capture_stats"] = capture.stats()
    metadata.update(
        sim_time=outcome.sim_time,
        wall_time=outcome.wall_time,
        realtime_factor=outcome.sim_time / outcome.wall_time if outcome.wall_time > 0 else None,
        dut_returncode=outcome.dut_returncode,
        dut_clock_base_s=session.dut_clock_base_s,
        bus_transactions=outcome.transactions,
    )
    if isinstance(session, BenchSession):
        metadata["bridge"] = session.link_figures()
    if psu is not None:
        metadata["bench_power"] = psu.figures()
        signals.update(psu.signals(signals["t"]))
    if realtime:
        metadata["realtime_lateness"] = {
            "events": outcome.events_run,
            "late_over_1ms": outcome.events_late,
            "max_s": outcome.max_lateness_s,
            "p99_s": outcome.p99_lateness_s,
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
    error = _idle(outcome) if outcome.verdict == "ok" else None
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
    return RunResult(scenario, verdict, error, measurements, signals, metadata, outcome.exit_code, stderr,
                     notes)


def identity(scenario: Scenario, seed: int) -> dict[str, object]:
    """What every result.json says about where and when it was made, errored or not."""
    return {
        "rig_version": __version__,
        "scenario": scenario.stem,
        "scenario_name": scenario.name,
        "scenario_file": str(scenario.path.resolve()),
        "scenario_sha256": scenario.sha256,
        "seed": seed,
        "started": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "host": socket.gethostname(),
    }


def _idle(outcome: Outcome) -> str | None:
    """Why a run that ended well still tested nothing, or None."""
    if outcome.transactions == 0:
        return ("the DUT never read a sensor (no I2C transfer reached the rig): nothing it did was a "
                "flight under test")
    if outcome.pwm_writes == 0:
        return "the DUT never drove a motor (no sysfs PWM write reached the rig): nothing was flown"
    return None


def not_run(scenario: Scenario, seed: int, error: str, realtime: bool = False,
            bridge: str | None = None) -> RunResult:
    """The result of a scenario the rig could not fly at all (an error before the DUT started):
    nothing recorded, nothing judged."""
    empty = {name: np.zeros(0) for name in ("t", *SIGNALS)}
    measurements = [
        Measurement(c.name, c.metric, c.signal, math.nan, c.units, c.min, c.max, c.start, c.end, NOT_JUDGED,
                    "the run did not take place")
        for c in scenario.criteria
    ]
    metadata: dict[str, object] = {**identity(scenario, seed), "duration": scenario.duration,
                                   "mode": mode(realtime, bridge)}
    if bridge is not None:
        metadata["bridge"] = bridge
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


def _psu_prepare(psu: PsuRun) -> None:
    """The supply opened, set and switched off before the link starts (a RuntimeError, which the
    suite reports as a run the rig could not fly, when it does not answer)."""
    try:
        psu.prepare()
    except PsuError as e:
        raise RuntimeError(f"bench supply: {e}") from None


def _psu_switch_on(psu: PsuRun) -> Callable[[], None]:
    def switch_on() -> None:
        try:
            psu.switch_on()
        except PsuError as e:
            raise BridgeError(f"bench supply: {e}") from None

    return switch_on


def _psu_sampler(psu: PsuRun, session: BenchSession) -> Callable[[Host], None]:
    """A session event every PSU_SAMPLE_S: the supply's latest reading into the run's record; an
    over-current or a supply gone silent ends the run as an error."""

    def sample(host: Host) -> None:
        t = host.now_ns / 1e9
        problem = psu.sample(t)
        if problem is not None:
            session.sched.fail(EXIT_RIG_ERROR, f"{problem} at sim t={t:.3f} s")
            return
        host.at(t + PSU_SAMPLE_S, sample)

    return sample
