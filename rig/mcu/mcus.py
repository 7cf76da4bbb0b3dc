"""The microcontrollers the MCU tier knows, as data from their datasheets: memory sizes, which pin each
timer's output-compare channel drives, the USARTs' pins and the external-interrupt pins. A board file
(rig/mcu/board.py) is checked against these, so a motor on a pin its timer cannot drive is refused
before anything runs.

Sources: ATmega640/1280/1281/2560/2561 datasheet (2549Q), §13 "I/O-Ports" alternate functions, §7
memories and the "Reset and Interrupt Vectors" table (57); ATmega48A/PA/88A/PA/168A/PA/328/P datasheet
(DS40002061), §14.3, §8 and its vector table (26 for the 328P); avr-gcc's "AVR Options" (-mmcu): the
ATmega328P is avr5, the ATmega2560 avr6. STM32F405: its datasheet (DS8626) table 9, "Alternate function
mapping" (the timers' channels CH1..CH4, the USARTs' pins, I2C1), and RM0090 table 3 (memories).
The STM32s' analog inputs: DS8626's and DS10314's pin definitions tables ("additional functions":
ADC123_IN0-3 on PA0-PA3, ADC12_IN4-7 on PA4-PA7, ADC12_IN8/9 on PB0/PB1, ADC123_IN10-13 on PC0-PC3,
ADC12_IN14/15 on PC4/PC5; the F411 has ADC1 alone, on the same pins; the F405's ADC3-only inputs on
port F, which its 64-pin package lacks, are left out). STM32F411xC/E: its datasheet (DS10314) table 9,
"Alternate function mapping", and RM0383 section 2.3
(memory map): 512 KB of flash, 128 KB of SRAM, no CCM RAM; TIM1-5 and TIM9-11; USART1, 2 and 6; GPIO
ports A-E and H.

``engine`` says which engine runs the MCU (rig/mcu/engines.py): simavr ("avr") or the rig's QEMU
("stm32"); ``machine`` which of QEMU's machines (qemu/hw/) is the chip, and ``rams`` where its RAMs are,
which the image check (rig/mcu/stm32_image.py) holds an image's stack to."""

from __future__ import annotations

from dataclasses import dataclass, field

#: the STM32s' analog pins, each the same channel number on every ADC that has it (the module's sources)
STM32_ADC_PINS = {**{f"PA{i}": i for i in range(8)}, "PB0": 8, "PB1": 9,
                  **{f"PC{i}": 10 + i for i in range(6)}}
#: the F405's ADC3 has IN0-3 and IN10-13 on the same pins as ADC1 and ADC2 (its others are on port F)
STM32F405_ADC_UNITS: dict[int, tuple[int, ...]] = {
    ch: (1, 2, 3) if ch in (0, 1, 2, 3, 10, 11, 12, 13) else (1, 2) for ch in STM32_ADC_PINS.values()}


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
    #: pins with a pin change interrupt the engine raises (PCINTn): a PWM receiver's or a PPM sum's
    pcint: frozenset[str] = frozenset()
    #: analog input pin -> ADC channel (ADMUX's MUX bits; an STM32's ADCx_INn)
    adc: dict[str, int] = field(default_factory=dict)
    #: an STM32's ADC channel -> the ADCs whose input of that number is its pin (an AVR has one ADC)
    adc_units: dict[int, tuple[int, ...]] = field(default_factory=dict)
    #: the engine that runs it: "avr" (simavr) or "stm32" (the rig's QEMU)
    engine: str = "avr"
    #: the fastest clock a board may give it
    max_clock_hz: int = 32_000_000
    #: a timer's compare channels as board files name them (OCnA.. on an AVR, TIMn CH1.. on an STM32)
    channels: tuple[str, ...] = ("A", "B", "C")
    #: the QEMU machine that is this chip (the STM32 tier's engine: rig/mcu/stm32_link.py)
    machine: str = ""
    #: where the flash starts (its size: ``flash``; an STM32 boots from it, aliased at 0)
    flash_base: int = 0
    #: the RAMs an image may put its stack and data in: (address, bytes)
    rams: tuple[tuple[int, int], ...] = ()
    #: how its flight controllers time a receiver's pulses (a PPM sum, a parallel PWM receiver's
    #: channels), which says the pins a board may wire them to (``rc_pins``): "interrupt", an edge's
    #: interrupt timed in software (an AVR's INTn and PCINTn pins, as MultiWii does); "capture", a timer
    #: channel's input capture (an STM32's, as Betaflight's PPM and PWM inputs do)
    rc_timing: str = "interrupt"

    def rc_pins(self) -> frozenset[str]:
        """The pins a PPM sum or a PWM receiver's channel may come in on (``rc_timing``)."""
        if self.rc_timing == "capture":
            return frozenset(self.oc_pins.values())
        return frozenset(self.ints.values()) | self.pcint

    def rc_pin_kind(self) -> str:
        """What a pin of ``rc_pins`` has, for a board check's message."""
        if self.rc_timing == "capture":
            return "timer channel (a receiver's pulses are timed by its input capture)"
        return "external or pin change interrupt"

    #: the bauds a USART makes, as the datasheet's formula: its clock over ``step`` x n, n an integer from
    #: ``low`` to ``high``, one (step, low, high) for each of its modes. An AVR: f_OSC / (16 (UBRR + 1)),
    #: or / (8 (UBRR + 1)) with U2X (UBRR 12 bits); an STM32 with OVER8 = 0: f_PCLK / (16 USARTDIV),
    #: BRR = 16 USARTDIV (mantissa and a 4-bit fraction), so f_PCLK / BRR, BRR from 16 (RM0090 30.3.4)
    baud_divisors: tuple[tuple[int, int, int], ...] = ((16, 1, 4096), (8, 1, 4096))
    #: USART n -> the most the clock of its bus may be (an STM32's APB1 or APB2; a firmware divides HCLK
    #: by the smallest power of 2 that keeps within it); a USART not here counts the CPU clock (an AVR's)
    usart_bus_max_hz: dict[int, int] = field(default_factory=dict)

    def usart_clock_hz(self, clock_hz: int, uart: int) -> int:
        """The clock USART ``uart`` counts at a CPU clock of ``clock_hz``: its bus's (HCLK divided by 1,
        2, 4, 8 or 16 to within ``usart_bus_max_hz``), else the CPU clock."""
        limit = self.usart_bus_max_hz.get(uart, clock_hz)
        div = 1
        while clock_hz / div > limit and div < 16:
            div *= 2
        return clock_hz // div

    def output_name(self, timer: int, channel: str) -> str:
        """A timer output as the datasheet names it: OC1A, TIM4_CH1."""
        return f"TIM{timer}_CH{channel}" if self.engine == "stm32" else f"OC{timer}{channel}"


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
        adc={**{f"PF{i}": i for i in range(8)}, **{f"PK{i}": 8 + i for i in range(8)}},
        # (PCINT0-7 on port B, 9-15 on PJ0-6, 16-23 on port K; PCINT8, PE0, is RXD0 and not wired)
        pcint=frozenset(f"P{port}{i}" for port, n in (("B", 8), ("J", 7), ("K", 8)) for i in range(n)),
    ),
    Mcu(
        "atmega328p", flash=32 * 1024, sram=2 * 1024, eeprom=1024,
        oc_pins={(0, "A"): "PD6", (0, "B"): "PD5", (1, "A"): "PB1", (1, "B"): "PB2",
                 (2, "A"): "PB3", (2, "B"): "PD3"},
        timers16=frozenset({1}),
        usarts={0: ("PD0", "PD1")},
        ints={0: "PD2", 1: "PD3"},
        twi=("PC4", "PC5"), avr_arch=5, vectors=26, ports="BCD",
        adc={f"PC{i}": i for i in range(6)},  # (ADC6 and ADC7 have no port pin: TQFP and QFN only)
        pcint=frozenset(f"P{port}{i}" for port, n in (("B", 8), ("C", 7), ("D", 8)) for i in range(n)),
    ),
    Mcu(
        "stm32f405", flash=1024 * 1024, sram=192 * 1024, eeprom=0,
        # (DS8626 table 9: each timer channel's pins, as qemu/hw/rig_stm32f405.c wires them)
        oc_pins={
            **{(1, c): p for c, p in (("1", "PA8"), ("2", "PA9"), ("3", "PA10"), ("4", "PA11"))},
            **{(2, c): p for c, p in (("1", "PA0"), ("2", "PA1"), ("3", "PA2"), ("4", "PA3"))},
            **{(3, c): p for c, p in (("1", "PA6"), ("2", "PA7"), ("3", "PB0"), ("4", "PB1"))},
            **{(4, c): p for c, p in (("1", "PB6"), ("2", "PB7"), ("3", "PB8"), ("4", "PB9"))},
            **{(5, c): p for c, p in (("1", "PA0"), ("2", "PA1"), ("3", "PA2"), ("4", "PA3"))},
            **{(8, c): p for c, p in (("1", "PC6"), ("2", "PC7"), ("3", "PC8"), ("4", "PC9"))},
        },
        timers16=frozenset({1, 3, 4, 8}),
        usarts={1: ("PA10", "PA9"), 2: ("PA3", "PA2"), 3: ("PB11", "PB10"), 6: ("PC7", "PC6")},
        twi=("PB7", "PB6"), ports="ABCDEFGHI",
        engine="stm32", max_clock_hz=168_000_000, channels=("1", "2", "3", "4"),
        machine="rig-stm32f405", flash_base=0x0800_0000,
        adc=STM32_ADC_PINS, adc_units=STM32F405_ADC_UNITS,
        # (RM0090 table 3: SRAM1 and SRAM2, then the CCM data RAM)
        rams=((0x2000_0000, 128 * 1024), (0x1000_0000, 64 * 1024)), rc_timing="capture",
        # (RM0090 30.3.4, OVER8 = 0; DS8626, general operating conditions: f_PCLK1 at most
        # 42 MHz, f_PCLK2 84 MHz; USART1 and USART6 are on APB2, USART2 and USART3 on APB1)
        baud_divisors=((1, 16, 0xFFFF),),
        usart_bus_max_hz={1: 84_000_000, 2: 42_000_000, 3: 42_000_000, 6: 84_000_000},
    ),
    Mcu(
        "stm32f411", flash=512 * 1024, sram=128 * 1024, eeprom=0,
        # (DS10314 table 9: each timer channel's first pin, as qemu/hw/rig_stm32f411.c wires them; TIM5's
        # channels share TIM2's pins, TIM9's USART2's, TIM10/11's I2C1's PB8/PB9)
        oc_pins={
            **{(1, c): p for c, p in (("1", "PA8"), ("2", "PA9"), ("3", "PA10"), ("4", "PA11"))},
            **{(2, c): p for c, p in (("1", "PA0"), ("2", "PA1"), ("3", "PA2"), ("4", "PA3"))},
            **{(3, c): p for c, p in (("1", "PA6"), ("2", "PA7"), ("3", "PB0"), ("4", "PB1"))},
            **{(4, c): p for c, p in (("1", "PB6"), ("2", "PB7"), ("3", "PB8"), ("4", "PB9"))},
            **{(5, c): p for c, p in (("1", "PA0"), ("2", "PA1"), ("3", "PA2"), ("4", "PA3"))},
            (9, "1"): "PA2", (9, "2"): "PA3", (10, "1"): "PB8", (11, "1"): "PB9",
        },
        timers16=frozenset({1, 3, 4, 9, 10, 11}),
        usarts={1: ("PA10", "PA9"), 2: ("PA3", "PA2"), 6: ("PA12", "PA11")},
        twi=("PB7", "PB6"), ports="ABCDEH",
        engine="stm32", max_clock_hz=100_000_000, channels=("1", "2", "3", "4"),
        machine="rig-stm32f411", flash_base=0x0800_0000, rams=((0x2000_0000, 128 * 1024),),
        rc_timing="capture",
        # (RM0383 19.3.4, as RM0090's; DS10314, general operating conditions: f_PCLK1 at most 50 MHz,
        # f_PCLK2 100 MHz; USART1 and USART6 on APB2, USART2 on APB1)
        baud_divisors=((1, 16, 0xFFFF),),
        usart_bus_max_hz={1: 100_000_000, 2: 50_000_000, 6: 100_000_000},
        adc=STM32_ADC_PINS, adc_units={ch: (1,) for ch in STM32_ADC_PINS.values()},
    ),
)}
