"""Riden RD60xx supplies: Modbus RTU over their USB serial port (115200 baud by default), unit 1,
holding registers (docs/power.md has the table and where it comes from).

The client is pymodbus's (its RTU framing and CRC-16), so the simulated supply in the tests, which
frames by hand from the same register table, is a second implementation of the wire."""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Final

from rig.power.supply import PsuError, Reading

#: register -> meaning (data: the driver and docs/power.md follow it)
REG_ID: Final = 0          # the model: 60062 is an RD6006
REG_V_SET: Final = 8       # volts × the model's voltage scale
REG_I_SET: Final = 9       # amps × the model's current scale
REG_V_OUT: Final = 10
REG_I_OUT: Final = 11
REG_PROTECTION: Final = 16  # 0 none, 1 over-voltage tripped, 2 over-current tripped
REG_CV_CC: Final = 17      # 0 constant voltage, 1 constant current
REG_OUTPUT: Final = 18     # 1 output enabled
UNIT: Final = 1


@dataclass(frozen=True)
class Model:
    name: str
    first_id: int
    last_id: int
    v_scale: int   # register counts per volt
    i_scale: int   # register counts per amp
    v_max: float
    i_max: float


#: the model register's ranges and each model's scales
MODELS: Final = (
    Model("RD6006", 60060, 60064, 100, 1000, 60.0, 6.0),
    Model("RD6006P", 60065, 60065, 1000, 10000, 60.0, 6.0),
    Model("RD6012", 60120, 60129, 100, 100, 60.0, 12.0),
    Model("RD6018", 60180, 60189, 100, 100, 60.0, 18.0),
)


def model_of(ident: int) -> Model:
    for m in MODELS:
        if m.first_id <= ident <= m.last_id:
            return m
    known = ", ".join(f"{m.name} ({m.first_id}..{m.last_id})" for m in MODELS)
    raise PsuError(f"riden: model register reads {ident}, not a model this driver knows: {known}")


class RidenSupply:
    DEFAULT_BAUD: Final = 115200

    def __init__(self, port: str, baud: int = DEFAULT_BAUD, timeout: float = 0.5) -> None:
        from pymodbus.client import ModbusSerialClient
        from pymodbus.framer import FramerType

        # pymodbus logs each failed attempt itself; our PsuError says it once, with the supply's name
        logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
        self.name = f"riden:{port}"
        self.timeout = timeout
        self._client = ModbusSerialClient(port, framer=FramerType.RTU, baudrate=baud, timeout=timeout,
                                          retries=1)
        if not self._client.connect():
            raise PsuError(f"{self.name}: cannot open the serial port")
        try:
            self.model = model_of(self._read(REG_ID, 1)[0])
        except PsuError:
            self._client.close()
            raise

    def _read(self, address: int, count: int) -> list[int]:
        from pymodbus.exceptions import ModbusException

        try:
            rr = self._client.read_holding_registers(address, count=count, device_id=UNIT)
        except ModbusException as e:
            raise PsuError(f"{self.name}: no valid answer to a read of registers "
                           f"{address}..{address + count - 1} within {self.timeout:g} s (twice): {e}") from e
        if rr.isError():
            raise PsuError(f"{self.name}: refused a read of registers {address}..{address + count - 1}: {rr}")
        if len(rr.registers) != count:
            raise PsuError(f"{self.name}: answered {len(rr.registers)} registers for {count}")
        return list(rr.registers)

    def _write(self, address: int, value: int) -> None:
        from pymodbus.exceptions import ModbusException

        try:
            rr = self._client.write_register(address, value, device_id=UNIT)
        except ModbusException as e:
            raise PsuError(f"{self.name}: no valid answer to a write of register {address} within "
                           f"{self.timeout:g} s (twice): {e}") from e
        if rr.isError():
            raise PsuError(f"{self.name}: refused a write of register {address} = {value}: {rr}")

    def identity(self) -> str:
        return f"Riden {self.model.name}"

    def set_voltage(self, volts: float) -> None:
        if not 0 <= volts <= self.model.v_max:
            raise PsuError(f"{self.name}: {volts:g} V is outside the {self.model.name}'s "
                           f"0..{self.model.v_max:g} V")
        self._write(REG_V_SET, round(volts * self.model.v_scale))

    def set_current_limit(self, amps: float) -> None:
        if not 0 <= amps <= self.model.i_max:
            raise PsuError(f"{self.name}: {amps:g} A is outside the {self.model.name}'s "
                           f"0..{self.model.i_max:g} A")
        self._write(REG_I_SET, round(amps * self.model.i_scale))

    def output(self, on: bool) -> None:
        self._write(REG_OUTPUT, int(on))

    def read(self) -> Reading:
        r = self._read(REG_V_SET, REG_OUTPUT - REG_V_SET + 1)
        m = self.model
        at = {reg: r[reg - REG_V_SET] for reg in range(REG_V_SET, REG_OUTPUT + 1)}
        detail = {1: "over-voltage protection tripped", 2: "over-current protection tripped"}.get(
            at[REG_PROTECTION], "CC" if at[REG_CV_CC] == 1 else "CV")
        return Reading(volts=at[REG_V_OUT] / m.v_scale, amps=at[REG_I_OUT] / m.i_scale,
                       volts_set=at[REG_V_SET] / m.v_scale, amps_limit=at[REG_I_SET] / m.i_scale,
                       output=at[REG_OUTPUT] == 1, detail=detail)

    def measure(self) -> tuple[float, float]:
        v, i = self._read(REG_V_OUT, 2)
        return v / self.model.v_scale, i / self.model.i_scale

    def close(self) -> None:
        self._client.close()
