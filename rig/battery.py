"""The flight pack: a LiPo battery whose terminal voltage sags with the current the motors draw and falls
as its charge is used, so a firmware's battery monitor sees what it sees on a flying quad (a low-voltage
warning, a throttle compensation) rather than a constant.

The model, deliberately simple and deterministic (a pure function of sim time and the ESC commands: no
randomness, no wall clock):

* ``cells`` in series, each at the open-circuit voltage OCV_TABLE gives for the state of charge (a
  common LiPo discharge table at rest, piecewise linear between its points: 4.20 V full, 3.27 V empty);
* the current is ``idle_amps`` plus, for each motor, ``motor_amps x throttle ** 1.5``, the throttle the
  ESC's pulse (1000 us: 0, 2000 us: 1, clamped). The 1.5 power is an assumption, not a fit to a motor:
  the current grows faster than the throttle, as a propeller's power does with its speed, so half
  throttle draws 35 % of the full current, not half of it;
* the charge drawn is the current integrated over time (coulomb counting), each current held from the
  update that set it to the next one (the ESC commands change at the session's step ends);
* the terminal voltage is the cells' OCV less the current through ``internal_ohms`` (Ohm's law), then
  the scenario's faults on the battery (rig/emulators/faults.py: a bias step, a drift, a scale error,
  a stuck reading, noise).

Not modelled: the pack's recovery after a load (its RC polarisation), temperature, the voltage cut-off
of an ESC, the wiring's own resistance.
"""

from __future__ import annotations

import bisect
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final

from rig.emulators.faults import FaultSet

#: (state of charge, volts a cell at rest): a common LiPo discharge table, piecewise linear between points
OCV_TABLE: Final = ((0.00, 3.27), (0.05, 3.61), (0.10, 3.69), (0.15, 3.71), (0.20, 3.73), (0.25, 3.75),
                    (0.30, 3.77), (0.35, 3.79), (0.40, 3.80), (0.45, 3.82), (0.50, 3.84), (0.55, 3.85),
                    (0.60, 3.87), (0.65, 3.91), (0.70, 3.95), (0.75, 3.98), (0.80, 4.02), (0.85, 4.08),
                    (0.90, 4.11), (0.95, 4.15), (1.00, 4.20))
CELL_EMPTY: Final = OCV_TABLE[0][1]
CELL_FULL: Final = OCV_TABLE[-1][1]
_SOC = [s for s, _ in OCV_TABLE]
_OCV = [v for _, v in OCV_TABLE]
#: the ESC's pulse at zero and at full throttle (us)
PULSE_ZERO_US: Final = 1000.0
PULSE_FULL_US: Final = 2000.0
#: the current at a throttle goes as its THROTTLE_POWER (the module's docstring says why)
THROTTLE_POWER: Final = 1.5


def cell_volts(soc: float) -> float:
    """A cell's open-circuit volts at state of charge ``soc`` (0..1, clamped), from OCV_TABLE."""
    if soc <= 0.0:
        return CELL_EMPTY
    if soc >= 1.0:
        return CELL_FULL
    k = bisect.bisect_right(_SOC, soc) - 1
    s0, s1, v0, v1 = _SOC[k], _SOC[k + 1], _OCV[k], _OCV[k + 1]
    return v0 + (v1 - v0) * (soc - s0) / (s1 - s0)


def state_of_charge(volts_a_cell: float) -> float:
    """The state of charge whose open-circuit volts a cell are ``volts_a_cell`` (cell_volts' inverse;
    ValueError outside CELL_EMPTY..CELL_FULL)."""
    if not CELL_EMPTY <= volts_a_cell <= CELL_FULL:
        raise ValueError(f"{volts_a_cell:.3f} V a cell is outside a LiPo's {CELL_EMPTY}..{CELL_FULL} V")
    k = min(bisect.bisect_right(_OCV, volts_a_cell) - 1, len(_OCV) - 2)
    s0, s1, v0, v1 = _SOC[k], _SOC[k + 1], _OCV[k], _OCV[k + 1]
    return s0 + (s1 - s0) * (volts_a_cell - v0) / (v1 - v0)


def throttle(pulse_us: float) -> float:
    """An ESC's throttle (0..1) for its pulse: 1000 us nothing, 2000 us full, clamped (no pulse: 0)."""
    return min(max((pulse_us - PULSE_ZERO_US) / (PULSE_FULL_US - PULSE_ZERO_US), 0.0), 1.0)


@dataclass(frozen=True)
class Pack:
    """A pack as a board file gives it (rig/mcu/board.py ``[battery]``): its open-circuit volts at the
    start (the state of charge follows from them), cells in series, capacity, internal resistance (the
    whole pack's), each motor's current at full throttle and the rest of the quad's draw."""

    volts: float
    cells: int
    capacity_mah: float
    internal_ohms: float
    motor_amps: float
    idle_amps: float = 0.0

    def amps(self, pulses_us: Sequence[float]) -> float:
        """The current drawn with the ESCs at ``pulses_us``."""
        return self.idle_amps + sum(self.motor_amps * throttle(p) ** THROTTLE_POWER for p in pulses_us)


class PackState:
    """A pack in use: ``update(t_ns, pulses_us)`` at each step end gives its terminal volts then."""

    def __init__(self, pack: Pack, faults: FaultSet | None = None) -> None:
        self.pack = pack
        self.faults = faults if faults is not None else FaultSet()
        self.soc0 = state_of_charge(pack.volts / pack.cells)
        self.drawn_mah = 0.0
        self.amps = pack.idle_amps
        self.t_ns = 0
        self.volts = self._terminal(0)

    @property
    def soc(self) -> float:
        """The state of charge now (0..1; an empty pack stays at 0)."""
        return max(self.soc0 - self.drawn_mah / self.pack.capacity_mah, 0.0)

    def update(self, t_ns: int, pulses_us: Sequence[float]) -> float:
        """The charge the held current drew up to ``t_ns``, then the current of the ESCs' ``pulses_us``
        from there on: the terminal volts at ``t_ns`` (faults applied)."""
        if t_ns > self.t_ns:
            self.drawn_mah += self.amps * (t_ns - self.t_ns) / 3.6e9  # (A x ns -> mAh)
            self.t_ns = t_ns
        self.amps = self.pack.amps(pulses_us)
        self.volts = self._terminal(t_ns)
        return self.volts

    def _terminal(self, t_ns: int) -> float:
        p = self.pack
        volts = p.cells * cell_volts(self.soc) - self.amps * p.internal_ohms
        return max(self.faults.apply(t_ns * 1e-9, (volts,))[0], 0.0)
