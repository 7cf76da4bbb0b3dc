"""Board files: what is wired where on a flight controller board, as data (TOML), one file per board
design. The MCU tier reads one to know which MCU runs the image at what clock, where the sensors are,
which timer channel drives which motor with which ESC protocol, where the RC link and the telemetry
come in and out, what EEPROM image to preload, and how the sensor board is mounted.

A board file is checked like a scenario: every error names the file and the dotted key, and a pin that
its timer cannot drive (rig/mcu/mcus.py) is refused before anything runs. The shipped boards are in
rig/mcu/boards/; ``--mcu NAME`` finds them by name, ``--mcu path/to/board.toml`` reads any other.

    [board]      name, description, mcu ("atmega2560" | "atmega328p" | "stm32f405" | "stm32f411"), clock_hz,
                 hse_hz (an STM32's crystal: 8 MHz unless given; the Black Pill's is 25 MHz)
    [sensors]    bus ("twi"), topology ("gy86" | "direct" | "gy521": the MPU-6050 alone), twi_hz,
                 mounting_yaw_deg (0, 90, 180, 270), mpu_address (0x68, or 0x69 with AD0 high)
    [[motors]]   motor (1..4: the plant's), pin ("PE4"), timer, channel ("A" | "B" | "C"; "1".."4" on
                 an STM32), protocol ("pwm" | "oneshot125"), label ("D2": the board's silk-screen
                 name); with no timer and channel, any port pin (AVR), its pulses measured from its edges
    [rc]         protocol ("sbus" | "ppm" | "msp" | "pwm"), uart (sbus, msp), baud (msp), pin (ppm),
                 pins (pwm: 4..8, one a channel); each pin one the MCU times a receiver's pulses on
                 (rig/mcu/mcus.py rc_pins: an AVR's INTn or PCINTn pins, an STM32's timer channels) and
                 no motor's; optional
    [telemetry]  uart, baud, format ("text": the reference FC's ``T t=… key=value`` lines); optional
    [eeprom]     image (a file of raw bytes, relative to the board file), or fc = true: built from the
                 scenario's [fc] table by the reference firmware's layout
    [fuses]      watchdog_always_on (WDTON programmed)
    [battery]    pin (an ADC input, "PF0"), divider ([ohms battery->pin, ohms pin->ground]); the pack
                 (rig/battery.py, its voltage sagging with the motors' current and falling with the
                 charge drawn): volts (at the start, at rest: 12.6 by default, a full 3S), cells
                 (round(volts / 4.2) unless given), capacity_mah (1300), internal_ohms (the pack's:
                 0.015 a cell), motor_amps (each motor's at full throttle: 20), idle_amps (the rest of the
                 quad's draw: 0, so a pack at rest reads its volts for the whole run)
    [limits]     hang_s (1: no TWI, pulse, USART byte or output pin change for this long is a hang; 0 off)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

from rig.battery import CELL_EMPTY, CELL_FULL, Pack
from rig.bridge.esc import ESC_PROTOCOLS
from rig.emulators.chips.board import TOPOLOGIES
from rig.emulators.mpu6050 import ADDRESS as MPU_ADDRESS
from rig.emulators.sensor_models import FLAT_ON_BOARD
from rig.mcu.mcus import MCUS, Mcu
from rig.plant.toml_file import TomlFileError, read_toml
from rig.scenarios.schema import ScenarioError, _Check

BOARDS: Final = Path(__file__).resolve().parent / "boards"
TOP: Final = {"board", "sensors", "motors", "rc", "telemetry", "eeprom", "fuses", "limits", "battery"}
BATTERY_KEYS: Final = {"pin", "divider", "volts", "cells", "capacity_mah", "internal_ohms", "motor_amps",
                       "idle_amps"}
#: a pack's defaults (rig/battery.py): a full 3S of a 5-inch quad's usual size, its motors' full-throttle
#: current; an internal resistance a cell of such a pack has when new (10-20 milliohms)
PACK_VOLTS: Final = 12.6
PACK_CAPACITY_MAH: Final = 1300.0
CELL_OHMS: Final = 0.015
MOTOR_AMPS: Final = 20.0
#: a board's supply and ADC reference (AVCC): an Arduino's 5 V; a divided battery above it is clamped
VCC: Final = 5.0
BOARD_KEYS: Final = {"name", "description", "mcu", "clock_hz", "hse_hz"}
#: an STM32's crystal unless the board says (the common boards'), and the range its HSE oscillator takes
#: (DS8626 and DS10314, "HSE 4-26 MHz oscillator characteristics")
HSE_HZ: Final = 8_000_000
HSE_RANGE: Final = (4_000_000, 26_000_000)
SENSOR_KEYS: Final = {"bus", "topology", "twi_hz", "mounting_yaw_deg", "mpu_address"}
MOTOR_KEYS: Final = {"motor", "pin", "timer", "channel", "protocol", "label"}
RC_KEYS: Final = {"protocol", "uart", "baud", "pin", "pins"}
TELEMETRY_KEYS: Final = {"uart", "baud", "format"}
EEPROM_KEYS: Final = {"image", "fc"}
FUSE_KEYS: Final = {"watchdog_always_on"}
LIMIT_KEYS: Final = {"hang_s"}
#: a firmware with no bus, pulse, USART byte or output pin change for this long is hung
HANG_S: Final = 1.0
RC_PROTOCOLS: Final = ("sbus", "ppm", "msp", "pwm")
#: a parallel PWM receiver's channels
PWM_CHANNELS: Final = (4, 8)
SBUS_BAUD: Final = 100_000
#: how far a USART's nearest baud may be from the board's: 115200 at 16 MHz is 2.1 % off on an AVR
#: (Arduino's usual serial speed, read well by USB bridges); beyond 3 % a frame's last bits are misread
BAUD_TOLERANCE: Final = 0.03


class BoardError(ScenarioError):
    """A board file that cannot be used: ``file: key: message``."""


@dataclass(frozen=True)
class MotorOut:
    motor: int      # 1..4, the plant's motor
    pin: str        # "PE4"
    timer: int | None  # None: measured from the pin's edges (software PWM on any port pin)
    channel: str    # "A" | "B" | "C" ("" without a timer)
    protocol: str   # rig/bridge/esc.py ESC_PROTOCOLS
    label: str


@dataclass(frozen=True)
class RcIn:
    protocol: str   # "sbus" | "ppm" | "msp" | "pwm"
    uart: int | None
    baud: int
    pin: str | None
    pins: tuple[str, ...] = ()  # pwm: one pin per channel, in channel order (AETR, then aux)


@dataclass(frozen=True)
class Battery:
    pin: str
    channel: int  # the ADC channel
    divider: tuple[float, float]  # ohms: battery to pin, pin to ground
    pack: Pack

    @property
    def volts(self) -> float:
        """The pack's at the start (at rest)."""
        return self.pack.volts

    @property
    def pin_volts(self) -> float:
        """What the ADC pin sees at the start."""
        return self.pin_volts_at(self.pack.volts)

    def pin_volts_at(self, volts: float) -> float:
        """What the ADC pin sees with the pack at ``volts``: through the divider, clamped at VCC (the
        pin's diodes)."""
        top, bottom = self.divider
        return min(VCC, volts * bottom / (top + bottom))


@dataclass(frozen=True)
class Board:
    path: Path
    name: str
    description: str
    mcu: Mcu
    clock_hz: int
    hse_hz: int  # an STM32's crystal (0 on an AVR board)
    topology: str
    mpu_address: int
    twi_hz: int
    mounting_yaw_deg: int
    motors: tuple[MotorOut, ...]
    rc: RcIn | None  # None: no receiver wired (a firmware brought up by hand, a sensor board's test)
    telemetry_uart: int | None  # None: no [telemetry] (a firmware that speaks MSP, or nothing)
    telemetry_baud: int
    eeprom_image: Path | None
    eeprom_from_fc: bool
    watchdog_always_on: bool
    hang_s: float = HANG_S
    battery: Battery | None = None


def find(name: str) -> Path:
    """A shipped board by name, else the file as given."""
    p = Path(name)
    if not p.exists() and p.parent == Path(".") and (BOARDS / f"{p.stem}.toml").exists():
        return BOARDS / f"{p.stem}.toml"
    return p


def names() -> list[str]:
    return sorted(p.stem for p in BOARDS.glob("*.toml"))


def load(name: str | Path) -> Board:
    """Reads and checks a board file (a shipped board's name, or a path); BoardError otherwise."""
    path = find(str(name))
    c = _BoardCheck(str(path))
    if not path.is_file():
        raise c.fail("", "no such board file, and no shipped board of that name (shipped: "
                         f"{', '.join(names())})")
    try:
        data = read_toml(path).data
    except TomlFileError as unreadable:
        raise c.fail("", str(unreadable)) from None
    c.table(data, "", TOP)
    b = c.table(data.get("board", {}), "board", BOARD_KEYS)
    mcu_name = c.string(b, "mcu", "board", choices=tuple(MCUS))
    mcu = MCUS[mcu_name]
    clock = c.integer(b, "clock_hz", "board", 1_000_000, mcu.max_clock_hz)
    hse = 0
    if mcu.engine == "stm32":
        hse = c.integer(b, "hse_hz", "board", *HSE_RANGE, default=HSE_HZ)
    elif "hse_hz" in b:
        raise c.fail("board.hse_hz", f"the {mcu.name} has no HSE crystal input: its clock is clock_hz")
    s = c.table(data.get("sensors", {}), "sensors", SENSOR_KEYS)
    c.string(s, "bus", "sensors", "twi", choices=("twi",))
    yaw = c.integer(s, "mounting_yaw_deg", "sensors", 0, 270, default=0)
    if yaw % 90:
        raise c.fail("sensors.mounting_yaw_deg", f"expected 0, 90, 180 or 270, got {yaw}")
    mpu_address = c.integer(s, "mpu_address", "sensors", 0, 127, default=MPU_ADDRESS)
    if mpu_address not in (MPU_ADDRESS, MPU_ADDRESS + 1):
        raise c.fail("sensors.mpu_address", f"an MPU-6050 answers at 0x68 (AD0 low) or 0x69 (AD0 high), "
                                            f"not {mpu_address:#04x}")
    motors = tuple(_motor(c, mcu, m, k) for k, m in enumerate(c.array(data, "motors")))
    got = sorted(m.motor for m in motors)
    if got != [1, 2, 3, 4]:
        raise c.fail("motors", f"expected one output for each of motors 1..4, got motors {got}")
    pins = [m.pin for m in motors]
    for p in pins:
        if pins.count(p) > 1:
            raise c.fail("motors", f"pin {p} drives two motors")
    rc = _rc(c, mcu, c.table(data["rc"], "rc", RC_KEYS), motors) if "rc" in data else None
    tel_uart: int | None = None
    tel_baud = 0
    if "telemetry" in data:
        t = c.table(data["telemetry"], "telemetry", TELEMETRY_KEYS)
        tel_uart = _uart(c, mcu, t, "telemetry")
        tel_baud = c.integer(t, "baud", "telemetry", 300, 2_000_000)
        c.string(t, "format", "telemetry", "text", choices=("text",))
        if baud_error(mcu, clock, tel_uart, tel_baud) > BAUD_TOLERANCE:
            raise c.fail("telemetry.baud", f"{tel_baud} baud is over {BAUD_TOLERANCE:.0%} off anything a "
                                           f"USART makes at {clock} Hz")
    # (the RC input and the telemetry may share a USART: RX and TX are separate lines, as a Pro Mini's
    # one USART takes SBUS in and sends telemetry out, and MSP is both on one port; a receiver's pulses
    # on the telemetry USART's pins may not: two things would drive one line)
    if rc is not None and tel_uart is not None:
        rx, tx = mcu.usarts[tel_uart]
        for rc_pin in (rc.pin, *rc.pins):
            if rc_pin in (rx, tx):
                line = "RX" if rc_pin == rx else "TX"
                raise c.fail("rc.pin" if rc.pin else "rc.pins", f"pin {rc_pin} is USART{tel_uart}'s {line}, "
                                                                "the telemetry's")
    e = c.table(data.get("eeprom", {}), "eeprom", EEPROM_KEYS)
    image: Path | None = None
    if "image" in e:
        image = (path.parent / c.string(e, "image", "eeprom")).resolve()
        if not image.is_file():
            raise c.fail("eeprom.image", f"no such file: {image}")
        if image.stat().st_size > mcu.eeprom:
            raise c.fail("eeprom.image", f"{image.stat().st_size} bytes, over the {mcu.name}'s "
                                         f"{mcu.eeprom} bytes of EEPROM")
    from_fc = c.boolean(e, "fc", "eeprom", False)
    if image is not None and from_fc:
        raise c.fail("eeprom", "either an image or fc = true, not both")
    f = c.table(data.get("fuses", {}), "fuses", FUSE_KEYS)
    limits = c.table(data.get("limits", {}), "limits", LIMIT_KEYS)
    return Board(
        path=path.resolve(),
        name=c.string(b, "name", "board", path.stem),
        description=c.string(b, "description", "board", ""),
        mcu=mcu,
        clock_hz=clock,
        hse_hz=hse,
        topology=c.string(s, "topology", "sensors", "gy86", choices=TOPOLOGIES),
        mpu_address=mpu_address,
        twi_hz=c.integer(s, "twi_hz", "sensors", 10_000, 1_000_000, default=400_000),
        mounting_yaw_deg=yaw,
        motors=tuple(sorted(motors, key=lambda m: m.motor)),
        rc=rc,
        telemetry_uart=tel_uart,
        telemetry_baud=tel_baud,
        eeprom_image=image,
        eeprom_from_fc=from_fc,
        watchdog_always_on=c.boolean(f, "watchdog_always_on", "fuses", False),
        hang_s=c.number(limits, "hang_s", "limits", HANG_S, low=0, high=600),
        battery=_battery(c, mcu, data["battery"]) if "battery" in data else None,
    )


class _BoardCheck(_Check):
    def fail(self, key: str, message: str) -> BoardError:
        return BoardError(self.file, key, message)

    def integer(self, data: dict[str, Any], key: str, path: str, low: int, high: int,
                default: int | None = None) -> int:
        full = f"{path}.{key}"
        if key not in data:
            if default is None:
                raise self.fail(full, "missing; expected an integer")
            return default
        v = data[key]
        if isinstance(v, bool) or not isinstance(v, int):
            raise self.fail(full, f"expected an integer, got {v!r}")
        if not low <= v <= high:
            raise self.fail(full, f"expected an integer in {low}..{high}, got {v}")
        return v


def _uart(c: _BoardCheck, mcu: Mcu, data: dict[str, Any], path: str) -> int:
    n = c.integer(data, "uart", path, 0, 7)
    if n not in mcu.usarts:
        raise c.fail(f"{path}.uart", f"the {mcu.name} has USART {', '.join(map(str, mcu.usarts))} only")
    return n


def _motor(c: _BoardCheck, mcu: Mcu, data: Any, k: int) -> MotorOut:
    where = f"motors[{k}]"
    m = c.table(data, where, MOTOR_KEYS)
    pin = c.string(m, "pin", where).upper()
    timer: int | None = None
    channel = ""
    if "timer" in m or "channel" in m:
        timer = c.integer(m, "timer", where, 0, max(t for t, _ in mcu.oc_pins))
        channel = str(c.string(m, "channel", where, choices=mcu.channels))
        output = mcu.output_name(timer, channel)
        oc = mcu.oc_pins.get((timer, channel))
        if oc is None:
            raise c.fail(f"{where}.channel", f"the {mcu.name} has no {output}")
        if pin != oc:
            raise c.fail(f"{where}.pin", f"{output} of the {mcu.name} drives {oc}, not {pin}")
    elif mcu.engine == "stm32":
        raise c.fail(where, f"the {mcu.name}'s motors are measured from its timers: give timer and channel")
    elif len(pin) != 3 or pin[0] != "P" or pin[1] not in mcu.ports or pin[2] not in "01234567":
        raise c.fail(f"{where}.pin", f"the {mcu.name} has no pin {pin}: P, a port letter ({mcu.ports}) and "
                                     "a bit 0..7")
    return MotorOut(
        motor=c.integer(m, "motor", where, 1, 4),
        pin=pin,
        timer=timer,
        channel=channel,
        protocol=c.string(m, "protocol", where, "pwm", choices=tuple(ESC_PROTOCOLS)),
        label=c.string(m, "label", where, pin),
    )


def _battery(c: _BoardCheck, mcu: Mcu, data: Any) -> Battery:
    b = c.table(data, "battery", BATTERY_KEYS)
    pin = c.string(b, "pin", "battery").upper()
    if pin not in mcu.adc:
        raise c.fail("battery.pin", f"the {mcu.name}'s analog inputs are {', '.join(mcu.adc)}, not {pin}")
    divider = b.get("divider", [0, 1])
    if (not isinstance(divider, list) or len(divider) != 2 or
            not all(isinstance(r, int | float) and not isinstance(r, bool) and r >= 0 for r in divider) or
            not divider[1] > 0):
        raise c.fail("battery.divider", f"expected [ohms from the battery to the pin, ohms from the pin to "
                                        f"ground], the second > 0, got {divider!r}")
    volts = c.number(b, "volts", "battery", PACK_VOLTS, low=0, high=60)
    cells = c.integer(b, "cells", "battery", 1, 14, default=max(round(volts / CELL_FULL), 1))
    if not CELL_EMPTY <= volts / cells <= CELL_FULL:
        raise c.fail("battery.volts", f"{volts:g} V is {volts / cells:.3f} V a cell for {cells} cell(s): a "
                                      f"LiPo cell is {CELL_EMPTY}..{CELL_FULL} V (give cells, or volts)")
    pack = Pack(volts, cells,
                capacity_mah=c.number(b, "capacity_mah", "battery", PACK_CAPACITY_MAH, positive=True,
                                      high=1_000_000),
                internal_ohms=c.number(b, "internal_ohms", "battery", CELL_OHMS * cells, low=0, high=10),
                motor_amps=c.number(b, "motor_amps", "battery", MOTOR_AMPS, low=0, high=1000),
                idle_amps=c.number(b, "idle_amps", "battery", 0.0, low=0, high=1000))
    return Battery(pin, mcu.adc[pin], (float(divider[0]), float(divider[1])), pack)


def _rc(c: _BoardCheck, mcu: Mcu, r: dict[str, Any], motors: tuple[MotorOut, ...]) -> RcIn:
    protocol = c.string(r, "protocol", "rc", choices=RC_PROTOCOLS)
    if protocol == "ppm":
        pin = c.string(r, "pin", "rc").upper()
        _rc_pin(c, mcu, "rc.pin", pin, motors)
        return RcIn("ppm", None, 0, pin)
    if protocol == "pwm":
        pins = r.get("pins")
        low, high = PWM_CHANNELS
        if (not isinstance(pins, list) or not low <= len(pins) <= high or
                not all(isinstance(p, str) for p in pins)):
            raise c.fail("rc.pins", f"expected {low} to {high} pins, one a channel in channel order, got "
                                    f"{pins!r}")
        names = tuple(p.upper() for p in pins)
        for p in names:
            _rc_pin(c, mcu, "rc.pins", p, motors)
            if names.count(p) > 1:
                raise c.fail("rc.pins", f"pin {p} is two channels")
        return RcIn("pwm", None, 0, None, names)
    uart = _uart(c, mcu, r, "rc")
    baud = SBUS_BAUD if protocol == "sbus" else c.integer(r, "baud", "rc", 300, 2_000_000, default=115_200)
    if protocol == "sbus" and r.get("baud", SBUS_BAUD) != SBUS_BAUD:
        raise c.fail("rc.baud", f"SBUS runs at {SBUS_BAUD} baud")
    return RcIn(protocol, uart, baud, None)


def _rc_pin(c: _BoardCheck, mcu: Mcu, key: str, pin: str, motors: tuple[MotorOut, ...]) -> None:
    """A receiver's pulses come in on a pin the MCU's flight controllers time them on (Mcu.rc_timing),
    and not on a motor's pin."""
    if pin not in mcu.rc_pins():
        raise c.fail(key, f"the {mcu.name}'s {pin} has no {mcu.rc_pin_kind()}")
    for m in motors:
        if m.pin == pin:
            raise c.fail(key, f"pin {pin} drives motor {m.motor}")


def baud_error(mcu: Mcu, clock_hz: int, uart: int, baud: int) -> float:
    """How far the nearest baud ``mcu``'s USART ``uart`` makes at a CPU clock of ``clock_hz`` is from
    ``baud``, as a fraction (BAUD_TOLERANCE is what a board may have): the MCU's formula
    (``Mcu.baud_divisors``) with the divisor nearest, in each of its modes."""
    f = mcu.usart_clock_hz(clock_hz, uart)
    best = math.inf
    for step, low, high in mcu.baud_divisors:
        n = min(max(round(f / (step * baud)), low), high)
        best = min(best, abs(f / (step * n) / baud - 1))
    return best


def mounting(yaw_deg: int) -> tuple[tuple[float, float, float], ...]:
    """Body FRD to the sensors' frame of a board turned ``yaw_deg`` clockwise (seen from above; a
    multiple of 90) from facing forward: the board's own FRD axes, then the flat board's
    (emulators/sensor_models.py FLAT_ON_BOARD)."""
    c, s = round(math.cos(math.radians(yaw_deg))), round(math.sin(math.radians(yaw_deg)))
    turned = ((c, s, 0), (-s, c, 0), (0, 0, 1))  # rows: the board's x, y, z axes in body FRD
    rows = [[float(sum(f[k] * turned[k][j] for k in range(3))) for j in range(3)] for f in FLAT_ON_BOARD]
    return tuple((r[0], r[1], r[2]) for r in rows)


def uart_baud(board: Board, uart: int) -> int | None:
    """The baud the board gives a USART: its telemetry's, else its RC link's (None: neither is on it)."""
    if board.telemetry_uart == uart:
        return board.telemetry_baud
    if board.rc is not None and board.rc.uart == uart:
        return board.rc.baud
    return None
