/* The EEPROM image of the configuration (config_image.h). The key table is kept in flash on the AVR
   (PROGMEM) and read entry by entry, so it costs no RAM there. */
#include "config_image.h"

#include <limits.h>
#include <string.h>

#ifdef __AVR__
#include <avr/pgmspace.h>
#define FLASH PROGMEM
#define flash_read(dst, src, n) memcpy_P(dst, src, n)
#else
#define FLASH
#define flash_read(dst, src, n) memcpy(dst, src, n)
#endif

struct image_key {
    char kind;
    uint8_t n;
    uint16_t off;
    float low, high; /* NAN: no limit */
};
#define ANY NAN
#define KIND_D 'D'
#define KIND_I 'I'
#define KIND_S 'S'
#define FC_KEY(name, kind, n, low, high) { KIND_##kind, n, offsetof(fc_config, name), low, high },
static const struct image_key keys[] FLASH = { FC_CONFIG_KEYS(FC_KEY) };
#undef FC_KEY

#define FC_KEY(name, kind, n, low, high) #name ":" #kind #n ";"
static const char signature[] FLASH = FC_CONFIG_KEYS(FC_KEY);
#undef FC_KEY

uint16_t fc_crc16(const uint8_t *p, unsigned n, uint16_t crc)
{
    while (n--) {
        crc ^= (uint16_t)(*p++ << 8);
        for (uint8_t b = 0; b < 8; b++)
            crc = crc & 0x8000 ? (uint16_t)(crc << 1 ^ 0x1021) : (uint16_t)(crc << 1);
    }
    return crc;
}

uint16_t fc_image_layout(void)
{
    uint16_t crc = 0xFFFF;
    for (unsigned i = 0; i < sizeof signature - 1; i++) {
        uint8_t ch;
        flash_read(&ch, &signature[i], 1);
        crc = fc_crc16(&ch, 1, crc);
    }
    return crc;
}

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static int in_range(float v, float low, float high)
{
    return v == v && v - v == 0 && (low != low || v >= low) && (high != high || v <= high); /* finite */
}

int config_from_image(fc_config *c, const uint8_t *img, unsigned n)
{
    config_defaults(c);
    if (n < FC_IMAGE_SIZE)
        return FC_IMAGE_MAGIC_BAD;
    if (img[0] == 0xFF && img[1] == 0xFF)
        return FC_IMAGE_BLANK;
    if ((img[0] | img[1] << 8) != FC_IMAGE_MAGIC)
        return FC_IMAGE_MAGIC_BAD;
    if ((unsigned)(img[2] | img[3] << 8) != fc_image_layout() || img[5] != FC_IMAGE_NKEYS)
        return FC_IMAGE_LAYOUT_BAD;
    unsigned body = FC_IMAGE_SIZE - 2;
    if (fc_crc16(img, body, 0xFFFF) != (uint16_t)(img[body] | img[body + 1] << 8))
        return FC_IMAGE_CRC_BAD;
    fc_config t = *c;
    if (img[4] != 0xFF && config_profile(&t, img[4]) < 0)
        return FC_IMAGE_PROFILE_BAD;
    const uint8_t *v = img + FC_IMAGE_HEADER;
    for (unsigned k = 0; k < FC_IMAGE_NKEYS; k++) {
        struct image_key key;
        flash_read(&key, &keys[k], sizeof key);
        if (key.kind == 'S')
            continue;
        int set = img[6 + k / 8] >> (k % 8) & 1;
        char *field = (char *)&t + key.off;
        if (key.kind == 'I') {
            int32_t x = (int32_t)le32(v);
            if (set) {
                if (!in_range((float)x, key.low, key.high) || x > INT_MAX || x < INT_MIN) /* AVR: 16 bits */
                    return FC_IMAGE_VALUE_BAD;
                *(int *)field = (int)x;
            }
            v += 4;
        } else {
            for (uint8_t j = 0; j < key.n; j++, v += 4) {
                uint32_t bits = le32(v);
                float x;
                memcpy(&x, &bits, 4);
                if (set) {
                    if (!in_range(x, key.low, key.high))
                        return FC_IMAGE_VALUE_BAD;
                    ((real *)field)[j] = x;
                }
            }
        }
    }
    if (config_check(&t) < 0)
        return FC_IMAGE_RATES_BAD;
    *c = t;
    return FC_IMAGE_OK;
}

const char *fc_image_why(int status)
{
    switch (status) {
    case FC_IMAGE_OK:
        return "eeprom";
    case FC_IMAGE_BLANK:
        return "blank";
    case FC_IMAGE_MAGIC_BAD:
        return "magic";
    case FC_IMAGE_LAYOUT_BAD:
        return "layout";
    case FC_IMAGE_CRC_BAD:
        return "crc";
    case FC_IMAGE_VALUE_BAD:
        return "value";
    case FC_IMAGE_PROFILE_BAD:
        return "profile";
    case FC_IMAGE_RATES_BAD:
        return "rates";
    default:
        return "?";
    }
}

int fc_image_sets(const uint8_t *img, enum fc_key_index key) { return img[6 + key / 8] >> (key % 8) & 1; }

int fc_image_has_profile(const uint8_t *img) { return img[4] != 0xFF; }
