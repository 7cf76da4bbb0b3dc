/* MS5611: the command state machine in time, PROM, conversion timing, the corrupt result of an early
 * ADC read or a second convert (emulators/ms5611.py, docs/sensors.md §5). The host's samples are the
 * raw words (D1, D2) of its exact inverse of the compensation; the chip picks the one its command
 * asked for. */
#include "chip_internal.h"

#define CMD_RESET 0x1E
#define CMD_ADC_READ 0x00
enum { IDLE, CONVERTING, DONE };

void baro_reset(chip_baro *s)
{
    memcpy(s->prom, CHIP_BARO_DEFAULT_PROM, sizeof s->prom);
    s->state = IDLE;
}

static void finish(chip_baro *s)
{
    uint32_t value = s->kind ? s->last.d2 : s->last.d1;
    if (s->corrupt) /* disturbed by an early ADC read or a second convert: "incorrect result" */
        value ^= 0x5A5A;
    s->result = value < 1 ? 1 : value > 0xFFFFFE ? 0xFFFFFE : value;
    s->state = DONE;
}

bool baro_advance(chip_board *b, uint64_t now_ns, chip_need *need)
{
    chip_baro *s = &b->baro;
    if (now_ns < s->now_ns)
        return false;
    s->now_ns = now_ns;
    if (s->state != CONVERTING || now_ns < s->t_done_ns)
        return false;
    if (chip_take_baro(s, s->t_done_ns)) {
        b->counts[CHIP_COUNT_BARO_CONVERSIONS]++;
    } else if (b->demand) {
        memset(need, 0, sizeof *need);
        need->chip = CHIP_BARO;
        need->osr = s->osr;
        need->t_ns = s->t_done_ns;
        need->anchor_ns = s->t_cmd_ns;
        need->target_ns = now_ns;
        return true;
    } else {
        b->counts[CHIP_COUNT_BARO_CONVERSIONS]++;
        b->counts[CHIP_COUNT_BARO_UNDERRUNS]++;
    }
    finish(s);
    return false;
}

void baro_start(chip_baro *s, bool read)
{
    (void)read;
    s->first_byte = true;
}

static void respond(chip_baro *s, uint32_t value, uint8_t n)
{
    for (uint8_t i = 0; i < n; i++)
        s->response[i] = (uint8_t)(value >> (8 * (n - 1 - i)));
    s->resp_len = n;
    s->resp_pos = 0;
}

void baro_write(chip_baro *s, uint8_t cmd)
{
    if (!s->first_byte) /* trailing bytes (MultiWii's 0x1E 0x00) are ignored */
        return;
    s->first_byte = false;
    if (cmd == CMD_RESET) {
        s->state = IDLE;
        s->resp_len = s->resp_pos = 0;
        s->corrupt = false;
    } else if (cmd == CMD_ADC_READ) {
        if (s->state == DONE) {
            respond(s, s->result, 3);
            s->state = IDLE;
        } else {
            if (s->state == CONVERTING)
                s->corrupt = true;
            respond(s, 0, 3);
        }
    } else if (cmd >= 0xA0 && cmd <= 0xAE && cmd % 2 == 0) {
        respond(s, s->prom[(cmd - 0xA0) / 2], 2);
    } else if ((cmd & 0xE1) == 0x40 && ((cmd >> 1) & 0x7) <= 4) { /* 0x40..0x48, 0x50..0x58 */
        s->corrupt = s->state == CONVERTING;
        s->kind = (cmd & 0x10) ? 1 : 0;
        s->osr = (cmd >> 1) & 0x7;
        s->t_cmd_ns = s->now_ns;
        s->t_done_ns =
            s->now_ns + (s->max_timing ? CHIP_BARO_CONVERSION_MAX_NS : CHIP_BARO_CONVERSION_TYPICAL_NS)[s->osr];
        s->state = CONVERTING;
        s->resp_len = s->resp_pos = 0;
    }
    /* anything else is not a command: ignored */
}

uint8_t baro_read(chip_baro *s)
{
    if (s->resp_pos < s->resp_len)
        return s->response[s->resp_pos++];
    return 0;
}
