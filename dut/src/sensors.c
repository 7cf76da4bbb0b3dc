/* GY-86 drivers on the TWI (sensors.h). Register numbers from the MPU-6000/6050 register map, the
   HMC5883L and MS5611 datasheets, as docs/sensors.md section 7 lists them. */
#include "sensors.h"
#include "gy86.h"

#include <string.h>

#include "clock.h"
#include "twi.h"

#define ACC_LSB_PER_G 8192.0  /* +-4 g */
#define GYRO_LSB_PER_DPS 16.4 /* +-2000 dps */

static int wreg(uint8_t addr, uint8_t reg, uint8_t v)
{
    uint8_t b[2] = { reg, v };
    return twi_xfer(addr, b, 2, NULL, 0);
}

static int rregs(uint8_t addr, uint8_t reg, uint8_t *out, uint8_t n) { return twi_xfer(addr, &reg, 1, out, n); }

static void wait_ms(uint16_t ms, void (*each)(void))
{
    while (ms--) {
        clock_wait_us(1000);
        if (each)
            each();
    }
}

static const char *const whys[] = {
    "ok",
    "MPU-6050: no answer",
    "MPU-6050: wrong WHO_AM_I",
    "MPU-6050: configuration write failed",
    "HMC5883L: no answer through the MPU-6050's bypass",
    "HMC5883L: wrong ID (expected H43)",
    "HMC5883L: configuration write failed",
    "MPU-6050: aux master set-up failed",
    "MS5611: no answer",
    "MS5611: PROM read failed",
    "MS5611: PROM CRC-4 mismatch",
};

const char *sensors_why(int code)
{
    return code <= 0 && -code < (int)(sizeof whys / sizeof whys[0]) ? whys[-code] : "?";
}

int sensors_init(uint8_t mpu, uint8_t hmc, uint8_t baro, ms5611_dev *d, void (*each)(void))
{
    uint8_t id = 0;
    if (rregs(mpu, 0x75, &id, 1) < 0)
        return -1;
    if ((id & 0x7E) != 0x68)
        return -2;
    for (uint8_t i = 0; i < MPU_SETUP_N; i++) {
        if (wreg(mpu, mpu_setup[i][0], mpu_setup[i][1]) < 0)
            return -3;
        if (i == 0)
            wait_ms(100, each);
    }
    uint8_t hid[3] = { 0 };
    if (rregs(hmc, 0x0A, hid, 3) < 0)
        return -4;
    if (memcmp(hid, "H43", 3) != 0)
        return -5;
    /* 75 Hz, 8-sample average; gain 1 (1090 LSB/gauss); continuous */
    if (wreg(hmc, 0x00, 0x18) < 0 || wreg(hmc, 0x01, 0x20) < 0 || wreg(hmc, 0x02, 0x00) < 0)
        return -6;
    static const uint8_t aux[][2] = {
        { 0x37, 0x00 },               /* bypass off: the HMC5883L is the aux master's */
        { 0x24, 0x0D },               /* I2C_MST_CTRL: 400 kHz */
        { 0x25, 0x80 | SENSORS_HMC }, /* I2C_SLV0_ADDR: read from 0x1E */
        { 0x26, 0x03 },               /* I2C_SLV0_REG: DXRA */
        { 0x27, 0x80 | 6 },           /* I2C_SLV0_CTRL: enabled, 6 bytes into EXT_SENS_DATA_00.. */
        { 0x6A, 0x20 },               /* USER_CTRL: I2C_MST_EN */
    };
    for (uint8_t i = 0; i < sizeof aux / sizeof aux[0]; i++)
        if (wreg(mpu, aux[i][0], i == 2 ? (uint8_t)(0x80 | hmc) : aux[i][1]) < 0)
            return -7;
    memset(d, 0, sizeof *d);
    uint8_t cmd = 0x1E; /* MS5611 reset */
    if (twi_xfer(baro, &cmd, 1, NULL, 0) < 0)
        return -8;
    wait_ms(3, each);
    uint16_t any = 0;
    for (uint8_t i = 0; i < 8; i++) {
        uint8_t b[2];
        if (rregs(baro, (uint8_t)(0xA0 + 2 * i), b, 2) < 0)
            return -9;
        d->prom[i] = (uint16_t)(b[0] << 8 | b[1]);
        any |= d->prom[i];
    }
    if (!any || ms5611_crc4(d->prom) != (d->prom[7] & 0xF))
        return -10;
    wait_ms(10, each); /* the aux master's first HMC5883L read */
    return 0;
}

static int16_t be16(const uint8_t *b) { return (int16_t)(b[0] << 8 | b[1]); }

int sensors_read(uint8_t mpu, vec3 *acc, vec3 *gyro, vec3 *mag, int *mag_ok)
{
    /* 0x36 I2C_MST_STATUS (bit 0: SLV0 NACK, cleared by reading) .. 0x4E EXT_SENS_DATA_05: 25 bytes */
    uint8_t b[25];
    int r = rregs(mpu, 0x36, b, sizeof b);
    if (r < 0)
        return r;
    const uint8_t *a = b + 5, *g = b + 13, *m = b + 19;
    const real ka = FC_G0 / ACC_LSB_PER_G, kg = (M_PI / 180.0) / GYRO_LSB_PER_DPS, km = 1.0 / 1090.0;
    *acc = v3(be16(a) * ka, be16(a + 2) * ka, be16(a + 4) * ka);
    *gyro = v3(be16(g) * kg, be16(g + 2) * kg, be16(g + 4) * kg);
    *mag = v3(be16(m) * km, be16(m + 4) * km, be16(m + 2) * km); /* data order X, Z, Y */
    *mag_ok = !(b[0] & 0x01);
    return 0;
}

static int baro_xfer(void *ctx, const uint8_t *w, int wn, uint8_t *r, int rn)
{
    return twi_xfer(*(uint8_t *)ctx, w, (uint8_t)wn, r, (uint8_t)rn);
}

static double baro_clock(void *ctx)
{
    (void)ctx;
    return clock_seconds();
}

ms5611_bus sensors_baro_bus(uint8_t *addr) { return (ms5611_bus){ baro_xfer, baro_clock, addr }; }
