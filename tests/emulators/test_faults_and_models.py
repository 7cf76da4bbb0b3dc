"""Faults (one vocabulary, scheduled in sim time) and sensor error models."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rig.emulators.faults import Fault, FaultSet
from rig.emulators.i2c_bus import I2CNack, read, write
from rig.emulators.sensor_models import (
    IMU_TRUTH,
    AxisErrors,
    BaroModel,
    ImuModel,
    MagModel,
    Normals,
    TruthRow,
)
from rig.world import World
from tests.emulators.boards import make_board, s16

G0 = 9.80665
REST = {"fx": 0.0, "fy": 0.0, "fz": -G0, "p": 0.0, "q": 0.0, "r": 0.2, "temperature": 15.0,
        "mag_x": 0.25, "mag_y": 0.0, "mag_z": 0.433, "pressure": 101325.0}


def rig(gyro_faults=(), bus_faults=(), device="mpu", seed=0):
    imu = ImuModel(lambda t: REST, gyro_faults=FaultSet(list(gyro_faults), seed=seed), seed=seed)
    b = make_board(imu, MagModel(lambda t: REST), BaroModel(lambda t: REST), "direct", dlpf=False,
                   bus_faults={device: FaultSet(list(bus_faults), seed=seed)})
    b.bus.transfer([write(0x68, 0x6B, 0x00), write(0x68, 0x1B, 0x08)], 0.0)  # wake, 500 dps
    b.bus.transfer([write(0x1E, 0x02, 0x00)], 0.0)
    return b


def gyro_z(bus, t):
    d = bus.transfer([write(0x68, 0x47), read(0x68, 2)], t)[0]
    return s16(d[0], d[1])


def test_level_resting_imu_reads_plus_one_g_and_the_yaw_rate_on_sensor_z():
    b = rig()
    d = b.bus.transfer([write(0x68, 0x3B), read(0x68, 14)], 0.01)[0]
    v = [s16(d[i], d[i + 1]) for i in range(0, 14, 2)]
    assert v[0:3] == [0, 0, 16384]                       # +1 g on sensor Z
    assert v[6] == round(-math.degrees(0.2) * 65.5)       # body yaw rate r maps to -z (z up)


def baseline():
    return gyro_z(rig().bus, 0.5)


@pytest.mark.parametrize(("fault", "check"), [
    (Fault("stuck", 0.3, 0.6), lambda inside, base: inside == base),
    (Fault("bias_step", 0.3, 0.6, magnitude=0.1), lambda i, b: abs(i - b - math.degrees(0.1) * 65.5) <= 1),
    (Fault("scale_error", 0.3, 0.6, magnitude=2.0), lambda i, b: abs(i - 2 * b) <= 1),
    # 0.5 rad/s per s for 0.1 s
    (Fault("drift", 0.3, 0.6, magnitude=0.5), lambda i, b: abs(i - b - math.degrees(0.05) * 65.5) <= 1),
    (Fault("noise_burst", 0.3, 0.6, magnitude=0.5), lambda i, b: abs(i - b) > 5),
])
def test_signal_faults_change_the_reading_only_inside_their_window(fault, check):
    base = baseline()
    b = rig(gyro_faults=[fault])
    assert gyro_z(b.bus, 0.2) == base
    inside = gyro_z(b.bus, 0.4)
    assert check(inside, base), (inside, base)
    assert gyro_z(b.bus, 0.7) == base  # over: back to normal


def test_stuck_holds_the_value_from_its_start():
    imu_truth = dict(REST)
    imu = ImuModel(lambda t: {**imu_truth, "r": t}, gyro_faults=FaultSet([Fault("stuck", 0.3, 0.6)]))
    b = make_board(imu, lambda t: (0, 0, 0), BaroModel(lambda t: REST), "direct", dlpf=False)
    b.bus.transfer([write(0x68, 0x6B, 0x00), write(0x68, 0x1B, 0x08)], 0.0)
    first = gyro_z(b.bus, 0.31)
    assert gyro_z(b.bus, 0.5) == first
    assert gyro_z(b.bus, 0.65) != first


def test_delay_fault_returns_the_past():
    imu = ImuModel(lambda t: {**REST, "r": t}, gyro_faults=FaultSet([Fault("delay", 0.3, 0.9, 0.2)]))
    b = make_board(imu, lambda t: (0, 0, 0), BaroModel(lambda t: REST), "direct", dlpf=False)
    b.bus.transfer([write(0x68, 0x6B, 0x00), write(0x68, 0x1B, 0x08)], 0.0)
    for k in range(1, 80):
        gyro_z(b.bus, k * 0.01)
    assert gyro_z(b.bus, 0.8) == round(-math.degrees(0.6) * 65.5)


@pytest.mark.parametrize("device", ["mpu", "hmc", "baro"])
def test_off_fault_nacks_in_its_window_and_the_bus_recovers(device):
    addr = {"mpu": 0x68, "hmc": 0x1E, "baro": 0x77}[device]
    b = rig(bus_faults=[Fault("off", 0.3, 0.6)], device=device)
    b.bus.transfer([write(addr)], 0.2)
    with pytest.raises(I2CNack):
        b.bus.transfer([write(addr)], 0.4)
    other = 0x77 if addr != 0x77 else 0x68
    b.bus.transfer([write(other)], 0.4)  # the rest of the bus works meanwhile
    b.bus.transfer([write(addr)], 0.6)


def test_intermittent_fault_nacks_part_of_the_time():
    b = rig(bus_faults=[Fault("intermittent", 0.0, 1.0, period=0.1, duty=0.3)], device="baro")
    answers = []
    for k in range(100):
        try:
            b.bus.transfer([write(0x77)], (k + 0.5) * 0.01)  # mid-slot: clear of phase edges
            answers.append(True)
        except I2CNack:
            answers.append(False)
    assert answers.count(False) == 30
    b.bus.transfer([write(0x77)], 1.0)


def test_garbage_fault_scrambles_bytes_then_stops():
    b = rig(bus_faults=[Fault("garbage", 0.3, 0.6)], device="mpu")
    who = lambda t: b.bus.transfer([write(0x68, 0x75), read(0x68, 8)], t)[0]  # noqa: E731
    assert who(0.2)[0] == 0x68
    assert who(0.4) != who(0.2)
    assert who(0.7)[0] == 0x68


def test_fault_schedule_is_validated():
    with pytest.raises(ValueError, match="unknown fault kind 'melt'"):
        Fault("melt", 0.0)
    with pytest.raises(ValueError, match="end .* must be after start"):
        Fault("off", 2.0, 1.0)


def test_models_are_deterministic_for_a_seed_and_differ_across_seeds():
    noisy = AxisErrors(noise_density=0.01, bias_random_walk=0.001)
    def run(seed):
        m = ImuModel(lambda t: REST, gyro=noisy, seed=seed)
        return [m(k * 0.001).gyro for k in range(100)]
    assert run(3) == run(3)
    assert run(3) != run(4)


def test_white_noise_has_the_density_it_was_given():
    density, dt = 0.005, 0.001
    m = ImuModel(lambda t: REST, gyro=AxisErrors(noise_density=density), seed=7)
    z = np.array([m(k * dt).gyro[0] for k in range(20001)][1:])
    assert np.std(z) == pytest.approx(density / math.sqrt(2 * dt), rel=0.03)


def test_bias_random_walk_grows_like_sqrt_time():
    rw = 0.01
    finals = []
    for seed in range(200):
        m = ImuModel(lambda t: REST, gyro=AxisErrors(bias_random_walk=rw), seed=seed)
        for k in range(101):
            g = m(k * 0.01).gyro
        finals.append(g[0])
    assert np.std(finals) == pytest.approx(rw * math.sqrt(1.0), rel=0.15)


def test_mounting_scale_bias_and_magnetic_disturbance():
    errors = AxisErrors(scale_misalignment=((1.02, 0.01, 0), (0, 0.98, 0), (0, 0, 1.0)), bias=(0.05, 0, 0))
    m = MagModel(lambda t: REST, errors=errors, disturbance=lambda t: (0.1, 0.0, 0.0) if t > 1 else (0, 0, 0))
    x0 = m(0.5)
    x1 = m(1.5)
    # sensor x = 1.02 * body x + 0.01 * sensor-y(= -body y) + bias
    assert x0[0] == pytest.approx(1.02 * 0.25 + 0.05)
    assert x1[0] - x0[0] == pytest.approx(1.02 * 0.1)
    assert x0[2] == pytest.approx(-0.433)  # body down is sensor -z


def test_the_imu_reads_the_worlds_table_and_a_truth_function_alike() -> None:
    # the world hands the IMU its plant history as a table that C reads by column; tests and users hand
    # a function of time. The plant's output layout puts none of fx..r, temperature where IMU_TRUTH has them.
    world = World.at_rest(seed=1)
    world.plant.u[:] = 1500.0  # something moves: the rows differ from step to step
    world.advance_to(50_000_000)
    assert [world.plant.y_index[n] for n in IMU_TRUTH] != list(range(7))
    accel = AxisErrors(noise_density=0.01, bias=(0.1, 0.0, 0.0))
    gyro = AxisErrors(noise_density=0.001, temp_coefficient=1e-3)
    source = world.board.mpu.source
    assert isinstance(source, ImuModel)
    by_table = ImuModel(source.truth, seed=3, accel=accel, gyro=gyro)
    by_function = ImuModel(world.truth, seed=3, accel=accel, gyro=gyro)
    samples = [(by_table(t), by_function(t)) for t in np.arange(0.02, 0.05, 0.0007)]
    assert all(a == b for a, b in samples) and samples[0][0] != samples[-1][0]
    no_temp = ImuModel(lambda t: TruthRow({"fx": 0, "fy": 1, "fz": 2, "p": 3, "q": 4, "r": 5}, [0.0] * 6))
    assert no_temp(0.0).temperature_c == 15.0 + no_temp.die_offset_c   # the default air temperature


def test_the_error_model_is_the_formula_of_axis_errors() -> None:
    """A second implementation, sample by sample, drawing from the same generator stream as the model:
    v = S·Mount·truth + bias + walk + k·(T - 25) + noise, walk += rw·√dt·z, noise = nd/√(2 dt)·z."""
    e = AxisErrors(mounting=((0, 1, 0), (1, 0, 0), (0, 0, -1)),
                   scale_misalignment=((1.02, 0.003, 0), (0.001, 0.97, 0.002), (0, 0.004, 1.01)),
                   bias=(0.3, -0.2, 0.1), bias_random_walk=0.05, noise_density=0.02, temp_coefficient=0.004)
    def truth(t):
        return {"fx": math.sin(7 * t), "fy": 0.5 - t, "fz": -G0, "p": 0.0, "q": 0.0, "r": 0.0,
                "temperature": 20.0 + 30.0 * t}
    model = ImuModel(truth, accel=e, seed=5)
    z = np.random.default_rng(np.random.default_rng(5).integers(2**63)).standard_normal(6 * 1100)
    mix = np.array(e.scale_misalignment) @ np.array(e.mounting)
    walk, last, j = np.zeros(3), None, 0
    times = np.cumsum([0.001 if k % 7 else 0.0042 for k in range(1100)])  # irregular, as after sleeps
    for t in times:
        tr = truth(t)
        temp = tr["temperature"] + model.die_offset_c
        dt = 0.0 if last is None else t - last
        last = t
        if dt > 0:
            walk = walk + e.bias_random_walk * math.sqrt(dt) * z[j:j + 3]
            j += 3
        v = mix @ [tr["fx"], tr["fy"], tr["fz"]] + e.bias + walk + e.temp_coefficient * (temp - 25.0)
        if dt > 0:
            v = v + e.noise_density / math.sqrt(2 * dt) * z[j:j + 3]
            j += 3
        got = model(t)
        assert got.accel == pytest.approx(v, rel=1e-12, abs=1e-12)
        assert got.temperature_c == temp
    assert j > 2 * 3072  # the model took its normals in several blocks: the stream runs on across them


def test_sample_block_refuses_a_buffer_it_cannot_fill() -> None:
    model = ImuModel(lambda t: REST)
    with pytest.raises(ValueError, match="7 columns"):
        model.sample_block([0.0], np.zeros((4, 6)))
    with pytest.raises(ValueError, match="0..2 samples"):
        model.sample_block([0.0, 0.001, 0.002], np.zeros((2, 7)))


def test_normals_taken_are_the_generators_sequence_across_blocks_and_readers() -> None:
    """Normals.take (from its list of the block) gives the generator's own values in order: across
    block boundaries, and after another reader moved ``pos`` (C reads a channel's block in place)."""
    normals = Normals(np.random.default_rng(5))
    block = normals.BLOCK  # (compiled by mypyc, the class's attribute is read on an instance)
    want = np.random.default_rng(5).standard_normal(3 * block).tolist()
    got: list[float] = []
    while len(got) < block + 10:
        got += normals.take(3)
    normals.pos += 7  # another reader used seven
    del want[len(got):len(got) + 7]
    while len(got) < 2 * block + 100:
        got += normals.take(5)
    assert got == want[:len(got)]
