"""The bridge target: a DUT behind a bench bridge (rig/bridge/session.py), in real time. Behind a serial
port the DUT is the board wired to the bridge (nothing for the rig to start); with ``virtual`` it is a
Linux program (the reference FC by default) on the virtual bridge. The sensors are the bridge's, the
motors the pulses it captures (or a CAN capture device's), the sticks SBUS it sends. A scenario's
[bench] supply power-cycles a board before the run and is sampled during it (rig/power)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, Final

import numpy as np

from rig.bridge.esc import esc_protocol
from rig.bridge.port import BridgeError
from rig.bridge.session import BenchConfig, BenchSession
from rig.host import Host
from rig.power.bench_run import PsuRun
from rig.power.supply import PsuError
from rig.scenarios.profile import Profile
from rig.scenarios.schema import Scenario
from rig.scheduler import EXIT_RIG_ERROR
from rig.session import Outcome
from rig.targets import RC_PATH, RunContext, TargetRun, telemetry_path
from rig.targets.process import command_for, describe_command

PSU_SAMPLE_S: Final = 0.1  # the bench supply's readings join the run's record at 10 Hz


class BridgeRun(TargetRun):
    session: BenchSession

    def __init__(self, session: BenchSession, psu: PsuRun | None, esc: str = "pwm") -> None:
        self.session = session
        self.psu = psu
        self.esc = esc

    def idle(self, outcome: Outcome) -> str | None:
        """As any target's, but no motor driven while the bridge counted pulse glitches is said as what it
        is: pulses came, outside the ESC protocol's window (a PWM board run with --esc oneshot125 read
        "the DUT never drove a motor" beside 11168 glitches in result.json)."""
        why = super().idle(outcome)
        if why is None or outcome.transactions == 0 or outcome.pwm_writes != 0:
            return why
        glitches = self.session.figures.status.get("pulse_glitches", 0)
        if not isinstance(glitches, int) or glitches <= 0:
            return why
        p = esc_protocol(self.esc)
        return (f"no pulse within the {p.name} protocol's window ({p.pulse_min_us}..{p.pulse_max_us} us, "
                f"{p.period_min_us} us apart at least) reached a motor, but the bridge counted {glitches} "
                f"pulses outside it (pulse glitches): is the board's ESC protocol {p.name}? (rig run --esc)")

    def figures(self, outcome: Outcome) -> dict[str, object]:
        out: dict[str, object] = {"bridge": self.session.link_figures()}
        if self.psu is not None:
            out["bench_power"] = self.psu.figures()
        return out

    def signals(self, t: np.ndarray) -> dict[str, np.ndarray]:
        return self.psu.signals(t) if self.psu is not None else {}

    def close(self) -> None:
        if self.psu is not None:
            self.psu.close()


class BridgeTarget:
    """``bridge``: "virtual" or the bridge's serial port; ``dut``: the program on the virtual bridge
    (None: the reference FC); ``can``: INTERFACE:CHANNEL of a CAN capture device for the motors;
    ``esc``: the board's ESC protocol (rig/bridge/esc.py)."""

    mode = "bridge"
    realtime = True

    def __init__(self, bridge: str, dut: list[str] | None = None, can: str | None = None,
                 esc: str = "pwm") -> None:
        self.board = bridge != "virtual"  # a real board: nothing for the rig to start
        if self.board and dut is not None:
            raise ValueError("behind a bridge's port the DUT is the board wired to it: no DUT command")
        self.bridge, self.dut, self.can, self.esc = bridge, dut, can, esc
        self._command: list[str] | None = None

    def describe(self, scenario: Scenario, work: Path, notes: list[str],
                 profile: Profile | None = None) -> dict[str, object]:
        if self.board:
            self._command = None
            who: dict[str, object] = {"dut_command": f"the board behind the bridge at {self.bridge}",
                                      "fc_config": None}
        else:
            self._command = command_for(self.dut, scenario, work, notes, profile)
            who = describe_command(self._command, scenario, self.dut is None)
        return {**who, "capture": f"can ({self.can})" if self.can else "bridge", "lockstep": False}

    def open(self, ctx: RunContext) -> BridgeRun:
        psu = PsuRun(ctx.scenario.bench) if ctx.scenario.bench.psu is not None else None
        try:
            if psu is not None:
                _psu_prepare(psu)
            session = BenchSession(BenchConfig(
                bridge=self.bridge, command=self._command, rc_path=RC_PATH,
                serial=[] if self.board else [telemetry_path(ctx.profile)], duration=ctx.scenario.duration,
                wall_timeout=ctx.wall_timeout, stdout=ctx.stdout, stderr=ctx.stderr, faults=ctx.faults,
                can=self.can, esc=self.esc, power_on=None if psu is None else _psu_switch_on(psu)), ctx.world)
        except BaseException:
            if psu is not None:
                psu.close()
            raise
        if psu is not None:
            session.at(0.0, _psu_sampler(psu, session))
        return BridgeRun(session, psu, self.esc)

    def world_options(self, profile: Profile | None = None) -> dict[str, Any]:
        return {}

    def not_run_metadata(self) -> dict[str, object]:
        return {"mode": self.mode, "bridge": self.bridge}


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
