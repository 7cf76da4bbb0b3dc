"""The flight pack's model (rig/battery.py) against truth worked by hand: the open-circuit table's ends
and a point between two of its rows, Ohm's law for the sag, coulomb counting for the charge drawn (the
current's integral, each current held to the next update), the throttle's 1.5 power; the faults on its
volts from a scenario file; and a battery fault where there is no battery."""

from __future__ import annotations

from pathlib import Path

import pytest

from rig.battery import Pack, PackState, cell_volts, state_of_charge, throttle
from rig.emulators.faults import Fault, FaultSet, TargetedFault
from rig.scenarios.schema import ScenarioError, load
from rig.world import World

#: a 3S pack, 1000 mAh, 0.05 ohm, 10 A a motor at full throttle, 0.5 A for the rest
PACK = Pack(volts=12.6, cells=3, capacity_mah=1000.0, internal_ohms=0.05, motor_amps=10.0, idle_amps=0.5)
MS = 1_000_000


def test_the_open_circuit_table() -> None:
    assert cell_volts(1.0) == 4.20 and cell_volts(0.0) == 3.27
    assert cell_volts(1.5) == 4.20 and cell_volts(-0.1) == 3.27  # (clamped)
    # halfway between the rows 0.50 (3.84 V) and 0.55 (3.85 V)
    assert cell_volts(0.525) == pytest.approx(3.845)
    assert state_of_charge(4.20) == pytest.approx(1.0) and state_of_charge(3.27) == 0.0
    assert state_of_charge(3.845) == pytest.approx(0.525)
    with pytest.raises(ValueError, match="outside a LiPo's 3.27..4.2 V"):
        state_of_charge(4.3)


def test_throttle_and_current() -> None:
    assert [throttle(us) for us in (0.0, 900.0, 1000.0, 1250.0, 2000.0, 2100.0)] == [0, 0, 0, 0.25, 1, 1]
    # 0.5 A idle + 10 A x 1 (full) + 10 A x 0.25^1.5 (= 1.25 A) + two stopped
    assert PACK.amps([2000.0, 1250.0, 1000.0, 0.0]) == pytest.approx(0.5 + 10.0 + 1.25)


def test_ohms_law_sag_and_coulomb_counting() -> None:
    p = PackState(PACK)
    # at the start: the open-circuit 12.6 V less the idle 0.5 A through 0.05 ohm
    assert p.volts == pytest.approx(12.6 - 0.5 * 0.05)
    # all four at full from 0: 40.5 A, a sag of 2.025 V at once (nothing drawn yet but the idle's 0 s)
    assert p.update(0, [2000.0] * 4) == pytest.approx(12.6 - 40.5 * 0.05)
    # 36 s at 40.5 A: 405 mAh of 1000, 40.5 % drawn; the state of charge 0.595, between the rows 0.55
    # (3.85 V) and 0.60 (3.87 V): 3.868 V a cell; then all stopped: the idle's sag only
    v = p.update(36_000 * MS, [1000.0] * 4)
    assert p.drawn_mah == pytest.approx(405.0)
    assert p.soc == pytest.approx(0.595)
    assert v == pytest.approx(3 * 3.868 - 0.5 * 0.05)
    # 18 s more at the idle 0.5 A: 2.5 mAh more (the current held is the last update's, not the first's)
    p.update(54_000 * MS, [1000.0] * 4)
    assert p.drawn_mah == pytest.approx(407.5)


def test_an_empty_pack_stays_empty() -> None:
    p = PackState(Pack(volts=9.81, cells=3, capacity_mah=100.0, internal_ohms=0.0, motor_amps=10.0))
    assert p.soc == 0.0
    assert p.update(3_600_000 * MS, [2000.0]) == pytest.approx(9.81) and p.soc == 0.0


def test_faults_on_the_terminal_volts() -> None:
    faults = FaultSet()
    faults.add(Fault("bias_step", 1.0, 2.0, magnitude=-1.5))
    faults.add(Fault("scale_error", 3.0, 4.0, magnitude=0.5))
    faults.add(Fault("stuck", 5.0, 6.0))
    p = PackState(Pack(12.6, 3, 1000.0, 0.0, 10.0), faults)
    s = 1_000_000_000
    assert p.update(s // 2, []) == pytest.approx(12.6)
    assert p.update(3 * s // 2, []) == pytest.approx(11.1)
    assert p.update(7 * s // 2, []) == pytest.approx(6.3)
    stuck = p.update(5 * s, [])
    assert p.update(5 * s + s // 2, [2000.0]) == stuck  # (full throttle: the reading frozen)
    assert p.update(6 * s, [2000.0]) < stuck


SCENARIO = """[scenario]
name = "battery fault"
duration = 2.0
[[faults]]
target = "battery"
kind = "{kind}"
start = 0.5
magnitude = -1.0
[[criteria]]
name = "level"
metric = "max"
signal = "battery_volts"
max = 13.0
"""


def test_a_scenario_faults_the_battery(tmp_path: Path) -> None:
    path = tmp_path / "s.toml"
    path.write_text(SCENARIO.format(kind="bias_step"))
    f = load(path).faults[0]
    assert f.target == "battery" and f.fault.kind == "bias_step" and f.fault.magnitude == -1.0
    for kind in ("off", "intermittent", "garbage"):
        path.write_text(SCENARIO.format(kind=kind))
        with pytest.raises(ScenarioError) as e:
            load(path)
        assert e.value.key == "faults[0]" and "means nothing on the battery's volts" in str(e.value)
    with pytest.raises(ValueError, match="a delay fault means nothing"):
        TargetedFault("battery", Fault("delay", 0.5, magnitude=0.1))


def test_a_battery_fault_needs_a_battery() -> None:
    faults = FaultSet()
    faults.add(Fault("bias_step", 0.5, magnitude=-1.0))
    with pytest.raises(ValueError, match="a fault on the battery, and no battery"):
        World.at_rest(faults={"battery": faults})
    world = World.at_rest(faults={"battery": faults}, battery=PACK)
    try:
        assert world.battery is not None and world.battery.faults is faults
    finally:
        world.close()
