"""How fast the MCU tier's engine runs (bench, not a test): simulated seconds per second for the
ATmega2560 and the ATmega328P at 16 MHz, and what one plant tick (a 1 ms run_until) costs. Seconds of
this process's CPU time, best of three: the machine is shared, wall time measures the neighbours.

  busy           the busy-loop firmware in one run_until of 2 s, then in 2000 calls of 1 ms; what a
                 call costs beyond the simulation (ctypes, the glue's checks), against 1 ms simulated
  pwm int4/5     the ATmega2560 with Timer3's fast PWM on OC3B/OC3C (PE4/PE5, also INT4/INT5): simavr
                 drives the pins low every period, which in stock 1.6 starts a per-cycle INTx poll
  usart poll     the RC echo firmware polling its USARTs: stock 1.6 usleep(1)s on each idle poll
  imu + escs     a flight controller's skeleton (imu_reader): the MPU-6050 read every 1 ms at 400 kHz
                 from the chip core in demand mode (a sample served each ms), two ESC outputs at 400 Hz,
                 run in 1 ms ticks with the pulses taken each tick, as the session does
  polling loops  the poll_loops firmware waiting on a flag in RAM its timer interrupt sets every 5 ms, and
                 on Timer2's overflow flag: with the polling-loop skip (rig/mcu/polling.c) and without
  reference FC   the AVR reference FC (build/avr/fc.elf, `make avr`) flying a library scenario through
                 the MCU target (rig/targets/mcu.py: the runner, the world, the session), whole run; then
                 the same split: the engine (time inside run_until: the firmware's instructions, its TWI
                 and timers) and the rest, per 1 ms plant tick (the world's step, the needs served, the
                 pulses and telemetry taken, the events and the recorder). With the polling-loop skip
                 (and the share of cycles it jumped), without it, and without it and with simavr's timers
                 in the modes it lacks overflowing every prescaler period (stock: before timer_modes.c)
  STM32F405      the reference FC built for the STM32 tier (build/stm32/fc.elf, `make stm32`) flying
                 hover_turbulence through the MCU target on QEMU with our models, whole run, on CPU time (QEMU
                 and the session take turns); bench/stm32_rates.py has the split and the link alone
  MultiWii 2.4   its image at rest on the mega2560-gy86 board for 10 s as `rig exec --mcu ... --fc
                 multiwii-2.4` runs it, unarmed (its main loop never waits; its TWI waits are counted
                 loops), with the polling-loop skip and without: only with --multiwii mw.elf or
                 $RIG_BENCH_MULTIWII (a local build, docs/multiwii.md; never in the repository)

Each runs with the glue's fixes, then with simavr's own behaviour back (AvrEngine.stock), without the
polling-loop skip (it would hide what the fixes measure) but where said. The goal is 2x real time;
the anchor is ArduPilot's AVR build under Renode: 0.03-0.2x.

    .venv/bin/python bench/mcu_rates.py [--multiwii mw.elf] [--targets-only]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rig import cli  # noqa: E402
from rig.emulators.chips.board import build_chip_board  # noqa: E402
from rig.emulators.mpu6050 import ImuTruth  # noqa: E402
from rig.emulators.ms5611 import BaroTruth  # noqa: E402
from rig.mcu import stm32_engine  # noqa: E402
from rig.mcu.engine import POLL_SKIP_ENV, TIMERS, AvrEngine, EngineConfig, Motor  # noqa: E402
from rig.mcu.session import McuSession  # noqa: E402
from rig.runner import run  # noqa: E402
from rig.scenarios.schema import load  # noqa: E402
from rig.targets.mcu import McuTarget  # noqa: E402
from tests.mcu.conftest import firmware  # noqa: E402

CLOCK = 16_000_000
#: MultiWii 2.4's image when --multiwii does not say (a local build: docs/multiwii.md)
MULTIWII_ENV = "RIG_BENCH_MULTIWII"
MULTIWII_S = 10.0
ANCHOR = "ArduPilot under Renode: 0.03-0.2x"


def rate(cfg: EngineConfig, sim_s: float, step_s: float | None = None, stock: dict[str, bool] | None = None,
         clock: Callable[[], float] = time.process_time) -> float:
    """The best of three runs (the machine is shared: the best is the engine's own speed)."""
    return max(rate_once(cfg, sim_s, step_s, stock, clock) for _ in range(3))


def rate_once(cfg: EngineConfig, sim_s: float, step_s: float | None, stock: dict[str, bool] | None,
              clock: Callable[[], float]) -> float:
    with AvrEngine(cfg, None) as e:
        if stock:
            e.stock(**stock)
        e.run_until(1_000_000)  # set-up out of the measure
        start, t0 = e.now_ns, clock()
        end = start + round(sim_s * 1e9)
        if step_s is None:
            stop = e.run_until(end)
        else:
            t = start
            while t < end:
                t += round(step_s * 1e9)
                stop = e.run_until(t)
        wall = clock() - t0
        assert stop.kind == "reached", stop.describe()
        return (e.now_ns - start) * 1e-9 / wall


def call_cost_us(cfg: EngineConfig) -> float:
    """What a run_until costs beyond the simulation: calls that have nothing to run."""
    with AvrEngine(cfg, None) as e:
        e.run_until(1_000_000)
        t = e.now_ns
        t0 = time.process_time()
        for _ in range(100_000):
            e.run_until(t)
        return (time.process_time() - t0) / 100_000 * 1e6


def imu_rate(mcu: str, skip: bool) -> float:
    """imu_reader in 1 ms ticks, needs served, pulses taken: the best of three."""
    best = 0.0
    for _ in range(3):
        board = build_chip_board(lambda t: ImuTruth((0.0, 0.0, 9.81), (0.0, 0.0, 0.0), 25.0),
                                 lambda t: (0.2, 0.0, 0.4), lambda t: BaroTruth(101325.0, 25.0))
        pins = ("PB1", "PB2") if mcu == "atmega328p" else ("PB5", "PB6")
        cfg = EngineConfig(mcu, CLOCK, firmware("imu_reader", mcu), poll_skip=skip,
                           motors=(Motor(pins[0], 1, "A"), Motor(pins[1], 1, "B")))
        with AvrEngine(cfg, board) as e:
            t0 = time.process_time()
            for k in range(1, 1001):
                assert e.run_served(k * 1_000_000).kind == "reached"
                e.pulses()
            best = max(best, 1.0 / (time.process_time() - t0))
    return best


def fc_rate(scenario: str = "step_roll", skip: bool = True,
            stock_timers: bool = False) -> tuple[float, float, float, float, float]:
    """The reference FC flying ``scenario`` through the target, best of three (target_rate)."""
    fc = Path(__file__).resolve().parents[1] / "build" / "avr" / "fc.elf"
    if not fc.is_file():
        raise SystemExit(f"{fc} is not built: make avr")
    sc = load(Path(__file__).resolve().parents[1] / "scenarios" / "library" / f"{scenario}.toml")

    def flight() -> float:
        r = run(sc, McuTarget("mega2560-gy86", fc), 0)
        assert r.verdict == "pass", r.error
        return sc.duration

    return target_rate(flight, skip, stock_timers)


def multiwii_rate(elf: Path, skip: bool) -> tuple[float, float, float, float, float]:
    """MultiWii 2.4 (a local image: never in the repository) at rest on the mega2560-gy86 board for
    MULTIWII_S, as `rig exec --mcu ... --fc multiwii-2.4` runs it, best of three (target_rate)."""

    def at_rest() -> float:
        code = cli.main(["exec", "--mcu", "mega2560-gy86", "--fc", "multiwii-2.4", "--firmware", str(elf),
                         "--duration", str(MULTIWII_S)])
        assert code == 0, f"rig exec ended {code}"
        return MULTIWII_S

    return target_rate(at_rest, skip, False)


def target_rate(job: Callable[[], float], skip: bool,
                stock_timers: bool) -> tuple[float, float, float, float, float]:
    """A firmware through the MCU target, best of three runs of ``job`` (which returns the sim seconds it
    ran): (sim s per CPU s of the whole run, the same of the engine alone: time inside run_until, the
    session's loop per plant tick beyond the engine in us, the engine per tick in us, the share of
    cycles the polling-loop skip jumped). run_until and the session's run are timed by wrappers of this
    bench's own (process time); ``skip`` is set through the environment variable the engine reads,
    ``stock_timers`` by AvrEngine.stock on each engine."""
    spent = {"engine": 0.0, "session": 0.0, "skipped": 0.0, "cycles": 0.0}

    def timed(fn: Callable[..., Any], key: str) -> Callable[..., Any]:
        def wrapper(*args: Any) -> Any:
            t0 = time.process_time()
            try:
                return fn(*args)
            finally:
                spent[key] += time.process_time() - t0
        return wrapper

    def opened(self: AvrEngine, *args: Any) -> None:
        engine_init(self, *args)
        if stock_timers:
            self.stock(timer_modes=True)

    def closed(self: AvrEngine) -> None:
        if getattr(self, "_open", False):
            spent["skipped"] += self.poll_figures()["skipped_cycles"]
            spent["cycles"] += self.cycle
        engine_close(self)

    best: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)
    run_until, session_run = AvrEngine.run_until, McuSession.run
    engine_init, engine_close = AvrEngine.__init__, AvrEngine.close
    was = os.environ.get(POLL_SKIP_ENV)
    os.environ[POLL_SKIP_ENV] = "1" if skip else "0"
    AvrEngine.run_until = timed(run_until, "engine")  # type: ignore[method-assign]
    McuSession.run = timed(session_run, "session")  # type: ignore[method-assign]
    AvrEngine.__init__ = opened  # type: ignore[method-assign,assignment]
    AvrEngine.close = closed  # type: ignore[method-assign]
    try:
        for _ in range(3):
            spent.update(engine=0.0, session=0.0, skipped=0.0, cycles=0.0)
            t0 = time.process_time()
            duration = job()
            whole = time.process_time() - t0
            ticks = duration * 1000
            loop_us = (spent["session"] - spent["engine"]) / ticks * 1e6
            best = max(best, (duration / whole, duration / spent["engine"], loop_us,
                              spent["engine"] / ticks * 1e6, spent["skipped"] / max(spent["cycles"], 1.0)))
    finally:
        AvrEngine.run_until, McuSession.run = run_until, session_run  # type: ignore[method-assign]
        AvrEngine.__init__, AvrEngine.close = engine_init, engine_close  # type: ignore[method-assign]
        if was is None:
            del os.environ[POLL_SKIP_ENV]
        else:
            os.environ[POLL_SKIP_ENV] = was
    return best


def pwm_script() -> bytes:
    _, tccra, tccrb, _, _, _, ocrb, ocrc = TIMERS["atmega2560"][3]
    writes = [(0x2D, 0x30), (ocrb, 128), (ocrc, 64), (tccra, 0x28 | 0x01), (tccrb, 0x08 | 0x03)]
    return b"".join(a.to_bytes(2, "little") + bytes([v]) for a, v in writes) + b"\xff\xff\x00"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="How fast the MCU tier's engine runs.")
    parser.add_argument("--multiwii", type=Path, default=os.environ.get(MULTIWII_ENV) or None,
                        help=f"MultiWii 2.4's image (mw.elf, built locally; default ${MULTIWII_ENV})")
    parser.add_argument("--targets-only", action="store_true",
                        help="only the firmwares through the target (the reference FC, MultiWii)")
    args = parser.parse_args(argv)
    if args.multiwii is not None and not args.multiwii.is_file():
        parser.error(f"--multiwii {args.multiwii}: no such file")
    print(f"simulated s per CPU s at 16 MHz (goal >= 2x; {ANCHOR})")
    if not args.targets_only:
        engine_rows()
    target_rows(args.multiwii)
    return 0


def engine_rows() -> None:
    """The engine alone: test firmwares, with the glue's fixes and with simavr's own behaviour."""
    for mcu in ("atmega2560", "atmega328p"):
        busy = EngineConfig(mcu, CLOCK, firmware("busy", mcu), hang_ns=0, poll_skip=False)
        one = rate(busy, 2.0)
        ticks = rate(busy, 2.0, 0.001)
        cost = call_cost_us(busy)
        print(f"{mcu:11s} busy          {one:6.2f}x in one call, {ticks:6.2f}x in 1 ms calls; a call "
              f"costs {cost:.1f} us: {cost * one / 10:.1f} % of a 1 ms tick")
    pwm = EngineConfig("atmega2560", CLOCK, firmware("regscript", "atmega2560"), eeprom=pwm_script(),
                       hang_ns=0, poll_skip=False)
    fixed, stock = rate(pwm, 1.0), rate(pwm, 0.2, stock={"extint_poll": True})
    print(f"atmega2560  pwm int4/5     {fixed:6.2f}x fixed, {stock:6.2f}x stock simavr 1.6 "
          f"({fixed / stock:.1f} times)")
    for mcu in ("atmega2560", "atmega328p"):
        rc = EngineConfig(mcu, CLOCK, firmware("rc_echo", mcu), hang_ns=0, poll_skip=False)
        wall = time.perf_counter  # (stock simavr sleeps: wall time)
        fixed, stock = rate(rc, 1.0, clock=wall), rate(rc, 0.01, stock={"uart_poll_sleep": True}, clock=wall)
        print(f"{mcu:11s} usart poll     {fixed:6.2f}x fixed, {stock:6.3f}x stock simavr 1.6 "
              f"({fixed / stock:.0f} times; wall time)")
    for mcu in ("atmega2560", "atmega328p"):
        on, off = imu_rate(mcu, True), imu_rate(mcu, False)
        print(f"{mcu:11s} imu + escs     {off:6.2f}x in 1 ms ticks, a sample served each; {on:6.2f}x with "
              f"the polling-loop skip")
    for mode, what in ((2, "a RAM flag its ISR sets"), (0, "Timer2's overflow flag")):
        loops = [EngineConfig("atmega2560", CLOCK, firmware("poll_loops", "atmega2560"), eeprom=bytes([mode]),
                              hang_ns=0, poll_skip=skip) for skip in (True, False)]
        on, off = rate(loops[0], 1.0), rate(loops[1], 1.0)
        print(f"atmega2560  polling loops  {on:6.2f}x with the polling-loop skip, {off:6.2f}x without "
              f"({on / off:.1f} times): {what}")


def stm32_row() -> None:
    """The STM32 tier's reference FC beside the AVR's (bench/stm32_rates.py measures it)."""
    fc = Path(__file__).resolve().parents[1] / "build" / "stm32" / "fc.elf"
    if stm32_engine.cached_binary() is None or not fc.is_file():
        print("stm32f405   reference FC   skipped: needs `make stm32-engine stm32`")
        return
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import stm32_rates  # (a bench script beside this one, not a package)

    speed, qemu_cpu, own_cpu = stm32_rates.scenario(fc)
    print(f"stm32f405   reference FC   {1 / (qemu_cpu + own_cpu):6.2f}x hover_turbulence through the target "
          f"on CPU time ({speed:.2f}x wall; QEMU {qemu_cpu:.2f} s and the session {own_cpu:.2f} s a "
          f"simulated second); {ANCHOR}; the tier's goal 5x")


def target_rows(multiwii: Path | None) -> None:
    """The reference FC flying step_roll and MultiWii at rest, through the target, skip on and off."""
    whole, engine, rest_us, engine_us, share = fc_rate()
    fc_plain = fc_rate(skip=False)
    fc_stock = fc_rate(skip=False, stock_timers=True)
    print(f"atmega2560  reference FC   {whole:6.2f}x step_roll through the target, the whole run (set-up and "
          f"criteria included); {ANCHOR}: {whole / 0.2:.0f}-{whole / 0.03:.0f} times that\n"
          f"{'':27s}{engine:6.2f}x the engine alone: {engine_us:.0f} us of CPU a 1 ms plant tick; the "
          f"session's loop adds {rest_us:.0f} us a tick (world, needs served, pulses, telemetry, events)\n"
          f"{'':27s}the polling-loop skip jumped {share:.0%} of the cycles; without it "
          f"{fc_plain[0]:6.2f}x the whole run, {fc_plain[1]:6.2f}x the engine ({whole / fc_plain[0]:.2f} and "
          f"{engine / fc_plain[1]:.2f} times)\n"
          f"{'':27s}without it and with simavr's timers in the modes it lacks (stock 1.6): "
          f"{fc_stock[0]:6.2f}x the whole run, {fc_stock[1]:6.2f}x the engine")
    stm32_row()
    if multiwii is None:
        print(f"atmega2560  MultiWii 2.4   skipped: no image (--multiwii mw.elf or ${MULTIWII_ENV}; "
              f"docs/multiwii.md)")
        return
    mw, plain = multiwii_rate(multiwii, True), multiwii_rate(multiwii, False)
    print(f"atmega2560  MultiWii 2.4   {mw[0]:6.2f}x at rest for {MULTIWII_S:g} s through the target (rig "
          f"exec), the whole run; {mw[1]:6.2f}x the engine alone: {mw[3]:.0f} us a tick, the session's loop "
          f"{mw[2]:.0f} us\n"
          f"{'':27s}the polling-loop skip jumped {mw[4]:.0%} of the cycles; without it {plain[0]:6.2f}x the "
          f"whole run, {plain[1]:6.2f}x the engine ({mw[0] / plain[0]:.2f} and {mw[1] / plain[1]:.2f} times)")

if __name__ == "__main__":
    sys.exit(main())
