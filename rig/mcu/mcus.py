"""The microcontrollers the MCU tier knows, as data from their datasheets: memory sizes, which pin each
timer's output-compare channel drives, the USARTs' pins and the external-interrupt pins. A board file
(rig/mcu/board.py) is checked against these, so a motor on a pin its timer cannot drive is refused
before anything runs.

Sources: ATmega640/1280/1281/2560/2561 datasheet (2549Q), §13 "I/O-Ports" alternate functions, §7
memories and the "Reset and Interrupt Vectors" table (57); ATmega48A/PA/88A/PA/168A/PA/328/P datasheet
(DS40002061), §14.3, §8 and its vector table (26 for the 328P); avr-gcc's "AVR Options" (-mmcu): the
ATmega328P is avr5, the ATmega2560 avr6."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Mcu:
    name: str
    flash: int     # bytes
    sram: int
    eeprom: int
    #: (timer, channel) -> the port pin its output-compare drives
    oc_pins: dict[tuple[int, str], str]
    #: timers whose counter is 16 bits wide
    timers16: frozenset[int]
    #: USART n -> (RXD pin, TXD pin)
    usarts: dict[int, tuple[str, str]]
    #: INTn -> pin
    ints: dict[int, str] = field(default_factory=dict)
    twi: tuple[str, str] = ("", "")  # (SDA, SCL)
    #: avr-gcc's architecture for -mmcu=<name>: an ELF's e_flags say it ("avr:6")
    avr_arch: int = 0
    #: the reset and interrupt vectors, each a 2-word JMP in avr-gcc's table
    vectors: int = 0
    #: the I/O ports' letters (pins "PE4": port E, bit 4)
    ports: str = ""


MCUS: dict[str, Mcu] = {m.name: m for m in (
    Mcu(
        "atmega2560", flash=256 * 1024, sram=8 * 1024, eeprom=4 * 1024,
        oc_pins={(0, "A"): "PB7", (0, "B"): "PG5",
                 (1, "A"): "PB5", (1, "B"): "PB6", (1, "C"): "PB7",
                 (2, "A"): "PB4", (2, "B"): "PH6",
                 (3, "A"): "PE3", (3, "B"): "PE4", (3, "C"): "PE5",
                 (4, "A"): "PH3", (4, "B"): "PH4", (4, "C"): "PH5",
                 (5, "A"): "PL3", (5, "B"): "PL4", (5, "C"): "PL5"},
        timers16=frozenset({1, 3, 4, 5}),
        usarts={0: ("PE0", "PE1"), 1: ("PD2", "PD3"), 2: ("PH0", "PH1"), 3: ("PJ0", "PJ1")},
        ints={0: "PD0", 1: "PD1", 2: "PD2", 3: "PD3", 4: "PE4", 5: "PE5", 6: "PE6", 7: "PE7"},
        twi=("PD1", "PD0"), avr_arch=6, vectors=57, ports="ABCDEFGHJKL",
    ),
    Mcu(
        "atmega328p", flash=32 * 1024, sram=2 * 1024, eeprom=1024,
        oc_pins={(0, "A"): "PD6", (0, "B"): "PD5", (1, "A"): "PB1", (1, "B"): "PB2",
                 (2, "A"): "PB3", (2, "B"): "PD3"},
        timers16=frozenset({1}),
        usarts={0: ("PD0", "PD1")},
        ints={0: "PD2", 1: "PD3"},
        twi=("PC4", "PC5"), avr_arch=5, vectors=26, ports="BCD",
    ),
)}
