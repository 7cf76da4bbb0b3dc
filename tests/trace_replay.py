"""What the MCU tiers' trace replays share (tests/mcu/test_twi.py on the AVR's TWI,
tests/stm32/test_i2c_replay.py on the STM32's I2C1): the trace's board, the bus's records read back as
transfers, and the three checks that tie a replay to lockstep. One chip core serves every path, so a
recorded client trace (emulators/traces) must read through a firmware's I2C controller the bytes the
lockstep path (ChipBus.transfer_ns at the same times, on a board of its own) gives for the same
messages."""

from __future__ import annotations

from rig.emulators.chips.board import ChipBoard, build_chip_board
from rig.emulators.faults import FaultSet
from rig.emulators.i2c_bus import I2CNack, Msg
from rig.emulators.mpu6050 import ImuTruth
from rig.emulators.ms5611 import BaroTruth
from rig.emulators.trace import parse_msg
from rig.mcu.engine import TwiRecord

#: a transfer as the bus carried it: its first START's time, its messages, the bytes of each read, whether
#: an address was not acknowledged
Transfer = tuple[int, list[Msg], list[bytes], bool]


def board_for(trace: dict, faults: dict[str, FaultSet] | None = None) -> ChipBoard:
    """The chip core's board in the trace's topology, its sensors holding the trace's truth."""
    tr = trace["truth"]
    return build_chip_board(lambda t: ImuTruth(tuple(tr["accel"]), tuple(tr["gyro"]), tr["temperature"]),
                            lambda t: tuple(tr["field"]),
                            lambda t: BaroTruth(tr["pressure"], tr["temperature"]),
                            trace["topology"], dlpf=False, faults=faults)


def transfers(records: list[TwiRecord]) -> list[Transfer]:
    """The bus's records as transfers (Transfer), one per STOP."""
    out: list[Transfer] = []
    msgs: list[Msg] = []
    reads: list[bytes] = []
    t0, nack = -1, False
    for r in records:
        if r.kind == "S" and t0 < 0:
            t0, msgs, reads, nack = r.t_ns, [], [], False
        elif r.kind == "A":
            if not r.ack:
                nack = True
            msgs.append(Msg(r.value >> 1, bool(r.value & 1), b"", 0))
            if r.value & 1:
                reads.append(b"")
        elif r.kind == "W":
            msgs[-1] = Msg(msgs[-1].addr, False, msgs[-1].data + bytes([r.value]))
        elif r.kind == "R":
            reads[-1] += bytes([r.value])
            msgs[-1] = Msg(msgs[-1].addr, True, b"", msgs[-1].length + 1)
        elif r.kind == "P":
            out.append((t0, msgs, reads, nack))
            t0 = -1
    return out


def check_replay(trace: dict, steps: list[tuple[int, bytes]], records: list[TwiRecord]) -> None:
    """A firmware's replay of ``trace``, (NACK flag, bytes read) per step as it reported them and the
    bus's records, against lockstep: the firmware reports what the bus carried; each transfer's bytes are
    lockstep's at the transfer's time (or both NACK); the bus carried the trace's messages."""
    assert len(steps) == len(trace["steps"])
    lockstep = board_for(trace)
    done = transfers(records)
    assert len(done) == len(steps)
    for i, ((t0, msgs, reads, nacked), (reported_nack, reported)) in enumerate(zip(done, steps, strict=True)):
        assert bool(reported_nack) == nacked, f"step {i}"
        assert b"".join(reads) == reported, f"step {i}: the firmware reports what the bus carried"
        try:
            got = lockstep.bus.transfer_ns(msgs, t0)
        except I2CNack:
            assert nacked, f"step {i}: lockstep NACKs, the bus did not"
            continue
        assert not nacked, f"step {i}: the bus NACKed, lockstep did not"
        assert got == reads, f"step {i}: {msgs}"
    # the bus carried the trace's messages (up to a NACK), so the bytes compared above answer them. (The
    # trace's expected bytes are lockstep's at the trace's times, tests/emulators/test_traces.py: on a
    # bus a transfer takes time, a 70-byte FIFO read 1.6 ms, and the steps after it start later)
    for i, (step, (flag, _), (_, msgs, _, _)) in enumerate(zip(trace["steps"], steps, done, strict=True)):
        assert bool(step.get("nack")) == bool(flag), f"step {i}"
        sent = [parse_msg(m) for m in step["msgs"]]
        if flag:  # the message NACKed carried its address only, and the ones after it nothing
            assert (msgs[-1].addr, msgs[-1].read) == (sent[len(msgs) - 1].addr, sent[len(msgs) - 1].read)
            msgs, sent = msgs[:-1], sent[:len(msgs) - 1]
        assert [(m.addr, m.read, m.data, m.length) for m in msgs] == [(m.addr, m.read, m.data, m.length)
                                                                      for m in sent], f"step {i}"
