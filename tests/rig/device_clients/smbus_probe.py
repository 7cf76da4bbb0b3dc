"""A DUT written as any Python driver would be: smbus2 on /dev/i2c-1. Prints what it measured as JSON.

It wakes the MPU-6050 and reads one 14-byte burst, reads the HMC5883L's ID after enabling bypass,
and runs an MS5611 conversion pair, compensating with the datasheet's integer maths (first and
second order), written out here independently of the emulator.
"""

import json
import time

from smbus2 import SMBus, i2c_msg

MPU, HMC, BARO = 0x68, 0x1E, 0x77


def s16(hi, lo):
    v = hi << 8 | lo
    return v - 65536 if v & 0x8000 else v


def ms5611_pressure(bus):
    bus.write_byte(BARO, 0x1E)                      # reset
    time.sleep(0.003)
    prom = []
    for i in range(8):
        w, r = i2c_msg.write(BARO, [0xA0 + 2 * i]), i2c_msg.read(BARO, 2)
        bus.i2c_rdwr(w, r)
        b = list(r)
        prom.append(b[0] << 8 | b[1])

    def adc(cmd):
        bus.write_byte(BARO, cmd)
        time.sleep(0.010)                           # OSR 4096 converts in at most 9.04 ms
        b = bus.read_i2c_block_data(BARO, 0x00, 3)
        return b[0] << 16 | b[1] << 8 | b[2]

    d1, d2 = adc(0x48), adc(0x58)
    c = prom
    dt = d2 - c[5] * 2**8
    temp = 2000 + dt * c[6] // 2**23
    off = c[2] * 2**16 + (c[4] * dt) // 2**7
    sens = c[1] * 2**15 + (c[3] * dt) // 2**8
    if temp < 2000:                                 # second-order compensation, datasheet p. 8
        t2 = dt * dt // 2**31
        off2 = 5 * (temp - 2000) ** 2 // 2
        sens2 = 5 * (temp - 2000) ** 2 // 4
        if temp < -1500:
            off2 += 7 * (temp + 1500) ** 2
            sens2 += 11 * (temp + 1500) ** 2 // 2
        temp, off, sens = temp - t2, off - off2, sens - sens2
    p = (d1 * sens // 2**21 - off) // 2**15
    return prom, p, temp


with SMBus(1) as bus:
    out: dict[str, object] = {"who_am_i": bus.read_byte_data(MPU, 0x75)}
    bus.write_byte_data(MPU, 0x6B, 0x00)            # wake
    time.sleep(0.05)
    b = bus.read_i2c_block_data(MPU, 0x3B, 14)
    accel = [s16(b[i], b[i + 1]) / 16384.0 for i in (0, 2, 4)]
    gyro = [s16(b[i], b[i + 1]) / 131.0 for i in (8, 10, 12)]
    out.update(accel_g=accel, gyro_dps=gyro, temp_raw=s16(b[6], b[7]))
    bus.write_byte_data(MPU, 0x37, 0x02)            # I2C_BYPASS_EN
    w, r = i2c_msg.write(HMC, [0x0A]), i2c_msg.read(HMC, 3)
    bus.i2c_rdwr(w, r)
    out["hmc_id"] = bytes(r).decode("ascii")
    prom, p, t = ms5611_pressure(bus)
    out.update(prom=prom, pressure_pa=p / 1.0, baro_temp_c=t / 100.0)
print(json.dumps(out))
