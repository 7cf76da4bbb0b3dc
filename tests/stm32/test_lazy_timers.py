"""The timers' lazy events (qemu/hw/rig_stm32_timer.c): a timer that raises no interrupt or DMA request and
whose pins no one watches counts its compare matches and update events when something looks (the link's
stop, a register access), not at a QEMU timer of their own. What the session reads must not tell the two
apart: hover_rate.c (TIM3 with its update interrupt, so eager; TIM2 with none, so lazy) is run with every
timer eager (the model's property "eager") and as built, and each stop's pulses (rise, width, period: the
latched-ns, latches and high ticks the link sends) are the same. The period of RM0090 18.3.2 (the update
event every (PSC + 1) * (ARR + 1) timer-clock ticks) is the independent truth of each rise's time: 84 MHz
/ 84 * 2041 = 2041 us between updates, whatever the stops' 1 ms grid."""

from __future__ import annotations

import math

from rig.emulators.chips.board import ChipBoard, build_chip_board
from rig.emulators.mpu6050 import ImuTruth
from rig.emulators.ms5611 import BaroTruth
from rig.mcu import board as boards
from rig.mcu.stm32_link import Stm32Config, Stm32Engine
from tests.stm32.conftest import engine_or_skip, firmware

G = 9.80665
STEP_NS = 1_000_000
RUN_NS = 800 * STEP_NS  # past the firmware's 0.5 s of ESC arming: widths that move
#: RM0090 18.3.2: hover_rate.c's PSC 83 and ARR 2040 on the 84 MHz APB1 timer clock
PERIOD_NS = (83 + 1) * (2040 + 1) * 1_000_000_000 // 84_000_000

Stops = list[tuple[str, int, list[list[tuple[int, int, int]]]]]


def turning_world() -> ChipBoard:
    """A board rocking about all three axes, so the rate loop moves each motor's width all the time."""
    def rates(t: float) -> tuple[float, float, float]:
        return 0.5 * math.sin(30 * t), -0.3 * math.cos(20 * t), 0.2 * math.sin(10 * t)

    return build_chip_board(lambda t: ImuTruth((0.0, 0.0, G), rates(t), 25.0),
                            lambda t: (0.2, 0.0, 0.4), lambda t: BaroTruth(101325.0, 20.0))


def stops(qemu_args: tuple[str, ...]) -> Stops:
    """hover_rate.c in 1 ms steps: at each stop its kind, cycle and each motor's pulses begun since."""
    chips = turning_world()
    cfg = Stm32Config(boards.load("stm32f405-gy86"), firmware("hover_rate"), engine_or_skip(),
                      qemu_args=qemu_args)
    engine = Stm32Engine(cfg, chips)
    out: Stops = []
    try:
        t = 0
        while t < RUN_NS:
            t += STEP_NS
            while (stop := engine.run_until(t)).kind == "need":
                assert stop.need is not None
                chips.serve(stop.need)
            out.append((stop.kind, stop.cycle, engine.pulses()))
            if stop.kind != "reached":
                break
        return out
    finally:
        engine.close()


def test_lazy_and_eager_timers_give_the_same_pulses_at_every_stop() -> None:
    lazy = stops(())
    eager = stops(("-global", "rig-stm32f4-timer.eager=on"))
    assert [s[0] for s in lazy] == ["reached"] * (RUN_NS // STEP_NS)
    assert lazy == eager
    # (a comparison of something: the four motors' pulses, with widths the rate loop moved)
    for motor in range(4):
        train = [p for _, _, pulses in lazy for p in pulses[motor]]
        assert len(train) > RUN_NS // PERIOD_NS // 2
        assert len({width for _, width, _ in train}) > 2
        assert {period for _, _, period in train} == {PERIOD_NS}
        # each rise an update event's own time, one period after the last, not a stop's
        rises = [rise for rise, _, _ in train]
        assert {b - a for a, b in zip(rises, rises[1:], strict=False)} == {PERIOD_NS}
