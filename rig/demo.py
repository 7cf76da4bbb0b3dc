"""``rig demo``: the plant FMU on its own, no DUT and no session, in a few seconds.

It flies seed 000's roll-stand test (released at -70 deg, throttle 1400 us), levelled by a minimal
stand-in for the seed's double-loop PID (angle loop outside, rate loop inside, eq. 9-10 and the '+'
mixer of eq. 15); an open-loop hover at the exact hover pulse width, which holds its altitude exactly;
then the same with a 1 % weaker ESC on motor 2, which an uncontrolled vehicle cannot survive. It prints
a short summary. The main job, the scenario library flown by the reference flight controller, is
``rig run`` (``make demo``).
"""

from __future__ import annotations

import math
import time

from rig.plant import Plant
from rig.plant.variables import G0

DT = 1e-3          # plant communication step
CONTROL_DIV = 4    # stand-in controller at 250 Hz


def hover_pwm(params: dict[str, float] | None = None) -> float:
    """Pulse width whose steady rotor speed makes total thrust equal weight (ESC gain 1, offset 0)."""
    p = {"mass": 1.2, "k_thrust": 3.13e-5, "omega_max": 600.0, "esc_min_us": 1000.0,
         "esc_max_us": 2000.0, "gravity": G0, **(params or {})}
    omega = math.sqrt(p["mass"] * p["gravity"] / (4 * p["k_thrust"]))
    return p["esc_min_us"] + omega / p["omega_max"] * (p["esc_max_us"] - p["esc_min_us"])


def roll_stand_release(duration: float = 5.0) -> dict[str, float]:
    """Seed 000's roll-stand test with the stand-in controller; returns the response's key numbers."""
    throttle, limit = 1400.0, 100.0
    kp_angle, kp_rate, ki_rate, kd_rate = 5.0, 15.0, 5.0, 0.3
    integral = prev_err = 0.0
    rolls: list[tuple[float, float]] = []
    with Plant(params={"stand": 1, "roll0": math.radians(-70)},
               inputs={f"pwm{i}_us": throttle for i in range(1, 5)}) as plant:
        iroll, ip = plant.y_index["roll"], plant.y_index["p"]
        u2, u4 = plant.u_index["pwm2_us"], plant.u_index["pwm4_us"]
        for k in range(int(round(duration / DT))):
            if k % CONTROL_DIV == 0:
                ts = DT * CONTROL_DIV
                rate_sp = kp_angle * (0.0 - plant.y[iroll])
                err = rate_sp - plant.y[ip]
                integral += err * ts
                out = kp_rate * err + ki_rate * integral + kd_rate * (err - prev_err) / ts
                prev_err = err
                out = max(-limit, min(limit, out))
                plant.u[u2], plant.u[u4] = throttle + out, throttle - out
            plant.step(DT)
            rolls.append((plant.time, math.degrees(plant.y[iroll])))
    overshoot = max(r for _, r in rolls)
    settled = next((t for i, (t, _) in enumerate(rolls) if all(abs(r) < 2.0 for _, r in rolls[i:])),
                   math.inf)
    return {"overshoot_deg": overshoot, "settle_2deg_s": settled, "final_deg": rolls[-1][1]}


def open_loop_hover(duration: float = 10.0, weak_motor2: float = 1.0) -> dict[str, float]:
    """Starts at 10 m with every ESC at the hover pulse width; reports how far the vehicle strays."""
    pwm = hover_pwm()
    with Plant(params={"pd0": -10.0, "esc_gain2": weak_motor2},
               inputs={f"pwm{i}_us": pwm for i in range(1, 5)}) as plant:
        plant.run(duration, DT)
        out = plant.outputs()
    return {"altitude_change_m": -(out["pd"] + 10.0), "roll_deg": math.degrees(out["roll"]),
            "on_ground": out["on_ground"]}


def main() -> int:
    start = time.perf_counter()
    stand = roll_stand_release()
    hover = open_loop_hover()
    weak = open_loop_hover(weak_motor2=0.99)
    wall = time.perf_counter() - start
    print("rig demo: the plant FMU alone, no DUT (`rig run` flies the scenario library against the "
          "reference FC)")
    print(f"  seed 000 roll stand, released at -70 deg, throttle 1400 us, stand-in PID:\n"
          f"    overshoot {stand['overshoot_deg']:+.1f} deg, inside +-2 deg after "
          f"{stand['settle_2deg_s']:.2f} s, roll after 5 s {stand['final_deg']:+.3f} deg")
    print(f"  open-loop hover at {hover_pwm():.2f} us from 10 m, 10 s:\n"
          f"    altitude change {_signed(hover['altitude_change_m'])} m, "
          f"roll {_signed(hover['roll_deg'])} deg")
    print(f"  same with motor 2's ESC 1 pct weak:\n"
          f"    altitude change {weak['altitude_change_m']:+.1f} m, roll {weak['roll_deg']:+.1f} deg, "
          f"on ground: {bool(weak['on_ground'])}")
    print(f"  25 s of flight simulated in {wall:.2f} s wall ({25 / wall:.1f}x real time)")
    return 0


def _signed(x: float) -> str:
    """A small signed number; an exact zero as +0 (IEEE's -0.0 printed as "-0.00e+00" reads as a
    drift that is not there)."""
    return "+0" if x == 0 else f"{x:+.2e}"
