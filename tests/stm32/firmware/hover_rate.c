/* A small flight firmware of ours for the STM32 tier's lockstep runs (rig run --mcu stm32f405-gy86): ST's
   168 MHz clock set-up, the MPU-6050 read over I2C1 with the HAL's polling sequences (i2c_hal_poll.h),
   and a rate loop at the ESCs' 490 Hz: each PWM period (TIM3's update interrupt; the core sleeps in WFI
   between, as an FC's idle task does: under QEMU's icount a sleeping core costs nothing, a polling one
   an MMIO access per loop) it reads the gyro and puts
   hover throttle plus a P term against the body rates on the four outputs of the board file
   (S1 PB0 TIM3_CH3, S2 PB1 TIM3_CH4, S3 PA3 TIM2_CH4, S4 PA2 TIM2_CH3), mixed as the reference FC's X
   mixer (dut/src/control.c: 1 front-right, 2 front-left, 3 rear-left, 4 rear-right). It never ends. */
#include "i2c_hal_poll.h"
#include "timer_checks.h"

#define MPU_SMPLRT_DIV 0x19u
#define MPU_CONFIG 0x1Au
#define MPU_GYRO_CONFIG 0x1Bu
#define MPU_GYRO_XOUT_H 0x43u
#define GYRO_FS_500 0x08u  /* ±500 °/s: 65.5 LSB per °/s */
#define DLPF_44HZ 3u       /* 1 kHz sampling */
#define APB1_HZ_MHZ 42u    /* 168 MHz / 4 */
#define I2C_FAST_CCR 35u   /* 42 MHz / (3 * 35): 400 kHz */
#define I2C_FAST_TRISE 13u /* 300 ns: 42 * 0.3 + 1 */
#define PWM_PSC 83u        /* the APB1 timer clock 84 MHz / 84: 1 us ticks */
#define PWM_ARR 2040u      /* 2041 us: 490 Hz */
#define IDLE_US 1000
#define HOVER_US 1540    /* a slow climb: the quad hovers at 1511 us (the reference FC hover_us) */
#define ARM_PERIODS 245u /* half a second at idle first, as ESCs arm */
#define RATE_GAIN_NUM 3  /* 3/655 us per LSB: 0.3 us per °/s */
#define RATE_GAIN_DEN 655
#define TIM3_IRQ 29u /* RM0090 table 61 */

static void pwm_channel(uint32_t timer, unsigned ch)
{
    volatile uint32_t *ccmr = ch <= 2 ? &TIM_CCMR1(timer) : &TIM_CCMR2(timer);
    unsigned shift = ch % 2 ? 0u : 8u;
    *ccmr = (*ccmr & ~(0xFFu << shift)) | ((TIM_CCMR_PWM1 | TIM_CCMR_OCPE) << shift);
    TIM_CCR(timer, ch) = IDLE_US;
    TIM_CCER(timer) |= TIM_CCER_E(ch);
}

static void outputs_init(void)
{
    RCC_APB1ENR |= (1u << 0) | (1u << 1); /* TIM2, TIM3 */
    pin_af(PORT_B, 0, 2);
    pin_af(PORT_B, 1, 2);
    pin_af(PORT_A, 3, 1);
    pin_af(PORT_A, 2, 1);
    pwm_channel(TIM3_BASE, 3);
    pwm_channel(TIM3_BASE, 4);
    pwm_channel(TIM2_BASE, 4);
    pwm_channel(TIM2_BASE, 3);
    timer_start(TIM2_BASE, PWM_PSC, PWM_ARR, TIM_CR1_ARPE);
    timer_start(TIM3_BASE, PWM_PSC, PWM_ARR, TIM_CR1_ARPE);
    TIM_DIER(TIM3_BASE) = TIM_DIER_UIE;
    NVIC_ISER(TIM3_IRQ / 32u) = 1u << (TIM3_IRQ % 32u);
}

static volatile uint32_t periods;

void tim3_handler(void)
{
    TIM_SR(TIM3_BASE) = ~TIM_SR_UIF;
    periods++;
}

static uint32_t clamp_us(int32_t us) { return (uint32_t)(us < IDLE_US ? IDLE_US : us > 2000 ? 2000 : us); }

static int16_t word_at(const uint8_t *bytes) { return (int16_t)(bytes[0] << 8 | bytes[1]); }

int main(void)
{
    clock_168mhz();
    i2c1_init(I2C_CCR_FS | I2C_FAST_CCR, I2C_FAST_TRISE);
    I2C1_CR1 = 0; /* FREQ for the 42 MHz APB1, set with the peripheral off */
    I2C1_CR2 = APB1_HZ_MHZ;
    I2C1_CR1 = I2C_CR1_PE;
    write_reg(MPU_ADDR, MPU_PWR_MGMT_1, 0x00);
    write_reg(MPU_ADDR, MPU_SMPLRT_DIV, 0);
    write_reg(MPU_ADDR, MPU_CONFIG, DLPF_44HZ);
    write_reg(MPU_ADDR, MPU_GYRO_CONFIG, GYRO_FS_500);
    outputs_init();
    for (uint32_t seen = 0;;) {
        while (periods == seen) {
            __asm volatile("wfi");
        }
        seen = periods;
        uint8_t raw[6];
        const uint8_t first = MPU_GYRO_XOUT_H;
        if (xfer(MPU_ADDR, &first, 1, raw, sizeof raw) != 0 || seen < ARM_PERIODS) {
            continue;
        }
        /* the sensor's axes (x forward, y left, z up on a flat board) to the body's (forward, right, down) */
        int32_t p = word_at(raw), q = -word_at(raw + 2), r = -word_at(raw + 4);
        int32_t roll = -p * RATE_GAIN_NUM / RATE_GAIN_DEN, pitch = -q * RATE_GAIN_NUM / RATE_GAIN_DEN;
        int32_t yaw = -r * RATE_GAIN_NUM / RATE_GAIN_DEN;
        TIM_CCR(TIM3_BASE, 3) = clamp_us(HOVER_US - roll + pitch + yaw); /* 1 front-right */
        TIM_CCR(TIM3_BASE, 4) = clamp_us(HOVER_US + roll + pitch - yaw); /* 2 front-left */
        TIM_CCR(TIM2_BASE, 4) = clamp_us(HOVER_US + roll - pitch + yaw); /* 3 rear-left */
        TIM_CCR(TIM2_BASE, 3) = clamp_us(HOVER_US - roll - pitch - yaw); /* 4 rear-right */
    }
}
