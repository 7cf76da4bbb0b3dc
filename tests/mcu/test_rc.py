"""RC into the MCU: SBUS at 100000 baud 8E2 with real byte timing, MSP SET_RAW_RC, a PPM sum on an
interrupt pin; the RC echo firmware decodes each and sends it back. A receiver set to another frame gets
frame errors and nothing else, as on the hardware."""

from __future__ import annotations

import pytest

from rig.emulators import sbus
from rig.mcu.engine import AvrEngine, EngineConfig
from tests.mcu.conftest import MCUS, firmware

CLOCK = 16_000_000
SBUS_UART = {"atmega328p": 0, "atmega2560": 1}
PPM_PIN = {"atmega328p": "PD2", "atmega2560": "PE4"}  # INT0, INT4


def rc_engine(mcu: str) -> AvrEngine:
    return AvrEngine(EngineConfig(mcu, CLOCK, firmware("rc_echo", mcu), hang_ns=0), None)


def echoes(data: bytes) -> list[tuple[int, list[int]]]:
    """(source, channels) of each echo frame (0 SBUS, 1 MSP, 2 PPM)."""
    out, at = [], 0
    while at + 2 <= len(data):
        source, n = data[at] - 0xE0, data[at + 1]
        body = data[at + 2:at + 2 + 2 * n]
        out.append((source, [body[2 * i] | body[2 * i + 1] << 8 for i in range(n)]))
        at += 2 + 2 * n
    return out


@pytest.mark.parametrize("mcu", MCUS)
def test_an_sbus_frame_arrives_whole_after_its_25_frame_times(mcu: str) -> None:
    channels = [172 + 97 * i for i in range(16)]
    frame = sbus.encode(channels)
    with rc_engine(mcu) as e:
        e.run_until(1_000_000)
        e.uart_send(SBUS_UART[mcu], frame, 100_000, "E", 2)
        e.run_until(1_000_000 + 25 * 120_000 - 1_000)  # 120 us a byte: the last one is not in yet
        assert e.uart_take(0) == b""
        e.run_until(1_000_000 + 25 * 120_000 + 300_000)  # it is, and decoded (2 kcycles of shifts)
        first = e.uart_take(0)
        assert first[:2] == b"\xe0\x10"
        e.run_until(12_000_000)
        got = echoes(first + e.uart_take(0))
        assert got == [(0, channels)]
        assert e.uart_counts(SBUS_UART[mcu])["delivered"] == 25


def test_a_byte_before_the_receiver_is_set_up_is_lost() -> None:
    """A byte that arrives while RXEN is clear is lost, and is no frame error: the receiver read nothing.
    (Bytes on another frame than an enabled receiver's are frame errors: MultiWii opens USART1 at 115200
    8N1 first and at SBUS's 100000 8E2 2.4 s later, and the SBUS frames between are.)"""
    with rc_engine("atmega2560") as e:
        e.uart_send(1, sbus.encode([1000] * 16), 100_000, "E", 2)  # at 0: the firmware has not started
        e.run_until(12_000_000)
        counts = e.uart_counts(1)
        assert (counts["receiver_off"], counts["frame_errors"], counts["delivered"]) == (1, 0, 24)
        assert e.uart_take(0) == b""  # 24 bytes, no 0x0F first: no frame


@pytest.mark.parametrize(("baud", "parity", "stops"),
                         [(115_200, "N", 1), (100_000, "N", 2), (90_000, "E", 2)])
def test_a_receiver_on_another_frame_gets_frame_errors(baud: int, parity: str, stops: int) -> None:
    with rc_engine("atmega2560") as e:
        e.run_until(1_000_000)  # (set up)
        e.uart_send(1, sbus.encode([1000] * 16), baud, parity, stops)
        e.run_until(10_000_000)
        assert e.uart_take(0) == b""
        assert e.uart_counts(1) == {"delivered": 0, "frame_errors": 25, "waiting": 0, "tx_dropped": 0,
                                    "receiver_off": 0}


def test_a_baud_within_the_receivers_tolerance_is_read() -> None:
    with rc_engine("atmega2560") as e:  # 103000 baud into a 100000 receiver: 3 % fast, inside 4.14 %
        e.run_until(1_000_000)  # (set up)
        e.uart_send(1, sbus.encode([1500] * 16), 103_000, "E", 2)
        e.run_until(12_000_000)
        assert echoes(e.uart_take(0)) == [(0, [1500] * 16)]


def msp_set_raw_rc(channels: list[int]) -> bytes:
    payload = b"".join(c.to_bytes(2, "little") for c in channels)
    body = bytes([len(payload), 200]) + payload
    check = 0
    for b in body:
        check ^= b
    return b"$M<" + body + bytes([check])


def test_msp_set_raw_rc_is_echoed() -> None:
    channels = [1500, 1500, 1000, 1500, 2000, 1000, 1200, 1800]
    with rc_engine("atmega2560") as e:
        e.run_until(1_000_000)  # (set up)
        e.uart_send(0, msp_set_raw_rc(channels), 115_200)
        e.run_until(5_000_000)
        assert echoes(e.uart_take(0)) == [(1, channels)]


@pytest.mark.parametrize("mcu", MCUS)
def test_a_ppm_sum_on_an_interrupt_pin_is_measured(mcu: str) -> None:
    widths = [1500, 1100, 1900, 1000, 2000, 1234, 1500, 1750]  # us
    edges: list[tuple[int, int]] = []
    rise = 5_000_000
    for _frame in range(2):
        for w in [*widths, 10_000]:  # the sync gap after the last channel
            edges += [(rise - 300_000, 0), (rise, 1)]
            rise += w * 1000
    edges += [(rise - 300_000, 0), (rise, 1)]  # the second frame's end
    with rc_engine(mcu) as e:
        e.pin_drive(PPM_PIN[mcu], edges)
        e.run_until(rise + 5_000_000)
        got = echoes(e.uart_take(0))
    assert [source for source, _ in got] == [2, 2]
    for _, measured in got:
        assert len(measured) == len(widths)
        assert all(abs(m - w) <= 1 for m, w in zip(measured, widths, strict=True)), measured


@pytest.mark.parametrize(("mcu", "pin"), [("atmega2560", "PK3"), ("atmega328p", "PD3")])
def test_a_pwm_receiver_on_a_pin_change_interrupt_is_measured(mcu: str, pin: str) -> None:
    """Port K's pin change interrupts (the Mega's RC inputs) are the glue's: simavr 1.6 has port B's only."""
    widths = [1500, 1000, 2000, 1234]
    edges: list[tuple[int, int]] = []
    for i, w in enumerate(widths):
        start = 2_000_000 + i * 20_000_000
        edges += [(start, 1), (start + w * 1000, 0)]
    with AvrEngine(EngineConfig(mcu, CLOCK, firmware("pcint_rc", mcu), hang_ns=0), None) as e:
        e.pin_drive(pin, edges)
        e.run_until(90_000_000)
        out = e.uart_take(0)
    got = [out[i] | out[i + 1] << 8 for i in range(0, len(out), 2)]
    assert len(got) == len(widths)
    assert all(abs(g - w) <= 1 for g, w in zip(got, widths, strict=True)), got
