"""The chip core on the MCU's TWI: every recorded client trace (emulators/traces) replayed by a firmware
through the TWI carries the trace's messages and gives the bytes the same transfers give through the
lockstep path (ChipBus.transfer_ns at the same times, on a board of its own); the engine stops for samples
the core lacks (demand mode) without the firmware seeing it. A chip that is off NACKs on the TWI."""

from __future__ import annotations

import pytest

from rig.emulators.chips.board import ChipBoard, build_chip_board
from rig.emulators.faults import Fault, FaultSet
from rig.emulators.mpu6050 import ImuTruth
from rig.emulators.ms5611 import BaroTruth
from rig.emulators.trace import TRACE_DIR, load
from rig.mcu.engine import AvrEngine, EngineConfig, Motor, TwiRecord
from tests.mcu.conftest import firmware
from tests.mcu.gen_traces import TRACE_NAMES
from tests.trace_replay import board_for, check_replay, transfers

CLOCK = 16_000_000


def replay_on_mcu(name: str, mcu: str,
                  board: ChipBoard) -> tuple[list[tuple[int, bytes]], list[TwiRecord], int]:
    """(nacked, bytes read) per step as the firmware reported them over USART0; the TWI's records; the
    needs served."""
    cfg = EngineConfig(mcu, CLOCK, firmware("twi_replay", mcu), eeprom=bytes([TRACE_NAMES.index(name)]))
    out = b""
    needs = 0
    with AvrEngine(cfg, board) as e:
        e.twi_log()
        t = 0
        while not out.endswith(b"\x5a\x5a") and t < 2_000_000_000:
            t += 1_000_000
            while (stop := e.run_until(t)).kind == "need":
                board.serve(stop.need)
                needs += 1
            assert stop.kind == "reached", stop.describe()
            out += e.uart_take(0)
        records = e.twi_take()
    assert out.endswith(b"\x5a\x5a")
    return parse(out[:-2], [sum(map(len, reads)) for _, _, reads, _ in transfers(records)]), records, needs


def parse(out: bytes, counts: list[int]) -> list[tuple[int, bytes]]:
    """The firmware's report, step by step: 0xA5, the NACK flag, the bytes read (as many as the TWI
    carried in that step's transfer)."""
    steps = []
    at = 0
    for n in counts:
        assert out[at] == 0xA5, f"byte {at}: {out[at:at + 8].hex()}"
        steps.append((out[at + 1], out[at + 2:at + 2 + n]))
        at += 2 + n
    assert at == len(out)
    return steps


@pytest.mark.parametrize("name", TRACE_NAMES)
def test_a_trace_through_the_twi_reads_what_lockstep_reads(name: str) -> None:
    trace = load(TRACE_DIR / f"{name}.json")
    steps, records, _ = replay_on_mcu(name, "atmega2560", board_for(trace))
    check_replay(trace, steps, records)


def test_the_engine_stops_for_samples_and_the_bytes_do_not_change() -> None:
    """The MPU-6050's aux master reading the HMC5883L (GY-86) keeps every sample: the core asks for them
    many times; the replay is the same run after run."""
    trace = load(TRACE_DIR / "multiwii_gy86.json")
    a = replay_on_mcu("multiwii_gy86", "atmega328p", board_for(trace))
    b = replay_on_mcu("multiwii_gy86", "atmega328p", board_for(trace))
    assert a[2] > 0 and a == b


def test_a_chip_that_is_off_nacks_on_the_twi() -> None:
    trace = load(TRACE_DIR / "i2c_tools.json")
    off = {"mpu": FaultSet([Fault("off", 0.0, float("inf"))], seed=1)}
    steps, records, _ = replay_on_mcu("i2c_tools", "atmega328p", board_for(trace, off))
    to_mpu = [r for r in records if r.kind == "A" and r.value >> 1 == 0x68]
    assert to_mpu and not any(r.ack for r in to_mpu)
    assert any(nacked for nacked, _ in steps)


@pytest.mark.parametrize("mcu", ["atmega328p", "atmega2560"])
@pytest.mark.parametrize(("accel_z", "width_ns"), [(9.80665, 1_128_500), (-9.80665, 872_500)])
def test_a_sample_reaches_the_motors_through_the_firmware(mcu: str, accel_z: float, width_ns: int) -> None:
    """The imu_reader firmware reads the MPU-6050 every millisecond and sets its ESC pulses from the
    accelerometer's z: (2000 + az_raw / 64 + 1) half-microseconds, az_raw = +-16384 at +-1 g (+-2 g range)."""
    imu = build_chip_board(lambda t: ImuTruth((0.0, 0.0, accel_z), (0.0, 0.0, 0.0), 25.0),
                           lambda t: (0.2, 0.0, 0.4), lambda t: BaroTruth(101325.0, 25.0))
    pins = ("PB1", "PB2") if mcu == "atmega328p" else ("PB5", "PB6")
    cfg = EngineConfig(mcu, CLOCK, firmware("imu_reader", mcu), motors=(Motor(pins[0], 1, "A"),
                                                                        Motor(pins[1], 1, "B")))
    with AvrEngine(cfg, imu) as e:
        widths = []
        for k in range(1, 31):
            assert e.run_served(k * 1_000_000).kind == "reached"
            widths += [w for _, w, p in e.pulses()[0] if p == 2_500_000]
    assert len(widths) >= 10 and widths[-5:] == [width_ns] * 5


def test_a_sleeping_cpu_wakes_for_the_twi_on_time() -> None:
    """simavr's sleep jumps to its next cycle timer: the glue keeps one at its next event, so a TWI byte
    ends at its time (START one bit, address nine: 40 cycles a bit at 400 kHz) however long the run."""
    trace = load(TRACE_DIR / "i2c_tools.json")
    cfg = EngineConfig("atmega328p", CLOCK, firmware("twi_sleep", "atmega328p"), hang_ns=0)
    with AvrEngine(cfg, board_for(trace)) as e:
        e.twi_log()
        assert e.run_served(50_000_000).kind == "reached"
        records = e.twi_take()
    assert [r.kind for r in records] == ["S", "A", "P"] and records[1].ack
    nine_bits = 9 * 40 * 1000 // 16
    assert records[0].t_ns < 10_000  # the START: one bit after the first instructions
    assert nine_bits <= records[1].t_ns - records[0].t_ns < nine_bits + 100 * 1000 // 16  # + the ISR's entry
