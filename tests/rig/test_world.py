"""The world takes what a scenario may change by name, and nothing else (issue 17: nothing outside the
world reaches into the plant's input buffer)."""

from __future__ import annotations

import ctypes

import pytest

from rig.plant.variables import MOTORS, PWM_INPUTS, SCENARIO_INPUTS
from rig.world import PwmChannel, World


def test_scenario_inputs_act_by_name_and_others_are_refused() -> None:
    world = World.at_rest(params={"stand": 0, "pd0": -10.0}, noise=False)
    try:
        assert set(SCENARIO_INPUTS) >= {"wind_n", "f_ext_d", "tau_ext_z", "motor_health1"}
        assert not set(SCENARIO_INPUTS) & set(PWM_INPUTS) and len(PWM_INPUTS) == MOTORS
        world.set_input("f_ext_e", 2.4)  # 2 m/s^2 east on 1.2 kg, against 0.25 N.s/m of drag
        world.advance_to(500_000_000)
        assert 0.8 < world.outputs()["ve"] < 1.0
        with pytest.raises(KeyError, match="'pwm1_us' is not an input of the world"):
            world.set_input("pwm1_us", 1500.0)  # the DUT's (or a capture link's): set_motor
        with pytest.raises(KeyError, match="'wind_x'"):
            world.set_input("wind_x", 1.0)
    finally:
        world.close()


def test_a_probe_reads_outputs_then_motors() -> None:
    world = World.at_rest(noise=False)
    try:
        world.set_motor(2, 1234.0)
        probe = world.probe(["pd", "qw"], extras=2, rows=2)
        for k in range(5):  # past the room made at once: the table grows, the rows already made stay
            probe.record((float(k), -1.0))
        assert probe.rows().tolist() == [[0.0, 1.0, 0.0, 0.0, 1234.0, 0.0, float(k), -1.0] for k in range(5)]
        with pytest.raises(ValueError, match="2 extras, not 3"):
            probe.record((1.0, 2.0, 3.0))
        assert probe.count == 5
    finally:
        world.close()


def test_a_pwm_channel_keeps_any_duty_the_shim_can_send_in_its_cell() -> None:
    """The duty is a 64-bit cell the fast path writes in place; the shim's field is unsigned 64-bit, so
    every value it can send is kept as sent, and the pulse an ESC sees is clamped to the period."""
    ch = PwmChannel(exported=True, period_ns=2_500_000, enabled=True)
    cell = (ctypes.c_uint64 * 1).from_address(ch.duty_addr)
    for duty, pulse in ((1_500_000, 1500.0), (2**63, 2500.0), (2**64 - 1, 2500.0), (0, 0.0)):
        ch.duty_ns = duty
        assert ch.duty_ns == duty == int(cell[0])
        assert ch.pulse_us() == pulse
    ch.inversed = True
    assert ch.pulse_us() == 2500.0  # (duty 0, inversed: high all period)
    cell[0] = 1_000_000  # as C writes it
    assert ch.duty_ns == 1_000_000 and ch.pulse_us() == 1500.0
    assert "duty_ns=1000000" in repr(ch)


def test_the_fc_s_output_order_decides_which_motor_a_channel_drives() -> None:
    # MultiWii's QUADX outputs: rear right, front right, rear left, front left; the plant's X motors are
    # 1 front-right, 2 front-left, 3 rear-left, 4 rear-right: outputs 1..4 drive motors 4, 1, 3, 2
    world = World.at_rest(noise=False, params={"frame": 1}, motor_order=(4, 1, 3, 2))
    try:
        world.set_motor(0, 1100.0)  # a capture link's output 1
        world.pwm[1] = PwmChannel(exported=True, period_ns=2_500_000, duty_ns=1_300_000, enabled=True)
        world.apply_pwm(1)  # the DUT's sysfs channel 1 (its output 2)
        probe = world.probe([], rows=1)
        probe.record(())
        # motors 1..4 in the plant's order: output 2 (front right) is motor 1, output 1 (rear right) motor 4
        assert probe.rows().tolist() == [[1300.0, 0.0, 0.0, 1100.0]]
    finally:
        world.close()


def baro_conversions_at_rest(osr_noise: bool, n: int = 20) -> list[bytes]:
    """n pressure conversions (D1, OSR 4096) of a world at rest, each read 10 ms after its start, as
    ArduPilot's MS5611 driver reads them; the plant sits on the ground, so its pressure never moves."""
    from rig.emulators.i2c_bus import read, write

    world = World.at_rest(seed=5, baro_osr_noise=osr_noise)
    try:
        out = []
        for k in range(n):
            t = 1_000_000_000 + k * 20_000_000
            world.transfer([write(0x77, 0x48)], t)  # convert D1 at OSR 4096 (0x40 + 2 * 4)
            out.append(world.transfer([write(0x77, 0x00), read(0x77, 3)], t + 10_000_000)[-1])
        return out
    finally:
        world.close()


def test_a_barometer_at_rest_reads_its_datasheet_noise_when_asked() -> None:
    # a real MS5611 at rest does not read one pressure for ever (1.2 Pa RMS at OSR 4096, its
    # datasheet); ArduPilot judges a barometer whose reading has not changed for 2 s stuck, unhealthy
    noisy = baro_conversions_at_rest(osr_noise=True)
    assert all(len(d) == 3 and d != b"\x00\x00\x00" for d in noisy)
    assert len(set(noisy)) >= 3
    d1 = [int.from_bytes(d, "big") for d in noisy]
    assert max(d1) - min(d1) < 0.01 * min(d1)  # noise, not another altitude
    quiet = baro_conversions_at_rest(osr_noise=False)
    assert len(set(quiet)) == 1  # (the default: exact, a reading checked to the pascal)
