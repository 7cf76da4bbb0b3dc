/*
 * The rig's STM32F4 device models (RM0090, the STM32F405/415/407/417 reference manual): RCC and PWR, the
 * FLASH interface and the flash, the independent and window watchdogs, GPIO ports, the DMA controllers,
 * the I2C controllers, the timers TIM1-TIM14, the USARTs, the ADCs, the Cortex-M4's DWT cycle counter, and the GY-86 sensor
 * board (the rig's chip core) as an I2C slave.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */

#ifndef RIG_STM32F4_H
#define RIG_STM32F4_H

#include "hw/boards.h"
#include "hw/clock.h"
#include "hw/i2c/i2c.h"
#include "hw/sysbus.h"
#include "qemu/timer.h"
#include "qom/object.h"

/*
 * One register of a block, as the reference manual's register map gives it: its offset, its reset
 * value and the bits software can write (the rest read as the hardware sets them).
 */
typedef struct RigRegister {
    uint16_t offset;
    const char *name;
    uint32_t reset;
    uint32_t writable;
} RigRegister;

/* The index of the register at @offset in @table, or -1 when the block has none there */
int rig_register_index(const RigRegister *table, int count, hwaddr offset);

/* RCC (RM0090 section 7.3) */
#define TYPE_RIG_STM32_RCC "rig-stm32f4-rcc"
OBJECT_DECLARE_SIMPLE_TYPE(RigStm32RccState, RIG_STM32_RCC)
#define RIG_RCC_REGISTERS 24 /* the most a chip has (the F411: 23 and DCKCFGR) */
#define RIG_RCC_RESETS 48

struct RigStm32RccState {
    SysBusDevice parent_obj;
    MemoryRegion iomem;
    uint32_t chip;                    /* property "chip": 405 (RM0090) or 411 (RM0383) */
    const RigRegister *table;         /* that chip's register table */
    unsigned count;                   /* its registers */
    uint32_t regs[RIG_RCC_REGISTERS]; /* in the table's order */
    uint32_t hse_hz;                  /* the board's crystal (property "hse-hz") */
    Clock *hclk;                      /* the AHB clock: the core, SysTick, DWT */
    Clock *tim_clk[2];                /* the timers' clocks on APB1 and APB2 ("apb1-tim", "apb2-tim") */
    uint64_t tim_hz[2];               /* their exact rates (a Clock keeps a period, which rounds) */
    bool powered;                     /* past the power-on reset: CSR's reset flags survive the next resets */
    /* the peripherals the reset registers (AHB1RSTR ... APB2RSTR) reset: register, bit, device */
    struct {
        hwaddr rstr_offset;
        unsigned bit;
        DeviceState *dev;
    } resets[RIG_RCC_RESETS];
    unsigned n_resets;
};

/* Whether the clock of bit @bit of the enable register at @enr_offset (AHB1ENR, APB1ENR, ...) is on */
bool rig_stm32_rcc_enabled(RigStm32RccState *rcc, hwaddr enr_offset, unsigned bit);

/* PCLK1 (@apb 1) or PCLK2 (@apb 2) in Hz: HCLK through the APB prescaler (RM0090 7.2) */
uint64_t rig_stm32_rcc_pclk_hz(RigStm32RccState *rcc, unsigned apb);

/* The timer clock of APB1 (@apb 1) or APB2 (@apb 2) in Hz: PCLKx, doubled when the APB prescaler is not 1
 * (RM0090 7.2, figure 21); with the F411's DCKCFGR.TIMPRE, HCLK up to a prescaler of 4, else 4 x PCLKx */
uint64_t rig_stm32_rcc_timer_hz(RigStm32RccState *rcc, unsigned apb);

/* @dev is reset while bit @bit of the reset register at @rstr_offset is set (RM0090 7.3.5-7.3.9) */
void rig_stm32_rcc_add_reset(RigStm32RccState *rcc, hwaddr rstr_offset, unsigned bit, DeviceState *dev);

/* PWR (RM0090 section 5.4) */
#define TYPE_RIG_STM32_PWR "rig-stm32f4-pwr"
OBJECT_DECLARE_SIMPLE_TYPE(RigStm32PwrState, RIG_STM32_PWR)

struct RigStm32PwrState {
    SysBusDevice parent_obj;
    MemoryRegion iomem;
    uint32_t chip;            /* property "chip": 405 (RM0090) or 411 (RM0383) */
    const RigRegister *table; /* that chip's CR and CSR */
    uint32_t cr, csr;
    RigStm32RccState *rcc;
};

/* The FLASH interface (RM0090 section 3.9) */
#define TYPE_RIG_STM32_FLASH_IF "rig-stm32f4-flash-if"
OBJECT_DECLARE_SIMPLE_TYPE(RigStm32FlashIfState, RIG_STM32_FLASH_IF)

#define RIG_FLASH_BYTES (1024 * 1024) /* the F405's main flash at 0x08000000 (RM0090 table 5) */

struct RigFlashChip;
struct RigStm32FlashIfState {
    SysBusDevice parent_obj;
    MemoryRegion iomem;
    uint32_t chip;                   /* property "chip": 405 (RM0090) or 411 (RM0383) */
    const struct RigFlashChip *part; /* that chip's registers, sectors and times */
    MemoryRegion cells; /* the main flash (sysbus MMIO 1): a ROM device, read from its RAM, written to program */
    MemoryRegion *rom;  /* the SoC's flash ROM, which the loader writes the image into */
    qemu_irq irq;       /* the FLASH global interrupt */
    QEMUTimer *busy;    /* the end of the operation under way (SR.BSY) */
    int64_t busy_until_ns;
    uint32_t acr, sr, cr, optcr;
    uint8_t key_step; /* 1 after KEY1 was written to KEYR */
    bool locked_out;  /* a wrong key: CR stays locked until reset */
};

/* The flash's cells over the SoC's flash ROM @rom: disabled until the machine first starts, when they take
 * the image the loader wrote into @rom */
void rig_stm32_flash_if_over(RigStm32FlashIfState *s, MemoryRegion *rom);

/* The watchdogs (RM0090 sections 19, 20) */
#define TYPE_RIG_STM32_IWDG "rig-stm32f4-iwdg"
OBJECT_DECLARE_SIMPLE_TYPE(RigStm32IwdgState, RIG_STM32_IWDG)

struct RigStm32IwdgState {
    SysBusDevice parent_obj;
    MemoryRegion iomem;
    RigStm32RccState *rcc;
    QEMUTimer *timer; /* the down-counter reaching 0 */
    uint32_t pr, rlr;
    bool running;                       /* started by KR = 0xCCCC (only a reset stops it) */
    bool unlocked;                      /* KR = 0x5555: PR and RLR writable */
    int64_t pvu_until_ns, rvu_until_ns; /* PR and RLR updates under way (SR.PVU, SR.RVU) */
};

#define TYPE_RIG_STM32_WWDG "rig-stm32f4-wwdg"
OBJECT_DECLARE_SIMPLE_TYPE(RigStm32WwdgState, RIG_STM32_WWDG)

struct RigStm32WwdgState {
    SysBusDevice parent_obj;
    MemoryRegion iomem;
    RigStm32RccState *rcc;
    qemu_irq irq;     /* the early wakeup interrupt */
    QEMUTimer *timer; /* the counter's next event: reaching 0x40 (EWIF), or 0x3F with WDGA (a reset) */
    uint32_t cr, cfr, sr;
    uint8_t base_count; /* the counter at base_ns */
    int64_t base_ns;
    uint64_t hz; /* counting PCLK1 at this rate (0: take it at the next use) */
};

/* What caused the system reset under way (rig_reset_cause): the link names it to the session */
typedef enum {
    RIG_RESET_SYSTEM = 0, /* a reset request (AIRCR.SYSRESETREQ) or anything but a watchdog */
    RIG_RESET_IWDG = 1,
    RIG_RESET_WWDG = 2,
} RigResetCause;
extern RigResetCause rig_reset_cause;

/* A watchdog's reset: its flag in RCC_CSR (@csr_flag, kept through the reset as on the chip) and a system
 * reset requested */
void rig_stm32_rcc_watchdog_reset(RigStm32RccState *rcc, uint32_t csr_flag, RigResetCause cause);

/* GPIO ports A..I (RM0090 section 8.4) */
#define TYPE_RIG_STM32_GPIO "rig-stm32f4-gpio"
OBJECT_DECLARE_SIMPLE_TYPE(RigStm32GpioState, RIG_STM32_GPIO)
#define RIG_GPIO_PINS 16
#define RIG_GPIO_AFS 16
/* a pin's alternate function lines (qdev GPIO "af-drive" in and "af-input" out): pin * 16 + AF number */
#define RIG_GPIO_AF_LINE(pin, af) ((pin)*RIG_GPIO_AFS + (af))
/* the "af-drive" level of a peripheral that lets go of the pin (an input, a disabled output): Hi-Z */
#define RIG_GPIO_AF_RELEASED (-1)

struct RigStm32GpioState {
    SysBusDevice parent_obj;
    MemoryRegion iomem;
    uint8_t port;  /* 0 for A ... 8 for I (property "port") */
    uint32_t chip; /* property "chip": 405 (RM0090) or 411 (RM0383), whose ports A and B reset apart */
    RigStm32RccState *rcc;
    uint32_t moder, otyper, ospeedr, pupdr, odr, afr[2];
    uint32_t lckr;      /* LCK[15:0] and LCKK once the lock sequence has completed */
    uint8_t lock_step;  /* how far the lock key sequence has come */
    uint32_t lock_try;  /* the LCK bits written in its first step */
    uint16_t ext_level; /* what outside drivers put on the pins (qdev GPIO inputs) */
    uint16_t ext_driven;
    uint16_t pins; /* the levels last sent out */
    qemu_irq out[RIG_GPIO_PINS];
    qemu_irq level[RIG_GPIO_PINS]; /* the same levels for SYSCFG's EXTI multiplexer ("level") */
    /* the peripherals' outputs on each AF (a bit per pin): driven at all, and their levels */
    uint16_t af_driven[RIG_GPIO_AFS];
    uint16_t af_level[RIG_GPIO_AFS];
    /* the peripherals' inputs: a pin in AF mode sends its level to the AF it selects */
    qemu_irq af_input[RIG_GPIO_PINS * RIG_GPIO_AFS];
    int8_t af_input_sent[RIG_GPIO_PINS];  /* the AF each pin last sent to (-1: none) */
    int8_t af_input_level[RIG_GPIO_PINS]; /* and the level it sent */
};

/* SYSCFG (RM0090 9.2): EXTICR's multiplexer from the ports' pins ("pin", port * 16 + pin) to EXTI's
 * lines 0..15 ("line"); EXTI (12.3): edges and SWIER into PR, PR & IMR to the NVIC (rig_stm32_exti.c) */
#define TYPE_RIG_STM32_SYSCFG "rig-stm32f4-syscfg"
OBJECT_DECLARE_SIMPLE_TYPE(RigStm32SyscfgState, RIG_STM32_SYSCFG)
#define TYPE_RIG_STM32_EXTI "rig-stm32f4-exti"
OBJECT_DECLARE_SIMPLE_TYPE(RigStm32ExtiState, RIG_STM32_EXTI)
#define RIG_EXTI_LINES 23
#define RIG_EXTI_IRQS 14 /* the NVIC inputs the lines raise (rig_exti_nvic) */
extern const uint8_t rig_exti_nvic[RIG_EXTI_IRQS];

struct RigStm32SyscfgState {
    SysBusDevice parent_obj;
    MemoryRegion iomem;
    RigStm32RccState *rcc;
    uint32_t regs[7];
    uint16_t pins[9];      /* each port's pin levels (the ports' "level" outputs) */
    int8_t line_level[16]; /* the level each line was last sent */
    qemu_irq line[16];
};

struct RigStm32ExtiState {
    SysBusDevice parent_obj;
    MemoryRegion iomem;
    uint32_t regs[6];
    uint32_t inputs; /* the lines' levels, for their edges */
    qemu_irq irq[RIG_EXTI_IRQS];
};

/* Connects I2C1's lines to the port B pins the firmware's AFR selects (rig_stm32_i2c_pins.c) */
void rig_stm32_route_i2c1(DeviceState *i2c1, DeviceState *gpiob);

/* True while an I2C controller ends a transfer for a repeated START (QEMU's bus has no such event): the
 * slaves' I2C_FINISH then is no STOP */
extern bool rig_i2c_repeated_start;

/* The virtual time of the bus event an I2C controller is carrying out (-1: none), which may lie before
 * now: a controller without its interrupts enabled ends a phase of the bus when the firmware next looks
 * (rig_stm32_i2c.c), and the slaves see it at the instant it ended on the wire */
extern int64_t rig_i2c_event_ns;
static inline int64_t rig_i2c_now_ns(void)
{
    return rig_i2c_event_ns >= 0 ? rig_i2c_event_ns : qemu_clock_get_ns(QEMU_CLOCK_VIRTUAL);
}

/* What a lazy model brings up to now before the link tells the session a time is reached (rig_link.c) */
void rig_link_sync_add(void (*sync)(void *opaque), void *opaque);

/* Every timer whose events need no QEMU timer brought up to now, its pins with it (rig_stm32_timer.c):
 * for a read of the pins (GPIO IDR), and, with @rearm, when what needs the events' instants changed
 * (EXTI starting or stopping to watch edges) */
void rig_stm32_timers_sync(bool rearm);
/* Whether an EXTI line 0..15 has an edge enabled (RTSR, FTSR): pins are watched (rig_stm32_exti.c) */
bool rig_stm32_exti_watches_pins(void);

/* The pin levels a port shows on its IDR */
uint16_t rig_stm32_gpio_levels(RigStm32GpioState *s);

/* The DMA controllers DMA1 and DMA2 (RM0090 section 10): one model, property "controller" 1 or 2 */
#define TYPE_RIG_STM32_DMA "rig-stm32f4-dma"
OBJECT_DECLARE_SIMPLE_TYPE(RigStm32DmaState, RIG_STM32_DMA)
#define RIG_DMA_STREAMS 8
#define RIG_DMA_FIFO 16
#define RIG_DMA_SYNCS 8
/* The DMA requests of the modelled peripherals: the DMA's "request" inputs and "eot1" outputs by number. A
 * timer's seven are numbered as their flags in TIMx_SR (UIF bit 0, CCxIF bit x, COMIF 5, TIF 6), whose DMA
 * enables in DIER are the same bits plus 8 */
enum { RIG_DMA_UP, RIG_DMA_CC1, RIG_DMA_CC2, RIG_DMA_CC3, RIG_DMA_CC4, RIG_DMA_COM, RIG_DMA_TRIG, RIG_DMA_TIM_REQS };
#define RIG_DMA_TIMER(n, request) ((n)*RIG_DMA_TIM_REQS + (request)) /* TIMn, n 1..14 */
#define RIG_DMA_I2C1_RX RIG_DMA_TIMER(15, 0)
#define RIG_DMA_I2C1_TX (RIG_DMA_I2C1_RX + 1)
#define RIG_DMA_USART_RX(n) (RIG_DMA_I2C1_TX + 2 * (n)-1) /* USARTn's RXNE request, n 1..6 (UART4, UART5 among them) */
#define RIG_DMA_USART_TX(n) (RIG_DMA_USART_RX(n) + 1)     /* its TXE request */
#define RIG_DMA_ADC(n) (RIG_DMA_USART_TX(6) + (n))        /* ADCn, n 1..3 */
#define RIG_DMA_SOURCES (RIG_DMA_ADC(3) + 1)

typedef struct RigDmaStream {
    uint32_t cr, ndtr, par, m0ar, m1ar, fcr;
    uint32_t reload;            /* NDTR at the enable: circular and double-buffer rounds start from it */
    uint32_t p_off, m_off;      /* bytes the peripheral and memory addresses have moved on this round */
    uint8_t fifo[RIG_DMA_FIFO]; /* bytes read and not yet written (packing when PSIZE and MSIZE differ) */
    unsigned fifo_len;
} RigDmaStream;

struct RigStm32DmaState {
    SysBusDevice parent_obj;
    MemoryRegion iomem;
    RigStm32RccState *rcc;
    uint8_t controller; /* 1 (DMA1) or 2 (DMA2) */
    uint32_t isr[2];    /* LISR (streams 0-3), HISR (4-7) */
    RigDmaStream stream[RIG_DMA_STREAMS];
    qemu_irq irq[RIG_DMA_STREAMS];
    qemu_irq eot1[RIG_DMA_SOURCES]; /* "eot1": the last-but-one item of a transfer taken (I2C's LAST) */
    bool level[RIG_DMA_SOURCES];    /* the request lines' levels */
    bool pending[RIG_DMA_SOURCES];  /* requests raised while the controller was moving an item */
    bool busy;
    QEMUTimer *later; /* the requests left when too many came at one instant */
    struct {
        void (*fn)(void *opaque);
        void *opaque;
    } sync[RIG_DMA_SYNCS]; /* what a lazy peripheral brings up to now before the registers are accessed */
    unsigned n_sync;
};

/* @fn(@opaque) runs before each access to the DMA's registers, and after a write to a stream's: a peripheral
 * that feeds a stream lazily (a USART's transmitter or receiver, an ADC's scan) moves the items due by now first, so NDTR
 * and the flags read are the chip's, and arms its QEMU timer again for the stream as written */
void rig_stm32_dma_add_sync(RigStm32DmaState *s, void (*fn)(void *opaque), void *opaque);
/* The stream @source's requests reach now (the controller clocked, the stream enabled, its CHSEL the
 * request's channel, items left): its SxCR, NDTR and the NDTR it was enabled with; false when there is none */
bool rig_stm32_dma_request_stream(RigStm32DmaState *s, unsigned source, uint32_t *cr, uint32_t *ndtr, uint32_t *reload);
/* The same stream itself (its addresses too), or NULL */
const RigDmaStream *rig_stm32_dma_request_target(RigStm32DmaState *s, unsigned source);

/* I2C v1 (RM0090 section 27), master mode */
#define TYPE_RIG_STM32_I2C "rig-stm32f4-i2c"
OBJECT_DECLARE_SIMPLE_TYPE(RigStm32I2cState, RIG_STM32_I2C)

/* What the bus is doing (the timer ends it); IDLE: nothing on the wire (idle, or SCL held low) */
typedef enum {
    RIG_I2C_IDLE,
    RIG_I2C_START,
    RIG_I2C_ADDRESS,
    RIG_I2C_TX_BYTE,
    RIG_I2C_RX_BYTE,
    RIG_I2C_STOP,
} RigI2cPhase;

struct RigStm32I2cState {
    SysBusDevice parent_obj;
    MemoryRegion iomem;
    RigStm32RccState *rcc;
    uint8_t apb1_bit; /* its clock enable in RCC_APB1ENR (property "apb1-bit": 21 for I2C1) */
    I2CBus *bus;
    qemu_irq ev_irq, er_irq;
    qemu_irq line_out[2]; /* the bus's drive of SCL and SDA: 1 released (pull-up), 0 held low */
    QEMUTimer *timer;
    RigI2cPhase phase;
    int64_t phase_end_ns; /* when the phase under way ends on the wire */
    int64_t event_ns;     /* while a phase's end is carried out: its time (else -1) */
    uint32_t cr1, cr2, oar1, oar2, ccr, trise, sr1, sr2;
    uint32_t sr1_seen; /* SR1 as last read: the first half of the SB and ADDR clear sequences */
    uint8_t dr, shift, address;
    bool shift_full;        /* receiver: a byte waits in the shift register behind a full DR (BTF) */
    bool receiving;         /* receiver: the last byte was acknowledged, so the slave sends another */
    bool scl, sda;          /* the lines as the GPIO pins show them (qdev GPIO inputs "scl-sda" 0 and 1) */
    bool slave_sends;       /* a read under way whose slave has a byte to send */
    bool sda_held;          /* that slave, abandoned without a STOP, holds SDA low */
    uint8_t unstick_clocks; /* SCL pulses by GPIO since */
    bool ack_next;          /* POS = 1: CR1.ACK at the end of the byte (or address) before this one */
    qemu_irq dma[2];        /* "dma": the receive (RXNE) and transmit (TXE) requests with CR2.DMAEN */
    bool dma_level[2];
    bool nack_last; /* CR2.LAST and the DMA's EOT_1: the next byte received is NACKed */
};

/* A timer (RM0090 sections 17-20): the advanced TIM1/TIM8, the general-purpose TIM2-TIM5 (TIM2 and TIM5
 * 32-bit) and TIM9-TIM14, the basic TIM6/TIM7 */
#define TYPE_RIG_STM32_TIMER "rig-stm32f4-timer"
OBJECT_DECLARE_SIMPLE_TYPE(RigStm32TimerState, RIG_STM32_TIMER)
#define RIG_TIM_CHANNELS 4
#define RIG_TIM_OUTPUTS 7          /* OC1..OC4, and TIM1/TIM8's complementary OC1N..OC3N */
#define RIG_TIM_PINS_PER_CHANNEL 4 /* "channel-out" line = output * 4 + the n-th pin it reaches */
#define RIG_TIM_REGS 21

typedef enum {
    RIG_TIM_IRQ_BRK, /* the advanced timers' four lines; the others raise only the first */
    RIG_TIM_IRQ_UP,
    RIG_TIM_IRQ_TRG_COM,
    RIG_TIM_IRQ_CC,
    RIG_TIM_IRQS,
} RigTimerIrq;

struct RigStm32TimerState {
    SysBusDevice parent_obj;
    MemoryRegion iomem;
    RigStm32RccState *rcc;
    uint8_t index;        /* 1..14 (property "index"): TIMn */
    uint8_t apb, rcc_bit; /* its bus (1, 2) and bit in RCC_APBxENR/APBxRSTR (properties "apb", "rcc-bit") */
    bool trace_pulses;    /* property "trace-pulses": each latched pulse on stderr */
    bool eager;           /* property "eager": the QEMU timer for every event, needed or not */
    const struct RigTimerKind *kind;
    Clock *clk;       /* the APB timer clock (RCC "apb1-tim" or "apb2-tim"): its changes */
    uint64_t hz;      /* its rate while the counter counted since base_ns */
    QEMUTimer *timer; /* the next event (a compare match, the end of the counting period) when it needs its instant */
    uint32_t regs[RIG_TIM_REGS];              /* as software reads them (ARR, PSC and CCRx: the preload registers) */
    uint32_t arr, psc, ccr[RIG_TIM_CHANNELS]; /* the shadow (active) registers */
    uint32_t prescaler;                       /* the prescaler's counter */
    uint8_t repetition;                       /* the repetition down-counter (advanced timers) */
    bool down;                                /* counting down (DIR as the counter sets it in center-aligned modes) */
    bool counting;                            /* CEN with a clock: base_ns and ticks_done run */
    int64_t base_ns;                          /* virtual time of timer-clock tick 0 */
    uint64_t ticks_done;                      /* timer-clock ticks accounted since base_ns */
    int64_t event_ns;                         /* the virtual time of the event being counted (its tick's) */
    bool ref[RIG_TIM_CHANNELS];               /* OCxREF */
    int8_t out[RIG_TIM_OUTPUTS];              /* last sent to the pins: 0, 1, released, -2 at reset */
    bool input[RIG_TIM_CHANNELS];             /* TIx: the level of each channel's input pin */
    uint8_t capture_count[RIG_TIM_CHANNELS];  /* edges since the last capture (ICxPSC) */
    uint32_t pulse_ticks[RIG_TIM_OUTPUTS], period_ticks; /* the pulses latched at the last update */
    uint64_t latched_hz;                                 /* the timer clock then */
    uint64_t latches;                                    /* periods latched since power-on ("latches") */
    uint64_t latched_ns;                                 /* the virtual time of the last ("latched-ns") */
    qemu_irq irq[RIG_TIM_IRQS];
    qemu_irq channel_out[RIG_TIM_OUTPUTS * RIG_TIM_PINS_PER_CHANNEL];
    qemu_irq pulse_ns[RIG_TIM_OUTPUTS]; /* "pulse-ns": each output's latched high time in ns */
    qemu_irq dma[RIG_DMA_TIM_REQS];     /* "dma": the DMA requests (RIG_DMA_UP ...), a pulse each */
    uint8_t dma_pending;                /* requests of the events being handled, sent once they are */
    bool settling;                      /* in settle(): the next event is armed by the outermost */
    uint8_t dma_sent;                   /* the requests last sent: a DMAR burst raises them again */
    uint8_t burst;                      /* the DMAR burst's next register, from DCR.DBA */
};

/* A USART or UART (RM0090 section 30, rig_stm32_usart.c): qdev GPIO outputs "dma-rx" (RXNE with
 * CR3.DMAR) and "dma-tx" (TXE with CR3.DMAT) are its DMA requests */
#define TYPE_RIG_STM32_USART "rig-stm32f4-usart"
/* A frame on the USART's RX line from @start_ns (not before now, nor before the end of the frames given
 * before): the start bit, @byte's 8 data bits, a parity bit ('E' even, 'O' odd, 'N' none) and @stop_bits
 * stop bits at @baud. False when the USART holds RIG_USART_FRAMES frames not yet over. */
#define RIG_USART_FRAMES 4096
bool rig_stm32_usart_receive(DeviceState *dev, uint8_t byte, int64_t start_ns, uint32_t baud, char parity,
                             unsigned stop_bits);

/* ADC1..ADC3 and their common registers (RM0090 section 13, rig_stm32_adc.c): one device, properties "count"
 * (the ADCs the chip has) and "chip" (405, 411); qdev GPIO outputs "dma" 0..2 are ADCn's DMA requests */
#define TYPE_RIG_STM32_ADC "rig-stm32f4-adc"
OBJECT_DECLARE_SIMPLE_TYPE(RigStm32AdcState, RIG_STM32_ADC)
/* External channel @channel (0..15) of ADC @adc (1..) at @microvolts from now on; false when there is none */
bool rig_stm32_adc_set_input(DeviceState *dev, unsigned adc, unsigned channel, uint32_t microvolts);

/* The GY-86 board (MPU-6050 at 0x68, the HMC5883L behind its bypass, MS5611 at 0x77): the rig's chip
 * core as one I2C slave that answers the addresses the chip core acknowledges */
#define TYPE_RIG_GY86 "rig-gy86"

/* The link to the rig's session (rig_link.c): lockstep in virtual time, and the GY-86's bus events
 * answered by the session's chip core when the board is linked (the GY-86's "link" property) */
#define TYPE_RIG_LINK "rig-link"
typedef struct RigLinkState RigLinkState;
bool rig_link_i2c_start(RigLinkState *s, uint64_t t_ns, uint8_t address, bool read);
void rig_link_i2c_write(RigLinkState *s, uint8_t byte);
uint8_t rig_link_i2c_read(RigLinkState *s);
void rig_link_i2c_nack(RigLinkState *s);
void rig_link_i2c_stop(RigLinkState *s);

/* DWT (ARMv7-M ARM C1.8): CYCCNT counts HCLK cycles in virtual time */
#define TYPE_RIG_DWT "rig-dwt"
OBJECT_DECLARE_SIMPLE_TYPE(RigDwtState, RIG_DWT)

struct RigDwtState {
    SysBusDevice parent_obj;
    MemoryRegion iomem;
    Clock *hclk;
    uint32_t ctrl;
    uint32_t cyccnt_base; /* CYCCNT when counting last (re)started */
    int64_t base_ns;      /* the virtual time then */
};

/* What one chip of the family has, as data (its datasheet's and reference manual's): the machines
 * rig-stm32f405 and rig-stm32f411 are one construction (rig_stm32f405.c) over QEMU's STM32F405 SoC,
 * each from its chip's table */
#define RIG_GPIO_PORTS 9 /* A..I, the most a chip of the family has */
typedef struct RigStm32Region {
    hwaddr base, size;
    const char *what;
} RigStm32Region;
typedef struct RigStm32Chip {
    const char *name;                   /* the machine's */
    uint32_t part;                      /* 405 or 411: the register tables the models take ("chip") */
    uint32_t flash_size;                /* bytes at 0x08000000 (and aliased at 0) */
    uint32_t ccm_size;                  /* the CCM data RAM's bytes at 0x10000000 (QEMU's SoC has none) */
    uint16_t timers;                    /* bit n: TIMn */
    uint8_t usarts;                     /* bit n: USARTn (UART4, UART5 among them) */
    uint8_t adcs;                       /* ADC1..ADCn */
    uint16_t port_pins[RIG_GPIO_PORTS]; /* each port's pins (bit n: Pxn); 0: the chip has no such port */
    const RigStm32Region *absent;       /* what the F405 SoC maps and the chip lacks: a bus error there */
    unsigned n_absent;
} RigStm32Chip;

/* The machine's init for @chip, and its class's (description, the "wires" property) */
void rig_stm32f4_machine_init(MachineState *machine, const RigStm32Chip *chip);
void rig_stm32f4_machine_class_init(MachineClass *mc, const char *desc);

#endif
