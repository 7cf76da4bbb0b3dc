"""The chip core (emulators/chips/) against the Python chips, its reference: random transactions at
random nanosecond times through three boards fed by noisy models (the Python chips, the core's whole
transfers, the core's byte-level target events) must give the same bytes, NACKs and errors. Also the
core's sample queues, demand mode, its portability rules and a plain C program that runs it."""

from __future__ import annotations

import ctypes
import math
import random
import re
import subprocess
from pathlib import Path

import pytest

from rig.emulators import native
from rig.emulators.chips import gen
from rig.emulators.chips.board import CHIP_BARO, CHIP_HMC, CHIP_MPU, ChipBoard, build_chip_board
from rig.emulators.faults import Fault, FaultSet
from rig.emulators.i2c_bus import I2CNack, I2CProtocolError, Msg, read, write
from rig.emulators.sensor_models import AxisErrors, BaroModel, ImuModel, MagModel
from tests.emulators import boards

M, H, B = 0x68, 0x1E, 0x77
CHIPS = Path(native.__file__).resolve().parent / "chips"
REPO = CHIPS.parents[1]


def truth(t: float) -> dict[str, float]:
    return {"fx": 3 * math.sin(7 * t), "fy": -2 * math.cos(5 * t), "fz": -9.8 + math.sin(3 * t),
            "p": 2 * math.sin(11 * t), "q": math.cos(4 * t), "r": 0.5 * math.sin(2 * t),
            "temperature": 20 + 5 * math.sin(t), "mag_x": 0.25 + 0.2 * math.sin(3 * t),
            "mag_y": 0.1 * math.cos(2 * t), "mag_z": 0.433 - 0.1 * math.sin(t),
            "pressure": 101325.0 + 300 * math.sin(t)}


def models(seed: int) -> tuple[ImuModel, MagModel, BaroModel]:
    imu = ImuModel(truth, accel=AxisErrors(noise_density=0.004, bias_random_walk=0.001),
                   gyro=AxisErrors(noise_density=0.0009), seed=seed)
    mag = MagModel(truth, errors=AxisErrors(noise_density=0.0007), seed=seed + 1)
    baro = BaroModel(truth, noise_pa=2.0, seed=seed + 2)
    return imu, mag, baro


def fault_plan(rng: random.Random) -> dict[str, list[Fault]]:
    plan: dict[str, list[Fault]] = {}
    for name in ("mpu", "hmc", "baro"):
        faults = []
        if rng.random() < 0.4:
            start = rng.uniform(0.0, 1.5)
            faults.append(Fault("off", start, start + rng.uniform(0.01, 0.3)))
        if rng.random() < 0.3:
            start = rng.uniform(0.0, 1.5)
            period = rng.choice((0.01, 0.03))
            faults.append(Fault("intermittent", start, start + 0.5, period=period, duty=0.4))
        if rng.random() < 0.4:
            start = rng.uniform(0.0, 1.5)
            faults.append(Fault("garbage", start, start + rng.uniform(0.01, 0.3)))
        if faults:
            plan[name] = faults
    return plan


def three_boards(seed: int, topology: str, plan: dict[str, list[Fault]]) -> list:
    out = []
    for impl in ("python", "core", "core"):
        imu, mag, baro = models(seed)
        faults = {k: FaultSet(list(v), seed=seed * 7 + i) for i, (k, v) in enumerate(sorted(plan.items()))}
        if impl == "core":
            faults = {("baro_bus" if k == "baro" else k): v for k, v in faults.items()}
        out.append(boards.make_board(imu, mag, baro, topology, dlpf=True, bus_faults=faults, impl=impl,
                                     osr_noise=True, seed=seed + 3))
    return out


def read_ahead(lib, a: int, n: int) -> bytes:
    """n bytes as the STM32's target reads them: one more, taken while the master clocks the last, is
    given back when the master NACKs (chip_unread_byte); the state must be as if it was never read."""
    got = bytes(lib.chip_read_byte(a) for _ in range(n + 1))
    lib.chip_unread_byte(a)
    return got[:n]


def previews(board: ChipBoard, t_ns: int) -> dict[int, int | None]:
    """chip_read_preview of each chip's address (None: it would NACK), asserting it changed nothing of
    the board, byte for byte (a bridge target without clock stretching takes one before every address
    it might be sent)."""
    before = board._mem.raw
    out: dict[int, int | None] = {}
    for addr in (M, H, B):
        byte = ctypes.c_uint8()
        answers = board.lib.chip_read_preview(board.addr, t_ns, addr, ctypes.byref(byte))
        out[addr] = byte.value if answers else None
    assert board._mem.raw == before, "a preview changed the board"
    return out


def byte_transfer(board: ChipBoard, msgs: list[Msg], t_ns: int) -> list[bytes]:
    """The transfer as a bridge's I2C target sees it: START, bytes, STOP (demand served first), each
    read one byte ahead and the extra byte given back. Before each message, and between its bytes, the
    chips' read previews are taken (they must change nothing: the other boards take none), and a read's
    first byte must be its preview's."""
    board.bus.advance_ns(t_ns)
    lib, a = board.lib, board.addr
    out = []
    for m in msgs:
        seen = previews(board, t_ns)
        if not lib.chip_start(a, t_ns, m.addr, m.read):
            assert seen.get(m.addr) is None, f"previewed {seen.get(m.addr)} from {m.addr:#x}, which NACKed"
            raise I2CNack(m.addr)
        if m.read and m.length and not m.recv_len:
            first = read_ahead(lib, a, m.length)
            assert seen.get(m.addr) == first[0], f"preview {seen.get(m.addr)} of {m.addr:#x}, read {first[0]}"
            out.append(first)
            continue
        if m.recv_len:
            count = lib.chip_read_byte(a)
            assert seen.get(m.addr) == count
            if not 1 <= count <= 32:
                lib.chip_stop(a)
                raise I2CProtocolError("count")
            out.append(bytes([count]) + read_ahead(lib, a, count))
        elif m.read:
            out.append(read_ahead(lib, a, m.length))
        else:
            for byte in m.data:
                lib.chip_write_byte(a, byte)
                previews(board, t_ns)
    lib.chip_stop(a)
    return out


def outcome(fn, *args) -> tuple:
    try:
        return ("ok", fn(*args))
    except I2CNack as e:
        return ("nack", e.addr)
    except I2CProtocolError:
        return ("protocol",)


MPU_WRITES = [
    (0x19, lambda r: r.choice((0, 0, 1, 3, 7, 9))), (0x1A, lambda r: r.randrange(8) | r.choice((0, 0x40))),
    (0x1B, lambda r: r.randrange(4) << 3 | r.choice((0, 0, 0xE0))),
    (0x1C, lambda r: r.randrange(4) << 3 | r.choice((0, 0, 0xE0))),
    (0x23, lambda r: r.choice((0, 0x08, 0xF8, 0x78, 0x01, 0x03, 0xFF))),
    (0x37, lambda r: r.choice((0, 0x02, 0x10, 0x12))),
    (0x6A, lambda r: r.choice((0, 0x40, 0x20, 0x60, 0x04, 0x44, 0x01, 0x64))),
    (0x6B, lambda r: r.choice((0, 0, 0, 0x40, 0x08, 0x01, 0x80))),
    (0x6C, lambda r: r.choice((0, 0, 0x20, 0x05, 0x3F))),
    (0x25, lambda r: r.choice((0x9E, 0x1E, 0x9E, 0x77, 0xE8))),
    (0x26, lambda r: r.choice((0x03, 0x02, 0x09, 0x0A))),
    (0x27, lambda r: r.choice((0x86, 0x81, 0x06, 0xA6, 0x8F, 0x83))),
    (0x28, lambda r: r.choice((0x9E, 0x1E))), (0x29, lambda r: r.choice((0x03, 0x02, 0x00))),
    (0x2A, lambda r: r.choice((0x86, 0x81, 0x00, 0xA1))),
    (0x63, lambda r: r.choice((0x00, 0x01, 0x18))), (0x64, lambda r: r.choice((0x01, 0x00, 0x14))),
    (0x74, lambda r: r.randrange(256)), (0x75, lambda r: r.randrange(256)),
]


def random_transfer(r: random.Random) -> list[Msg]:
    k = r.random()
    if k < 0.30:  # MPU register writes, sometimes several in one transfer
        return [write(M, reg, fn(r)) for reg, fn in r.sample(MPU_WRITES, r.choice((1, 1, 2, 3)))]
    if k < 0.35:  # a burst write across register boundaries
        return [write(M, r.randrange(0x0C, 0x76), *(r.randrange(256) for _ in range(r.randrange(1, 6))))]
    if k < 0.55:  # MPU reads: data bursts, FIFO, INT_STATUS, anything
        start = r.choice((0x3B, 0x3B, 0x43, 0x3A, 0x72, 0x74, 0x49, r.randrange(0x80)))
        n = r.choice((1, 2, 6, 14, r.randrange(0, 40)))
        if start == 0x74:
            return [write(M, 0x72), read(M, 2), write(M, 0x74), read(M, r.randrange(1, 60))]
        return [write(M, start), read(M, n)]
    if k < 0.65:  # the magnetometer (NACK on a GY-86 unless in bypass)
        kk = r.random()
        if kk < 0.4:
            reg = r.choice((0x00, 0x01, 0x02))
            val = {0x00: r.choice((0x10, 0x18, 0x14, 0x11, 0x12, 0x70, 0x0C)),
                   0x01: r.randrange(8) << 5, 0x02: r.choice((0, 0, 1, 2, 3))}[reg]
            return [write(H, reg, val)]
        reg = r.choice((0x03, 0x03, 0x09, 0x05, 0x0A, r.randrange(20)))
        return [write(H, reg), read(H, r.randrange(0, 10))]
    if k < 0.85:  # the barometer
        cmd = r.choice((0x48, 0x58, 0x40, 0x50, 0x44, 0x56, 0x00, 0x00, 0x1E, 0xA2, 0xAE, 0x33))
        if cmd == 0x00 or 0xA0 <= cmd <= 0xAE:
            return [write(B, cmd), read(B, r.choice((2, 3, 4)))]
        return [write(B, cmd)] if r.random() < 0.9 else [write(B)]
    if k < 0.90:  # SMBus block reads
        return [write(r.choice((M, H, B)), r.randrange(0x80)), Msg(r.choice((M, H, B)), True, b"", 0, True)]
    if k < 0.95:  # a reading with a repeated start to another chip, a quick write, a zero-length read
        return [write(M, 0x3B), read(M, 6), write(B, 0x00), read(B, 3)]
    return [r.choice((read(M, 0), write(0x50, 1), write(M), read(B, 0)))]


def run_differential(seed: int, transfers: int) -> int:
    r = random.Random(seed)
    topology = r.choice(("gy86", "direct"))
    oracle, whole, events = three_boards(seed, topology, fault_plan(r))
    oracle.bus.transfer([write(M, 0x6B, 0x00)], 0.0)
    for b in (whole, events):
        b.bus.transfer_ns([write(M, 0x6B, 0x00)], 0)
    t_ns = 0
    compared = 0
    for i in range(transfers):
        t_ns += r.choice((0, r.randrange(1, 400_000), r.randrange(1, 3_000_000), r.randrange(1, 3_000_000),
                          r.randrange(10_000_000, 120_000_000) if r.random() < 0.05 else 17))
        msgs = random_transfer(r)
        want = outcome(oracle.bus.transfer, msgs, t_ns * 1e-9)
        got = outcome(whole.bus.transfer_ns, msgs, t_ns)
        got_events = outcome(byte_transfer, events, msgs, t_ns)
        assert got == want, f"seed {seed} transfer {i} at {t_ns} ns: {msgs}"
        assert got_events == want, f"seed {seed} transfer {i} at {t_ns} ns (byte events): {msgs}"
        compared += 1
    return compared


@pytest.mark.parametrize("seed", range(24))
def test_random_transactions_give_the_python_chips_bytes(seed) -> None:
    assert run_differential(seed, 350) == 350


# ---- portability: strict C99, the allowed headers only, the generated tables ----

CORE_SOURCES = sorted(CHIPS.glob("*.c"))


def test_the_core_builds_as_strict_c99_with_only_the_allowed_headers(tmp_path) -> None:
    header = gen.write()
    for src in CORE_SOURCES:
        subprocess.run(["gcc", "-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror", "-ffp-contract=off",
                        f"-I{header.parent}", "-c", str(src), "-o", str(tmp_path / (src.stem + ".o"))],
                       check=True, capture_output=True, text=True)
    allowed = {"stdint.h", "stdbool.h", "string.h", "math.h", "chip_core.h", "chip_internal.h",
               "chip_registers.h"}
    for path in [*CORE_SOURCES, *CHIPS.glob("*.h")]:
        included = set(re.findall(r'#include [<"]([^>"]+)[>"]', path.read_text()))
        assert included <= allowed, f"{path.name} includes {included - allowed}"
        assert not re.search(r"\b(malloc|calloc|realloc|free|printf|fopen|time|clock_gettime)\s*\(",
                             path.read_text()), path.name


def test_the_generated_tables_are_the_python_ones() -> None:
    from rig.emulators import hmc5883l, mpu6050

    text = gen.header()
    assert f"#define CHIP_MPU_ST_GYRO_DPS {mpu6050.ST_GYRO_DPS.hex()}" in text
    reset = re.search(r"CHIP_MPU_RESET\[128\] = \{([^}]*)\}", text)
    assert reset is not None
    assert bytes(int(v, 16) for v in reset.group(1).replace(",", " ").split()) == bytes(
        mpu6050.REGISTERS.reset_bytes())
    assert "CHIP_HMC_GAINS[8] = { " + ", ".join(map(str, hmc5883l.GAINS)) in text


def test_a_bridge_mode_board_holds_the_last_sample_and_counts_underruns() -> None:
    board = build_chip_board(lambda t: None, lambda t: (0.0, 0.0, 0.0), lambda t: None)  # type: ignore
    lib, a = board.lib, board.addr
    lib.chip_board_demand(a, False)
    push = native.fast().chip_push_imu
    import numpy as np

    rows = np.zeros((2, 7))
    rows[:, 2] = 9.80665
    rows[1, 2] = -9.80665
    push(a, 0, 1_000_000, 2, rows.ctypes.data, 7)  # valid from 0 and from 1 ms
    board.bus.transfer_ns([write(M, 0x6B, 0x00), write(M, 0x1A, 0x01)], 0)
    z = lambda t: board.bus.transfer_ns([write(M, 0x3F), read(M, 2)], t)[0]  # noqa: E731
    assert z(500_000) == b"\x40\x00"      # the sample valid at 0
    assert z(1_500_000) == b"\xc0\x00"    # the one valid from 1 ms
    assert board.count("mpu_underruns") == 0
    assert z(5_500_000) == b"\xc0\x00"    # nothing new: held, an underrun at each instant (2, 3, 4, 5 ms)
    assert board.count("mpu_underruns") == 4
    push(a, 6_000_000, 1_000_000, 2, rows.ctypes.data, 7)  # valid from 6 and 7 ms; none for 8 and 9 ms
    assert z(9_500_000) == b"\xc0\x00" and board.count("mpu_underruns") == 6
    assert board.peek(CHIP_MPU, 0x75) == 0x68 and board.peek(CHIP_HMC, 0x0A) == 0x48
    assert board.peek(CHIP_BARO, 0) == 0
