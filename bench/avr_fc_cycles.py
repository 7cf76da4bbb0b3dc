"""The AVR reference firmware's cycle budget: cycles per call of each part of its loop, counted in
simavr by the firmware's own timer (bench/avr_fc_cycles.c: timer 1 at the CPU clock, canned samples of a
moving vehicle), the TWI bus time of a cycle computed from its bytes at 400 kHz (simavr has no chips to
answer; the MCU tier's runs report the measured loop in the telemetry's loop_us), a single loop's
headroom at 250 Hz and at the estimator's rate (AVR_RATE_HZ in dut/avr/board.h), each slot of the
firmware's loop (the rate loop AVR_INNER_PER_EST times a cycle, the estimator and the outer loops in
alternate slots) against its budget; then flash, RAM and EEPROM of build/avr/fc.elf.

Why: the ATmega2560 has no FPU; every float operation is a libm call of 100-3000 cycles, so which
estimator fits, and at what loop rate, is a measurement, not a guess. Simavr counts cycles exactly, so
the numbers do not depend on this machine's speed. Prints; asserts nothing.

    python bench/avr_fc_cycles.py
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
ELF = REPO / "build" / "avr" / "bench.elf"
FC_ELF = REPO / "build" / "avr" / "fc.elf"
F_CPU = 16_000_000
TWI_HZ = 400_000


def bench_lines(elf: Path) -> list[str]:
    """The bench firmware's USART0 lines under simavr (it ends asleep with interrupts off)."""
    done = subprocess.run(["simavr", "-m", "atmega2560", "-f", str(F_CPU), str(elf)], capture_output=True,
                          text=True, timeout=300)
    text = re.sub(r"\x1b\[[0-9;]*m", "", done.stdout + done.stderr)
    return [line.rstrip(".") for line in text.splitlines() if line.startswith(("B ", "T "))]


def parts(lines: list[str]) -> dict[str, int]:
    return {f[1]: int(f[2]) for f in (line.split() for line in lines) if f[0] == "B" and len(f) == 3}


def twi_cycles(nbytes: int) -> int:
    """CPU cycles a transfer of nbytes (address bytes included) holds the loop: 9 SCL periods a byte,
    plus a START/STOP's worth, at 400 kHz."""
    return round((9 * nbytes + 3) * F_CPU / TWI_HZ)


def board_rate() -> int:
    m = re.search(r"#define AVR_RATE_HZ (\d+)", (REPO / "dut" / "avr" / "board.h").read_text())
    return int(m.group(1)) if m else 250


def board_inner() -> int:
    m = re.search(r"#define AVR_INNER_PER_EST (\d+)", (REPO / "dut" / "avr" / "board.h").read_text())
    return int(m.group(1)) if m else 1


def main() -> int:
    subprocess.run(["make", "-s", "-C", str(REPO / "dut"), "avr", "avr-bench"], check=True)
    p = parts(bench_lines(ELF))
    burst = twi_cycles(1 + 1 + 1 + 25)  # MPU: address+W, register, address+R, 25 bytes (0x36..0x4E)
    baro_io = twi_cycles(2) + twi_cycles(1 + 1 + 1 + 3)  # a conversion command; an ADC read
    rows = [
        ("estimator: seed-000 quaternion CF (+ Euler)", p["estimator_cf"]),
        ("estimator: seed-002 Mahony DCM (+ Euler)", p["estimator_mahony"]),
        ("estimator: EKF, 7 states (+ Euler)", p["estimator_ekf"]),
        ("flight_sense (calibration, Mahony, vertical acceleration)", p["flight_sense_mahony"]),
        ("  flight_measure (the gyro check, calibration)", p["flight_measure"]),
        ("  flight_estimate (Mahony, vertical acceleration)", p["flight_estimate_mahony"]),
        ("flight_control (RC, arming, 7 PIDs in altitude hold, mixer)", p["flight_control"]),
        ("  flight_outer (RC, arming, 2 attitude + 2 altitude PIDs)", p["flight_outer"]),
        ("  flight_inner (3 rate PIDs, mixer)", p["flight_inner"]),
        ("flight_baro (eq. 6, the gate, the altitude filter)", p["flight_baro"]),
        ("MS5611 compensation (64-bit integer)", p["ms5611_compensate"]),
        ("SBUS frame decode", p["sbus_decode"]),
        ("telemetry line", p["telemetry_line"]),
        ("driver: MPU-6050 + aux burst on the TWI (bus time)", burst),
        ("driver: MS5611 command + ADC read (bus time)", baro_io),
    ]
    print("AVR reference FC (ATmega2560, 16 MHz), cycles per call, counted in simavr:")
    for name, cyc in rows:
        print(f"  {name:<62} {cyc:>9,d}  {cyc / F_CPU * 1e6:>8.0f} us")
    # one loop of everything at once (the firmware before its rate loop ran alone)
    worst = (p["flight_sense_mahony"] + p["flight_control"] + p["flight_baro"] + p["ms5611_compensate"]
             + p["sbus_decode"] + p["telemetry_line"] + burst + baro_io)
    usual = p["flight_sense_mahony"] + p["flight_control"] + burst
    print("one loop doing everything each cycle:")
    for name, cyc in (("a cycle, usual (sense, control, MPU burst)", usual),
                      ("a cycle, worst (+ baro pair, SBUS frame, telemetry line)", worst)):
        print(f"  {name:<62} {cyc:>9,d}  {cyc / F_CPU * 1e6:>8.0f} us")
    ekf_cycle = worst - p["estimator_mahony"] + p["estimator_ekf"]
    for rate in sorted({250, board_rate()}, reverse=True):
        budget = F_CPU // rate
        print(f"  at {rate} Hz: budget {budget:,d} cycles; worst cycle {100 * worst / budget:.0f} % "
              f"(headroom {budget - worst:,d}); usual {100 * usual / budget:.0f} %; "
              f"with the EKF {100 * ekf_cycle / budget:.0f} %")
    # the firmware's loop (dut/avr/main.c): slots at board_rate() * inner, each the MPU burst and the
    # rate loop; the first slot of a cycle adds the estimator, the others the outer loops, a barometer
    # step, an SBUS frame and, when no barometer pair came in the same slot, the telemetry line
    inner = board_inner()
    slot_rate = board_rate() * inner
    budget = F_CPU // slot_rate
    rate_loop = burst + p["flight_measure"] + p["flight_inner"]
    outer = rate_loop + p["flight_outer"] + baro_io + p["sbus_decode"]
    slots = (
        ("slot: rate loop + estimator", rate_loop + p["flight_estimate_mahony"]),
        ("slot: rate loop + outer loops, baro step, SBUS frame", outer),
        ("slot: ... + a barometer pair (compensation, fusion)",
         outer + p["ms5611_compensate"] + p["flight_baro"]),
        ("slot: ... + a telemetry line (no barometer pair)", outer + p["telemetry_line"]),
    )
    print(f"the firmware's loop: the rate loop at {slot_rate} Hz, the estimator and outer loops at "
          f"{board_rate()} Hz; a slot's budget {budget:,d} cycles:")
    for name, cyc in slots:
        print(f"  {name:<62} {cyc:>9,d}  {cyc / F_CPU * 1e6:>8.0f} us  {100 * cyc / budget:>4.0f} %")
    print(f"  the rate loop alone (burst, measure, rate PIDs): {rate_loop:,d} cycles, "
          f"{rate_loop / F_CPU * 1e6:.0f} us from the sample's request to the compare registers")
    size = subprocess.run(["avr-size", "-A", str(FC_ELF)], capture_output=True, text=True, check=True).stdout
    rows_ = (line.split() for line in size.splitlines())
    sec = {f[0]: int(f[1]) for f in rows_ if len(f) >= 2 and f[1].isdigit()}
    flash = sec.get(".text", 0) + sec.get(".data", 0)
    ram = sec.get(".data", 0) + sec.get(".bss", 0) + sec.get(".noinit", 0)
    print(f"build/avr/fc.elf: flash {flash:,d} of 262,144 bytes ({100 * flash / 262144:.1f} %), "
          f"RAM {ram:,d} of 8,192 static ({100 * ram / 8192:.1f} %), EEPROM {sec.get('.eeprom', 0)} of 4,096")
    return 0


if __name__ == "__main__":
    sys.exit(main())
