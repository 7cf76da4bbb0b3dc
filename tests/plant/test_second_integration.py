"""A second, independent integration of the same equations agrees with the FMU.

The reference below is written from the equations in docs/plant.md, not from the C code, and uses a
different formulation: attitude as a rotation matrix (dR/dt = R [w]x) rather than a quaternion, and
scipy's adaptive DOP853 at tight tolerances rather than fixed-step RK4.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rig.plant import Plant
from tests.plant.helpers import ARM, HOVER_PWM, IXX, IYY, IZZ, K_THRUST, K_TORQUE, MASS, G

OMEGA_MAX, TAU = 600.0, 0.02
DRAG = np.array([0.25, 0.3, 0.4])
HEALTH = np.array([1.0, 0.9, 1.0, 1.0])
GAIN, OFFSET = np.array([1.0, 1.02, 0.97, 1.0]), np.array([0.0, -0.01, 0.015, 0.0])
# "+" frame, FRD body: motor 1 front, 2 left, 3 rear, 4 right; 1 and 3 counter-clockwise.
ARMS = ARM * np.array([[1.0, 0.0], [0.0, -1.0], [-1.0, 0.0], [0.0, 1.0]])
SPIN = np.array([1.0, -1.0, 1.0, -1.0])
INERTIA = np.array([IXX, IYY, IZZ])
SEGMENT = 0.01  # inputs change every 10 ms
PARAMS = {"drag_n": DRAG[0], "drag_e": DRAG[1], "drag_d": DRAG[2], "pd0": -500.0,
          "roll0": 0.1, "pitch0": -0.05, "yaw0": 1.0,
          **{f"esc_gain{i + 1}": GAIN[i] for i in range(4)},
          **{f"esc_offset{i + 1}": OFFSET[i] for i in range(4)}}


def inputs_at(t: float) -> dict[str, float]:
    """A varied, deterministic input history (held constant over each 10 ms segment)."""
    u = {f"pwm{i}_us": HOVER_PWM + 25 * math.sin(2 * math.pi * (0.7 + 0.3 * i) * t + i)
         for i in range(1, 5)}
    u.update(wind_n=3 * math.sin(t), wind_e=-2.0, wind_d=0.5 * math.cos(2 * t),
             f_ext_n=0.3 * math.sin(3 * t), f_ext_e=0.1, f_ext_d=-0.2,
             tau_ext_x=1e-3 * math.cos(t), tau_ext_y=-5e-4, tau_ext_z=2e-3 * math.sin(t))
    u.update({f"motor_health{i + 1}": HEALTH[i] for i in range(4)})
    return u


def omega_cmd(pwm: np.ndarray) -> np.ndarray:
    x = np.clip((pwm - 1000.0) / 1000.0, 0.0, 1.0)
    return OMEGA_MAX * np.clip(GAIN * x + OFFSET, 0.0, 1.0)


def skew(w: np.ndarray) -> np.ndarray:
    return np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


def rhs(_t: float, x: np.ndarray, u: dict[str, float]) -> np.ndarray:
    v, R, w, om = x[3:6], x[6:15].reshape(3, 3), x[15:18], x[18:22]
    pwm = np.array([u[f"pwm{i}_us"] for i in range(1, 5)])
    thrust = K_THRUST * HEALTH * om**2
    torque = np.array([np.sum(-ARMS[:, 1] * thrust), np.sum(ARMS[:, 0] * thrust),
                       np.sum(SPIN * K_TORQUE * HEALTH * om**2)])
    torque += [u["tau_ext_x"], u["tau_ext_y"], u["tau_ext_z"]]
    wind = np.array([u["wind_n"], u["wind_e"], u["wind_d"]])
    f_ext = np.array([u["f_ext_n"], u["f_ext_e"], u["f_ext_d"]])
    acc = (R @ np.array([0, 0, -thrust.sum()]) - DRAG * (v - wind) + f_ext) / MASS + [0, 0, G]
    dw = (torque - np.cross(w, INERTIA * w)) / INERTIA
    dR = R @ skew(w)
    dom = (omega_cmd(pwm) - om) / TAU
    return np.concatenate([v, acc, dR.ravel(), dw, dom])


def euler_zyx(R: np.ndarray) -> tuple[float, float, float]:
    return (math.atan2(R[2, 1], R[2, 2]), -math.asin(R[2, 0]), math.atan2(R[1, 0], R[0, 0]))


def initial_state() -> np.ndarray:
    r, p, y = PARAMS["roll0"], PARAMS["pitch0"], PARAMS["yaw0"]
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    om0 = omega_cmd(np.array([inputs_at(0.0)[f"pwm{i}_us"] for i in range(1, 5)]))
    return np.concatenate([[0, 0, PARAMS["pd0"]], [0, 0, 0], (Rz @ Ry @ Rx).ravel(), [0, 0, 0], om0])


def test_fmu_agrees_with_scipy_over_five_seconds_of_varying_inputs():
    x = initial_state()
    with Plant(params=PARAMS, inputs=inputs_at(0.0)) as plant:
        worst = {"pos": 0.0, "vel": 0.0, "angle": 0.0, "rate": 0.0, "omega": 0.0}
        for k in range(500):
            u = inputs_at(k * SEGMENT)
            for name, value in u.items():
                plant.set_input(name, value)
            plant.run(SEGMENT, 1e-3)
            sol = solve_ivp(rhs, (0.0, SEGMENT), x, method="DOP853", rtol=1e-12, atol=1e-12, args=(u,))
            x = sol.y[:, -1]
            out = plant.outputs()
            R = x[6:15].reshape(3, 3)
            worst["pos"] = max(worst["pos"], np.max(np.abs(x[0:3] - [out["pn"], out["pe"], out["pd"]])))
            worst["vel"] = max(worst["vel"], np.max(np.abs(x[3:6] - [out["vn"], out["ve"], out["vd"]])))
            angle_err = np.subtract(euler_zyx(R), (out["roll"], out["pitch"], out["yaw"]))
            angle_err = (angle_err + math.pi) % (2 * math.pi) - math.pi
            worst["angle"] = max(worst["angle"], np.max(np.abs(angle_err)))
            worst["rate"] = max(worst["rate"], np.max(np.abs(x[15:18] - [out["p"], out["q"], out["r"]])))
            worst["omega"] = max(worst["omega"],
                                 np.max(np.abs(x[18:22] - [out[f"omega{i}"] for i in range(1, 5)])))
        assert not plant.on_ground and plant.output("pd") < -100  # stayed in free flight
        moved = abs(plant.output("pn")) + abs(plant.output("pe"))
    assert moved > 1.0  # the test exercised real motion
    # Measured: 3e-8 m, 3e-8 m/s, 4e-8 rad, 2e-7 rad/s (RK4 at 1 ms). A modelling error (a sign, an
    # arm, an axis) shows as 1e-2 or more within the first second.
    assert worst["pos"] < 1e-6, worst
    assert worst["vel"] < 1e-6, worst
    assert worst["angle"] < 1e-6, worst
    assert worst["rate"] < 1e-5, worst
    assert worst["omega"] < 1e-5, worst


def _trajectory(comm_step: float) -> np.ndarray:
    """Outputs at every 10 ms boundary with inputs changing every 10 ms."""
    rows = []
    with Plant(params=PARAMS, inputs=inputs_at(0.0)) as plant:
        for k in range(100):
            for name, value in inputs_at(k * SEGMENT).items():
                plant.set_input(name, value)
            plant.run(SEGMENT, comm_step)
            rows.append(plant.y.copy())
    return np.array(rows)


def test_communication_steps_of_0_1_1_and_10_ms_agree():
    fine, mid, coarse = (_trajectory(h) for h in (1e-4, 1e-3, 1e-2))
    # 1 ms and 10 ms steps both integrate in 1 ms sub-steps: the same arithmetic, bit for bit.
    assert np.array_equal(mid, coarse)
    scale = np.maximum(np.max(np.abs(fine), axis=0), 1.0)
    # What remains is RK4 truncation at 1 ms sub-steps (h/motor_tau = 0.05): about 1e-9 here.
    assert np.max(np.abs(fine - mid) / scale) < 1e-7
    assert np.max(np.abs(fine[-1] - fine[0])) > 1.0  # and the state did change


@pytest.mark.parametrize("h_max", [1e-3, 2.5e-4])
def test_internal_step_is_never_longer_than_h_max_step(h_max):
    # A 10 ms communication step must give the same result as ten 1 ms steps when h_max_step = 1 ms
    # (ten sub-steps either way), and a finer h_max_step must change the result only slightly.
    with Plant(params={**PARAMS, "h_max_step": h_max}, inputs=inputs_at(0.3)) as a, \
            Plant(params={**PARAMS, "h_max_step": h_max}, inputs=inputs_at(0.3)) as b:
        a.run(0.5, 0.01)
        b.run(0.5, h_max)
        assert np.allclose(a.y, b.y, rtol=1e-12, atol=1e-12)
