"""Plant physics against analytic truth: each test computes its expectation from textbook mechanics
and the constants of seed 001 / docs/design.md, never from the plant's own code."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rig.plant import Plant
from tests.plant.helpers import (
    ARM,
    DT,
    HOVER_PWM,
    IXX,
    IYY,
    IZZ,
    K_THRUST,
    K_TORQUE,
    MASS,
    MOTOR_TAU,
    OMEGA_HOVER,
    G,
    flying,
    pwm_for_omega,
    pwms,
)


def test_hover_speed_is_the_design_value():
    assert OMEGA_HOVER == pytest.approx(306.6, abs=0.05)  # docs/design.md §3


def test_hover_at_the_analytic_rotor_speed_holds_altitude():
    with flying(pd0=-10.0) as plant:
        plant.run(10.0, DT)
        out = plant.outputs()
    assert out["pd"] == pytest.approx(-10.0, abs=1e-9)
    assert out["vd"] == pytest.approx(0.0, abs=1e-9)
    assert sum(out[f"thrust{i}"] for i in range(1, 5)) == pytest.approx(MASS * G, rel=1e-12)
    assert out["omega1"] == pytest.approx(OMEGA_HOVER, rel=1e-12)
    assert max(abs(out[k]) for k in ("roll", "pitch", "yaw", "pn", "pe")) < 1e-9
    # Hovering, the accelerometer feels exactly the thrust: 1 g upwards (-z in FRD).
    assert out["fz"] == pytest.approx(-G, rel=1e-9)


def test_free_fall_follows_half_g_t_squared_until_the_ground_stops_it():
    h0 = 50.0
    with Plant(params={"pd0": -h0, "drag_n": 0.0, "drag_e": 0.0, "drag_d": 0.0}) as plant:
        for t_check in (0.5, 1.0, 2.0, 3.0):
            plant.run(t_check - plant.time, DT)
            assert plant.output("pd") == pytest.approx(-h0 + 0.5 * G * t_check**2, abs=1e-9)
            assert plant.output("vd") == pytest.approx(G * t_check, abs=1e-9)
            assert np.allclose([plant.output(k) for k in ("fx", "fy", "fz")], 0.0, atol=1e-12)
            assert not plant.on_ground
        t_impact = math.sqrt(2 * h0 / G)
        plant.run(round(t_impact - plant.time, 3) + 0.01, DT)
        assert plant.on_ground
        plant.run(2.0, DT)
        out = plant.outputs()
    assert out["pd"] == 0.0 and out["vd"] == 0.0 and out["on_ground"] == 1.0
    assert out["fz"] == pytest.approx(-G)


def test_free_fall_with_linear_drag_matches_the_exponential_solution():
    k, h0 = 0.5, 200.0
    with Plant(params={"pd0": -h0, "drag_d": k}) as plant:
        plant.run(4.0, DT)
        t = plant.time
        v_term = MASS * G / k
        v = v_term * (1 - math.exp(-k * t / MASS))
        z = v_term * (t - MASS / k * (1 - math.exp(-k * t / MASS)))
        assert plant.output("vd") == pytest.approx(v, rel=1e-9)
        assert plant.output("pd") == pytest.approx(-h0 + z, rel=1e-9)


def test_resting_on_the_ground_neither_drifts_nor_sinks():
    with Plant(inputs={"wind_n": 5.0, "wind_e": -3.0, **pwms(1400, 1400, 1400, 1400)}) as plant:
        assert plant.on_ground
        plant.run(10.0, DT)
        out = plant.outputs()
    for k in ("pn", "pe", "pd", "vn", "ve", "vd", "p", "q", "r", "roll", "pitch", "yaw"):
        assert out[k] == 0.0, k
    assert out["on_ground"] == 1.0
    assert out["fz"] == pytest.approx(-G) and out["pressure"] == pytest.approx(101325.0)


def test_takes_off_when_thrust_exceeds_weight():
    with Plant(inputs=pwms(*[HOVER_PWM + 50] * 4)) as plant:
        plant.run(1.0, DT)
        assert not plant.on_ground
        assert plant.output("pd") < -0.1


def _pair(delta: float) -> tuple[float, float]:
    """Pulse widths for two rotors at OMEGA_HOVER + delta and the speed that keeps the sum of their
    squares (so total thrust and reaction torque) at the hover value: no yaw torque, no climb."""
    fast = OMEGA_HOVER + delta
    return pwm_for_omega(fast), pwm_for_omega(math.sqrt(2 * OMEGA_HOVER**2 - fast**2))


def _steady_omegas(pwm):
    return [(p - 1000.0) / 1000.0 * 600.0 for p in pwm]


@pytest.mark.parametrize(
    ("pwm", "axis"),
    [
        ((HOVER_PWM, *_pair(10)[:1], HOVER_PWM, _pair(10)[1]), "roll"),  # 2 (left) faster than 4
        ((_pair(10)[0], HOVER_PWM, _pair(10)[1], HOVER_PWM), "pitch"),  # 1 (front) faster than 3
    ],
)
def test_motor_differences_roll_right_and_pitch_nose_up(pwm, axis):
    with flying(pwm) as plant:
        plant.run(0.1, DT)
        out = plant.outputs()
    assert out[axis] > 1e-2
    for other in {"roll", "pitch", "yaw"} - {axis}:
        assert out[other] == pytest.approx(0.0, abs=1e-12), other


def test_counter_clockwise_pair_faster_yaws_nose_right():
    # 1+3 (CCW seen from above) faster than 2+4, thrust moments balanced.
    pwm = (HOVER_PWM + 20, HOVER_PWM - 20, HOVER_PWM + 20, HOVER_PWM - 20)
    with flying(pwm) as plant:
        plant.run(0.3, DT)
        out = plant.outputs()
    assert out["yaw"] > 1e-3
    assert out["roll"] == pytest.approx(0.0, abs=1e-12) and out["pitch"] == pytest.approx(0.0, abs=1e-12)


def test_x_frame_turns_the_arms_by_45_degrees():
    # X frame: motor 2 front-left, motor 4 rear-right, so 2 faster than 4 rolls right and pitches up
    # by the same amount (Ixx == Iyy and the arm lies on the diagonal).
    fast, slow = _pair(10)
    with flying((HOVER_PWM, fast, HOVER_PWM, slow), frame=1) as plant:
        plant.run(0.05, DT)
        p, q, r = plant.output("p"), plant.output("q"), plant.output("r")
    w = _steady_omegas((HOVER_PWM, fast, HOVER_PWM, slow))
    moment = ARM / math.sqrt(2) * K_THRUST * (w[1] ** 2 - w[3] ** 2)
    assert p == pytest.approx(moment / IXX * 0.05, rel=1e-9)
    assert q == pytest.approx(p, rel=1e-12) and r == pytest.approx(0.0, abs=1e-12)


def test_izz_times_yaw_acceleration_equals_the_reaction_torque_sum():
    pwm = (HOVER_PWM + 40, HOVER_PWM - 40, HOVER_PWM + 40, HOVER_PWM - 40)
    w = _steady_omegas(pwm)
    tau_z = K_TORQUE * (w[0] ** 2 - w[1] ** 2 + w[2] ** 2 - w[3] ** 2)
    with flying(pwm) as plant:
        plant.run(0.5, DT)
        r = plant.output("r")
    assert IZZ * r / 0.5 == pytest.approx(tau_z, rel=1e-9)


@pytest.mark.parametrize(("motors", "inertia", "rate"), [((1, 3), IYY, "q"), ((2, 4), IXX, "p")])
def test_roll_and_pitch_accelerations_equal_the_thrust_moments(motors, inertia, rate):
    fast, slow = _pair(15)
    pwm = [HOVER_PWM] * 4
    pwm[motors[0] - 1], pwm[motors[1] - 1] = fast, slow
    w = _steady_omegas(pwm)
    moment = ARM * K_THRUST * (w[motors[0] - 1] ** 2 - w[motors[1] - 1] ** 2)
    with flying(tuple(pwm)) as plant:
        plant.run(0.2, DT)
        assert inertia * plant.output(rate) / 0.2 == pytest.approx(moment, rel=1e-9)


@pytest.mark.parametrize("tau", [MOTOR_TAU, 0.05])
def test_motor_reaches_63_percent_of_a_step_at_motor_tau(tau):
    with Plant(params={"motor_tau": tau}) as plant:  # on the ground, rotors stopped
        assert plant.output("omega1") == 0.0
        plant.set_input("pwm1_us", pwm_for_omega(300.0))
        plant.run(tau, DT / 10)
        assert plant.output("omega1") == pytest.approx(300.0 * (1 - math.exp(-1)), rel=1e-9)
        assert plant.output("omega2") == 0.0


@pytest.mark.parametrize(
    ("height", "pressure", "temperature"),
    [(0.0, 101325.0, 15.0), (100.0, 100129.4, 14.35), (500.0, 95460.8, 11.75),
     (1000.0, 89874.6, 8.5), (2000.0, 79495.2, 2.0)],  # docs/sensors.md §6 check values
)
def test_pressure_and_temperature_follow_isa(height, pressure, temperature):
    with Plant(params={"pd0": -height, "stand": 4}) as plant:
        assert plant.output("pressure") == pytest.approx(pressure, abs=0.05)
        assert plant.output("temperature") == pytest.approx(temperature, abs=1e-9)


def test_ground_pressure_parameter_scales_the_column():
    with Plant(params={"pd0": -1000.0, "stand": 4, "p_ground": 100000.0}) as plant:
        assert plant.output("pressure") == pytest.approx(89874.6 * 100000.0 / 101325.0, abs=0.05)


ALL_LOADS = {**pwms(1300, 1500, 1450, 1600), "tau_ext_x": 0.01, "tau_ext_y": -0.02, "tau_ext_z": 0.03,
             "f_ext_n": 3.0, "f_ext_d": -20.0, "wind_e": 4.0}


@pytest.mark.parametrize(("stand", "free_axis"), [(1, "roll"), (2, "pitch"), (3, "yaw")])
def test_single_axis_stands_move_only_their_axis(stand, free_axis):
    init = {"roll0": math.radians(-70), "pitch0": math.radians(10), "yaw0": math.radians(30)}
    if free_axis == "roll":
        init["pitch0"] = 0.0
    with Plant(params={"stand": stand, "pd0": -1.0, **init}, inputs=ALL_LOADS) as plant:
        plant.run(2.0, DT)
        out = plant.outputs()
    for axis in ("roll", "pitch", "yaw"):
        if axis == free_axis:
            assert abs(out[axis] - init[f"{axis}0"]) > 0.01
        else:
            assert out[axis] == pytest.approx(init[f"{axis}0"], abs=1e-12), axis
    assert (out["pn"], out["pe"], out["pd"]) == (0.0, 0.0, -1.0)
    assert out["on_ground"] == 0.0


def test_roll_stand_accelerates_by_the_roll_moment_over_ixx():
    w = _steady_omegas((1500, 1520, 1500, 1480))
    tau_x = ARM * K_THRUST * (w[1] ** 2 - w[3] ** 2)
    with Plant(params={"stand": 1}, inputs=pwms(1500, 1520, 1500, 1480)) as plant:
        plant.run(0.1, DT)
        assert plant.output("p") == pytest.approx(tau_x / IXX * 0.1, rel=1e-9)
        assert plant.output("roll") == pytest.approx(0.5 * tau_x / IXX * 0.1**2, rel=1e-9)


def test_attitude_gimbal_holds_position_and_turns_freely():
    with Plant(params={"stand": 4, "pn0": 1.0, "pd0": -2.0}, inputs=ALL_LOADS) as plant:
        plant.run(1.0, DT)
        out = plant.outputs()
    assert (out["pn"], out["pe"], out["pd"], out["vn"], out["vd"]) == (1.0, 0.0, -2.0, 0.0, 0.0)
    assert min(abs(out["roll"]), abs(out["pitch"]), abs(out["yaw"])) > 1e-3


def test_magnetometer_and_accelerometer_truth_rotate_into_the_body():
    mag = (0.25, 0.0, 0.433)
    with Plant(params={"stand": 4, "yaw0": math.radians(90)}) as plant:
        # Nose east: body x = east, body y = south.
        got = [plant.output(k) for k in ("mag_x", "mag_y", "mag_z")]
        assert np.allclose(got, (mag[1], -mag[0], mag[2]), atol=1e-12)
    roll = math.radians(30)
    with Plant(params={"stand": 1, "roll0": roll}) as plant:
        got = [plant.output(k) for k in ("fx", "fy", "fz")]
        assert np.allclose(got, (0.0, -G * math.sin(roll), -G * math.cos(roll)), atol=1e-12)

