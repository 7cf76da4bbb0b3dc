/* RC by MSP on a USART, as a flight controller takes it from a companion computer or an MSP receiver:
   USART1 (the STM32F405 board's RC port) at 115200 baud 8N1 from the reset clock's 16 MHz HSI
   (BRR 139: RM0090 30.3.4, USARTDIV = 16 MHz / (16 x 115200) = 8.68, mantissa 8, fraction 11/16),
   each byte taken in the RXNE interrupt (NVIC 37), the core asleep in WFI between.

   MSP v1 as MultiWii and Betaflight define it: a request is "$M<", the payload's size, the command, the
   payload, and the XOR of size, command and payload; a reply is the same with '>' (or '!' for a command
   the FC does not know, with no payload).
     SET_RAW_RC (200): the payload is the channels, u16 little-endian each (microseconds); kept, and
       acknowledged with an empty reply. The first REPORTED frames go out through semihosting as
       "msp_F_n" (the channel count) and "msp_F_C" (each channel).
     MSP_RC (105): the reply carries the channels last set, u16 little-endian each.
     anything else: "$M!", size 0, the command.
   A frame whose checksum is wrong is dropped (counted: "msp_bad"), as is one too long for the buffer.
   At boot it reads the MPU-6050's WHO_AM_I over I2C1 ("who_am_i"), as a flight controller finds its gyro
   and holds the board's four ESCs at idle, 1000 us every 2500 us (TIM3 CH3/CH4 on PB0/PB1, TIM2 CH4/CH3
   on PA3/PA2, 1 us ticks: 16 MHz / (PSC 15 + 1)): a run through `rig run` wants a firmware that read a
   sensor and drove the motors. */
#include "i2c_hal_poll.h"
#include "timer_checks.h"

#define BRR_115200_AT_16MHZ 139u
#define MSP_RC 105u
#define MSP_SET_RAW_RC 200u
#define MAX_CHANNELS 18u /* Betaflight's most (MultiWii sends 8) */
#define MAX_PAYLOAD (2u * MAX_CHANNELS)
#define REPORTED 3u
#define QUEUE 4u /* frames taken and not yet answered */

struct frame {
    uint8_t command, size, payload[MAX_PAYLOAD];
};

static struct frame queue[QUEUE];
static volatile uint32_t queued, answered, bad;

/* The receiver's state: how much of the frame under way has come */
static uint8_t state, size, command, sum, have, payload[MAX_PAYLOAD];

static void byte_in(uint8_t b)
{
    static const uint8_t head[3] = { '$', 'M', '<' };
    if (state < 3) {
        state = b == head[state] ? state + 1u : (b == '$');
        return;
    }
    if (state == 3) {
        size = b;
        sum = b;
        have = 0;
        state = size > MAX_PAYLOAD ? 0 : 4;
        return;
    }
    if (state == 4) {
        command = b;
        sum ^= b;
        state = 5;
        return;
    }
    if (have < size) {
        payload[have++] = b;
        sum ^= b;
        return;
    }
    state = 0;
    if (b != sum) {
        bad++;
        return;
    }
    if (queued - answered == QUEUE) {
        return; /* (the main loop is behind: the frame is lost, as a full buffer loses it) */
    }
    struct frame *f = &queue[queued % QUEUE];
    f->command = command;
    f->size = size;
    for (unsigned i = 0; i < size; i++) {
        f->payload[i] = payload[i];
    }
    queued++;
}

void usart1_handler(void)
{
    uint32_t sr = USART_SR(USART1_BASE);
    if (sr & (USART_SR_RXNE | USART_SR_ORE)) {
        uint8_t b = (uint8_t)USART_DR(USART1_BASE); /* (SR then DR: clears ORE, FE too) */
        if (!(sr & USART_SR_FE)) {
            byte_in(b);
        }
    }
}

static void put(uint8_t b)
{
    while (!(USART_SR(USART1_BASE) & USART_SR_TXE)) {
    }
    USART_DR(USART1_BASE) = b;
}

static void reply(char direction, uint8_t cmd, const uint8_t *data, uint8_t n)
{
    uint8_t check = n ^ cmd;
    put('$');
    put('M');
    put((uint8_t)direction);
    put(n);
    put(cmd);
    for (unsigned i = 0; i < n; i++) {
        put(data[i]);
        check ^= data[i];
    }
    put(check);
}

static uint8_t channels[MAX_PAYLOAD], channel_bytes;

static void answer(const struct frame *f, unsigned sets)
{
    if (f->command == MSP_SET_RAW_RC) {
        channel_bytes = f->size & ~1u;
        for (unsigned i = 0; i < channel_bytes; i++) {
            channels[i] = f->payload[i];
        }
        if (sets < REPORTED) {
            char name[] = "msp_0_n";
            name[4] = (char)('0' + sets);
            report(name, channel_bytes / 2u);
            for (unsigned c = 0; c < channel_bytes / 2u; c++) {
                char channel_name[] = "msp_0_00";
                channel_name[4] = (char)('0' + sets);
                channel_name[6] = (char)('0' + (c + 1u) / 10u);
                channel_name[7] = (char)('0' + (c + 1u) % 10u);
                report(channel_name, (uint32_t)channels[2u * c] | (uint32_t)channels[2u * c + 1u] << 8);
            }
        }
        reply('>', MSP_SET_RAW_RC, 0, 0);
    } else if (f->command == MSP_RC) {
        reply('>', MSP_RC, channels, channel_bytes);
    } else {
        reply('!', f->command, 0, 0);
    }
}

/* The board's motor outputs at @us (PWM mode 1, preloaded) */
static void escs_idle(uint32_t us)
{
    static const struct {
        uint32_t timer, port;
        unsigned pin, channel, af;
    } escs[4] = {
        { TIM3_BASE, PORT_B, 0, 3, 2 },
        { TIM3_BASE, PORT_B, 1, 4, 2 },
        { TIM2_BASE, PORT_A, 3, 4, 1 },
        { TIM2_BASE, PORT_A, 2, 3, 1 },
    };
    RCC_APB1ENR |= (1u << 0) | (1u << 1); /* TIM2, TIM3 */
    for (unsigned m = 0; m < 4; m++) {
        uint32_t t = escs[m].timer;
        unsigned ch = escs[m].channel;
        pin_af(escs[m].port, escs[m].pin, escs[m].af);
        TIM_CCMR2(t) |= (TIM_CCMR_PWM1 | TIM_CCMR_OCPE) << (ch == 3 ? 0u : 8u);
        TIM_CCR(t, ch) = us;
        TIM_CCER(t) |= TIM_CCER_E(ch);
    }
    timer_start(TIM2_BASE, 15u, 2499u, TIM_CR1_ARPE);
    timer_start(TIM3_BASE, 15u, 2499u, TIM_CR1_ARPE);
}

int main(void)
{
    escs_idle(1000u);
    i2c1_init(80u, 17u); /* 16 MHz / (2 * 80): 100 kHz; 1000 ns rise: 16 + 1 */
    report("who_am_i", read_reg(MPU_ADDR, MPU_WHO_AM_I));
    RCC_APB2ENR |= RCC_APB2ENR_USART1EN;
    USART_BRR(USART1_BASE) = BRR_115200_AT_16MHZ;
    USART_CR1(USART1_BASE) = USART_CR1_UE | USART_CR1_TE | USART_CR1_RE | USART_CR1_RXNEIE;
    NVIC_ISER(USART1_IRQ / 32u) = 1u << (USART1_IRQ % 32u);
    unsigned sets = 0;
    uint32_t bad_reported = 0;
    for (;;) {
        __asm volatile("cpsid i"); /* (an interrupt between the test and WFI still wakes it) */
        if (answered == queued && bad_reported == bad) {
            __asm volatile("wfi");
        }
        __asm volatile("cpsie i");
        if (bad_reported != bad) {
            bad_reported = bad;
            report("msp_bad", bad_reported);
        }
        if (answered != queued) {
            const struct frame *f = &queue[answered % QUEUE];
            answer(f, sets);
            sets += f->command == MSP_SET_RAW_RC;
            answered++;
        }
    }
}
