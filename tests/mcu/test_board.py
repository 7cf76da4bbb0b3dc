"""Board files (rig/mcu/board.py) are checked like scenarios: the shipped ones load and say what their
boards' silk screens and datasheets say, and each kind of mistake is refused naming the file and the
key before anything runs."""

from __future__ import annotations

from pathlib import Path

import pytest

from rig.mcu import board
from rig.mcu.board import BoardError, baud_error, mounting
from rig.mcu.mcus import MCUS

#: The Arduino boards' pin maps (Arduino's schematics: Mega 2560 rev3, Pro Mini), for the shipped
#: boards' motors: silk-screen name -> port pin
ARDUINO_MEGA = {"D2": "PE4", "D3": "PE5", "D5": "PE3", "D6": "PH3"}
ARDUINO_PRO_MINI = {"D9": "PB1", "D10": "PB2", "D11": "PB3", "D3": "PD3"}


def test_the_shipped_boards_load_as_their_silk_screens_say() -> None:
    mega = board.load("mega2560-gy86")
    assert mega.mcu.name == "atmega2560" and mega.clock_hz == 16_000_000
    assert {m.label: m.pin for m in mega.motors} == ARDUINO_MEGA
    assert [(m.timer, m.channel) for m in mega.motors] == [(3, "B"), (3, "C"), (3, "A"), (4, "A")]
    assert mega.rc is not None
    assert mega.rc.protocol == "sbus" and mega.rc.uart == 1 and mega.rc.baud == 100_000
    mini = board.load("promini328-gy86")
    assert {m.label: m.pin for m in mini.motors} == ARDUINO_PRO_MINI
    assert mini.rc is not None and mini.rc.protocol == "ppm" and mini.rc.pin == "PD2"
    assert set(board.names()) >= {"mega2560-gy86", "promini328-gy86"}


def test_a_board_file_by_path_loads_too(tmp_path: Path) -> None:
    p = tmp_path / "mine.toml"
    p.write_text(board.find("mega2560-gy86").read_text().replace('name = "mega2560-gy86"', 'name = "mine"'))
    assert board.load(str(p)).name == "mine"


MEGA = board.find("mega2560-gy86").read_text()


@pytest.mark.parametrize(
    ("change", "key", "words"),
    [
        (('pin = "PE4"', 'pin = "PE6"'), "motors[0].pin", "OC3B of the atmega2560 drives PE4, not PE6"),
        (('channel = "C"', 'channel = "D"'), "motors[1].channel", "expected one of A, B, C"),
        (("timer = 4", "timer = 0"), "motors[3].pin", "OC0A of the atmega2560 drives PB7, not PH3"),
        (("motor = 4", "motor = 3"), "motors", "expected one output for each of motors 1..4"),
        (('mcu = "atmega2560"', 'mcu = "atmega8"'), "board.mcu", "expected one of atmega2560, atmega328p"),
        (("uart = 1", "uart = 7"), "rc.uart", "USART 0, 1, 2, 3 only"),
        (("uart = 0 ", "uart = 4 "), "telemetry.uart", "USART 0, 1, 2, 3 only"),
        (("baud = 500_000", "baud = 230_400"), "telemetry.baud", "over 3% off"),
        (("clock_hz = 16_000_000", "clock_hz = 16e6"), "board.clock_hz", "expected an integer"),
        (("[rc]", "[rc]\nbaud = 115200"), "rc.baud", "SBUS runs at 100000 baud"),
        (("[fuses]", "[fuse]"), "fuse", "unknown key; did you mean 'fuses'?"),
        (('format = "text"', 'format = "mavlink"'), "telemetry.format", "expected one of text"),
    ],
)
def test_each_mistake_is_refused_naming_the_key(tmp_path: Path, change: tuple[str, str], key: str,
                                                words: str) -> None:
    old, new = change
    text = MEGA + "\n[fuses]\n" if old == "[fuses]" else MEGA
    assert old in text
    p = tmp_path / "bad.toml"
    p.write_text(text.replace(old, new, 1))
    with pytest.raises(BoardError) as e:
        board.load(str(p))
    assert str(e.value).startswith(f"{p}: {key}: ")
    assert words and words in str(e.value)


def test_a_motor_without_a_timer_is_any_port_pin(tmp_path: Path) -> None:
    """Software PWM: no timer and no channel, any pin of the MCU's ports (the 2560's A-L without I; the
    328P's B, C, D)."""
    motor2 = 'pin = "PE5"\ntimer = 3\nchannel = "C"'
    assert motor2 in MEGA
    p = tmp_path / "bitbang.toml"
    p.write_text(MEGA.replace(motor2, 'pin = "PA0"'))
    assert [(m.pin, m.timer, m.channel) for m in board.load(str(p)).motors][1] == ("PA0", None, "")
    for pin, words in (("PI0", "the atmega2560 has no pin PI0"), ("PA8", "the atmega2560 has no pin PA8")):
        p.write_text(MEGA.replace(motor2, f'pin = "{pin}"'))
        with pytest.raises(BoardError, match=rf"motors\[1\]\.pin: {words}"):
            board.load(str(p))
    p.write_text(MEGA.replace(motor2, 'pin = "PE5"\nchannel = "C"'))
    with pytest.raises(BoardError, match=r"motors\[1\]\.timer"):
        board.load(str(p))


def test_a_ppm_receiver_needs_an_interrupt_pin(tmp_path: Path) -> None:
    """Port A of the ATmega2560 has neither INTn nor PCINTn (its datasheet's pin functions)."""
    p = tmp_path / "bad.toml"
    sbus = 'protocol = "sbus"    # RX1 D19 (PD2)\nuart = 1'
    p.write_text(board.find("mega2560-gy86").read_text().replace(sbus, 'protocol = "ppm"\npin = "PA0"'))
    with pytest.raises(BoardError, match=r"rc.pin: the atmega2560.s PA0 has no external or pin change"):
        board.load(str(p))


def test_no_such_board_names_the_shipped_ones() -> None:
    with pytest.raises(BoardError, match="mega2560-gy86"):
        board.load("no-such-board")


def test_baud_errors_are_the_datasheets() -> None:
    # ATmega2560 datasheet, table 22-12 (16 MHz): 115.2k is -3.5 % at U2X 0 and 2.1 % at U2X 1;
    # 250k, 500k and 1M are exact
    mega = MCUS["atmega2560"]
    assert baud_error(mega, 16_000_000, 0, 115_200) == pytest.approx(0.021, abs=0.001)
    assert baud_error(mega, 16_000_000, 0, 250_000) == 0.0
    assert baud_error(mega, 16_000_000, 0, 1_000_000) == 0.0


def stm32_baud(pclk_hz: int, baud: int) -> float:
    """RM0090 30.3.4 with OVER8 = 0: Tx/Rx baud = f_PCLK / (16 USARTDIV), BRR = 16 USARTDIV (a 12-bit
    mantissa and a 4-bit fraction), so the baud made is f_PCLK / BRR for the nearest BRR, at least 16."""
    brr = max(16, round(pclk_hz / baud))
    return pclk_hz / brr


@pytest.mark.parametrize("mcu,clock_hz,uart,pclk_hz,baud", [
    ("stm32f405", 168_000_000, 1, 84_000_000, 115_200),  # APB2 at its 84 MHz most (DS8626)
    ("stm32f405", 168_000_000, 2, 42_000_000, 921_600),  # APB1 at 42 MHz
    ("stm32f405", 16_000_000, 6, 16_000_000, 115_200),   # the HSI: both APBs undivided
    ("stm32f405", 8_000_000, 2, 8_000_000, 1_000_000),   # BRR 8 is below 16: 500000 is the fastest
    ("stm32f411", 100_000_000, 2, 50_000_000, 460_800),  # APB1 at its 50 MHz most (DS10314)
    ("stm32f411", 100_000_000, 6, 100_000_000, 2_000_000),
])
def test_an_stm32_usarts_baud_error_is_its_brrs(mcu: str, clock_hz: int, uart: int, pclk_hz: int,
                                                baud: int) -> None:
    """An STM32 USART counts its APB's clock, HCLK divided to within the bus's maximum, and makes
    f_PCLK / BRR: its error is the nearest BRR's, not an AVR's UBRR's."""
    expected = abs(stm32_baud(pclk_hz, baud) / baud - 1)
    assert baud_error(MCUS[mcu], clock_hz, uart, baud) == pytest.approx(expected, abs=1e-12)


def test_an_stm32_refuses_what_only_an_avr_makes(tmp_path: Path) -> None:
    """1 Mbaud at 8 MHz: an AVR makes it exactly (U2X, UBRR 0), an STM32 USART with OVER8 = 0 at most
    8 MHz / 16 = 500000 baud (50 % off), so a board asking it is refused; 500000 is exact."""
    assert baud_error(MCUS["atmega328p"], 8_000_000, 0, 1_000_000) == 0.0
    assert baud_error(MCUS["stm32f405"], 8_000_000, 6, 1_000_000) == pytest.approx(0.5)
    assert baud_error(MCUS["stm32f405"], 8_000_000, 6, 500_000) == 0.0
    text = (board.BOARDS / "stm32f405-gy86.toml").read_text().replace("clock_hz = 168_000_000",
                                                                       "clock_hz = 8_000_000", 1)
    p = tmp_path / "slow.toml"
    p.write_text(text)
    assert board.load(str(p)).telemetry_baud == 500_000
    p.write_text(text.replace("baud = 500_000", "baud = 1_000_000", 1))
    with pytest.raises(BoardError, match="telemetry.baud: 1000000 baud is over 3% off"):
        board.load(str(p))


def test_a_board_turned_90_degrees_sees_the_nose_on_its_right() -> None:
    """A board turned 90° clockwise: the body's forward axis is the board's -y (its right, FRD), which
    a flat board (x forward, y left, z up) reads on +y; the body's down is the sensor's -z either way."""
    m = mounting(90)
    forward = [m[i][0] for i in range(3)]
    down = [m[i][2] for i in range(3)]
    assert forward == [0.0, 1.0, 0.0]
    assert down == [0.0, 0.0, -1.0]
    assert mounting(0) == ((1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, -1.0))


def test_a_receiver_pin_on_the_telemetry_usart_is_refused(tmp_path: Path) -> None:
    """The 328P's PD1 is TXD (USART0, the Pro Mini's telemetry) and PCINT17: two drivers on one line."""
    p = tmp_path / "bad.toml"
    p.write_text(board.find("promini328-gy86").read_text().replace('pin = "PD2"', 'pin = "PD1"'))
    with pytest.raises(BoardError, match=r"rc.pin: pin PD1 is USART0's TX, the telemetry's"):
        board.load(str(p))
